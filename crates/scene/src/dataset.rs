//! Dataset folders (`dataset.json` + EXRs, DATASET.md) and the Mitsuba reference-render format.
//!
//! Two folder formats load into the same [`Dataset`], so `--dataset` accepts either:
//!
//! * **translucent dataset** (`dataset.json`, format `"translucent-dataset"`, version 1): written by
//!   [`Dataset::save`], documented in DATASET.md, parsed strictly (unknown fields are errors).
//! * **Mitsuba reference folder** (`scene.json` as written by `render_reference.py`, e.g.
//!   `reference-renders/mitsuba-sphere-rgb-64`): read by [`load_reference_folder`]; only the fields
//!   we need are read, the rest is ignored.
//!
//! Loading checks everything a renderer or optimiser would trip over later: format and version,
//! cameras (resolution, fov, orthonormal to_world), lights, the truth medium, that the mesh and
//! every image exist, that each image has the camera's resolution and only finite pixels.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::fsutil::atomic_write;
use crate::image::auto_exposure;
use crate::rig::check_intensity;
use crate::scene_file::{
    MediumSpec, RenderInfo, Rgb, ShapeSpec, ViewDesc, base_dir, check_finite3, look_at_checked,
    resolve_mesh_path,
};
use crate::{Camera, Image, Medium, MeshSource, PointLight, SceneDesc, SceneError};

/// `format` value of dataset.json.
pub const DATASET_FORMAT: &str = "translucent-dataset";
/// The dataset.json version this code reads and writes.
pub const DATASET_VERSION: u32 = 1;
/// File name of the dataset description.
pub const DATASET_FILE: &str = "dataset.json";
/// File name of the description in a Mitsuba reference-render folder.
pub const REFERENCE_FILE: &str = "scene.json";

const UNITS_NOTE: &str = "lengths in scene units; sigma_t in 1/unit; light intensity = radiant \
                          intensity in W/sr per RGB channel (irradiance I/r^2 facing the light); \
                          images are linear radiance, float32 RGB OpenEXR";
const CONVENTIONS_NOTE: &str = "Mitsuba 3: right-handed, +Y up; camera to_world row-major with \
                                columns [x = image left, y = image up, z = view direction, \
                                origin]; fov along image x; row 0 = top; volpath depth semantics; \
                                see DATASET.md";

/// One view of a dataset.
#[derive(Clone, Debug)]
pub struct View {
    pub camera: Camera,
    pub light: PointLight,
    pub image: Option<Image>,
    /// The file the image was read from (absolute or relative to the working directory).
    pub image_path: Option<PathBuf>,
    /// Mean RGB of the image recorded in the description (Mitsuba reference folders).
    pub expected_mean: Option<[f64; 3]>,
}

impl View {
    /// The camera and light of this view.
    pub fn desc(&self) -> ViewDesc {
        ViewDesc {
            camera: self.camera.clone(),
            light: self.light,
        }
    }
}

/// Which folder format a dataset was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DatasetKind {
    /// `dataset.json` (DATASET.md), or built in memory.
    Native,
    /// A Mitsuba reference-render folder (`scene.json`).
    MitsubaReference,
}

/// Informational fields of a dataset.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DatasetMetadata {
    pub units: Option<String>,
    pub conventions: Option<String>,
    /// What made the dataset (program and version).
    pub generator: Option<String>,
    /// Free-form JSON carried along unchanged.
    pub notes: Option<Value>,
}

/// A loaded dataset.
#[derive(Clone, Debug)]
pub struct Dataset {
    pub views: Vec<View>,
    /// Mesh file (resolved path) or built-in shape.
    pub mesh: MeshSource,
    /// The medium the images were rendered with, when known.
    pub truth: Option<Medium>,
    /// How the images were rendered (informational; `max_depth` matters for comparisons).
    pub render: RenderInfo,
    pub metadata: DatasetMetadata,
    /// The folder it was loaded from (empty for a dataset built in memory).
    pub root: PathBuf,
    pub kind: DatasetKind,
    /// Non-fatal findings of loading (e.g. an image mean that differs from the recorded one).
    pub warnings: Vec<String>,
}

impl Dataset {
    /// A dataset with the views, mesh, render settings and (as truth) medium of a scene, and no
    /// images yet: fill `views[i].image` (e.g. by rendering) and [`Dataset::save`] it.
    pub fn from_scene(scene: &SceneDesc) -> Dataset {
        Dataset {
            views: scene
                .views
                .iter()
                .map(|v| View {
                    camera: v.camera.clone(),
                    light: v.light,
                    image: None,
                    image_path: None,
                    expected_mean: None,
                })
                .collect(),
            mesh: scene.mesh.clone(),
            truth: Some(scene.medium),
            render: scene.render.clone(),
            metadata: DatasetMetadata {
                units: Some(UNITS_NOTE.into()),
                conventions: Some(CONVENTIONS_NOTE.into()),
                generator: Some(format!("translucent {}", env!("CARGO_PKG_VERSION"))),
                notes: None,
            },
            root: PathBuf::new(),
            kind: DatasetKind::Native,
            warnings: Vec::new(),
        }
    }

    /// The scene of this dataset rendered with `medium` (e.g. the truth, or an estimate).
    pub fn scene(&self, medium: Medium) -> SceneDesc {
        SceneDesc {
            mesh: self.mesh.clone(),
            medium,
            views: self.views.iter().map(View::desc).collect(),
            render: self.render.clone(),
            path: self.root.join(match self.kind {
                DatasetKind::Native => DATASET_FILE,
                DatasetKind::MitsubaReference => REFERENCE_FILE,
            }),
        }
    }

    /// Build (shape) or load (file) the mesh, validated.
    pub fn load_mesh(&self) -> Result<(geometry::Mesh, Vec<geometry::MeshWarning>), SceneError> {
        self.mesh.load()
    }

    /// Load a dataset in either format: `path` is a folder holding `dataset.json` (translucent
    /// dataset) or `scene.json` (Mitsuba reference folder), or one of those two files.
    pub fn load(path: &Path) -> Result<Dataset, SceneError> {
        if path.is_file() {
            let dir = base_dir(path);
            return match path.file_name().and_then(|n| n.to_str()) {
                Some(REFERENCE_FILE) => load_reference_folder(&dir),
                _ => Self::load_dataset_json(path),
            };
        }
        if !path.exists() {
            return Err(SceneError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "dataset folder not found",
                ),
            });
        }
        if path.join(DATASET_FILE).is_file() {
            Self::load_dataset_json(&path.join(DATASET_FILE))
        } else if path.join(REFERENCE_FILE).is_file() {
            load_reference_folder(path)
        } else {
            Err(SceneError::Invalid {
                location: path.display().to_string(),
                reason: format!(
                    "no {DATASET_FILE} (translucent dataset) and no {REFERENCE_FILE} (Mitsuba \
                     reference folder) here; fix: point to a dataset folder (see DATASET.md), \
                     or create one with `translucent dataset`"
                ),
            })
        }
    }

    /// Load a translucent dataset from its `dataset.json` file (images next to it).
    pub fn load_dataset_json(file: &Path) -> Result<Dataset, SceneError> {
        let text = std::fs::read_to_string(file).map_err(|source| SceneError::Io {
            path: file.to_path_buf(),
            source,
        })?;
        let name = file.display().to_string();
        let dir = base_dir(file);

        // Format and version first, so that a wrong file gets a clear message rather than a list
        // of unknown fields.
        #[derive(Deserialize)]
        struct Header {
            format: Option<Value>,
            version: Option<Value>,
        }
        let header: Header = serde_json::from_str(&text).map_err(|e| SceneError::Parse {
            path: file.to_path_buf(),
            reason: format!("not valid JSON: {e}"),
        })?;
        match header.format.as_ref().and_then(Value::as_str) {
            Some(DATASET_FORMAT) => {}
            other => {
                return Err(SceneError::Invalid {
                    location: format!(
                        "{name}: format = {}",
                        other
                            .map(|s| format!("\"{s}\""))
                            .unwrap_or_else(|| "(missing)".into())
                    ),
                    reason: format!(
                        "not a translucent dataset; fix: the file must start with \
                         {{\"format\": \"{DATASET_FORMAT}\", \"version\": {DATASET_VERSION}, …}} \
                         (DATASET.md); a Mitsuba reference folder has scene.json instead"
                    ),
                });
            }
        }
        match header.version.as_ref().and_then(Value::as_u64) {
            Some(v) if v == DATASET_VERSION as u64 => {}
            Some(v) if v > DATASET_VERSION as u64 => {
                return Err(SceneError::Invalid {
                    location: format!("{name}: version = {v}"),
                    reason: format!(
                        "written by a newer translucent (this one reads version \
                         {DATASET_VERSION}); fix: update translucent"
                    ),
                });
            }
            _ => {
                return Err(SceneError::Invalid {
                    location: format!(
                        "{name}: version = {}",
                        header
                            .version
                            .map(|v| v.to_string())
                            .unwrap_or_else(|| "(missing)".into())
                    ),
                    reason: format!(
                        "unsupported dataset version; fix: set \"version\": {DATASET_VERSION} \
                         and follow DATASET.md"
                    ),
                });
            }
        }

        let raw: RawDataset = serde_json::from_str(&text).map_err(|e| SceneError::Parse {
            path: file.to_path_buf(),
            reason: e.to_string(),
        })?;

        let mesh = match (raw.mesh, raw.shape) {
            (Some(_), Some(_)) => {
                return Err(SceneError::Invalid {
                    location: format!("{name}: mesh, shape"),
                    reason: "both are given; fix: keep exactly one".into(),
                });
            }
            (None, None) => {
                return Err(SceneError::Invalid {
                    location: format!("{name}: mesh"),
                    reason: "missing; fix: add \"mesh\": \"mesh.ply\" (relative to the dataset \
                             folder) or \"shape\": {\"name\": \"sphere\", …}"
                        .into(),
                });
            }
            (Some(m), None) => {
                MeshSource::File(resolve_mesh_path(&m, &dir, &format!("{name}: mesh"))?)
            }
            (None, Some(s)) => MeshSource::Shape(s.to_shape(&format!("{name}: shape"))?),
        };
        let truth = match raw.truth {
            Some(t) => Some(t.to_medium(&format!("{name}: truth"))?),
            None => None,
        };
        let render = raw.render.unwrap_or_default();
        render.validate(&format!("{name}: render"))?;
        if raw.views.is_empty() {
            return Err(SceneError::Invalid {
                location: format!("{name}: views"),
                reason: "no views; fix: add at least one view".into(),
            });
        }
        let mut views = Vec::with_capacity(raw.views.len());
        for (i, v) in raw.views.into_iter().enumerate() {
            let ctx = format!("{name}: views[{i}]");
            let camera = v.camera.to_camera(&format!("{ctx}.camera"))?;
            let position = check_finite3(v.light.position, &format!("{ctx}.light.position"))?;
            check_intensity(&v.light.intensity.0, &format!("{ctx}.light.intensity"))?;
            let (image, image_path) =
                load_view_image(&dir, &v.image, &format!("{ctx}.image"), &camera)?;
            views.push(View {
                camera,
                light: PointLight {
                    position,
                    intensity: v.light.intensity.0,
                },
                image: Some(image),
                image_path: Some(image_path),
                expected_mean: None,
            });
        }
        Ok(Dataset {
            views,
            mesh,
            truth,
            render,
            metadata: DatasetMetadata {
                units: raw.units,
                conventions: raw.conventions,
                generator: raw.generator,
                notes: raw.notes,
            },
            root: dir,
            kind: DatasetKind::Native,
            warnings: Vec::new(),
        })
    }

    /// Load a Mitsuba reference-render folder (`scene.json`); see [`load_reference_folder`].
    pub fn load_reference(dir: &Path) -> Result<Dataset, SceneError> {
        load_reference_folder(dir)
    }

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

        let (mesh, shape) = match &self.mesh {
            MeshSource::Shape(s) => (None, Some(ShapeSpec::from_shape(s))),
            MeshSource::File(p) => (Some(place_mesh(p, dir, overwrite)?), None),
        };

        let images: Vec<Image> = self.views.iter().filter_map(|v| v.image.clone()).collect();
        let exposure = auto_exposure(&images);
        let mut raw_views = Vec::with_capacity(self.views.len());
        for (i, (v, img)) in self.views.iter().zip(&images).enumerate() {
            let exr_name = format!("view_{i:03}.exr");
            img.write_exr(&dir.join(&exr_name), overwrite)?;
            img.write_png(&dir.join(format!("view_{i:03}.png")), exposure, overwrite)?;
            // Through the shortest decimal of each f32, so that the file shows "0.8660254", not
            // "0.8660253882408142".
            let rows = v
                .camera
                .to_world_rows()
                .map(|r| r.map(|x| format!("{x}").parse::<f64>().unwrap_or(x as f64)));
            raw_views.push(RawView {
                camera: RawCamera {
                    origin: None,
                    target: None,
                    up: None,
                    to_world: Some(rows),
                    fov_x_deg: v.camera.fov_x_deg,
                    width: v.camera.width,
                    height: v.camera.height,
                },
                light: RawLight {
                    position: v.light.position.to_array(),
                    intensity: Rgb(v.light.intensity),
                },
                image: exr_name,
            });
        }
        let raw = RawDataset {
            format: DATASET_FORMAT.into(),
            version: DATASET_VERSION,
            units: Some(
                self.metadata
                    .units
                    .clone()
                    .unwrap_or_else(|| UNITS_NOTE.into()),
            ),
            conventions: Some(
                self.metadata
                    .conventions
                    .clone()
                    .unwrap_or_else(|| CONVENTIONS_NOTE.into()),
            ),
            generator: self.metadata.generator.clone(),
            mesh,
            shape,
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

fn check_image_size(img: &Image, camera: &Camera, location: &str) -> Result<(), SceneError> {
    if img.width != camera.width || img.height != camera.height {
        return Err(SceneError::Invalid {
            location: location.to_string(),
            reason: format!(
                "image is {}×{} but the camera is {}×{}; fix: render the image at the camera's \
                 resolution or correct the camera's width/height",
                img.width, img.height, camera.width, camera.height
            ),
        });
    }
    Ok(())
}

fn load_view_image(
    dir: &Path,
    name: &str,
    location: &str,
    camera: &Camera,
) -> Result<(Image, PathBuf), SceneError> {
    let rel = Path::new(name);
    let path = if rel.is_absolute() {
        rel.to_path_buf()
    } else {
        dir.join(rel)
    };
    if !path.is_file() {
        return Err(SceneError::Invalid {
            location: format!("{location} = \"{name}\""),
            reason: format!(
                "image file not found (looked for {}); fix: put the EXR in the dataset folder \
                 or correct the name",
                path.display()
            ),
        });
    }
    let img = Image::read_exr(&path)?;
    check_image_size(&img, camera, &format!("{location} = \"{name}\""))?;
    Ok((img, path))
}

// ---------------------------------------------------------------------------------------------
// dataset.json as written.

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDataset {
    format: String,
    version: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    units: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    conventions: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    generator: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mesh: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    shape: Option<ShapeSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    truth: Option<MediumSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    render: Option<RenderInfo>,
    views: Vec<RawView>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    notes: Option<Value>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawView {
    camera: RawCamera,
    light: RawLight,
    image: String,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    position: [f32; 3],
    intensity: Rgb,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCamera {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    origin: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    target: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    up: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    to_world: Option<[[f64; 4]; 4]>,
    fov_x_deg: f32,
    width: u32,
    height: u32,
}

impl RawCamera {
    fn to_camera(&self, ctx: &str) -> Result<Camera, SceneError> {
        match (&self.to_world, self.origin, self.target) {
            (Some(m), None, None) if self.up.is_none() => {
                camera_from_matrix(m, self.fov_x_deg, self.width, self.height, ctx)
            }
            (Some(_), ..) => Err(SceneError::Invalid {
                location: format!("{ctx}.to_world"),
                reason: "given together with origin/target/up; fix: describe the camera either \
                         by to_world or by origin + target (+ up), not both"
                    .into(),
            }),
            (None, Some(o), Some(t)) => look_at_checked(
                ctx,
                o,
                t,
                self.up.unwrap_or([0.0, 1.0, 0.0]),
                self.fov_x_deg,
                "fov_x_deg",
                self.width,
                self.height,
            ),
            (None, o, _) => Err(SceneError::Invalid {
                location: format!("{ctx}.{}", if o.is_none() { "origin" } else { "target" }),
                reason: "missing; fix: give either \"to_world\" (4×4, row-major) or \"origin\" \
                         and \"target\" (and optionally \"up\")"
                    .into(),
            }),
        }
    }
}

/// A camera from a row-major 4×4 Mitsuba to_world, validated (finite, last row [0, 0, 0, 1],
/// orthonormal right-handed rotation, resolution, fov).
fn camera_from_matrix(
    m: &[[f64; 4]; 4],
    fov: f32,
    width: u32,
    height: u32,
    ctx: &str,
) -> Result<Camera, SceneError> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(SceneError::Invalid {
            location: format!("{ctx}.to_world"),
            reason: "contains NaN or infinite entries; fix: write finite numbers".into(),
        });
    }
    let last = m[3];
    if last[0].abs() > 1e-6
        || last[1].abs() > 1e-6
        || last[2].abs() > 1e-6
        || (last[3] - 1.0).abs() > 1e-6
    {
        return Err(SceneError::Invalid {
            location: format!("{ctx}.to_world[3] = {last:?}"),
            reason: "the last row of a camera to_world must be [0, 0, 0, 1] (rows are stored \
                     first: to_world[r][c]); fix: check that the matrix is row-major"
                .into(),
        });
    }
    let rows = m.map(|r| r.map(|v| v as f32));
    let cam = Camera::from_to_world(rows, fov, width, height);
    let probe = Camera {
        rotation: glam::Mat3::IDENTITY,
        ..cam.clone()
    };
    probe.validate_named(ctx, "fov_x_deg")?;
    cam.validate_named(ctx, "fov_x_deg")?;
    Ok(cam)
}

// ---------------------------------------------------------------------------------------------
// Mitsuba reference-render folders.

/// Navigation in a JSON document with errors naming the file and the field path.
struct Doc<'a> {
    file: &'a str,
}

impl Doc<'_> {
    fn err(&self, path: &str, reason: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            location: format!("{}: {path}", self.file),
            reason: reason.into(),
        }
    }
    fn get<'v>(&self, v: &'v Value, path: &str) -> Option<&'v Value> {
        let mut cur = v;
        for key in path.split('.') {
            cur = cur.get(key)?;
        }
        if cur.is_null() { None } else { Some(cur) }
    }
    fn req<'v>(&self, v: &'v Value, path: &str, full: &str) -> Result<&'v Value, SceneError> {
        self.get(v, path).ok_or_else(|| {
            self.err(
                full,
                "missing; fix: add it (see DATASET.md, reference folders)",
            )
        })
    }
    fn num(&self, v: &Value, full: &str) -> Result<f64, SceneError> {
        v.as_f64()
            .ok_or_else(|| self.err(full, format!("= {v}: expected a number")))
    }
    fn uint(&self, v: &Value, full: &str) -> Result<u32, SceneError> {
        v.as_u64()
            .and_then(|u| u32::try_from(u).ok())
            .ok_or_else(|| self.err(full, format!("= {v}: expected a non-negative integer")))
    }
    fn str<'v>(&self, v: &'v Value, full: &str) -> Result<&'v str, SceneError> {
        v.as_str()
            .ok_or_else(|| self.err(full, format!("= {v}: expected a string")))
    }
    fn arr<const N: usize>(&self, v: &Value, full: &str) -> Result<[f64; N], SceneError> {
        let a = v
            .as_array()
            .filter(|a| a.len() == N)
            .ok_or_else(|| self.err(full, format!("= {v}: expected an array of {N} numbers")))?;
        let mut out = [0.0; N];
        for (i, x) in a.iter().enumerate() {
            out[i] = self.num(x, &format!("{full}[{i}]"))?;
        }
        Ok(out)
    }
    fn f3(&self, v: &Value, full: &str) -> Result<[f32; 3], SceneError> {
        // One number is accepted for all three channels, like scene files.
        if let Some(x) = v.as_f64() {
            return Ok([x as f32; 3]);
        }
        Ok(self.arr::<3>(v, full)?.map(|x| x as f32))
    }
    fn mat4(&self, v: &Value, full: &str) -> Result<[[f64; 4]; 4], SceneError> {
        let rows = v.as_array().filter(|a| a.len() == 4).ok_or_else(|| {
            self.err(
                full,
                "expected a 4×4 matrix as 4 rows of 4 numbers (row-major)",
            )
        })?;
        let mut m = [[0.0; 4]; 4];
        for (r, row) in rows.iter().enumerate() {
            m[r] = self.arr::<4>(row, &format!("{full}[{r}]"))?;
        }
        Ok(m)
    }
}

/// Read a Mitsuba reference-render folder (`scene.json` + mesh + `view_XXX.exr`, as written by
/// `render_reference.py`) into a [`Dataset`] of kind [`DatasetKind::MitsubaReference`].
///
/// Fields read (others are ignored): `shape.mesh_file`; `medium.sigma_t`, `medium.albedo`,
/// `medium.phase.g` (default 0); `boundary.bsdf` (`"null"` → η = 1; `"dielectric"` with
/// `int_ior`/`ext_ior` → η = int/ext); `light.intensity_rgb` (or `light.intensity`) and
/// `light.position` (default for views without `light_position`); `camera.fov_deg`,
/// `camera.fov_axis` (default "x"; y/diagonal/smaller/larger are converted), `camera.width`,
/// `camera.height`; per view `to_world` (4×4 row-major, columns x, y, z, origin; used as is) or
/// `origin`/`target`/`up`, `light_position`, `file_exr`, `mean_rgb` (optional, checked against
/// the image with a warning); `integrator.max_depth`; `render.spp`, `render.seed`.
pub fn load_reference_folder(dir: &Path) -> Result<Dataset, SceneError> {
    let file = dir.join(REFERENCE_FILE);
    let name = file.display().to_string();
    let text = std::fs::read_to_string(&file).map_err(|source| SceneError::Io {
        path: file.clone(),
        source,
    })?;
    let doc: Value = serde_json::from_str(&text).map_err(|e| SceneError::Parse {
        path: file.clone(),
        reason: format!("not valid JSON: {e}"),
    })?;
    let d = Doc { file: &name };

    // Mesh.
    let mesh_rel = d.str(
        d.req(&doc, "shape.mesh_file", "shape.mesh_file")?,
        "shape.mesh_file",
    )?;
    let mesh = MeshSource::File(resolve_mesh_path(
        Path::new(mesh_rel),
        dir,
        &format!("{name}: shape.mesh_file"),
    )?);

    // Medium.
    if let Some(t) = d.get(&doc, "medium.type") {
        let t = d.str(t, "medium.type")?;
        if t != "homogeneous" {
            return Err(d.err(
                &format!("medium.type = \"{t}\""),
                "only homogeneous media are supported",
            ));
        }
    }
    let sigma_t = d.f3(
        d.req(&doc, "medium.sigma_t", "medium.sigma_t")?,
        "medium.sigma_t",
    )?;
    let albedo = d.f3(
        d.req(&doc, "medium.albedo", "medium.albedo")?,
        "medium.albedo",
    )?;
    let g = match d.get(&doc, "medium.phase.g") {
        Some(v) => d.num(v, "medium.phase.g")? as f32,
        None => match d.get(&doc, "medium.phase.type").and_then(Value::as_str) {
            None | Some("isotropic") => 0.0,
            Some(other) => {
                return Err(d.err(
                    "medium.phase.g",
                    format!(
                        "missing for phase function \"{other}\"; fix: add g (Henyey–Greenstein)"
                    ),
                ));
            }
        },
    };
    let eta = match d
        .get(&doc, "boundary.bsdf")
        .map(|v| d.str(v, "boundary.bsdf"))
        .transpose()?
    {
        None | Some("null") => 1.0,
        Some("dielectric") | Some("roughdielectric") => {
            let int = d.num(
                d.req(&doc, "boundary.int_ior", "boundary.int_ior")?,
                "boundary.int_ior",
            )?;
            let ext = match d.get(&doc, "boundary.ext_ior") {
                Some(v) => d.num(v, "boundary.ext_ior")?,
                None => 1.000_277,
            };
            (int / ext) as f32
        }
        Some(other) => {
            return Err(d.err(
                &format!("boundary.bsdf = \"{other}\""),
                "unsupported boundary; fix: use \"null\" (index-matched) or \"dielectric\" with int_ior/ext_ior",
            ));
        }
    };
    let truth = Medium {
        sigma_t,
        albedo,
        g,
        eta,
    };
    truth.validate(&format!("{name}: medium"))?;

    // Light.
    let intensity = match (
        d.get(&doc, "light.intensity_rgb"),
        d.get(&doc, "light.intensity"),
    ) {
        (Some(v), _) => d.f3(v, "light.intensity_rgb")?,
        (None, Some(v)) => d.f3(v, "light.intensity")?,
        (None, None) => {
            return Err(d.err(
                "light.intensity_rgb",
                "missing; fix: add the radiant intensity per channel [W/sr]",
            ));
        }
    };
    check_intensity(&intensity, &format!("{name}: light.intensity_rgb"))?;
    if let Some(t) = d.get(&doc, "light.type") {
        let t = d.str(t, "light.type")?;
        if t != "point" {
            return Err(d.err(
                &format!("light.type = \"{t}\""),
                "only point lights are supported",
            ));
        }
    }
    let default_light = d
        .get(&doc, "light.position")
        .map(|v| d.f3(v, "light.position"))
        .transpose()?;

    // Camera intrinsics.
    let fov = d.num(
        d.req(&doc, "camera.fov_deg", "camera.fov_deg")?,
        "camera.fov_deg",
    )?;
    let width = d.uint(d.req(&doc, "camera.width", "camera.width")?, "camera.width")?;
    let height = d.uint(
        d.req(&doc, "camera.height", "camera.height")?,
        "camera.height",
    )?;
    let axis = match d.get(&doc, "camera.fov_axis") {
        Some(v) => d.str(v, "camera.fov_axis")?,
        None => "x",
    };
    if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
        return Err(d.err(
            &format!("camera.fov_deg = {fov}"),
            "field of view must be in (0, 180) degrees",
        ));
    }
    let (w, h) = (width as f64, height as f64);
    let t = (0.5 * fov.to_radians()).tan();
    let tx = match axis {
        "x" => t,
        "y" => t * w / h.max(1.0),
        "diagonal" => t * w / (w * w + h * h).sqrt().max(1.0),
        "smaller" if width <= height => t,
        "smaller" => t * w / h.max(1.0),
        "larger" if width >= height => t,
        "larger" => t * w / h.max(1.0),
        other => {
            return Err(d.err(
                &format!("camera.fov_axis = \"{other}\""),
                "unknown fov axis; fix: use x, y, diagonal, smaller or larger",
            ));
        }
    };
    let fov_x = (2.0 * tx.atan()).to_degrees() as f32;
    let probe = Camera {
        origin: Vec3::ZERO,
        rotation: glam::Mat3::IDENTITY,
        fov_x_deg: fov_x,
        width,
        height,
        crop: None,
    };
    probe.validate_named(&format!("{name}: camera"), "fov_deg")?;

    // Views.
    let views_v = d
        .req(&doc, "views", "views")?
        .as_array()
        .ok_or_else(|| d.err("views", "expected an array of views"))?;
    if views_v.is_empty() {
        return Err(d.err("views", "no views; fix: add at least one view"));
    }
    let mut views = Vec::with_capacity(views_v.len());
    let mut warnings = Vec::new();
    for (i, v) in views_v.iter().enumerate() {
        let p = format!("views[{i}]");
        let ctx = format!("{name}: {p}");
        let camera = if let Some(m) = d.get(v, "to_world") {
            let m = d.mat4(m, &format!("{p}.to_world"))?;
            camera_from_matrix(&m, fov_x, width, height, &ctx)?
        } else {
            let o = d.f3(
                d.req(v, "origin", &format!("{p}.origin"))?,
                &format!("{p}.origin"),
            )?;
            let tg = d.f3(
                d.req(v, "target", &format!("{p}.target"))?,
                &format!("{p}.target"),
            )?;
            let up = match d.get(v, "up") {
                Some(u) => d.f3(u, &format!("{p}.up"))?,
                None => [0.0, 1.0, 0.0],
            };
            look_at_checked(&ctx, o, tg, up, fov_x, "fov_deg", width, height)?
        };
        let light_pos = match d.get(v, "light_position") {
            Some(lp) => d.f3(lp, &format!("{p}.light_position"))?,
            None => default_light.ok_or_else(|| {
                d.err(
                    &format!("{p}.light_position"),
                    "missing, and there is no light.position to fall back on; fix: add it",
                )
            })?,
        };
        let position = check_finite3(light_pos, &format!("{ctx}.light_position"))?;
        let exr = d.str(
            d.req(v, "file_exr", &format!("{p}.file_exr"))?,
            &format!("{p}.file_exr"),
        )?;
        let (image, image_path) = load_view_image(dir, exr, &format!("{ctx}.file_exr"), &camera)?;
        let expected_mean = match d.get(v, "mean_rgb") {
            Some(m) => Some(d.arr::<3>(m, &format!("{p}.mean_rgb"))?),
            None => None,
        };
        if let Some(e) = expected_mean {
            let got = image.mean();
            let off = (0..3).any(|c| (got[c] - e[c]).abs() > 1e-4 * e[c].abs().max(1e-3));
            if off {
                let msg = format!(
                    "{ctx}: image mean {got:?} differs from mean_rgb {e:?} recorded in scene.json \
                     (the image may not be the one described)"
                );
                tracing::warn!("{msg}");
                warnings.push(msg);
            }
        }
        views.push(View {
            camera,
            light: PointLight {
                position,
                intensity,
            },
            image: Some(image),
            image_path: Some(image_path),
            expected_mean,
        });
    }

    // Render settings and metadata (informational).
    let opt_u = |path: &str| -> Result<Option<u64>, SceneError> {
        d.get(&doc, path)
            .map(|v| {
                v.as_u64()
                    .ok_or_else(|| d.err(path, format!("= {v}: expected a non-negative integer")))
            })
            .transpose()
    };
    let max_depth = opt_u("integrator.max_depth")?.map(|v| v.min(u32::MAX as u64) as u32);
    let spp = opt_u("render.spp")?.map(|v| v.min(u32::MAX as u64) as u32);
    let seed = opt_u("render.seed")?;
    let version = d
        .get(&doc, "software.mitsuba_version")
        .and_then(Value::as_str);
    let integrator = d
        .get(&doc, "integrator.type")
        .and_then(Value::as_str)
        .unwrap_or("volpath");
    let renderer = Some(match version {
        Some(v) => format!("mitsuba {v} {integrator}"),
        None => format!("mitsuba {integrator}"),
    });
    let render = RenderInfo {
        spp,
        max_depth,
        seed,
        renderer,
    };
    render.validate(&format!("{name}: integrator"))?;
    let text_of = |path: &str| {
        d.get(&doc, path)
            .and_then(Value::as_str)
            .map(str::to_string)
    };
    let metadata = DatasetMetadata {
        units: text_of("units"),
        conventions: text_of("coordinate_system"),
        generator: text_of("generator"),
        notes: d.get(&doc, "command").cloned(),
    };
    Ok(Dataset {
        views,
        mesh,
        truth: Some(truth),
        render,
        metadata,
        root: dir.to_path_buf(),
        kind: DatasetKind::MitsubaReference,
        warnings,
    })
}

#[cfg(test)]
#[allow(clippy::excessive_precision, clippy::type_complexity)] // numbers copied verbatim from Mitsuba's scene.json
mod tests {
    use super::*;

    fn image(w: u32, h: u32, seed: f32) -> Image {
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                img.set(
                    x,
                    y,
                    [
                        seed + x as f32 * 0.01,
                        seed * 0.5 + y as f32 * 0.02,
                        0.001 * (x + y) as f32,
                    ],
                );
            }
        }
        img
    }

    /// A scene (2 views, mesh file in `src`) turned into a dataset with images.
    fn sample_dataset(src: &Path) -> Dataset {
        std::fs::write(
            src.join("object.ply"),
            b"ply\nformat ascii 1.0\nend_header\n",
        )
        .unwrap();
        let text = r#"
mesh = "object.ply"
medium = { sigma_t = [50, 60, 70], albedo = [0.95, 0.9, 0.85], g = 0.1, eta = 1.0 }
rig = { views = 2, radius = 0.5, width = 12, height = 8, light = "fixed", light_position = [0.3, 0.4, 0.1], intensity = 0.785 }
render = { spp = 64, max_depth = 32, seed = 3 }
"#;
        let scene = SceneDesc::parse(text, &src.join("scene.toml")).unwrap();
        let mut ds = Dataset::from_scene(&scene);
        for (i, v) in ds.views.iter_mut().enumerate() {
            v.image = Some(image(12, 8, 0.1 * (i + 1) as f32));
        }
        ds
    }

    fn assert_same_views(a: &Dataset, b: &Dataset) {
        assert_eq!(a.views.len(), b.views.len());
        for (va, vb) in a.views.iter().zip(&b.views) {
            assert!((va.camera.origin - vb.camera.origin).length() < 1e-6);
            assert!((va.camera.rotation - vb.camera.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-6));
            assert_eq!(
                (va.camera.fov_x_deg, va.camera.width, va.camera.height),
                (vb.camera.fov_x_deg, vb.camera.width, vb.camera.height)
            );
            assert_eq!(va.light, vb.light);
            assert_eq!(va.image, vb.image);
        }
    }

    #[test]
    fn save_load_round_trip() {
        let src = tempfile::tempdir().unwrap();
        let out = tempfile::tempdir().unwrap();
        let dir = out.path().join("ds");
        let ds = sample_dataset(src.path());
        ds.save(&dir, false).unwrap();
        for f in [
            "dataset.json",
            "view_000.exr",
            "view_001.exr",
            "view_000.png",
            "view_001.png",
            "object.ply",
        ] {
            assert!(dir.join(f).is_file(), "{f} written");
        }
        let back = Dataset::load(&dir).unwrap();
        assert_eq!(back.kind, DatasetKind::Native);
        assert_eq!(back.mesh, MeshSource::File(dir.join("object.ply")));
        assert_eq!(back.truth, ds.truth);
        assert_eq!(back.render, ds.render);
        assert_eq!(back.metadata.generator, ds.metadata.generator);
        assert!(back.metadata.units.as_deref().unwrap().contains("W/sr"));
        assert_eq!(back.root, dir);
        assert_same_views(&ds, &back);
        assert_eq!(
            back.views[1].image_path.as_deref(),
            Some(dir.join("view_001.exr").as_path())
        );
        // The file itself also loads, and the scene built from it has the same cameras.
        let again = Dataset::load(&dir.join("dataset.json")).unwrap();
        assert_same_views(&back, &again);
        let scene = back.scene(back.truth.unwrap());
        assert_eq!(scene.views[0], back.views[0].desc());
        // Saving the loaded dataset into its own folder keeps the mesh where it is.
        back.save(&dir, true).unwrap();
        assert_same_views(&back, &Dataset::load(&dir).unwrap());
    }

    #[test]
    fn shape_datasets_round_trip() {
        let src = tempfile::tempdir().unwrap();
        let mut ds = sample_dataset(src.path());
        ds.mesh = MeshSource::Shape(geometry::Shape::Blob {
            radius: 0.2,
            amplitude: 0.1,
            bumps: 5,
            seed: 3,
            subdivisions: 2,
        });
        ds.truth = None;
        let out = tempfile::tempdir().unwrap();
        ds.save(out.path(), false).unwrap();
        let back = Dataset::load(out.path()).unwrap();
        assert_eq!(back.mesh, ds.mesh);
        assert_eq!(back.truth, None);
    }

    #[test]
    fn save_refuses_to_overwrite() {
        let src = tempfile::tempdir().unwrap();
        let out = tempfile::tempdir().unwrap();
        let ds = sample_dataset(src.path());
        ds.save(out.path(), false).unwrap();
        let err = ds.save(out.path(), false).unwrap_err();
        assert!(
            matches!(err, SceneError::Exists { .. }) && err.to_string().contains("dataset.json"),
            "{err}"
        );
        ds.save(out.path(), true).unwrap();
        // A view without an image cannot be saved.
        let mut no_img = ds.clone();
        no_img.views[1].image = None;
        let msg = no_img
            .save(&out.path().join("x"), false)
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("views[1].image") && msg.contains("no image"),
            "{msg}"
        );
        let mut bad = ds.clone();
        bad.views[0]
            .image
            .as_mut()
            .unwrap()
            .set(1, 1, [f32::NAN; 3]);
        let msg = bad
            .save(&out.path().join("y"), false)
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("views[0].image") && msg.contains("(x=1, y=1)"),
            "{msg}"
        );
        assert!(
            !out.path().join("y").exists(),
            "nothing written for an invalid dataset"
        );
    }

    fn saved(dir: &Path) -> Dataset {
        let src = tempfile::tempdir().unwrap();
        let ds = sample_dataset(src.path());
        ds.save(dir, false).unwrap();
        ds
    }

    fn load_err(dir: &Path) -> String {
        Dataset::load(dir)
            .expect_err("must be rejected")
            .to_string()
    }

    #[test]
    fn wrong_image_size_missing_image_and_nan_are_rejected() {
        let out = tempfile::tempdir().unwrap();
        let dir = out.path();
        saved(dir);
        image(6, 4, 0.3)
            .write_exr(&dir.join("view_001.exr"), true)
            .unwrap();
        let msg = load_err(dir);
        assert!(
            msg.contains("views[1].image = \"view_001.exr\"")
                && msg.contains("6×4")
                && msg.contains("12×8"),
            "{msg}"
        );
        std::fs::remove_file(dir.join("view_001.exr")).unwrap();
        let msg = load_err(dir);
        assert!(
            msg.contains("views[1].image = \"view_001.exr\"") && msg.contains("not found"),
            "{msg}"
        );
        let mut nan = image(12, 8, 0.3);
        nan.set(11, 7, [0.0, 0.0, f32::NAN]);
        nan.write_exr(&dir.join("view_001.exr"), true).unwrap();
        let msg = load_err(dir);
        assert!(
            msg.contains("view_001.exr") && msg.contains("pixel (x=11, y=7) channel B"),
            "{msg}"
        );
        std::fs::remove_file(dir.join("object.ply")).unwrap();
        let msg = load_err(dir);
        assert!(
            msg.contains("dataset.json: mesh = \"object.ply\"") && msg.contains("not found"),
            "{msg}"
        );
    }

    fn edit_json(dir: &Path, f: impl FnOnce(&mut Value)) {
        let p = dir.join(DATASET_FILE);
        let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        f(&mut v);
        std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    }

    #[test]
    fn header_and_field_errors() {
        let empty = tempfile::tempdir().unwrap();
        let msg = load_err(empty.path());
        assert!(
            msg.contains("no dataset.json") && msg.contains("scene.json"),
            "{msg}"
        );
        let msg = load_err(&empty.path().join("nowhere"));
        assert!(msg.contains("nowhere"), "{msg}");

        let cases: Vec<(Box<dyn Fn(&mut Value)>, &[&str])> = vec![
            (
                Box::new(|v| v["format"] = "something-else".into()),
                &["format = \"something-else\"", "translucent-dataset"],
            ),
            (
                Box::new(|v| v["version"] = 2.into()),
                &["version = 2", "newer"],
            ),
            (Box::new(|v| v["version"] = 0.into()), &["version = 0"]),
            (
                Box::new(|v| v["colour"] = 1.into()),
                &["unknown field `colour`"],
            ),
            (
                Box::new(|v| v["truth"]["albedo"] = 1.5.into()),
                &["truth.albedo[0] = 1.5"],
            ),
            (
                Box::new(|v| v["views"][1]["camera"]["fov_x_deg"] = 0.into()),
                &["views[1].camera.fov_x_deg"],
            ),
            (
                Box::new(|v| v["views"][0]["camera"]["width"] = 0.into()),
                &["views[0].camera.width"],
            ),
            (
                Box::new(|v| v["views"][0]["camera"]["to_world"][0][0] = 2.0.into()),
                &["views[0].camera.to_world", "orthonormal"],
            ),
            (
                Box::new(|v| v["views"][0]["camera"]["to_world"][3][3] = 0.0.into()),
                &["views[0].camera.to_world[3]", "row-major"],
            ),
            (
                Box::new(|v| v["views"][0]["camera"]["origin"] = serde_json::json!([0, 0, 1])),
                &["views[0].camera.to_world", "not both"],
            ),
            (
                Box::new(|v| v["views"][0]["light"]["intensity"] = (-1).into()),
                &["views[0].light.intensity[0] = -1"],
            ),
            (
                Box::new(|v| v["views"] = serde_json::json!([])),
                &["views", "no views"],
            ),
            (
                Box::new(|v| v["shape"] = serde_json::json!({"name": "sphere"})),
                &["mesh, shape"],
            ),
        ];
        for (edit, wants) in cases {
            let out = tempfile::tempdir().unwrap();
            saved(out.path());
            edit_json(out.path(), edit);
            let msg = load_err(out.path());
            for w in wants {
                assert!(msg.contains(w), "{msg:?} should contain {w:?}");
            }
            assert!(msg.contains("dataset.json"), "{msg}");
        }
    }

    #[test]
    fn look_at_cameras_load() {
        let out = tempfile::tempdir().unwrap();
        let ds = saved(out.path());
        let cam = ds.views[0].camera.clone();
        edit_json(out.path(), |v| {
            let c = &mut v["views"][0]["camera"];
            c.as_object_mut().unwrap().remove("to_world");
            c["origin"] = serde_json::json!(cam.origin.to_array());
            c["target"] = serde_json::json!([0.0, 0.0, 0.0]);
        });
        let back = Dataset::load(out.path()).unwrap();
        assert!((back.views[0].camera.rotation - cam.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-6));
        edit_json(out.path(), |v| {
            v["views"][0]["camera"]["up"] = serde_json::json!(cam.direction().to_array());
        });
        let msg = load_err(out.path());
        assert!(
            msg.contains("views[0].camera.up") && msg.contains("parallel"),
            "{msg}"
        );
    }

    /// A Mitsuba reference folder as written by render_reference.py (the fields we read, plus
    /// some we ignore).
    fn reference_folder(dir: &Path) {
        std::fs::write(dir.join("mesh.ply"), b"ply\n").unwrap();
        let img0 = image(8, 6, 0.2);
        let img1 = image(8, 6, 0.4);
        img0.write_exr(&dir.join("view_000.exr"), false).unwrap();
        img1.write_exr(&dir.join("view_001.exr"), false).unwrap();
        let doc = serde_json::json!({
            "generator": "Mitsuba 3.9.1 (llvm_ad_rgb), rendered for this project as reference data",
            "software": { "variant": "llvm_ad_rgb", "mitsuba_version": "3.9.1" },
            "units": "all lengths in abstract scene units",
            "shape": { "kind": "sphere", "params": { "radius": 0.125 }, "mesh_file": "mesh.ply", "face_count": 16128 },
            "boundary": { "bsdf": "null" },
            "medium": {
                "type": "homogeneous",
                "sigma_t": [50.0, 60.0, 70.0],
                "albedo": [0.95, 0.9, 0.85],
                "phase": { "type": "isotropic", "g": 0.0 }
            },
            "light": { "type": "point", "mode": "fixed", "intensity_rgb": [0.785, 0.785, 0.785], "position": [0.26, 0.4, 0.13] },
            "integrator": { "type": "volpath", "max_depth": 32, "rr_depth": 5 },
            "camera": { "fov_deg": 40.0, "fov_axis": "x", "width": 8, "height": 6 },
            "views": [
                {
                    "index": 0,
                    "origin": [0.23125014452548345, 0.4375, 0.07153405242919639],
                    "target": [0.0, 0.0, 0.0],
                    "up": [0.0, 1.0, 0.0],
                    "to_world": [
                        [-0.29552020666133955, -0.8359194279849053, -0.4625002890509669, 0.23125014452548345],
                        [0.0, 0.4841229182759271, -0.875, 0.4375],
                        [0.955336489125606, -0.2585801808286721, -0.14306810485839278, 0.07153405242919639],
                        [0.0, 0.0, 0.0, 1.0]
                    ],
                    "light_position": [0.2672612419124244, 0.4008918628686366, 0.1336306209562122],
                    "file_exr": "view_000.exr",
                    "mean_rgb": img0.mean()
                },
                {
                    "index": 1,
                    "origin": [-0.3528644108831139, 0.3125, 0.1668246310714128],
                    "target": [0.0, 0.0, 0.0],
                    "file_exr": "view_001.exr",
                    "mean_rgb": [0.5, 0.5, 0.5]
                }
            ],
            "render": { "spp": 1024, "seed": 0 }
        });
        std::fs::write(
            dir.join(REFERENCE_FILE),
            serde_json::to_string_pretty(&doc).unwrap(),
        )
        .unwrap();
    }

    #[test]
    fn mitsuba_reference_folder_loads() {
        let out = tempfile::tempdir().unwrap();
        let dir = out.path();
        reference_folder(dir);
        let ds = Dataset::load(dir).unwrap();
        assert_eq!(ds.kind, DatasetKind::MitsubaReference);
        assert_eq!(ds.mesh, MeshSource::File(dir.join("mesh.ply")));
        assert_eq!(
            ds.truth,
            Some(Medium {
                sigma_t: [50.0, 60.0, 70.0],
                albedo: [0.95, 0.9, 0.85],
                g: 0.0,
                eta: 1.0
            })
        );
        assert_eq!(ds.render.max_depth, Some(32));
        assert_eq!(ds.render.spp, Some(1024));
        assert_eq!(ds.render.renderer.as_deref(), Some("mitsuba 3.9.1 volpath"));
        assert_eq!(ds.views.len(), 2);
        let v0 = &ds.views[0];
        let look = Camera::look_at(
            Vec3::new(0.23125014452548345, 0.4375, 0.07153405242919639),
            Vec3::ZERO,
            Vec3::Y,
            40.0,
            8,
            6,
        );
        assert!((v0.camera.rotation - look.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-6));
        assert_eq!(
            v0.light.position,
            Vec3::new(0.2672612419124244, 0.4008918628686366, 0.1336306209562122)
        );
        assert_eq!(v0.light.intensity, [0.785; 3]);
        assert_eq!(v0.image.as_ref().unwrap().width, 8);
        // View 1: look-at form, light from light.position.
        assert_eq!(ds.views[1].light.position, Vec3::new(0.26, 0.4, 0.13));
        assert!(
            (ds.views[1].camera.direction() + ds.views[1].camera.origin.normalize()).length()
                < 1e-6
        );
        // View 1's recorded mean is wrong: a warning, not an error.
        assert_eq!(ds.warnings.len(), 1);
        assert!(ds.warnings[0].contains("views[1]") && ds.warnings[0].contains("mean_rgb"));
        assert!(Dataset::load(&dir.join("scene.json")).is_ok());
        // The reference folder saves as a translucent dataset with the same content.
        let out2 = tempfile::tempdir().unwrap();
        ds.save(out2.path(), false).unwrap();
        let back = Dataset::load(out2.path()).unwrap();
        assert_eq!(back.kind, DatasetKind::Native);
        assert_eq!(back.truth, ds.truth);
        assert_eq!(back.render, ds.render);
        assert_same_views(&ds, &back);
    }

    #[test]
    fn mitsuba_reference_errors_name_the_field() {
        let edits: Vec<(Box<dyn Fn(&mut Value)>, &[&str])> = vec![
            (
                Box::new(|v| v["medium"]["sigma_t"] = serde_json::json!([50, -1, 70])),
                &["scene.json: medium.sigma_t[1] = -1"],
            ),
            (
                Box::new(|v| {
                    v["medium"]
                        .as_object_mut()
                        .unwrap()
                        .remove("albedo")
                        .map(drop)
                        .unwrap()
                }),
                &["medium.albedo", "missing"],
            ),
            (
                Box::new(|v| v["boundary"]["bsdf"] = "diffuse".into()),
                &["boundary.bsdf = \"diffuse\""],
            ),
            (
                Box::new(|v| v["camera"]["width"] = 0.into()),
                &["camera.width"],
            ),
            (
                Box::new(|v| v["camera"]["fov_deg"] = 200.into()),
                &["camera.fov_deg"],
            ),
            (
                Box::new(|v| v["views"][0]["to_world"][1] = serde_json::json!([0, 1])),
                &["views[0].to_world[1]", "4 numbers"],
            ),
            (
                Box::new(|v| v["views"][1]["file_exr"] = "gone.exr".into()),
                &["views[1].file_exr = \"gone.exr\"", "not found"],
            ),
            (
                Box::new(|v| v["shape"]["mesh_file"] = "gone.ply".into()),
                &["shape.mesh_file = \"gone.ply\"", "not found"],
            ),
            (
                Box::new(|v| v["camera"]["width"] = 16.into()),
                &["views[0].file_exr", "8×6", "16×6"],
            ),
        ];
        for (edit, wants) in edits {
            let out = tempfile::tempdir().unwrap();
            reference_folder(out.path());
            let p = out.path().join(REFERENCE_FILE);
            let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
            edit(&mut v);
            std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
            let msg = load_err(out.path());
            for w in wants {
                assert!(msg.contains(w), "{msg:?} should contain {w:?}");
            }
        }
    }

    #[test]
    fn dataset_md_example_loads() {
        let md = include_str!("../../../DATASET.md");
        let blocks = crate::scene_file::tests::code_blocks(md, "json");
        assert_eq!(blocks.len(), 1);
        let out = tempfile::tempdir().unwrap();
        let dir = out.path();
        std::fs::write(dir.join("dataset.json"), &blocks[0]).unwrap();
        std::fs::write(dir.join("bunny.ply"), b"ply\n").unwrap();
        let v: Value = serde_json::from_str(&blocks[0]).unwrap();
        for view in v["views"].as_array().unwrap() {
            let c = &view["camera"];
            let (w, h) = (
                c["width"].as_u64().unwrap() as u32,
                c["height"].as_u64().unwrap() as u32,
            );
            image(w, h, 0.1)
                .write_exr(&dir.join(view["image"].as_str().unwrap()), false)
                .unwrap();
        }
        let ds = Dataset::load(dir).unwrap();
        assert_eq!(ds.views.len(), 2);
        let (a, b) = (&ds.views[0].camera, &ds.views[1].camera);
        assert!(
            (a.direction() + a.origin.normalize()).length() < 1e-6,
            "view 0 looks at the origin"
        );
        assert!(
            (b.direction() + b.origin.normalize()).length() < 1e-6,
            "view 1 looks at the origin"
        );
        assert_eq!(b.height, 48);
        assert_eq!(
            ds.views[1].light.intensity,
            [std::f32::consts::FRAC_PI_4; 3]
        );
        assert_eq!(ds.render.max_depth, Some(32));
    }

    #[test]
    fn reference_fov_axis_y_is_converted() {
        let out = tempfile::tempdir().unwrap();
        reference_folder(out.path());
        let p = out.path().join(REFERENCE_FILE);
        let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        v["camera"]["fov_axis"] = "y".into();
        std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
        let ds = Dataset::load(out.path()).unwrap();
        let fx = ds.views[0].camera.fov_x_deg;
        let want = (2.0 * (20f64.to_radians().tan() * 8.0 / 6.0).atan()).to_degrees() as f32;
        assert!((fx - want).abs() < 1e-4, "{fx} vs {want}");
    }
}
