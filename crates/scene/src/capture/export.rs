//! A dataset written as a photographed capture would arrive ([`write_capture`]): a COLMAP text
//! model (`sparse/`), 8-bit sRGB JPEG photos (`images/IMG_0000.jpg`, …) at an exposure that
//! the capture does not state, a mask per photo from the object's silhouette
//! (`masks/IMG_0000.jpg.png`, COLMAP's naming) and the mesh as a scan gives it (`object.ply`,
//! its vertices moved along their normals by Gaussian noise). What `translucent import colmap`
//! reads back, and the worked example of the documentation.

use std::path::Path;

use geometry::{Accel, Mesh};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;

use super::CapturedView;
use crate::SceneError;
use crate::colmap::write_text;
use crate::dataset::Dataset;
use crate::image::PixelMask;

/// How the capture is written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CaptureExport {
    /// The factor between the images' linear radiance and the photos' linear code values
    /// (what the capture leaves unknown, with the light's intensity).
    pub exposure: f32,
    /// JPEG quality, 1–100.
    pub quality: u8,
    /// The standard deviation of the mesh's noise along its normals, as a fraction of the
    /// mesh's bounding-box diagonal (0: the exact mesh).
    pub mesh_noise: f32,
    pub seed: u64,
}

/// The name of view `i`'s photo.
pub fn photo_name(i: usize) -> String {
    format!("IMG_{i:04}.jpg")
}

/// Writes `ds` (with images) around `mesh` as a capture in `dir` (see the module's doc);
/// returns how many pixels the photos saturate.
pub fn write_capture(
    ds: &Dataset,
    mesh: &Mesh,
    dir: &Path,
    settings: &CaptureExport,
    overwrite: bool,
) -> Result<usize, SceneError> {
    let mkdir = |d: &Path| {
        std::fs::create_dir_all(d).map_err(|source| SceneError::Io {
            path: d.to_path_buf(),
            source,
        })
    };
    for sub in ["sparse", "images", "masks"] {
        mkdir(&dir.join(sub))?;
    }
    let views: Vec<CapturedView> = ds
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| CapturedView {
            name: photo_name(i),
            camera: v.camera.clone(),
        })
        .collect();
    write_text(&dir.join("sparse"), &views, overwrite)?;
    let accel = Accel::new(mesh.clone());
    let mut saturated = 0;
    for (i, (v, cv)) in ds.views.iter().zip(&views).enumerate() {
        let image = v.image.as_ref().ok_or_else(|| SceneError::Invalid {
            location: format!("view {i}"),
            reason: "has no image to write as a photo; render it first".into(),
        })?;
        saturated += image.write_jpeg(
            &dir.join("images").join(&cv.name),
            settings.exposure,
            settings.quality,
            overwrite,
        )?;
        silhouette(&accel, &cv.camera).write_png(
            &dir.join("masks").join(format!("{}.png", cv.name)),
            overwrite,
        )?;
    }
    let scan = noisy_mesh(mesh, settings.mesh_noise, settings.seed);
    let path = dir.join("object.ply");
    crate::fsutil::check_overwrite(&path, overwrite)?;
    geometry::io::save_ply(&scan, &path).map_err(|e| SceneError::Parse {
        path,
        reason: e.to_string(),
    })?;
    Ok(saturated)
}

/// The pixels whose centre sees the object.
fn silhouette(accel: &Accel, camera: &crate::Camera) -> PixelMask {
    let rays = camera.ray_gen();
    let mut m = PixelMask::all(camera.width, camera.height);
    for y in 0..camera.height {
        for x in 0..camera.width {
            let (o, d) = rays.ray(x as f32 + 0.5, y as f32 + 0.5);
            m.bits[(y * camera.width + x) as usize] =
                accel.closest(o, d, 0.0, f32::INFINITY).is_some();
        }
    }
    m
}

/// `mesh` with each vertex moved along its normal by N(0, (f·diagonal)²), the diagonal of its
/// bounding box (Box–Muller normals from `seed`): a scan's noise.
pub fn noisy_mesh(mesh: &Mesh, f: f32, seed: u64) -> Mesh {
    let mut rng = Pcg32::seed_from_u64(seed);
    geometry::remesh::normal_noise(mesh, f, || {
        let u1 = rng.random::<f64>().max(1e-12);
        let u2 = rng.random::<f64>();
        ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
    })
}
