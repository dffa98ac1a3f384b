//! A photographed object as a dataset: a COLMAP model's cameras and poses, an image per
//! registered image (linear EXR), the object's mesh in the model's frame, the light of each
//! image (a flash at a fixed place beside the lens, or a position per image) and what is known
//! about the object (boundary, phase function).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::Vec3;

use super::ColmapModel;
use crate::dataset::{Dataset, DatasetKind, DatasetMetadata, View};
use crate::{Image, MeshSource, Object, PointLight, RenderInfo, SceneError};

/// Where each image's light was.
#[derive(Clone, Debug, PartialEq)]
pub enum CaptureLight {
    /// A flash fixed to the camera: `offset` from the lens in the camera's frame as COLMAP
    /// defines it (x to the image's right, y down, z forward), in the model's units.
    Flash { offset: Vec3 },
    /// A position per image name (world coordinates of the model).
    Positions(BTreeMap<String, Vec3>),
}

/// What a capture adds to a COLMAP model.
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    /// The folder of linear EXR images: image `NAME.jpg` of the model is `NAME.exr` here.
    pub images: PathBuf,
    /// The object's mesh (PLY or OBJ) in the model's frame and units.
    pub mesh: PathBuf,
    pub light: CaptureLight,
    /// The light's radiant intensity per channel [W/sr] (relative where it is not known:
    /// recover its scale with the light scale free).
    pub intensity: [f32; 3],
    /// What is known about the object; `None`: nothing is stated.
    pub object: Option<Object>,
}

impl CaptureLight {
    /// Light positions from a text file: one `NAME X Y Z` per line (NAME as in the model; it may
    /// hold spaces), `#` comments.
    pub fn read_positions(path: &Path) -> Result<CaptureLight, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut out = BTreeMap::new();
        for (i, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let words: Vec<&str> = line.split_whitespace().collect();
            let bad = || SceneError::Invalid {
                location: format!("{}:{}", path.display(), i + 1),
                reason: format!(
                    "{line:?}: write NAME X Y Z (the image's name in the model, then the light's \
                     position in the model's frame)"
                ),
            };
            if words.len() < 4 {
                return Err(bad());
            }
            let xyz: Vec<f32> = words[words.len() - 3..]
                .iter()
                .map(|w| w.parse::<f32>().ok().filter(|v| v.is_finite()))
                .collect::<Option<_>>()
                .ok_or_else(bad)?;
            let name = words[..words.len() - 3].join(" ");
            out.insert(name, Vec3::new(xyz[0], xyz[1], xyz[2]));
        }
        Ok(CaptureLight::Positions(out))
    }
}

/// The image of model image `name` in `dir`: `name` with the extension `.exr`.
fn image_path(dir: &Path, name: &str) -> PathBuf {
    dir.join(name).with_extension("exr")
}

impl ColmapModel {
    /// The capture as a dataset: a view per registered image, in the model's order.
    pub fn dataset(&self, capture: &Capture) -> Result<Dataset, SceneError> {
        crate::rig::check_intensity(&capture.intensity, "the light's intensity")?;
        let mut views = Vec::with_capacity(self.images.len());
        for im in &self.images {
            let camera = self.camera(im)?;
            let position = match &capture.light {
                CaptureLight::Flash { offset } => {
                    // COLMAP's camera axes are ours with x and y negated.
                    let r = camera.rotation;
                    camera.origin - r.x_axis * offset.x - r.y_axis * offset.y + r.z_axis * offset.z
                }
                CaptureLight::Positions(p) => {
                    *p.get(&im.name).ok_or_else(|| SceneError::Invalid {
                        location: format!("the light positions: image {:?}", im.name),
                        reason: "has no light position; fix: give every registered image of \
                                 the model a line NAME X Y Z"
                            .into(),
                    })?
                }
            };
            let path = image_path(&capture.images, &im.name);
            let image = read_image(&path, &im.name)?;
            if (image.width, image.height) != (camera.width, camera.height) {
                return Err(SceneError::Invalid {
                    location: path.display().to_string(),
                    reason: format!(
                        "{}×{} pixels, but its camera in the model is {}×{}; fix: pass the \
                         images the model was made from (undistorted, unscaled)",
                        image.width, image.height, camera.width, camera.height
                    ),
                });
            }
            image.check_finite(&path.display().to_string())?;
            views.push(View {
                camera,
                light: PointLight {
                    position,
                    intensity: capture.intensity,
                },
                image: Some(image),
                image_path: Some(path),
                expected_mean: None,
            });
        }
        Ok(Dataset {
            views,
            mesh: MeshSource::File(capture.mesh.clone()),
            object: capture.object,
            truth: None,
            render: RenderInfo::default(),
            metadata: DatasetMetadata {
                units: Some(format!(
                    "lengths in the units of the COLMAP model {} (sigma_t in 1/those units); \
                     light intensity in W/sr, relative unless measured; images linear radiance",
                    self.dir.display()
                )),
                conventions: None,
                generator: Some(format!(
                    "translucent {} (COLMAP import)",
                    env!("CARGO_PKG_VERSION")
                )),
                notes: None,
            },
            root: PathBuf::new(),
            kind: DatasetKind::Native,
            warnings: Vec::new(),
        })
    }
}

/// The linear EXR of image `name`; a clear refusal for a photo (sRGB) or a missing file.
fn read_image(path: &Path, name: &str) -> Result<Image, SceneError> {
    if path.is_file() {
        return Image::read_exr(path);
    }
    let photo = ["jpg", "jpeg", "JPG", "JPEG", "png", "PNG"]
        .iter()
        .map(|e| path.with_extension(e))
        .find(|p| p.is_file());
    let reason = match photo {
        Some(p) => format!(
            "missing; {} is a photo (8-bit sRGB), which is not read: its response is not \
             linear; fix: develop the RAW files (or convert the photos with their camera \
             response) into linear EXR named like the model's images",
            p.display()
        ),
        None => format!(
            "missing: the model's image {name:?} needs its linear EXR here; fix: pass the folder \
             of EXR images named like the model's images"
        ),
    };
    Err(SceneError::Invalid {
        location: path.display().to_string(),
        reason,
    })
}
