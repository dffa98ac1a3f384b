//! # translucent-dipole
//!
//! The planar dipole baseline of Deng et al. 2022 (DLW22; docs/model.md §9): the classical dipole
//! of Jensen et al. 2001 evaluated between the camera point and entry points found by probe rays,
//! differentiated with the sample positions held fixed.
//!
//! Per pixel sample: camera ray → x_o (a front-facing hit, else 0); an entry point x_i with
//! density p(x_i) ([`probe`]); a shadow ray to the point light. Every sample serves all three
//! channels (the probe density mixes them):
//!
//!   I_c ≈ (1/spp) Σ_s R_d,c(|x_o − x_i|) · Sw(w_l) · (1 − F(cos θ_cam)) · max(0, n_i·w_l) · V · I_c/r_l² / p(x_i)
//!
//! with R_d,c the channel's dipole profile ([`profile`]; S_p = √(R_d(x_i←x_o)·R_d(x_o←x_i)) =
//! R_d for a homogeneous medium), Sw the light-side factor of docs/model.md §1 and 1 − F the
//! camera side's transmission. As in the learned renderer the subsurface branch is always taken
//! and weighted by 1 − F (DLW22 chooses it with probability 1 − F; the expectation is the same)
//! and the surface's specular reflection is left out.
//!
//! Derivatives ("ad"): x_i comes from the probe's intersection with the fixed mesh and p is a
//! detached density, so nothing but R_d depends on σ_t,c and α_c:
//! ∂I_c/∂θ_c ≈ (1/spp) Σ_s ∂R_d,c/∂θ_c · (the other factors)/p, from the same samples as the
//! value (the derivatives of the profile are analytic, [`DipoleProfile::with_derivatives`]).
//! This is the exact derivative of the estimator's expectation, since the sampling measure does
//! not depend on the medium.
//!
//! Rows in parallel (rayon), per-thread buffers, camera rays through the view's per-pixel
//! triangle lists; every random number comes from the (seed, view, pixel) stream, so images do
//! not depend on the thread count.

pub mod probe;
pub mod profile;

pub use probe::{ProbeSample, ProbeSampler};
pub use profile::{DipoleProfile, ProfileValue};

use base::pixel::pixel_jitter;
use base::rng::{Sampler, hash_key};
use geometry::bvh::offset_origin;
use geometry::{Accel, Frame, Hit, PixelBins};
use rayon::prelude::*;
use scene::{Camera, Image, Medium, PointLight, RayGen};

use base::boundary::{sw, transmittance};
use base::pixel::RenderSettings;
use scene::loss::DiffImages;

/// Why the dipole cannot render.
#[derive(Debug, thiserror::Error)]
pub enum DipoleError {
    /// The medium is not one (σ_t, α or η out of range).
    #[error("medium: {0}")]
    Medium(String),
}

/// Purpose key of the probe's random stream.
const PROBE_STREAM: u64 = 0xD1_9013;

/// The dipole model of one medium over one mesh.
pub struct DipoleScene<'a> {
    pub accel: &'a Accel,
    pub medium: Medium,
    profiles: [DipoleProfile; 3],
    sampler: ProbeSampler,
}

impl<'a> DipoleScene<'a> {
    /// The dipole of `medium` (validated) over `accel`.
    pub fn new(accel: &'a Accel, medium: Medium) -> Result<Self, DipoleError> {
        medium
            .validate("medium")
            .map_err(|e| DipoleError::Medium(e.to_string()))?;
        let profiles = std::array::from_fn(|c| {
            DipoleProfile::new(
                medium.sigma_t[c] as f64,
                medium.albedo[c] as f64,
                medium.g.channels()[c] as f64,
                medium.eta as f64,
            )
        });
        Ok(DipoleScene {
            accel,
            medium,
            profiles,
            sampler: ProbeSampler::new(&profiles),
        })
    }

    /// The channels' profiles.
    pub fn profiles(&self) -> &[DipoleProfile; 3] {
        &self.profiles
    }

    /// The probe sampler.
    pub fn sampler(&self) -> &ProbeSampler {
        &self.sampler
    }
}

/// A view's camera rays and light, set up once for several renders.
pub struct DipoleView<'a> {
    camera: &'a Camera,
    light: &'a PointLight,
    rays: RayGen,
    bins: Option<PixelBins>,
}

impl<'a> DipoleView<'a> {
    /// The rays of `camera` over `accel`, lit by `light`.
    pub fn new(accel: &Accel, camera: &'a Camera, light: &'a PointLight) -> Self {
        DipoleView {
            camera,
            light,
            rays: camera.ray_gen(),
            bins: camera.pixel_bins(accel),
        }
    }

    /// The ray through film point (fx, fy) and its closest hit.
    #[inline]
    fn trace(&self, accel: &Accel, fx: f32, fy: f32) -> (glam::Vec3, Option<Hit>) {
        let (o, d) = self.rays.ray(fx, fy);
        let hit = match &self.bins {
            Some(b) => b.closest_film(accel, fx, fy, d, 0.0, f32::INFINITY),
            None => accel.closest(o, d, 0.0, f32::INFINITY),
        };
        (d, hit)
    }
}

/// One pixel's sums: value, ∂/∂σ_t, ∂/∂α per channel.
type PixelSums = [[f64; 3]; 3];

/// Render one view's value image.
pub fn render_image(scene: &DipoleScene, view: &DipoleView, rs: &RenderSettings) -> Image {
    render(scene, view, rs, false).value
}

/// Render one view's value and derivative images (module docs).
pub fn render_derivatives(
    scene: &DipoleScene,
    view: &DipoleView,
    rs: &RenderSettings,
) -> DiffImages {
    render(scene, view, rs, true)
}

fn render(
    scene: &DipoleScene,
    view: &DipoleView,
    rs: &RenderSettings,
    derivatives: bool,
) -> DiffImages {
    let (w, h) = (view.camera.width, view.camera.height);
    let mut out = DiffImages {
        value: Image::new(w, h),
        d_sigma_t: Image::new(w, h),
        d_albedo: Image::new(w, h),
        d_g: None,
    };
    let inv = 1.0 / rs.spp.max(1) as f64;
    let rows = out.value.data.par_chunks_mut(w as usize);
    let rows = rows.zip(out.d_sigma_t.data.par_chunks_mut(w as usize));
    let rows = rows.zip(out.d_albedo.data.par_chunks_mut(w as usize));
    rows.enumerate()
        .for_each_init(Vec::new, |buf, (y, ((value, d_sigma_t), d_albedo))| {
            for x in 0..w as usize {
                if !view.camera.measures(x as u32, y as u32) {
                    continue;
                }
                let s = pixel(scene, view, rs, x as u32, y as u32, derivatives, buf);
                value[x] = s[0].map(|v| (v * inv) as f32);
                if derivatives {
                    d_sigma_t[x] = s[1].map(|v| (v * inv) as f32);
                    d_albedo[x] = s[2].map(|v| (v * inv) as f32);
                }
            }
        });
    out
}

/// The sums of one pixel's samples.
fn pixel(
    scene: &DipoleScene,
    view: &DipoleView,
    rs: &RenderSettings,
    x: u32,
    y: u32,
    derivatives: bool,
    buf: &mut Vec<Hit>,
) -> PixelSums {
    let accel = scene.accel;
    let m = &scene.medium;
    let pixel = y as u64 * view.camera.width as u64 + x as u64;
    let mut stream = Sampler::new(rs.seed, rs.view, pixel, PROBE_STREAM);
    let key = hash_key(&[rs.seed, rs.view, pixel]);
    let mut sums = [[0.0; 3]; 3];
    for i in 0..rs.spp {
        let (jx, jy) = pixel_jitter(i, key, &mut stream);
        let u: [f32; 5] = std::array::from_fn(|_| stream.next_f32());
        let (d, hit) = view.trace(accel, x as f32 + jx, y as f32 + jy);
        let Some(hit) = hit.filter(|h| h.entering(d)) else {
            continue;
        };
        let x_o = hit.p;
        let frame = Frame::from_normal(hit.ns);
        let cos_cam = (-d).dot(hit.ns).max(0.0);
        let t_cam = transmittance(cos_cam, m.eta);
        let Some(s) = scene.sampler.sample(accel, x_o, &frame, u, buf) else {
            continue;
        };
        let (x_i, n_i, ng) = (s.hit.p, s.hit.ns, s.hit.ng);
        let to_l = view.light.position - x_i;
        let r2 = to_l.length_squared();
        if r2 <= 0.0 {
            continue;
        }
        let dir = to_l / r2.sqrt();
        let cos_l = n_i.dot(dir);
        if cos_l <= 0.0 || ng.dot(dir) <= 0.0 {
            continue;
        }
        if !accel.exit_is_final(s.hit.tri)
            && accel.occluded(offset_origin(x_i, ng, dir), dir, 0.0, r2.sqrt())
        {
            continue;
        }
        let common = (t_cam * sw(cos_l, m.eta) * cos_l / r2) as f64 / s.pdf;
        if !common.is_finite() {
            continue;
        }
        let r = (x_i - x_o).length() as f64;
        for c in 0..3 {
            let k = common * view.light.intensity[c] as f64;
            if derivatives {
                let v = scene.profiles[c].with_derivatives(r);
                sums[0][c] += k * v.value;
                sums[1][c] += k * v.d_sigma_t;
                sums[2][c] += k * v.d_albedo;
            } else {
                sums[0][c] += k * scene.profiles[c].value(r);
            }
        }
    }
    sums
}
