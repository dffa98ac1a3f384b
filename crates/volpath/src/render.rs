//! Image rendering: pixels in parallel (rayon, one task per row), `spp` samples per pixel with a
//! box filter, per-pixel seeded streams (same seed → same image for any thread count).
//! Pixel positions use Owen-scrambled Sobol points (Burley 2020) per pixel for the first 2¹⁶
//! samples; all other dimensions come from the pixel's PCG32 stream.

use geometry::{LightBins, PixelBins};
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::{Camera, Image};

use crate::derivative::{DerivativeImages, PathDerivatives};
use crate::integrator::{CameraLine, Tally, VolpathScene, VolpathSettings, trace};
use crate::rng::{Sampler, hash_key};
use crate::shadow::ShadowTransmittance;

pub use base::pixel::{RenderSettings, pixel_jitter};

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
///
/// The same image as a [`Progressive`] render advanced by `rs.spp` samples in any number of
/// passes.
pub fn render_image(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    camera: &Camera,
    rs: &RenderSettings,
    progress: Option<&ProgressBar>,
) -> Image {
    let mut p = Progressive::new(scene, settings, camera, rs.seed, rs.view);
    p.advance(rs.spp, progress);
    p.image()
}

/// Render one view with the derivatives of every pixel with respect to the medium's σ_t and α
/// ([`crate::derivative`]). Its value image is bit for bit [`render_image`]'s with the same
/// settings (the same paths, the same random numbers).
pub fn render_derivatives(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    camera: &Camera,
    rs: &RenderSettings,
    progress: Option<&ProgressBar>,
) -> DerivativeImages {
    let mut p = Progressive::with_derivatives(scene, settings, camera, rs.seed, rs.view);
    p.advance(rs.spp, progress);
    p.derivative_images()
}

/// The state of one pixel between passes: its random stream, its Sobol scramble key and the sums
/// of its samples so far.
struct PixelState<S> {
    stream: Sampler,
    key: u64,
    sum: S,
}

/// A view rendered in passes: [`Progressive::advance`] adds samples to every pixel, continuing
/// each pixel's random stream and Sobol sequence where the last pass left them, so that passes of
/// n₁, n₂, … samples give bit for bit the image of [`render_image`] at n₁ + n₂ + … spp. Used
/// where the number of samples is decided while rendering (`validate-mitsuba --equal-time`
/// renders until the reference's render time is spent). `T` is what each path adds up: the
/// radiance (`[f32; 3]`, [`Progressive::new`]) or the radiance with its derivatives
/// ([`Progressive::with_derivatives`]).
pub struct Progressive<'a, T: Tally = [f32; 3]> {
    scene: VolpathScene<'a>,
    settings: VolpathSettings,
    camera: Camera,
    /// The camera's per-pixel triangle lists (when the view allows them), built once.
    bins: Option<PixelBins>,
    /// The shadow rays' lists, when the scene does not bring them and the settings use them.
    light_bins: Option<LightBins>,
    pixels: Vec<PixelState<T::Sum>>,
    spp: u32,
}

impl<'a> Progressive<'a> {
    /// A view with no samples yet: streams keyed by `(seed, view, pixel)` as in
    /// [`render_image`].
    pub fn new(
        scene: &VolpathScene<'a>,
        settings: &VolpathSettings,
        camera: &Camera,
        seed: u64,
        view: u64,
    ) -> Self {
        Self::start(scene, settings, camera, seed, view)
    }

    /// The mean of the samples so far (black before the first pass).
    pub fn image(&self) -> Image {
        let mut img = Image::new(self.camera.width, self.camera.height);
        let inv = 1.0 / self.spp.max(1) as f64;
        for (px, st) in img.data.iter_mut().zip(&self.pixels) {
            *px = st.sum.map(|v| (v * inv) as f32);
        }
        img
    }
}

impl<'a> Progressive<'a, PathDerivatives> {
    /// [`Progressive::new`] for a render with derivatives ([`render_derivatives`]).
    pub fn with_derivatives(
        scene: &VolpathScene<'a>,
        settings: &VolpathSettings,
        camera: &Camera,
        seed: u64,
        view: u64,
    ) -> Self {
        Self::start(scene, settings, camera, seed, view)
    }

    /// The mean value and derivative images of the samples so far.
    pub fn derivative_images(&self) -> DerivativeImages {
        let image = |part: usize| {
            let mut img = Image::new(self.camera.width, self.camera.height);
            let inv = 1.0 / self.spp.max(1) as f64;
            for (px, st) in img.data.iter_mut().zip(&self.pixels) {
                *px = st.sum[part].map(|v| (v * inv) as f32);
            }
            img
        };
        DerivativeImages {
            value: image(0),
            d_sigma_t: image(1),
            d_albedo: image(2),
            d_g: image(3),
        }
    }
}

impl<'a, T: Tally> Progressive<'a, T> {
    fn start(
        scene: &VolpathScene<'a>,
        settings: &VolpathSettings,
        camera: &Camera,
        seed: u64,
        view: u64,
    ) -> Self {
        let pixels = (0..camera.width as u64 * camera.height as u64)
            .into_par_iter()
            .map(|pixel| PixelState {
                stream: Sampler::new(seed, view, pixel, 0),
                key: hash_key(&[seed, view, pixel, 1]),
                sum: T::Sum::default(),
            })
            .collect();
        let light_bins = match scene.light_bins {
            None => shadow_lists(scene, settings),
            Some(_) => None,
        };
        Progressive {
            scene: *scene,
            settings: *settings,
            camera: camera.clone(),
            bins: camera.pixel_bins(scene.accel),
            light_bins,
            pixels,
            spp: 0,
        }
    }

    /// Samples per pixel so far.
    pub fn spp(&self) -> u32 {
        self.spp
    }

    /// Add `samples` samples to every pixel (pixels in parallel, one task per row). `progress`
    /// is advanced by one per finished row.
    pub fn advance(&mut self, samples: u32, progress: Option<&ProgressBar>) {
        let w = self.camera.width as usize;
        let project = self.camera.projector();
        let rays = self.camera.ray_gen();
        let camera = &self.camera;
        let scene = &VolpathScene {
            light_bins: self.scene.light_bins.or(self.light_bins.as_ref()),
            ..self.scene
        };
        let (settings, bins, first) = (&self.settings, self.bins.as_ref(), self.spp);
        self.pixels
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, px) in row.iter_mut().enumerate() {
                    if !camera.measures(x as u32, y as u32) {
                        continue;
                    }
                    let s = &mut px.stream;
                    for i in first..first + samples {
                        let (jx, jy) = pixel_jitter(i, px.key, s);
                        let (fx, fy) = (x as f32 + jx, y as f32 + jy);
                        let (o, d) = rays.ray(fx, fy);
                        let line = bins.map(|bins| CameraLine::new(bins, fx, fy, &project));
                        trace::<T>(scene, settings, o, d, line, s).add_to(&mut px.sum);
                    }
                }
                if let Some(pb) = progress {
                    pb.inc(1);
                }
            });
        self.spp += samples;
    }
}
