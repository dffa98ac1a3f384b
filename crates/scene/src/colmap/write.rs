//! Writing a COLMAP text model ([`write_text`]): a `PINHOLE` camera per view (f_x, f_y, c_x, c_y
//! of its intrinsics) and its pose, the inverse of [`super::ColmapModel::camera`]: COLMAP's
//! world-to-camera rotation R has rows (−x, −y, z) of our camera's axes, and t = −R·origin.

use std::fmt::Write as _;
use std::path::Path;

use glam::{DMat3, DQuat};

use crate::SceneError;
use crate::capture::CapturedView;
use crate::fsutil::{atomic_write, check_overwrite};

/// Writes `cameras.txt` and `images.txt` of `views` (camera and image ids 1, 2, …, in order) in
/// `dir`; refuses to replace either unless `overwrite`.
pub fn write_text(dir: &Path, views: &[CapturedView], overwrite: bool) -> Result<(), SceneError> {
    let (cameras_path, images_path) = (dir.join("cameras.txt"), dir.join("images.txt"));
    check_overwrite(&cameras_path, overwrite)?;
    check_overwrite(&images_path, overwrite)?;
    let mut cameras = String::from(
        "# Camera list with one line of data per camera:\n\
         #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n",
    );
    let mut images = String::from(
        "# Image list with two lines of data per image:\n\
         #   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n",
    );
    for (i, v) in views.iter().enumerate() {
        let c = &v.camera;
        let k = c.intrinsics();
        let id = i + 1;
        let _ = writeln!(
            cameras,
            "{id} PINHOLE {} {} {} {} {} {}",
            c.width, c.height, k.fx, k.fy, k.cx, k.cy
        );
        let m = c.rotation.as_dmat3();
        let r = DMat3::from_cols(-m.x_axis, -m.y_axis, m.z_axis).transpose();
        let q = DQuat::from_mat3(&r).normalize();
        let t = -(r * c.origin.as_dvec3());
        let _ = writeln!(
            images,
            "{id} {} {} {} {} {} {} {} {id} {}\n",
            q.w, q.x, q.y, q.z, t.x, t.y, t.z, v.name
        );
    }
    atomic_write(&cameras_path, cameras.as_bytes(), overwrite)?;
    atomic_write(&images_path, images.as_bytes(), overwrite)
}
