//! A photographed object as a dataset, whatever gave its cameras (a COLMAP model, a NeRF-style
//! `transforms.json`): an image per view (a photo, PNG or JPEG, decoded by its transfer
//! function, or a linear EXR; saturated pixels and those outside its mask leave the
//! measurement), the object's mesh in the model's frame, the light of each
//! image (a flash at a fixed place beside the lens, or a position per image) and what is known
//! about the object (boundary, phase function).

mod export;

pub use export::{CaptureExport, noisy_mesh, photo_name, write_capture};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::dataset::{Dataset, DatasetKind, DatasetMetadata, View, read_view_photo};
use crate::image::{PhotoSettings, is_photo_file};
use crate::measured::LengthUnit;
use crate::{Camera, MeshSource, Object, PointLight, RenderInfo, SceneError};

/// Where each image's light was.
#[derive(Clone, Debug, PartialEq)]
pub enum CaptureLight {
    /// A flash fixed to the camera: `offset` from the lens in the camera's frame as COLMAP
    /// defines it (x to the image's right, y down, z forward), in the model's units.
    Flash { offset: Vec3 },
    /// A position per image name (world coordinates of the model).
    Positions(BTreeMap<String, Vec3>),
}

/// What a capture adds to its cameras (from a COLMAP model or a `transforms.json`).
#[derive(Clone, Debug, PartialEq)]
pub struct Capture {
    /// The folder of images: view `NAME.jpg` is that photo here, or `NAME.exr` (linear).
    pub images: PathBuf,
    /// A folder of mask images (white = the object): `NAME.jpg.png` or `NAME.png`; `None`:
    /// every pixel that is not saturated is measured.
    pub masks: Option<PathBuf>,
    /// How the images are decoded (transfer function, exposure scale).
    pub photo: PhotoSettings,
    /// The object's mesh (PLY or OBJ) in the model's frame and units.
    pub mesh: PathBuf,
    pub light: CaptureLight,
    /// The light's radiant intensity per channel [W/sr] (relative where it is not known:
    /// recover its scale with the light scale free).
    pub intensity: [f32; 3],
    /// What is known about the object; `None`: nothing is stated.
    pub object: Option<Object>,
    /// What one unit of the cameras' lengths is, where known.
    pub length_unit: Option<LengthUnit>,
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

/// The image `name` in `dir`: the file of that name (a photo, `NAME.jpg`), else `NAME.exr` (a
/// linear developed image), else, for a name without an extension (the NeRF scenes'
/// `./train/r_0`), `NAME.png` or `NAME.jpg`.
fn image_path(dir: &Path, name: &str) -> Result<PathBuf, SceneError> {
    let photo = dir.join(name);
    let mut candidates = vec![photo.clone(), photo.with_extension("exr")];
    if photo.extension().is_none() {
        candidates.extend(["png", "jpg"].map(|e| photo.with_extension(e)));
    }
    candidates
        .iter()
        .find(|p| p.is_file())
        .cloned()
        .ok_or_else(|| SceneError::Invalid {
            location: format!("image {name:?}"),
            reason: format!(
                "missing: looked for {}; fix: pass the folder of the images the poses were \
                 made from (photos, or linear EXRs named like them)",
                candidates
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })
}

/// The mask of model image `name` in `dir`: `NAME.png` (COLMAP's convention, `IMG_1.jpg.png`),
/// else the image's name with the extension `.png`.
fn mask_path(dir: &Path, name: &str) -> Result<PathBuf, SceneError> {
    let colmap = dir.join(format!("{name}.png"));
    let plain = dir.join(name).with_extension("png");
    [&colmap, &plain]
        .into_iter()
        .find(|p| p.is_file())
        .cloned()
        .ok_or_else(|| SceneError::Invalid {
            location: format!("the mask of image {name:?}"),
            reason: format!(
                "missing: looked for {} and {}; fix: give a mask per registered image (white = \
                 the object), or leave the masks out",
                colmap.display(),
                plain.display()
            ),
        })
}

/// One view of a capture: the name of its image and its camera.
#[derive(Clone, Debug, PartialEq)]
pub struct CapturedView {
    /// The image's name in the capture (`IMG_0001.JPG`, `./train/r_0`).
    pub name: String,
    pub camera: Camera,
}

impl Capture {
    /// The dataset of `views` (in their order): each view's image and mask read and checked
    /// against its camera (`fix` says how to mend an image of another size), its light placed.
    /// `units` and `source` describe where the cameras came from (the dataset's units note and
    /// its generator).
    pub fn dataset(
        &self,
        views: &[CapturedView],
        units: String,
        source: &str,
        fix: &str,
    ) -> Result<Dataset, SceneError> {
        crate::rig::check_intensity(&self.intensity, "the light's intensity")?;
        let mut out = Vec::with_capacity(views.len());
        for v in views {
            let position = self.light_position(v)?;
            let path = image_path(&self.images, &v.name)?;
            let mask = match &self.masks {
                Some(dir) => Some(mask_path(dir, &v.name)?),
                None => None,
            };
            let location = format!("image {:?} ({})", v.name, path.display());
            let (image, mask) = read_view_photo(
                &path,
                mask.as_deref(),
                &self.photo,
                &location,
                &v.camera,
                fix,
            )?;
            out.push(View {
                camera: Camera {
                    mask,
                    ..v.camera.clone()
                },
                light: PointLight {
                    position,
                    intensity: self.intensity,
                },
                image: Some(image),
                image_path: Some(path),
                expected_mean: None,
            });
        }
        Ok(Dataset {
            views: out,
            mesh: MeshSource::File(self.mesh.clone()),
            object: self.object,
            truth: None,
            render: RenderInfo::default(),
            metadata: DatasetMetadata {
                units: Some(units),
                conventions: None,
                generator: Some(format!(
                    "translucent {} ({source})",
                    env!("CARGO_PKG_VERSION")
                )),
                notes: None,
                length_unit: self.length_unit,
            },
            root: PathBuf::new(),
            kind: DatasetKind::Native,
            warnings: Vec::new(),
        })
    }

    /// The size in pixels of image `name` (read from the file's header where it is a photo).
    pub fn image_size(&self, name: &str) -> Result<(u32, u32), SceneError> {
        let path = image_path(&self.images, name)?;
        if is_photo_file(&path) {
            return image::image_dimensions(&path).map_err(|e| SceneError::Parse {
                path: path.clone(),
                reason: format!("cannot read the image's size: {e}"),
            });
        }
        let img = crate::Image::read_exr(&path)?;
        Ok((img.width, img.height))
    }

    /// The light of view `v`: the flash beside its lens, or its stated position.
    fn light_position(&self, v: &CapturedView) -> Result<Vec3, SceneError> {
        match &self.light {
            CaptureLight::Flash { offset } => {
                // The flash's frame (COLMAP's, OpenCV's) is ours with x and y negated.
                let r = v.camera.rotation;
                Ok(v.camera.origin - r.x_axis * offset.x - r.y_axis * offset.y
                    + r.z_axis * offset.z)
            }
            CaptureLight::Positions(p) => {
                p.get(&v.name).copied().ok_or_else(|| SceneError::Invalid {
                    location: format!("the light positions: image {:?}", v.name),
                    reason: "has no light position; fix: give every image a light position \
                             (a line NAME X Y Z)"
                        .into(),
                })
            }
        }
    }
}
