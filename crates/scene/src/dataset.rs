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
//!
//! This module holds the types ([`Dataset`], [`View`], …), loading by folder format and the checks
//! shared by both formats; `dataset/json.rs` reads `dataset.json`, `dataset/save.rs` writes a
//! dataset folder and `dataset/reference.rs` reads Mitsuba reference folders.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::Value;

use crate::image::{Photo, PhotoSettings, PixelMask};
use crate::measured::LengthUnit;
use crate::scene_file::desc::{RenderInfo, ViewDesc};
use crate::scene_file::parse::base_dir;
use crate::{Camera, Image, Medium, MeshSource, Object, PointLight, SceneDesc, SceneError};

mod json;
mod reference;
#[cfg(test)]
// Numbers copied verbatim from Mitsuba's scene.json.
#[allow(clippy::excessive_precision, clippy::type_complexity)]
mod reference_tests;
mod save;
#[cfg(test)]
#[allow(clippy::type_complexity)]
pub(crate) mod tests;
mod xml;

pub use reference::load_reference_folder;

/// `format` value of dataset.json.
pub const DATASET_FORMAT: &str = "translucent-dataset";
/// The dataset.json version this code reads and writes.
pub const DATASET_VERSION: u32 = 1;
/// File name of the dataset description.
pub const DATASET_FILE: &str = "dataset.json";
/// File name of the description in a Mitsuba reference-render folder.
pub const REFERENCE_FILE: &str = "scene.json";
/// File name of the scene in a Mitsuba 3 scene folder (the scene file and an image per sensor).
pub const MITSUBA_SCENE_FILE: &str = "scene.xml";

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
    /// A Mitsuba 3 scene folder (`scene.xml` and an image per sensor).
    MitsubaScene,
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
    /// What one unit of the dataset's lengths is, when known: σ_t is then reported in mm⁻¹ too.
    pub length_unit: Option<LengthUnit>,
}

/// A loaded dataset.
#[derive(Clone, Debug)]
pub struct Dataset {
    pub views: Vec<View>,
    /// Mesh file (resolved path) or built-in shape.
    pub mesh: MeshSource,
    /// What the dataset states about the object besides σ_t and α (boundary, phase function):
    /// what a recovery renders with. `None`: the dataset states nothing.
    pub object: Option<Object>,
    /// The medium the images were rendered with, when known: a report, never read for
    /// rendering a recovery.
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
            object: Some(Object::of(&scene.medium)),
            truth: Some(scene.medium),
            render: scene.render.clone(),
            metadata: DatasetMetadata {
                // With a stated unit, the written note names it (`save`).
                units: scene.length_unit.is_none().then(|| UNITS_NOTE.into()),
                conventions: Some(CONVENTIONS_NOTE.into()),
                generator: Some(format!("translucent {}", env!("CARGO_PKG_VERSION"))),
                notes: None,
                length_unit: scene.length_unit,
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
                DatasetKind::MitsubaScene => MITSUBA_SCENE_FILE,
            }),
            length_unit: self.metadata.length_unit,
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
                Some(MITSUBA_SCENE_FILE) => xml::load_scene_folder(&dir),
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
        } else if path.join(MITSUBA_SCENE_FILE).is_file() {
            xml::load_scene_folder(path)
        } else {
            Err(SceneError::Invalid {
                location: path.display().to_string(),
                reason: format!(
                    "no {DATASET_FILE} (translucent dataset), no {REFERENCE_FILE} (Mitsuba \
                     reference folder) and no {MITSUBA_SCENE_FILE} (Mitsuba 3 scene with an \
                     image per sensor) here; fix: point to a dataset folder (see DATASET.md), \
                     or create one with `translucent dataset`"
                ),
            })
        }
    }

    /// Load a Mitsuba reference-render folder (`scene.json`); see [`load_reference_folder`].
    pub fn load_reference(dir: &Path) -> Result<Dataset, SceneError> {
        load_reference_folder(dir)
    }
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

/// The file `name` names, relative to `dir` unless absolute; an error naming `location` where it
/// is missing.
fn resolve(dir: &Path, name: &str, location: &str, what: &str) -> Result<PathBuf, SceneError> {
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
                "{what} file not found (looked for {}); fix: put it in the dataset folder or \
                 correct the name",
                path.display()
            ),
        });
    }
    Ok(path)
}

/// A linear EXR view image, checked against its camera.
fn load_view_image(
    dir: &Path,
    name: &str,
    location: &str,
    camera: &Camera,
) -> Result<(Image, PathBuf), SceneError> {
    let path = resolve(dir, name, location, "image")?;
    let img = Image::read_exr(&path)?;
    check_image_size(&img, camera, &format!("{location} = \"{name}\""))?;
    Ok((img, path))
}

/// One view's photo (EXR, PNG or JPEG, [`Photo`]) and its optional mask image, checked against
/// the camera: the linear image, zero where no pixel is measured, its path, and the measured
/// pixels where some are not (`None`: all are).
pub(crate) fn load_view_photo(
    dir: &Path,
    name: &str,
    mask: Option<&str>,
    photo: &PhotoSettings,
    location: &str,
    camera: &Camera,
) -> Result<(Image, PathBuf, Option<Arc<PixelMask>>), SceneError> {
    let path = resolve(dir, name, &format!("{location}.image"), "image")?;
    let mask = match mask {
        Some(m) => Some(resolve(dir, m, &format!("{location}.mask"), "mask")?),
        None => None,
    };
    let fix = "render the image at the camera's resolution or correct the camera's width/height";
    let at = format!("{location}.image = \"{name}\"");
    let (image, measured) = read_view_photo(&path, mask.as_deref(), photo, &at, camera, fix)?;
    Ok((image, path, measured))
}

/// A photo at `path` with its optional mask image at `mask`, checked against `camera` (errors
/// name `location`; `fix` says how to mend an image of another size than the camera's): the
/// linear image, zero where no pixel is measured, and the measured pixels where some are not
/// (`None`: all are).
pub(crate) fn read_view_photo(
    path: &Path,
    mask: Option<&Path>,
    photo: &PhotoSettings,
    location: &str,
    camera: &Camera,
    fix: &str,
) -> Result<(Image, Option<Arc<PixelMask>>), SceneError> {
    let mut p = Photo::read(path, photo)?;
    if (p.image.width, p.image.height) != (camera.width, camera.height) {
        return Err(SceneError::Invalid {
            location: location.to_string(),
            reason: format!(
                "{}×{} pixels, but its camera is {}×{}; fix: {fix}",
                p.image.width, p.image.height, camera.width, camera.height
            ),
        });
    }
    let mut measured = p.measured;
    if let Some(mpath) = mask {
        let mask = PixelMask::read(mpath)?;
        if (mask.width, mask.height) != (camera.width, camera.height) {
            return Err(SceneError::Invalid {
                location: mpath.display().to_string(),
                reason: format!(
                    "the mask is {}×{} but its image is {}×{}; fix: give a mask of the image's \
                     size",
                    mask.width, mask.height, camera.width, camera.height
                ),
            });
        }
        measured = measured.and(&mask);
    }
    if measured.count() == 0 {
        return Err(SceneError::Invalid {
            location: location.to_string(),
            reason: format!(
                "no pixel of this view is measured ({} saturated, the rest masked out or \
                 transparent); fix: check the mask (white = the object), or lower the exposure \
                 of the capture",
                p.saturated
            ),
        });
    }
    if measured.is_full() {
        return Ok((p.image, None));
    }
    p.image.apply_mask(&measured);
    Ok((p.image, Some(Arc::new(measured))))
}
