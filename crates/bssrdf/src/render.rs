//! Forward rendering with the learned shape-adaptive BSSRDF (docs/model.md §7.3; Son et al. 2024
//! eq. 3–5).
//!
//! Per pixel sample: camera ray → x_o (front-facing hit, else 0); colour channel c and its weight
//! w (the sample's value goes to channel c only, times w: the channels in turn with w = spp/n_c,
//! or the paper's uniform channel with w = 3, docs/model.md A13, [`PixelSampling`]; for a grey
//! medium, whose channels share σ_t and α, the sample serves all three channels instead); refracted incident direction d_in
//! (η); the vertex polynomials of channel c interpolated at x_o (world axes, scaled by 1/σ_n,c);
//! d_in aligned to the polynomial normal (§3.5); light-space frame e3 = −d_in; the 23 normalised
//! inputs → feature MLP → S_abs = 1 − Absorb (a scale factor, never roulette, A8); z ~ N(0, I₄)
//! by inversion of the sample's uniforms (a scrambled Sobol point by default, [`PixelSampling`]); decoder → y; x̃ = x_o + σ_n·(y₁e₁ + y₂e₂ + y₃e₃);
//! x_i = Π(x̃) ([`crate::projection`]); shadow ray to the point light;
//!
//!   C = w·e_c · S_abs · (1 − F(cos θ_cam)) · D(w_l) · (A/N) · max(0, n_i·w_l) · V · I / r²
//!
//! (§1, eq. 5), with D the light-side exit law ([`crate::exit`]; Sw(w_l) of the paper with
//! `ExitLaw::Cosine`) and A/N the light-side incidence factor ([`crate::incidence`]; 1 with
//! [`Incidence::Isotropic`]). Stage 3 (placement, projection and the light term at the entry
//! point) is in the submodule `entry`.
//!
//! A rough boundary adds its own reflection of the light at x_o to every channel of every camera
//! sample ([`surface`]).
//!
//! Invalid samples (projection miss, back-facing light, occlusion) count with value 0.
//! Batched: one image row (width × spp samples) per network call, one feature evaluation per
//! shading point; rows run in parallel (rayon), buffers are reused per worker thread, and every
//! random number comes from the (seed, view, pixel) stream, so images do not depend on the thread
//! count. Camera rays are answered by the view's per-pixel triangle lists ([`ViewRays`],
//! [`geometry::PixelBins`]: the BVH's closest hit, bit for bit, from a few triangle tests).
//!
//! Descriptor scale: the vertex polynomials are fitted once (at σ_n,fit, docs/model.md §3.4) but
//! the networks see them at the current σ_n: the light-space coefficients are rescaled by
//! k = σ_n/σ_n,fit ([`Poly3::rescaled`]: the same surface in the new units, exact up to the
//! change of the fit's kernel width), so a fit at the initial medium serves a whole optimisation.
//! [`LearnedSettings::frozen_descriptor`] keeps SON24's fixed coefficients instead.
//!
//! Switches: [`LearnedSettings::planar_features`] replaces the shape descriptor by the plane
//! p = u_z and projects along −n(x_o) (the "planar" ablation); the model's
//! [`FrameConvention::Son24Compat`] reproduces SON24's frames (features in (−e₁, −e₂, w_i) of the
//! unrefracted camera direction, outputs in the shading frame of x_o), see docs/model.md A4.

use base::rng::hash_key;
use geometry::{Accel, Frame, Hit, PixelBins};
use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::{Camera, Image, Medium, PointLight, RayGen};

use crate::curvature::{CurvatureCoords, CurvatureSlice, CurvatureTable};
use crate::exit::{EscapeSlice, ExitLaw, ExitSlice, ExitTable};
use crate::fit::{FitError, interpolate};
use crate::gaussian::probit;
use crate::incidence::{IncidenceSlice, IncidenceTable};
use crate::medium::{ReducedMedium, effective_albedo};
use crate::model::FrameConvention;
use crate::nn::{INPUT_DIM, LATENT_DIM, ShapeAdaptiveModel, Workspace};
use crate::polynomial::Poly3;
use crate::projection::ProjectionRule;
use base::boundary::transmittance;

mod describe;
mod entry;
mod features;
mod networks;
mod sampling;
mod surface;
mod walks;
pub use entry::{Incidence, LightCurvature};
pub(crate) use entry::{
    light_contribution, place_and_project, projection_gradient, proposed_point,
};
pub use features::{DFIT_STEP, VertexFeatures};
pub(crate) use networks::{NetOutputs, evaluate_networks, run_networks};
use sampling::PixelPlan;
pub use sampling::PixelSampling;
pub use surface::Surface;
pub use walks::{EntrySampler, MAX_TRIES as WALK_MAX_TRIES, walk_exit};
pub(crate) use walks::{walk_entries, walk_media, walk_medium};

/// Errors of the learned renderer.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("medium: {0}")]
    Medium(String),
    #[error(transparent)]
    Fit(#[from] FitError),
    #[error(transparent)]
    Model(#[from] crate::model::ModelError),
}

/// Settings of the learned renderer.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct LearnedSettings {
    pub projection: ProjectionRule,
    /// Planar-features ablation: plane descriptor p = u_z, projection along −n(x_o).
    pub planar_features: bool,
    /// Frame convention to use instead of the model's own (A/B comparisons, docs/model.md A4).
    pub frames: Option<FrameConvention>,
    /// Keep the shape descriptor exactly as fitted (SON24) instead of rescaling it to the
    /// current σ_n ([`Poly3::rescaled`] with k = σ_n/σ_n,fit); the default rescales.
    pub frozen_descriptor: bool,
    /// Trace the camera rays through the BVH instead of the view's per-pixel triangle lists
    /// ([`geometry::PixelBins`]; the answers are identical, the lists are faster). The reference
    /// path of the tests.
    #[serde(skip)]
    pub bvh_camera_rays: bool,
    /// The light-side exit law: half-space walks conditioned on the camera side (default) or
    /// the cosine law of Sw ([`crate::exit`]).
    pub exit: ExitLaw,
    /// The light-side incidence factor: where obliquely entering light leaves, relative to its
    /// direction ([`crate::incidence`]; default) or isotropic in azimuth (VKJ19, SON24). Files
    /// written before the factor existed lack the field and read as isotropic.
    #[serde(default = "Incidence::absent")]
    pub incidence: Incidence,
    /// Where the entry points come from: the decoder (default) or the random walks it imitates
    /// (a diagnostic of the decoder, [`EntrySampler`]).
    pub entry: EntrySampler,
    /// The light side's curvature correction ([`crate::curvature`]; default). Files written
    /// before it existed lack the field and read as uncorrected.
    #[serde(default = "LightCurvature::absent")]
    pub light_curvature: LightCurvature,
    /// How a pixel's samples are spread over the channels, the film and the latent space
    /// ([`PixelSampling`]; default stratified). Files written before the choice existed lack
    /// the field and read as one-hot.
    #[serde(default = "PixelSampling::absent")]
    pub sampling: PixelSampling,
}

/// A view's camera rays and its light: the camera, the point light and, unless disabled or
/// impossible, the per-pixel triangle lists of the camera ([`Camera::pixel_bins`]). Built once
/// per rendered view; renders of the same view with the same scene geometry can share one
/// ([`render_image_view`], [`crate::diff::render_diff_view`]).
pub struct ViewRays<'a> {
    pub(crate) camera: &'a Camera,
    pub(crate) light: &'a PointLight,
    rays: RayGen,
    bins: Option<PixelBins>,
}

impl<'a> ViewRays<'a> {
    /// The rays of `camera` over `scene.accel` (lists unless
    /// [`LearnedSettings::bvh_camera_rays`]), lit by `light`.
    pub fn new(scene: &LearnedScene, camera: &'a Camera, light: &'a PointLight) -> Self {
        let bins = if scene.settings.bvh_camera_rays {
            None
        } else {
            camera.pixel_bins(scene.accel)
        };
        ViewRays {
            camera,
            light,
            rays: camera.ray_gen(),
            bins,
        }
    }

    /// The ray through film point (x + jx, y + jy) and its closest hit (`Accel::closest`).
    #[inline]
    fn trace(&self, accel: &Accel, x: u32, y: u32, jx: f32, jy: f32) -> (Vec3, Option<Hit>) {
        let (fx, fy) = (x as f32 + jx, y as f32 + jy);
        let (o, d) = self.rays.ray(fx, fy);
        let hit = match &self.bins {
            Some(b) => b.closest_film(accel, fx, fy, d, 0.0, f32::INFINITY),
            None => accel.closest(o, d, 0.0, f32::INFINITY),
        };
        (d, hit)
    }
}

/// σ_n per channel (docs/model.md §2) with range checks.
pub(crate) fn channel_sigma_n(m: &Medium) -> Result<[f32; 3], RenderError> {
    let mut out = [0.0; 3];
    for c in 0..3 {
        let g = m.g.channels()[c] as f64;
        let r = ReducedMedium::try_new(m.sigma_t[c] as f64, m.albedo[c] as f64, g)
            .map_err(|e| RenderError::Medium(format!("channel {c}: {e}")))?;
        out[c] = r.sigma_n() as f32;
    }
    Ok(out)
}

/// Everything the learned renderer needs for one medium.
pub struct LearnedScene<'a> {
    pub accel: &'a Accel,
    pub model: &'a ShapeAdaptiveModel,
    pub features: &'a VertexFeatures,
    pub medium: Medium,
    pub settings: LearnedSettings,
    /// σ_n per channel at the CURRENT medium (the features may be fitted at another one).
    pub(crate) sigma_n: [f32; 3],
    /// α_eff(α') per channel (network input).
    pub(crate) eff_albedo: [f32; 3],
    /// k = σ_n/σ_n,fit per channel: the descriptor the networks see is the fitted one rescaled
    /// by k (1 with a frozen descriptor or planar features).
    pub(crate) descriptor_scale: [f32; 3],
    /// All three channels share σ_t and α: one sample serves every channel (no one-hot ×3,
    /// a third of the variance; unbiased because the sample is distributed as each channel's).
    pub(crate) grey: bool,
    /// The exit law at each channel's albedo ([`ExitLaw::HalfSpace`]; `None`: the cosine law).
    pub(crate) exit: Option<Box<[ExitSlice; 3]>>,
    /// The incidence factor at each channel's albedo ([`Incidence::Directional`]).
    pub(crate) incidence: Option<Box<[IncidenceSlice; 3]>>,
    /// The curvature correction at each channel's albedo ([`LightCurvature::Ball`]; not behind
    /// a smooth dielectric boundary).
    pub(crate) curvature: Option<Box<[CurvatureSlice; 3]>>,
    /// The rough boundary's reflection ([`surface`]; `None` for a smooth or index-matched one).
    pub(crate) surface: Option<Surface>,
    /// With a rough boundary and the half-space exit law: the escaped share of the entered
    /// energy per channel through the rough and through the smooth boundary ([`surface`]).
    pub(crate) escape: Option<Box<[(EscapeSlice, EscapeSlice); 3]>>,
}

impl<'a> LearnedScene<'a> {
    pub fn new(
        accel: &'a Accel,
        model: &'a ShapeAdaptiveModel,
        features: &'a VertexFeatures,
        medium: Medium,
        settings: LearnedSettings,
    ) -> Result<Self, RenderError> {
        let sigma_n = channel_sigma_n(&medium)?;
        let mut eff_albedo = [0.0; 3];
        for c in 0..3 {
            let r = ReducedMedium::new(
                medium.sigma_t[c] as f64,
                medium.albedo[c] as f64,
                medium.g.channels()[c] as f64,
            );
            eff_albedo[c] = effective_albedo(r.albedo_red) as f32;
        }
        if features
            .polys
            .iter()
            .any(|p| p.len() != accel.mesh().positions.len())
        {
            return Err(RenderError::Medium(
                "vertex features were fitted on another mesh".into(),
            ));
        }
        let same = |v: &[f32; 3]| v.iter().all(|&x| x == v[0]);
        let grey = same(&medium.sigma_t)
            && same(&medium.albedo)
            && features.polys[1..].iter().all(|p| *p == features.polys[0]);
        let mut scene = LearnedScene {
            accel,
            model,
            features,
            medium,
            settings,
            sigma_n,
            eff_albedo,
            descriptor_scale: [1.0; 3],
            grey,
            exit: None,
            incidence: None,
            curvature: None,
            surface: Surface::of(&medium),
            escape: None,
        };
        if settings.exit == ExitLaw::HalfSpace {
            // The tables are built for one g: a chromatic medium's mean (a physics gap the
            // model states).
            let table = ExitTable::for_medium(medium.g.mean(), medium.eta, medium.roughness);
            scene.exit = Some(Box::new(std::array::from_fn(|c| {
                table.slice(medium.albedo[c])
            })));
            if medium.roughness > 0.0 {
                // The networks' walks crossed a smooth boundary ([`surface`]).
                let smooth = ExitTable::for_medium(medium.g.mean(), medium.eta, 0.0);
                scene.escape = Some(Box::new(std::array::from_fn(|c| {
                    (
                        table.escape(medium.albedo[c]),
                        smooth.escape(medium.albedo[c]),
                    )
                })));
            }
        }
        if settings.incidence == Incidence::Directional {
            let table = IncidenceTable::for_medium(medium.g.mean(), medium.eta);
            scene.incidence = Some(Box::new(std::array::from_fn(|c| {
                table.slice(medium.albedo[c])
            })));
        }
        // The balls' walks are index-matched. Behind a rough boundary the correction is that
        // of the same medium without it (an approximation); a smooth one traps by total
        // internal reflection the light that travels along the surface, the very light the
        // correction is about, and goes without it (docs/notes/learned-real-media.md).
        if settings.light_curvature == LightCurvature::Ball
            && (medium.eta == 1.0 || medium.roughness > 0.0)
        {
            let table = CurvatureTable::for_medium(medium.g.mean());
            scene.curvature = Some(Box::new(std::array::from_fn(|c| {
                table.slice(medium.albedo[c])
            })));
        }
        scene.descriptor_scale = scene.descriptor_scale_at(sigma_n);
        Ok(scene)
    }

    /// k = σ_n/σ_n,fit per channel for the kernel scales `sigma_n` (module docs).
    pub(crate) fn descriptor_scale_at(&self, sigma_n: [f32; 3]) -> [f32; 3] {
        if self.settings.frozen_descriptor || self.settings.planar_features {
            return [1.0; 3];
        }
        std::array::from_fn(|c| sigma_n[c] / self.features.sigma_n[c])
    }

    /// The light-space descriptor the networks see: `coeffs` (at the fit scale) rescaled by
    /// `k`, plus ln k times the fit derivative `dcoeffs` when there is one.
    #[inline]
    pub(crate) fn descriptor_at(coeffs: &Poly3, dcoeffs: Option<&Poly3>, k: f32) -> Poly3 {
        if k == 1.0 {
            return *coeffs;
        }
        let mut p = coeffs.rescaled(k);
        if let Some(dc) = dcoeffs {
            let l = k.ln();
            for (v, d) in p.0.iter_mut().zip(&dc.0) {
                *v += l * d;
            }
        }
        p
    }

    /// The normalised network inputs of a light-space descriptor `coeffs` (at the fit scale)
    /// rescaled by `k` ([`LearnedScene::descriptor_at`]), for channel `c`.
    #[inline]
    pub(crate) fn inputs_at(
        &self,
        coeffs: &Poly3,
        dcoeffs: Option<&Poly3>,
        c: usize,
        k: f32,
    ) -> [f32; INPUT_DIM] {
        let m = &self.medium;
        let p = Self::descriptor_at(coeffs, dcoeffs, k);
        let norm = self.model.normalisation();
        norm.inputs(&p.0, self.eff_albedo[c], m.g.channels()[c], m.eta)
    }
}

/// One BSSRDF sample between the batched network calls.
#[derive(Clone, Copy)]
pub(crate) struct Pending {
    pub(crate) pixel: u32,
    pub(crate) channel: u8,
    /// The channel's weight w_s ([`PixelSampling`]; unused for a grey medium).
    pub(crate) weight: f32,
    pub(crate) x_o: Vec3,
    /// Output frame (e1, e2, e3) in world axes.
    pub(crate) out_frame: Frame,
    /// Interpolated world polynomial (for the projection direction).
    pub(crate) poly: Poly3,
    /// Shading normal at x_o (planar projection direction).
    pub(crate) n_o: Vec3,
    /// (1 − F(cos θ_cam)).
    pub(crate) t_cam: f32,
    /// cos θ_cam (the camera side of the exit law).
    pub(crate) mu_cam: f32,
    /// Unit tangential part of the camera ray's direction at x_o (its forward direction along
    /// the surface; zero at normal incidence): the camera side of the incidence factor.
    pub(crate) cam_fwd: Vec3,
    /// Random stream of the sample's walks ([`EntrySampler::Walks`]), shared by its offsets.
    pub(crate) key: u64,
    /// Mean curvature of `poly` at x_o in inverse scene units ([`Poly3::mean_curvature`] over
    /// the fit scale σ_n,fit), for the curvature correction; 0 without it.
    pub(crate) kappa: f32,
    /// The curvature table's camera-point coordinates for this view's light (default without
    /// the correction).
    pub(crate) curv: CurvatureCoords,
}

/// Reused per worker thread.
#[derive(Default)]
pub(crate) struct RowBuffers {
    pub(crate) pending: Vec<Pending>,
    pub(crate) inputs: Vec<[f32; INPUT_DIM]>,
    /// Light-space descriptor of each sample at the fit scale (before the rescaling by k).
    pub(crate) coeffs: Vec<Poly3>,
    /// Its light-space `dfit` (empty when the features have none).
    pub(crate) dcoeffs: Vec<Poly3>,
    pub(crate) z: Vec<[f32; LATENT_DIM]>,
    pub(crate) point: Vec<u32>,
    pub(crate) net: NetOutputs,
    pub(crate) sums: Vec<[f64; 3]>,
    pub(crate) ws: Workspace,
}

/// Per-render settings (shared with the volumetric renderer).
pub use base::pixel::RenderSettings;

/// Render one view with the learned BSSRDF. `progress` advances by one per row.
pub fn render_image(
    scene: &LearnedScene,
    camera: &Camera,
    light: &PointLight,
    rs: &RenderSettings,
    progress: Option<&ProgressBar>,
) -> Result<Image, RenderError> {
    render_image_view(scene, &ViewRays::new(scene, camera, light), rs, progress)
}

/// [`render_image`] of a view whose rays are already set up (`view` built over `scene.accel`).
pub fn render_image_view(
    scene: &LearnedScene,
    view: &ViewRays,
    rs: &RenderSettings,
    progress: Option<&ProgressBar>,
) -> Result<Image, RenderError> {
    let camera = view.camera;
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut img = Image::new(camera.width, camera.height);
    let result: Result<(), RenderError> = img.data.par_chunks_mut(w).enumerate().try_for_each_init(
        RowBuffers::default,
        |buf, (y, row)| {
            render_row(scene, view, rs, y as u32, buf)?;
            let inv = 1.0 / rs.spp.max(1) as f64;
            for (px, s) in row.iter_mut().zip(&buf.sums) {
                *px = s.map(|v| (v * inv) as f32);
            }
            if let Some(pb) = progress {
                pb.inc(1);
            }
            Ok(())
        },
    );
    result?;
    debug_assert_eq!(img.data.len(), w * h);
    Ok(img)
}

/// Render one image row into `buf.sums` (per pixel, summed over the spp samples).
pub(crate) fn render_row(
    scene: &LearnedScene,
    view: &ViewRays,
    rs: &RenderSettings,
    y: u32,
    buf: &mut RowBuffers,
) -> Result<(), RenderError> {
    let light = view.light;
    prepare_row(scene, view, rs, y, buf);
    run_networks(scene, buf)?;
    // Stage 3: placement, projection, light.
    for k in 0..buf.pending.len() {
        let p = &buf.pending[k];
        let c = p.channel as usize;
        let Some(hit) = place_and_project(scene, p, buf.net.y[k], scene.sigma_n[c]) else {
            continue;
        };
        let (v, _) = light_contribution(scene, view, p, &hit, scene.medium.sigma_t[c]);
        if v <= 0.0 {
            continue;
        }
        let s_abs = 1.0 - buf.net.absorb[k];
        let base = s_abs * p.t_cam * v;
        if !base.is_finite() {
            continue;
        }
        let sum = &mut buf.sums[p.pixel as usize];
        if scene.grey {
            for (ch, acc) in sum.iter_mut().enumerate() {
                *acc += (base * light.intensity[ch]) as f64;
            }
        } else {
            sum[c] += (p.weight * base * light.intensity[c]) as f64;
        }
    }
    Ok(())
}

/// Stage 1 of a row: camera rays, channel choice, shape descriptor, network inputs, latent
/// samples (all random numbers of the row; `buf.sums` is reset to zeros).
pub(crate) fn prepare_row(
    scene: &LearnedScene,
    view: &ViewRays,
    rs: &RenderSettings,
    y: u32,
    buf: &mut RowBuffers,
) {
    let w = view.camera.width;
    let m = &scene.medium;
    let model = scene.model;
    let convention = scene
        .settings
        .frames
        .unwrap_or(model.info().frame_convention);
    let mesh = scene.accel.mesh();
    buf.pending.clear();
    buf.inputs.clear();
    buf.coeffs.clear();
    buf.dcoeffs.clear();
    buf.z.clear();
    buf.sums.clear();
    buf.sums.resize(w as usize, [0.0; 3]);

    // Stage 1: camera rays, channel choice, shape descriptor, network inputs, latent samples.
    for x in 0..w {
        if !view.camera.measures(x, y) {
            continue;
        }
        let pixel = y as u64 * w as u64 + x as u64;
        let mut plan = PixelPlan::new(
            scene.settings.sampling,
            scene.grey,
            rs.spp,
            [rs.seed, rs.view, pixel],
        );
        for i in 0..rs.spp {
            let draw = plan.draw(i);
            let ((jx, jy), channel, u) = (draw.jitter, draw.channel, draw.u);
            let (d, hit) = view.trace(scene.accel, x, y, jx, jy);
            let Some(hit) = hit else {
                continue;
            };
            let z = u.map(|u| probit(u as f64 + 0.5 / 16_777_216.0) as f32);
            if !hit.entering(d) {
                continue;
            }
            if let Some(surface) = &scene.surface {
                surface.add_reflection(scene.accel, view.light, &hit, d, &mut buf.sums[x as usize]);
            }
            let n_o = hit.ns;
            let cos_cam = (-d).dot(n_o).max(0.0);
            let t_cam = match &scene.surface {
                Some(surface) => surface.transmittance(cos_cam),
                None => transmittance(cos_cam, m.eta),
            };
            let [i0, i1, i2] = mesh.indices[hit.tri as usize];
            let b = [1.0 - hit.bary.x - hit.bary.y, hit.bary.x, hit.bary.y];
            let polys = &scene.features.polys[channel];
            let poly = interpolate(
                [
                    &polys[i0 as usize],
                    &polys[i1 as usize],
                    &polys[i2 as usize],
                ],
                b,
            );
            let (axes, out_frame) = features::light_space(convention, d, n_o, m.eta, &poly);
            let coeffs = if scene.settings.planar_features {
                Poly3::plane(Vec3::Z)
            } else {
                poly.rotate_fast(axes[0], axes[1], axes[2])
            };
            // The fit's σ_n-derivative beyond the rescaling, in the same light space.
            let dcoeffs = match &scene.features.dfit {
                Some(dfit) if !scene.settings.planar_features => {
                    let dv = &dfit[channel];
                    let dp = interpolate([&dv[i0 as usize], &dv[i1 as usize], &dv[i2 as usize]], b);
                    Some(dp.rotate_fast(axes[0], axes[1], axes[2]))
                }
                _ => None,
            };
            buf.inputs.push(scene.inputs_at(
                &coeffs,
                dcoeffs.as_ref(),
                channel,
                scene.descriptor_scale[channel],
            ));
            buf.coeffs.push(coeffs);
            if let Some(dc) = dcoeffs {
                buf.dcoeffs.push(dc);
            }
            buf.z.push(z);
            let cam_fwd = (d - n_o * d.dot(n_o)).normalize_or_zero();
            let (kappa, curv) = if scene.curvature.is_some() {
                (
                    poly.mean_curvature() as f32 / scene.features.sigma_n[channel],
                    CurvatureCoords::at_point((hit.p, n_o, cos_cam, cam_fwd), view.light.position),
                )
            } else {
                (0.0, CurvatureCoords::default())
            };
            buf.pending.push(Pending {
                pixel: x,
                channel: channel as u8,
                weight: draw.weight,
                x_o: hit.p,
                out_frame,
                poly,
                n_o,
                t_cam,
                mu_cam: cos_cam,
                cam_fwd,
                key: hash_key(&[rs.seed, rs.view, pixel, 2, i as u64]),
                kappa,
                curv,
            });
        }
    }
}
