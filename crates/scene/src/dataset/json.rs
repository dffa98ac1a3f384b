//! `dataset.json` (DATASET.md): the serialised form (`RawDataset` and its parts; strict: unknown
//! fields are errors) and reading it into a [`Dataset`], header (format, version) first, then
//! every field validated and every image checked against its camera.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::{
    DATASET_FORMAT, DATASET_VERSION, Dataset, DatasetKind, DatasetMetadata, View, load_view_photo,
};
use crate::camera::{Intrinsics, camera_from_matrix};
use crate::image::{PhotoSettings, Transfer};
use crate::measured::LengthUnit;
use crate::object::ObjectSpec;
use crate::rig::check_intensity;
use crate::scene_file::{
    MediumSpec, RenderInfo, Rgb, ShapeSpec, base_dir, check_finite3, look_at_checked,
    resolve_mesh_path,
};
use crate::{Camera, Medium, MeshSource, Object, PointLight, SceneError};

impl Dataset {
    /// Load a translucent dataset from its `dataset.json` file (images next to it).
    pub fn load_dataset_json(file: &Path) -> Result<Dataset, SceneError> {
        let text = std::fs::read_to_string(file).map_err(|source| SceneError::Io {
            path: file.to_path_buf(),
            source,
        })?;
        let name = file.display().to_string();
        let dir = base_dir(file);

        check_header(&text, file, &name)?;

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
        let object = match raw.object {
            Some(o) => Some(o.to_object(&format!("{name}: object"))?),
            None => None,
        };
        check_truth_agrees(object.as_ref(), truth.as_ref(), &name)?;
        let render = raw.render.unwrap_or_default();
        render.validate(&format!("{name}: render"))?;
        if raw.views.is_empty() {
            return Err(SceneError::Invalid {
                location: format!("{name}: views"),
                reason: "no views; fix: add at least one view".into(),
            });
        }
        let views = raw
            .views
            .into_iter()
            .enumerate()
            .map(|(i, v)| load_view(v, &dir, &format!("{name}: views[{i}]")))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Dataset {
            views,
            mesh,
            object,
            truth,
            render,
            metadata: DatasetMetadata {
                units: raw.units,
                conventions: raw.conventions,
                generator: raw.generator,
                notes: raw.notes,
                length_unit: raw.length_unit,
            },
            root: dir,
            kind: DatasetKind::Native,
            warnings: Vec::new(),
        })
    }
}

/// The `format` and `version` fields, read first so that a wrong file gets a clear message
/// rather than a list of unknown fields.
fn check_header(text: &str, file: &Path, name: &str) -> Result<(), SceneError> {
    #[derive(Deserialize)]
    struct Header {
        format: Option<Value>,
        version: Option<Value>,
    }
    let header: Header = serde_json::from_str(text).map_err(|e| SceneError::Parse {
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
    Ok(())
}

/// One entry of `views` (`ctx` names it): its camera, its light and its image, checked.
fn load_view(v: RawView, dir: &Path, ctx: &str) -> Result<View, SceneError> {
    let camera = v.camera.to_camera(&format!("{ctx}.camera"))?;
    let position = check_finite3(v.light.position, &format!("{ctx}.light.position"))?;
    check_intensity(&v.light.intensity.0, &format!("{ctx}.light.intensity"))?;
    let photo = PhotoSettings {
        transfer: v.transfer,
        exposure: v.exposure.unwrap_or(1.0),
        saturation: v.saturation,
    };
    let (image, image_path, mask) =
        load_view_photo(dir, &v.image, v.mask.as_deref(), &photo, ctx, &camera)?;
    Ok(View {
        camera: Camera { mask, ..camera },
        light: PointLight {
            position,
            intensity: v.light.intensity.0,
        },
        image: Some(image),
        image_path: Some(image_path),
        expected_mean: None,
    })
}

/// A dataset whose `truth` (what rendered it) contradicts its `object` (what a recovery renders
/// with) is inconsistent: refused, naming both. A truth without an object is fine here (the
/// recovery says what it assumes); an object needs no truth.
pub(super) fn check_truth_agrees(
    object: Option<&Object>,
    truth: Option<&Medium>,
    name: &str,
) -> Result<(), SceneError> {
    if let (Some(o), Some(t)) = (object, truth)
        && Object::of(t) != *o
    {
        return Err(SceneError::Invalid {
            location: format!("{name}: truth"),
            reason: format!(
                "the medium that rendered the images has a {}, but object states a {}; fix: \
                 make object state the boundary and phase function of the capture (the \
                 recovery renders with object, never with truth)",
                Object::of(t).describe(),
                o.describe()
            ),
        });
    }
    Ok(())
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDataset {
    pub(super) format: String,
    pub(super) version: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) units: Option<String>,
    /// What one unit of length is ("mm", "cm", "m").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) length_unit: Option<LengthUnit>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) conventions: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) generator: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) mesh: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) shape: Option<ShapeSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) object: Option<ObjectSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) truth: Option<MediumSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) render: Option<RenderInfo>,
    pub(super) views: Vec<RawView>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) notes: Option<Value>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawView {
    pub(super) camera: RawCamera,
    pub(super) light: RawLight,
    pub(super) image: String,
    /// A mask image: white where the pixel measures the object.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) mask: Option<String>,
    /// The image's transfer function (default: sRGB for PNG/JPEG, linear for EXR).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) transfer: Option<Transfer>,
    /// The exposure scale k: linear radiance = k · decoded value (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) exposure: Option<f32>,
    /// An EXR's clipping level: pixels with a channel at or above it leave the loss.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) saturation: Option<f32>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawLight {
    pub(super) position: [f32; 3],
    pub(super) intensity: Rgb,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCamera {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) origin: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) target: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) up: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) to_world: Option<[[f64; 4]; 4]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) fov_x_deg: Option<f32>,
    /// A calibrated camera's intrinsics, instead of `fov_x_deg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub(super) intrinsics: Option<RawIntrinsics>,
    pub(super) width: u32,
    pub(super) height: u32,
}

/// A camera's intrinsic matrix in pixels of its image (DATASET.md).
#[derive(Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawIntrinsics {
    pub(super) fx: f32,
    pub(super) fy: f32,
    pub(super) cx: f32,
    pub(super) cy: f32,
}

impl RawIntrinsics {
    /// The camera's intrinsics as the file writes them.
    pub(super) fn of(camera: &Camera) -> Self {
        let k = camera.intrinsics();
        RawIntrinsics {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
        }
    }

    /// The intrinsics, checked: positive, finite focal lengths (the principal point and their
    /// ratio are checked with the camera).
    fn checked(&self, ctx: &str) -> Result<Intrinsics, SceneError> {
        for (field, f) in [("fx", self.fx), ("fy", self.fy)] {
            if !(f.is_finite() && f > 0.0) {
                return Err(SceneError::Invalid {
                    location: format!("{ctx}.intrinsics.{field}"),
                    reason: format!(
                        "= {f}: a focal length must be a positive number of pixels; fix: give \
                         the calibration's f in pixels (e.g. COLMAP's PINHOLE fx)"
                    ),
                });
            }
        }
        Ok(Intrinsics {
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
        })
    }
}

impl RawCamera {
    fn to_camera(&self, ctx: &str) -> Result<Camera, SceneError> {
        let (fov, k) = match (self.fov_x_deg, &self.intrinsics) {
            (Some(fov), None) => (fov, None),
            (None, Some(k)) => {
                let k = k.checked(ctx)?;
                (
                    2.0 * (0.5 * self.width as f32 / k.fx).atan().to_degrees(),
                    Some(k),
                )
            }
            (Some(_), Some(_)) => {
                return Err(SceneError::Invalid {
                    location: format!("{ctx}.fov_x_deg"),
                    reason: "given together with intrinsics; fix: describe the lens either by \
                             fov_x_deg or by intrinsics {fx, fy, cx, cy}, not both"
                        .into(),
                });
            }
            (None, None) => {
                return Err(SceneError::Invalid {
                    location: format!("{ctx}.fov_x_deg"),
                    reason: "missing; fix: give \"fov_x_deg\" (degrees, centred camera) or \
                             \"intrinsics\": {\"fx\", \"fy\", \"cx\", \"cy\"} (pixels)"
                        .into(),
                });
            }
        };
        let camera = self.placed(fov, ctx)?;
        let Some(k) = k else {
            return Ok(camera);
        };
        let camera = camera.with_intrinsics(&k);
        if let Some(p) = &camera.pinhole {
            p.validate(&format!("{ctx}.intrinsics"), self.width, self.height)?;
        }
        Ok(camera)
    }

    /// The camera's placement (`to_world`, or `origin` + `target` + `up`) with the field of view
    /// `fov`.
    fn placed(&self, fov: f32, ctx: &str) -> Result<Camera, SceneError> {
        match (&self.to_world, self.origin, self.target) {
            (Some(m), None, None) if self.up.is_none() => {
                camera_from_matrix(m, fov, self.width, self.height, ctx)
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
                fov,
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
