//! Writing a dataset folder ([`Dataset::save`]): EXR images and PNG previews, the mesh (copied in
//! unless already inside the folder) and `dataset.json`, last, with arrays of numbers kept on
//! one line.

use std::path::{Path, PathBuf};

use super::json::{RawCamera, RawDataset, RawIntrinsics, RawLight, RawView};
use super::{
    CONVENTIONS_NOTE, DATASET_FILE, DATASET_FORMAT, DATASET_VERSION, Dataset, UNITS_NOTE,
    check_image_size,
};
use crate::fsutil::atomic_write;
use crate::image::auto_exposure;
use crate::object::ObjectSpec;
use crate::rig::check_intensity;
use crate::scene_file::{MediumSpec, RenderInfo, Rgb, ShapeSpec, check_finite3};
use crate::{Image, MeshSource, SceneError};

impl Dataset {
    /// Write the dataset to `dir` (created if needed): `view_000.exr`, … (linear f32 RGB),
    /// `view_000.png`, … (sRGB previews, one exposure shared by all views), the mesh file (copied
    /// into the folder unless it is already inside it; built-in shapes are written as a shape
    /// spec) and `dataset.json`, last. Refuses to touch an existing `dataset.json` or image
    /// unless `overwrite`. Every view needs an image of its camera's resolution with finite pixels.
    pub fn save(&self, dir: &Path, overwrite: bool) -> Result<(), SceneError> {
        let json_path = dir.join(DATASET_FILE);
        let ctx_name = json_path.display().to_string();
        // Check everything before writing anything.
        if self.views.is_empty() {
            return Err(SceneError::Invalid {
                location: format!("{ctx_name}: views"),
                reason: "the dataset has no views; fix: add at least one view".into(),
            });
        }
        if let Some(t) = &self.truth {
            t.validate(&format!("{ctx_name}: truth"))?;
        }
        if let Some(o) = &self.object {
            o.validate(&format!("{ctx_name}: object"))?;
        }
        super::json::check_truth_agrees(self.object.as_ref(), self.truth.as_ref(), &ctx_name)?;
        self.render.validate(&format!("{ctx_name}: render"))?;
        for (i, v) in self.views.iter().enumerate() {
            let ctx = format!("{ctx_name}: views[{i}]");
            v.camera
                .validate_named(&format!("{ctx}.camera"), "fov_x_deg")?;
            check_finite3(
                v.light.position.to_array(),
                &format!("{ctx}.light.position"),
            )?;
            check_intensity(&v.light.intensity, &format!("{ctx}.light.intensity"))?;
            let Some(img) = &v.image else {
                return Err(SceneError::Invalid {
                    location: format!("{ctx}.image"),
                    reason: "this view has no image; fix: render the view before saving".into(),
                });
            };
            check_image_size(img, &v.camera, &format!("{ctx}.image"))?;
            img.check_finite(&format!("{ctx}.image"))?;
        }
        if !overwrite && json_path.exists() {
            return Err(SceneError::Exists { path: json_path });
        }
        std::fs::create_dir_all(dir).map_err(|source| SceneError::Io {
            path: dir.to_path_buf(),
            source,
        })?;

        let (mesh, shape) = self.saved_mesh(dir, overwrite)?;

        let images: Vec<Image> = self.views.iter().filter_map(|v| v.image.clone()).collect();
        let exposure = auto_exposure(&images);
        let mut raw_views = Vec::with_capacity(self.views.len());
        for (i, (v, img)) in self.views.iter().zip(&images).enumerate() {
            raw_views.push(save_view(dir, i, v, img, exposure, overwrite)?);
        }
        let raw = RawDataset {
            format: DATASET_FORMAT.into(),
            version: DATASET_VERSION,
            units: Some(self.metadata.units.clone().unwrap_or_else(|| {
                match self.metadata.length_unit {
                    Some(u) => UNITS_NOTE.replace(
                        "scene units; sigma_t in 1/unit",
                        &format!("{0}; sigma_t in 1/{0}", u.name()),
                    ),
                    None => UNITS_NOTE.into(),
                }
            })),
            length_unit: self.metadata.length_unit,
            conventions: Some(
                self.metadata
                    .conventions
                    .clone()
                    .unwrap_or_else(|| CONVENTIONS_NOTE.into()),
            ),
            generator: self.metadata.generator.clone(),
            mesh,
            shape,
            object: self.object.as_ref().map(ObjectSpec::from),
            truth: self.truth.as_ref().map(MediumSpec::from),
            render: if self.render == RenderInfo::default() {
                None
            } else {
                Some(self.render.clone())
            },
            views: raw_views,
            notes: self.metadata.notes.clone(),
        };
        let pretty = serde_json::to_string_pretty(&raw).map_err(|e| SceneError::Parse {
            path: json_path.clone(),
            reason: format!("cannot encode JSON: {e}"),
        })?;
        let mut text = compact_number_arrays(&pretty);
        text.push('\n');
        atomic_write(&json_path, text.as_bytes(), overwrite)
    }

    /// The mesh as the saved dataset names it: a file in `dir` (copied in when it lies outside;
    /// a placed mesh written as `object.ply` in world coordinates), or a built-in shape's spec.
    fn saved_mesh(
        &self,
        dir: &Path,
        overwrite: bool,
    ) -> Result<(Option<PathBuf>, Option<ShapeSpec>), SceneError> {
        Ok(match &self.mesh {
            MeshSource::Shape(s) => (None, Some(ShapeSpec::from_shape(s))),
            MeshSource::File(p) => (Some(place_mesh(p, dir, overwrite)?), None),
            MeshSource::Placed { .. } => {
                // The mesh as placed in the world, written beside the dataset.
                let (mesh, _) = self.mesh.load()?;
                let name = PathBuf::from("object.ply");
                if !overwrite && dir.join(&name).exists() {
                    return Err(SceneError::Exists {
                        path: dir.join(&name),
                    });
                }
                geometry::io::save_ply(&mesh, &dir.join(&name))?;
                (Some(name), None)
            }
        })
    }
}

/// Put the mesh file where dataset.json can name it relative to `dir`; returns that name.
fn place_mesh(mesh: &Path, dir: &Path, overwrite: bool) -> Result<PathBuf, SceneError> {
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| SceneError::Io { path: p, source }
    };
    let src = mesh.canonicalize().map_err(io(mesh))?;
    let dir_abs = dir.canonicalize().map_err(io(dir))?;
    if let Ok(rel) = src.strip_prefix(&dir_abs) {
        return Ok(rel.to_path_buf());
    }
    let Some(fname) = src.file_name() else {
        return Err(SceneError::Invalid {
            location: mesh.display().to_string(),
            reason: "the mesh path has no file name".into(),
        });
    };
    let dst = dir.join(fname);
    let bytes = std::fs::read(&src).map_err(io(&src))?;
    if dst.exists() {
        let same = std::fs::read(&dst).map(|b| b == bytes).unwrap_or(false);
        if same {
            return Ok(PathBuf::from(fname));
        }
    }
    atomic_write(&dst, &bytes, overwrite)?;
    Ok(PathBuf::from(fname))
}

/// `serde_json::to_string_pretty` output with arrays of plain numbers put on one line
/// (`[0.5, 1.0, 2.0]` instead of one number per line). Field order is kept.
fn compact_number_arrays(pretty: &str) -> String {
    let mut out = String::with_capacity(pretty.len());
    let (mut in_str, mut esc, mut skip_to) = (false, false, 0usize);
    for (i, c) in pretty.char_indices() {
        if i < skip_to {
            continue;
        }
        if in_str {
            if esc {
                esc = false;
            } else if c == '\\' {
                esc = true;
            } else if c == '"' {
                in_str = false;
            }
        } else if c == '"' {
            in_str = true;
        } else if c == '['
            && let Some(len) = pretty[i + 1..].find(']')
        {
            // The bracketed text holds only numbers: put it on one line.
            let inner = &pretty[i + 1..i + 1 + len];
            if !inner.contains(['[', '{', '"']) {
                let items: Vec<&str> = inner
                    .split(',')
                    .map(str::trim)
                    .filter(|t| !t.is_empty())
                    .collect();
                out.push('[');
                out.push_str(&items.join(", "));
                out.push(']');
                skip_to = i + len + 2;
                continue;
            }
        }
        out.push(c);
    }
    out
}

/// Writes view `i`'s image (EXR, and its PNG preview at `exposure`) and its mask (where some
/// pixels are not measured) into `dir`; returns its entry of dataset.json.
fn save_view(
    dir: &Path,
    i: usize,
    v: &super::View,
    img: &Image,
    exposure: f32,
    overwrite: bool,
) -> Result<RawView, SceneError> {
    let exr_name = format!("view_{i:03}.exr");
    img.write_exr(&dir.join(&exr_name), overwrite)?;
    let mask = match &v.camera.mask {
        Some(m) => {
            let name = format!("mask_{i:03}.png");
            m.write_png(&dir.join(&name), overwrite)?;
            Some(name)
        }
        None => None,
    };
    img.write_png(&dir.join(format!("view_{i:03}.png")), exposure, overwrite)?;
    // Through the shortest decimal of each f32, so that the file shows "0.8660254", not
    // "0.8660253882408142".
    let rows = v
        .camera
        .to_world_rows()
        .map(|r| r.map(|x| format!("{x}").parse::<f64>().unwrap_or(x as f64)));
    Ok(RawView {
        camera: RawCamera {
            origin: None,
            target: None,
            up: None,
            to_world: Some(rows),
            fov_x_deg: v.camera.pinhole.is_none().then_some(v.camera.fov_x_deg),
            intrinsics: v.camera.pinhole.map(|_| RawIntrinsics::of(&v.camera)),
            width: v.camera.width,
            height: v.camera.height,
        },
        light: RawLight {
            position: v.light.position.to_array(),
            intensity: Rgb(v.light.intensity),
        },
        image: exr_name,
        mask,
        transfer: None,
        exposure: None,
        saturation: None,
    })
}
