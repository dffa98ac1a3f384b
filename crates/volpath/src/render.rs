//! Image rendering: pixels in parallel (rayon, one task per row), `spp` samples per pixel with a
//! box filter, per-pixel seeded streams (same seed → same image for any thread count).
//! Pixel positions use Owen-scrambled Sobol points (Burley 2020) per pixel for the first 2¹⁶
//! samples; all other dimensions come from the pixel's PCG32 stream.

use geometry::LightBins;
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::{Camera, Image};

use crate::integrator::{CameraLine, VolpathScene, VolpathSettings, radiance_primary};
use crate::rng::{Sampler, hash_key};
use crate::shadow::ShadowTransmittance;

/// Per-render settings.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    pub spp: u32,
    pub seed: u64,
    /// Index of the view (part of every random stream's key).
    pub view: u64,
}

/// Pixel jitter for sample `i` of the pixel with scramble key `key`.
#[inline]
pub fn pixel_jitter(i: u32, key: u64, s: &mut Sampler) -> (f32, f32) {
    if i < (1 << 16) {
        let seed = key as u32;
        (
            sobol_burley::sample(i, 0, seed),
            sobol_burley::sample(i, 1, seed),
        )
    } else {
        (s.next_f32(), s.next_f32())
    }
}

/// The shadow rays' triangle lists ([`LightBins`]) that [`render_image`] uses for `scene`, built
/// here so that views sharing a light can share them (pass them in
/// [`VolpathScene::light_bins`]). `None` when the settings do not use them (tracked shadows,
/// [`VolpathSettings::light_lists`] off), the boundary refracts (η ≠ 1: no straight shadow
/// rays), there is no point light, or the light is too close to the object.
pub fn shadow_lists(scene: &VolpathScene, settings: &VolpathSettings) -> Option<LightBins> {
    let light = scene.light.as_ref()?;
    let used = settings.light_lists
        && scene.medium.eta == 1.0
        && settings.shadow == ShadowTransmittance::Exact;
    used.then(|| LightBins::build(scene.accel, light.position))
        .flatten()
}

/// Render one view. `progress` is advanced by one per finished row.
pub fn render_image(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    camera: &Camera,
    rs: &RenderSettings,
    progress: Option<&ProgressBar>,
) -> Image {
    let (w, h) = (camera.width, camera.height);
    // Camera rays, and their continuation through an index-matched boundary, through per-pixel
    // triangle lists (bit-identical to the BVH; when the view allows them).
    let bins = camera.pixel_bins(scene.accel);
    let project = camera.projector();
    let rays = camera.ray_gen();
    let light_bins = match scene.light_bins {
        None => shadow_lists(scene, settings),
        Some(_) => None,
    };
    let scene = &VolpathScene {
        light_bins: scene.light_bins.or(light_bins.as_ref()),
        ..*scene
    };
    let mut img = Image::new(w, h);
    img.data
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let pixel = y as u64 * w as u64 + x as u64;
                let mut s = Sampler::new(rs.seed, rs.view, pixel, 0);
                let key = hash_key(&[rs.seed, rs.view, pixel, 1]);
                let mut acc = [0.0f64; 3];
                for i in 0..rs.spp {
                    let (jx, jy) = pixel_jitter(i, key, &mut s);
                    let (fx, fy) = (x as f32 + jx, y as f32 + jy);
                    let (o, d) = rays.ray(fx, fy);
                    let line = bins
                        .as_ref()
                        .map(|bins| CameraLine::new(bins, fx, fy, &project));
                    let l = radiance_primary(scene, settings, o, d, line, &mut s);
                    for c in 0..3 {
                        acc[c] += l[c] as f64;
                    }
                }
                let inv = 1.0 / rs.spp.max(1) as f64;
                *px = acc.map(|v| (v * inv) as f32);
            }
            if let Some(pb) = progress {
                pb.inc(1);
            }
        });
    img
}
