//! COLMAP sparse models (`cameras` and `images`, text or binary; COLMAP's doc/format.rst): the
//! calibrated cameras and poses of a photographed object, read as [`Camera`]s.
//!
//! Cameras: `SIMPLE_PINHOLE` (f, c_x, c_y), `PINHOLE` (f_x, f_y, c_x, c_y), and the distortion
//! models `SIMPLE_RADIAL`, `RADIAL`, `OPENCV` and `FULL_OPENCV` when every distortion
//! coefficient is 0 (an undistorted camera written under its calibration's model); a camera that
//! distorts, or a fisheye model, is refused with the fix (`colmap image_undistorter`, which
//! writes `PINHOLE` cameras and undistorted images). Pixel coordinates are COLMAP's: the image's
//! top-left corner at (0, 0), the centre of its first pixel at (½, ½), as ours.
//!
//! Poses: `images` holds each image's world-to-camera rotation (a unit quaternion
//! (q_w, q_x, q_y, q_z), Hamilton convention) and translation t: X_cam = R·X_world + t, the
//! camera centre −Rᵀt. COLMAP's camera looks along +z with x to the image's right and y down;
//! ours ([`crate::camera`]) has x to the left and y up, so its axes in the world are
//! (−r₀, −r₁, r₂) for the rows r_i of R. Lengths are the reconstruction's own (arbitrary unless
//! the model was scaled): σ_t is then in 1/those units.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat, DVec3, Mat3};

use crate::SceneError;
use crate::camera::{Camera, Intrinsics};

pub use crate::capture::{Capture, CaptureLight, CapturedView};

mod binary;
mod capture;
#[cfg(test)]
pub(crate) mod tests;
mod text;
mod write;

pub use write::write_text;

/// One camera of `cameras.txt`/`.bin`: its model's name, its image size and its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    pub model: String,
    pub width: u32,
    pub height: u32,
    pub params: Vec<f64>,
}

/// One image of `images.txt`/`.bin`: its pose, its camera and its file name.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    pub id: u32,
    /// World-to-camera rotation (q_w, q_x, q_y, q_z).
    pub q: [f64; 4],
    /// World-to-camera translation.
    pub t: [f64; 3],
    pub camera_id: u32,
    /// The image file, relative to the project's image folder.
    pub name: String,
}

/// A sparse model: cameras by id, images in the file's order.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapModel {
    /// The folder it was read from.
    pub dir: PathBuf,
    pub cameras: BTreeMap<u32, ColmapCamera>,
    pub images: Vec<ColmapImage>,
}

/// The number of parameters of each camera model COLMAP writes, by its name and binary id.
const MODELS: [(&str, usize); 11] = [
    ("SIMPLE_PINHOLE", 3),
    ("PINHOLE", 4),
    ("SIMPLE_RADIAL", 4),
    ("RADIAL", 5),
    ("OPENCV", 8),
    ("OPENCV_FISHEYE", 8),
    ("FULL_OPENCV", 12),
    ("FOV", 5),
    ("SIMPLE_RADIAL_FISHEYE", 4),
    ("RADIAL_FISHEYE", 5),
    ("THIN_PRISM_FISHEYE", 12),
];

/// The parameter count of camera model `name`, or `None` for a model COLMAP does not define.
fn param_count(name: &str) -> Option<usize> {
    MODELS.iter().find(|(n, _)| *n == name).map(|(_, k)| *k)
}

impl ColmapModel {
    /// Reads the model in `dir`: `cameras.txt` and `images.txt`, else `cameras.bin` and
    /// `images.bin` (COLMAP's text and binary formats; `points3D` is not needed).
    pub fn read(dir: &Path) -> Result<ColmapModel, SceneError> {
        let (cameras, images) = if dir.join("cameras.txt").is_file() {
            let cameras = text::cameras(&dir.join("cameras.txt"))?;
            (cameras, text::images(&dir.join("images.txt"))?)
        } else if dir.join("cameras.bin").is_file() {
            let cameras = binary::cameras(&dir.join("cameras.bin"))?;
            (cameras, binary::images(&dir.join("images.bin"))?)
        } else {
            return Err(SceneError::Invalid {
                location: dir.display().to_string(),
                reason: "no COLMAP model here (cameras.txt + images.txt, or cameras.bin + \
                         images.bin); fix: pass the sparse model's folder, e.g. sparse/0"
                    .into(),
            });
        };
        let model = ColmapModel {
            dir: dir.to_path_buf(),
            cameras,
            images,
        };
        model.check()?;
        Ok(model)
    }

    /// Every image names a camera of the model, and there is at least one image.
    fn check(&self) -> Result<(), SceneError> {
        if self.images.is_empty() {
            return Err(SceneError::Invalid {
                location: self.dir.join("images").display().to_string(),
                reason: "the model has no registered images; fix: pass a reconstructed model"
                    .into(),
            });
        }
        for im in &self.images {
            if !self.cameras.contains_key(&im.camera_id) {
                return Err(SceneError::Invalid {
                    location: format!("{}: image {} ({})", self.dir.display(), im.id, im.name),
                    reason: format!(
                        "names camera {}, which the model's cameras do not hold; fix: export \
                         cameras and images of the same model",
                        im.camera_id
                    ),
                });
            }
        }
        Ok(())
    }

    /// The camera of image `im` as ours: its pose and its intrinsics.
    pub fn camera(&self, im: &ColmapImage) -> Result<Camera, SceneError> {
        let cam = &self.cameras[&im.camera_id];
        let ctx = format!(
            "{}: camera {} of image {}",
            self.dir.display(),
            im.camera_id,
            im.name
        );
        let k = cam.intrinsics(&ctx)?;
        let [w, x, y, z] = im.q;
        let norm = (w * w + x * x + y * y + z * z).sqrt();
        if !(norm.is_finite() && (norm - 1.0).abs() < 1e-3) || im.t.iter().any(|v| !v.is_finite()) {
            return Err(SceneError::Invalid {
                location: format!("{}: image {} ({})", self.dir.display(), im.id, im.name),
                reason: format!(
                    "pose q = {:?}, t = {:?}: the rotation must be a unit quaternion and the \
                     translation finite; fix: re-export the model",
                    im.q, im.t
                ),
            });
        }
        let r = DMat3::from_quat(DQuat::from_xyzw(x, y, z, w) / norm);
        let rt = r.transpose();
        let origin = -(rt * DVec3::from(im.t));
        // The rows of R are COLMAP's camera axes in the world (the columns of Rᵀ).
        let axes = [-rt.x_axis, -rt.y_axis, rt.z_axis].map(|a| a.as_vec3());
        let camera = Camera {
            origin: origin.as_vec3(),
            rotation: Mat3::from_cols(axes[0], axes[1], axes[2]),
            fov_x_deg: 40.0,
            width: cam.width,
            height: cam.height,
            crop: None,
            pinhole: None,
            mask: None,
        }
        .with_intrinsics(&k);
        camera.validate(&ctx)?;
        Ok(camera)
    }
}

impl ColmapCamera {
    /// The pinhole's intrinsics; an error naming the camera (`ctx`) for a model that distorts.
    pub fn intrinsics(&self, ctx: &str) -> Result<Intrinsics, SceneError> {
        let p = &self.params;
        let (f, distortion): ([f64; 4], &[f64]) = match self.model.as_str() {
            "SIMPLE_PINHOLE" => ([p[0], p[0], p[1], p[2]], &[]),
            "PINHOLE" => ([p[0], p[1], p[2], p[3]], &[]),
            "SIMPLE_RADIAL" | "RADIAL" => ([p[0], p[0], p[1], p[2]], &p[3..]),
            "OPENCV" | "FULL_OPENCV" => ([p[0], p[1], p[2], p[3]], &p[4..]),
            m => {
                return Err(SceneError::Invalid {
                    location: ctx.to_string(),
                    reason: format!(
                        "model {m} is a fisheye or field-of-view lens, not a pinhole; fix: \
                         undistort the images (colmap image_undistorter) and pass the model it \
                         writes"
                    ),
                });
            }
        };
        if let Some((i, d)) = distortion.iter().enumerate().find(|(_, d)| **d != 0.0) {
            return Err(SceneError::Invalid {
                location: ctx.to_string(),
                reason: format!(
                    "model {} distorts (its distortion coefficient {i} is {d}): the renderer \
                     models a pinhole; fix: undistort the images (colmap image_undistorter \
                     writes PINHOLE cameras and undistorted images) and pass that model",
                    self.model
                ),
            });
        }
        if f.iter().any(|v| !v.is_finite()) || f[0] <= 0.0 || f[1] <= 0.0 {
            return Err(SceneError::Invalid {
                location: ctx.to_string(),
                reason: format!(
                    "focal lengths {} and {} pixels: they must be positive; fix: re-export the \
                     model",
                    f[0], f[1]
                ),
            });
        }
        Ok(Intrinsics {
            fx: f[0] as f32,
            fy: f[1] as f32,
            cx: f[2] as f32,
            cy: f[3] as f32,
        })
    }
}

/// A camera's fields checked: a known model with its number of parameters and a size of
/// 1…65536 pixels per side (`at` names the line or record in errors).
fn checked_camera(
    at: &str,
    model: String,
    width: u64,
    height: u64,
    params: Vec<f64>,
) -> Result<ColmapCamera, SceneError> {
    let bad = |reason: String| SceneError::Invalid {
        location: at.to_string(),
        reason,
    };
    let want = param_count(&model).ok_or_else(|| {
        bad(format!(
            "camera model {model:?} is not one of COLMAP's ({})",
            MODELS.map(|(n, _)| n).join(", ")
        ))
    })?;
    if params.len() != want {
        return Err(bad(format!(
            "{model} has {want} parameters, the line gives {}",
            params.len()
        )));
    }
    let size = |v: u64| u32::try_from(v).ok().filter(|v| (1..=65536).contains(v));
    let (Some(width), Some(height)) = (size(width), size(height)) else {
        return Err(bad(format!(
            "image size {width} × {height}: each side must be 1…65536 pixels"
        )));
    };
    Ok(ColmapCamera {
        model,
        width,
        height,
        params,
    })
}
