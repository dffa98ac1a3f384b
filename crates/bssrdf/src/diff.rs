//! The differentiable learned renderer: per-pixel values and their derivatives with respect to
//! the six medium parameters σ_t,c and α_c (c = R, G, B), model-spec §8, architecture.md §4,
//! Son et al. 2024 §4 (eq. 6–17).
//!
//! Channel c of the image depends only on (σ_t,c, α_c) (model-spec §1, §2), so the derivatives
//! fit in two RGB images: `d_sigma_t` holds ∂I_c/∂σ_t,c in channel c and `d_albedo` holds
//! ∂I_c/∂α_c. The pixel estimator is the one of [`crate::render`] (model-spec §7.3):
//!
//!   I_c ≈ (1/spp) Σ_s w_c · S_abs · (1 − F(cos θ_cam)) · L(x_i),
//!   L(x) = Sw(w_l) · max(0, n·w_l) · V · I / r²  (without I in the code: w_c carries it),
//!
//! with w_c = 3·I_c·[c = channel of the sample] (one-hot, model-spec A13) or w_c = I_c for a grey
//! medium (one sample serves every channel), S_abs = 1 − Absorb(features(α)), x_i = Π(x̃),
//! x̃ = x_o + σ_n(σ_t, α)·R·y and y = decoder(z, features). The vertex polynomials are those of
//! the [`VertexFeatures`](crate::render::VertexFeatures) fit, kept fixed (model-spec A10); the
//! projection direction is the detached gradient of that fixed polynomial at x̃ (A5).
//!
//! The shape descriptor the networks see: the fitted polynomial in units of σ_n,fit, rescaled to
//! the current σ_n (`Poly3::rescaled`, c_m·k^(deg m − 1), k = σ_n/σ_n,fit), unless
//! `LearnedSettings::frozen_descriptor` (SON24's fixed features). A rescaled descriptor depends on
//! σ_t (and α) through σ_n; measured on the shipped model this term dominates ∂I/∂σ_t and has the
//! opposite sign of the position term (BENCHMARKS.md, "σ_t and the shape descriptor"), and with
//! it the loss landscape is that of a refit at every σ_t.
//!
//! Estimators ([`DiffMethod`]):
//!
//! * [`DiffMethod::Ours`] (paper §4.2–4.3, eq. 15–17; model-spec §8.1–8.2, A6): for σ_t the
//!   correlated offset samples x_i^± = Π(x_o + σ_n(σ_t ± Δ)·R·y^±) with the SAME z, channel,
//!   projection rule and fixed polynomial, each with the full light evaluation (V, cos, Sw,
//!   1/r²); per sample ∂C/∂σ_t ≈ (S_abs⁺·L(x_i⁺) − S_abs⁻·L(x_i⁻))·(1 − F)/(2Δ),
//!   Δ = `delta_rel`·σ_t (A7). With a frozen descriptor y^± = y and S_abs^± = S_abs (the paper
//!   exactly); with the rescaled one y^± and S_abs^± come from the networks run again on the
//!   descriptor at σ_n(σ_t ± Δ) (same z: the samples stay correlated). A miss or an occluded
//!   offset sample contributes 0, which is what carries the boundary (visibility) term.
//!   For α: positions detached; ∂C/∂α = −∂Absorb/∂α · (1 − F) · L(x_i) with
//!   ∂Absorb/∂α = ∂Absorb/∂input₂₀ · d input₂₀/dα' · dα'/dα (forward-mode tangent through the
//!   feature and absorption MLPs, [`ShapeAdaptiveModel::absorb_input_derivative_with`];
//!   `Normalisation::d_albedo_input_d_albedo_red`; `ReducedMedium::d_albedo_red_d_albedo`).
//! * [`DiffMethod::OursAlphaOffsets`] (model-spec A6, option): as `Ours`, plus the α-dependence
//!   of σ_n (model-spec §2) by offset samples x_i^± = Π(x_o + σ_n(α ± Δα)·R·y^±), z reused
//!   (y^±, S_abs^± as for σ_t): ∂C/∂α += (1 − F)·(S_abs⁺·L(x_i⁺) − S_abs⁻·L(x_i⁻))/(2Δα).
//! * [`DiffMethod::Naive`] (paper §4.1, the "naive" baseline; architecture.md §4): σ_t by the
//!   derivative of the sample position with visibility held fixed (interior term only):
//!   dx̃/dσ_t = R·(∂σ_n/∂σ_t·y + σ_n·∂y/∂σ_t), moved along the surface at x_i with the detached
//!   projection direction d: dx_i = (I − d n_gᵀ/(n_g·d))·dx̃ (n_g the normal of the hit
//!   triangle), then ∂C/∂σ_t = (1 − F)·V·(∂S_abs/∂σ_t·L̃ + S_abs·∇L̃(x_i)·dx_i) where
//!   L̃ = Sw(n·w_l)(n·w_l)/r² is the smooth light term (shading normal re-interpolated on the
//!   triangle, no visibility), differentiated by a central difference of step [`NAIVE_STEP`]
//!   along dx_i; ∂y/∂σ_t and ∂S_abs/∂σ_t (zero with a frozen descriptor) by central differences
//!   of the networks at the offset descriptors. α as `Ours`.
//! * [`DiffMethod::Fd`]: brute-force central differences of two full renders at θ ± Δ with
//!   identical random numbers (same seed, view and pixel streams), per parameter (12 extra
//!   renders; a reference). Steps Δ = `delta_rel`·σ_t and Δα = `delta_albedo` (clamped into
//!   [0, 1]). With [`DiffSettings::fd_fixed_sigma_n`] the perturbed renders keep the σ_n of the
//!   unperturbed medium (the FD through the networks only: S_abs and, if the decoder uses its
//!   features, y).
//!
//! Loss mode ([`render_loss_gradient`]): with a target image T and a loss ℓ averaged over the
//! N = 3·W·H pixel channels (L2: ℓ = (1/N) Σ (I − T)², L1: ℓ = (1/N) Σ |I − T|) the gradient
//! ∂ℓ/∂θ = Σ_pixels ∂ℓ/∂I_c · ∂I_c/∂θ is accumulated row by row during the render (the role of
//! the zero-valued term σ_t·D − detach(σ_t)·D of model-spec §8.1); derivative images are
//! kept only on request.
//!
//! Batched and parallel like [`crate::render`]: rows in parallel, one network batch per row,
//! per-thread buffers; every random number comes from the (seed, view, pixel) stream and the row
//! results are reduced in row order, so results do not depend on the thread count. The value
//! image is bit-identical to [`render_image`](crate::render::render_image) for the same settings.

use std::str::FromStr;

use geometry::{Hit, Mesh};
use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::{Camera, Image, PointLight};

use crate::boundary::sw;
use crate::medium::{ReducedMedium, sigma_n_derivatives};
use crate::nn::INPUT_DIM;
use crate::nn::{ALBEDO_INPUT, POSITION_DIM};
use crate::render::{
    LearnedScene, NetOutputs, Pending, RenderError, RenderSettings, RowBuffers, evaluate_networks,
    light_contribution, place_and_project, prepare_row, projection_gradient, render_row,
    run_networks,
};

/// Step (scene units) of the central difference of the smooth light term in
/// [`DiffMethod::Naive`]; the light term varies on the scale of the light distance.
pub const NAIVE_STEP: f32 = 1e-3;

/// How the derivatives are estimated (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DiffMethod {
    /// Correlated offset samples for σ_t, S_abs derivative for α (the paper's method).
    #[default]
    Ours,
    /// `Ours` plus offset samples for the α-dependence of σ_n.
    OursAlphaOffsets,
    /// Sample-position derivative with visibility held fixed (interior term only).
    Naive,
    /// Brute-force central differences of full renders (reference).
    Fd,
}

impl DiffMethod {
    /// All methods, in the order of their names.
    pub const ALL: [DiffMethod; 4] = [
        DiffMethod::Ours,
        DiffMethod::OursAlphaOffsets,
        DiffMethod::Naive,
        DiffMethod::Fd,
    ];

    /// The name accepted by [`FromStr`].
    pub fn name(self) -> &'static str {
        match self {
            DiffMethod::Ours => "ours",
            DiffMethod::OursAlphaOffsets => "ours-alpha-offsets",
            DiffMethod::Naive => "naive",
            DiffMethod::Fd => "fd",
        }
    }
}

/// An unknown [`DiffMethod`] name.
#[derive(Debug, thiserror::Error)]
#[error("unknown derivative method {0:?} (expected ours, ours-alpha-offsets, naive or fd)")]
pub struct UnknownMethod(pub String);

impl FromStr for DiffMethod {
    type Err = UnknownMethod;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let k = s.trim().to_ascii_lowercase().replace('_', "-");
        DiffMethod::ALL
            .into_iter()
            .find(|m| m.name() == k)
            .ok_or_else(|| UnknownMethod(s.to_string()))
    }
}

impl std::fmt::Display for DiffMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Settings of the differentiable renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffSettings {
    pub method: DiffMethod,
    /// Relative σ_t offset: Δ = `delta_rel`·σ_t,c (model-spec A7; default 0.02). Used by the
    /// offset samples and by `Fd`.
    pub delta_rel: f32,
    /// Absolute α offset Δα of `OursAlphaOffsets` and `Fd` (default 0.01), reduced where needed
    /// so that α ± Δα stays in [0, 1].
    pub delta_albedo: f32,
    /// `Fd` only: keep σ_n at its unperturbed value in the perturbed renders.
    pub fd_fixed_sigma_n: bool,
}

impl Default for DiffSettings {
    fn default() -> Self {
        DiffSettings {
            method: DiffMethod::Ours,
            delta_rel: 0.02,
            delta_albedo: 0.01,
            fd_fixed_sigma_n: false,
        }
    }
}

/// The value image and the two derivative images (channel c: ∂I_c/∂σ_t,c and ∂I_c/∂α_c).
#[derive(Clone, Debug, PartialEq)]
pub struct DiffImages {
    pub value: Image,
    pub d_sigma_t: Image,
    pub d_albedo: Image,
}

/// Image loss, averaged over the 3·W·H pixel channels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Loss {
    /// ℓ = (1/N) Σ (I − T)²; ∂ℓ/∂I = 2(I − T)/N.
    #[default]
    L2,
    /// ℓ = (1/N) Σ |I − T|; ∂ℓ/∂I = sign(I − T)/N (0 at I = T).
    L1,
}

impl Loss {
    /// Per pixel channel: (ℓ, ∂ℓ/∂I) before the 1/N normalisation.
    #[inline]
    pub fn element(self, value: f32, target: f32) -> (f64, f64) {
        let r = value as f64 - target as f64;
        match self {
            Loss::L2 => (r * r, 2.0 * r),
            Loss::L1 => (
                r.abs(),
                if r > 0.0 {
                    1.0
                } else if r < 0.0 {
                    -1.0
                } else {
                    0.0
                },
            ),
        }
    }
}

/// The loss, its gradient with respect to (σ_t,R, σ_t,G, σ_t,B) and (α_R, α_G, α_B), and the
/// images when asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct LossGradient {
    pub loss: f64,
    pub d_sigma_t: [f64; 3],
    pub d_albedo: [f64; 3],
    pub images: Option<DiffImages>,
}

/// Render one view with values and derivative images (module docs). `progress` advances by one
/// per row.
pub fn render_diff(
    scene: &LearnedScene,
    camera: &Camera,
    light: &PointLight,
    rs: &RenderSettings,
    ds: &DiffSettings,
    progress: Option<&ProgressBar>,
) -> Result<DiffImages, RenderError> {
    let out = run(scene, camera, light, rs, ds, None, true, progress)?;
    Ok(out.images.expect("images were requested"))
}

/// Render one view and accumulate the loss and its 6-parameter gradient against `target`
/// without storing derivative images (unless `keep_images`).
#[allow(clippy::too_many_arguments)]
pub fn render_loss_gradient(
    scene: &LearnedScene,
    camera: &Camera,
    light: &PointLight,
    rs: &RenderSettings,
    ds: &DiffSettings,
    target: &Image,
    loss: Loss,
    keep_images: bool,
    progress: Option<&ProgressBar>,
) -> Result<LossGradient, RenderError> {
    if (target.width, target.height) != (camera.width, camera.height) {
        return Err(RenderError::Medium(format!(
            "target image is {}×{}, the camera renders {}×{}",
            target.width, target.height, camera.width, camera.height
        )));
    }
    run(
        scene,
        camera,
        light,
        rs,
        ds,
        Some((target, loss)),
        keep_images,
        progress,
    )
}

/// Per-render constants of the estimators.
struct Consts<'a> {
    /// σ_n(σ_t ± Δ) per channel.
    sn_t: [[f32; 2]; 3],
    /// Descriptor scale k(σ_t ± Δ) per channel.
    k_t: [[f32; 2]; 3],
    /// Descriptor scale k(α ± Δα) per channel.
    k_a: [[f32; 2]; 3],
    /// The descriptor follows σ_n (not frozen, not planar): offset samples re-run the networks.
    moving: bool,
    /// 1/(2Δ) per channel.
    inv_2dt: [f32; 3],
    /// σ_n(α ± Δα) per channel.
    sn_a: [[f32; 2]; 3],
    /// 1/(2Δα) per channel.
    inv_2da: [f32; 3],
    /// ∂σ_n/∂σ_t per channel (Naive).
    dsn_dt: [f32; 3],
    /// d input₂₀/dα = d input₂₀/dα' · dα'/dα per channel.
    din_da: [f32; 3],
    /// Fd: (scene at θ + Δ, scene at θ − Δ, 1/(2Δ)) for σ_t,R..B then α_R..B.
    fd: Vec<(LearnedScene<'a>, LearnedScene<'a>, f64)>,
}

impl<'a> Consts<'a> {
    fn new(scene: &LearnedScene<'a>, ds: &DiffSettings) -> Result<Self, RenderError> {
        let m = &scene.medium;
        let g = m.g as f64;
        let norm = scene.model.normalisation();
        let mut c = Consts {
            sn_t: [[0.0; 2]; 3],
            k_t: [[1.0; 2]; 3],
            k_a: [[1.0; 2]; 3],
            moving: !(scene.settings.frozen_descriptor || scene.settings.planar_features),
            inv_2dt: [0.0; 3],
            sn_a: [[0.0; 2]; 3],
            inv_2da: [0.0; 3],
            dsn_dt: [0.0; 3],
            din_da: [0.0; 3],
            fd: Vec::new(),
        };
        let mut steps_t = [0.0f64; 3];
        let mut steps_a = [0.0f64; 3];
        for ch in 0..3 {
            let (st, al) = (m.sigma_t[ch] as f64, m.albedo[ch] as f64);
            let dt = ds.delta_rel as f64 * st;
            if !(dt > 0.0 && dt < st) {
                return Err(RenderError::Medium(format!(
                    "σ_t step {dt} must lie in (0, σ_t = {st})"
                )));
            }
            let da = (ds.delta_albedo as f64).min(al).min(1.0 - al);
            steps_t[ch] = dt;
            steps_a[ch] = da;
            c.sn_t[ch] = [
                ReducedMedium::new(st + dt, al, g).sigma_n() as f32,
                ReducedMedium::new(st - dt, al, g).sigma_n() as f32,
            ];
            c.inv_2dt[ch] = (0.5 / dt) as f32;
            if da > 0.0 {
                c.sn_a[ch] = [
                    ReducedMedium::new(st, al + da, g).sigma_n() as f32,
                    ReducedMedium::new(st, al - da, g).sigma_n() as f32,
                ];
                c.inv_2da[ch] = (0.5 / da) as f32;
            } else if matches!(ds.method, DiffMethod::OursAlphaOffsets | DiffMethod::Fd) {
                return Err(RenderError::Medium(format!(
                    "α = {al} leaves no room for a central α step"
                )));
            }
            c.dsn_dt[ch] = sigma_n_derivatives(st, al, g).0 as f32;
            let r = ReducedMedium::new(st, al, g);
            c.din_da[ch] =
                (norm.d_albedo_input_d_albedo_red(r.albedo_red) * r.d_albedo_red_d_albedo()) as f32;
        }
        for j in 0..2 {
            let kt = scene.descriptor_scale_at(std::array::from_fn(|ch| c.sn_t[ch][j]));
            let ka = scene.descriptor_scale_at(std::array::from_fn(|ch| c.sn_a[ch][j]));
            for ch in 0..3 {
                c.k_t[ch][j] = kt[ch];
                c.k_a[ch][j] = ka[ch];
            }
        }
        if ds.method == DiffMethod::Fd {
            for param in 0..6 {
                let ch = param % 3;
                let step = if param < 3 { steps_t[ch] } else { steps_a[ch] };
                let make = |sign: f64| -> Result<LearnedScene<'a>, RenderError> {
                    let mut med = scene.medium;
                    if param < 3 {
                        med.sigma_t[ch] = (m.sigma_t[ch] as f64 + sign * step) as f32;
                    } else {
                        med.albedo[ch] = (m.albedo[ch] as f64 + sign * step) as f32;
                    }
                    let mut s = LearnedScene::new(
                        scene.accel,
                        scene.model,
                        scene.features,
                        med,
                        scene.settings,
                    )?;
                    if ds.fd_fixed_sigma_n {
                        s.sigma_n = scene.sigma_n;
                        s.descriptor_scale = scene.descriptor_scale;
                    }
                    Ok(s)
                };
                // The actual f32 parameter difference (σ_t ± Δ is rounded to f32).
                let hi = make(1.0)?;
                let lo = make(-1.0)?;
                let diff = if param < 3 {
                    hi.medium.sigma_t[ch] as f64 - lo.medium.sigma_t[ch] as f64
                } else {
                    hi.medium.albedo[ch] as f64 - lo.medium.albedo[ch] as f64
                };
                c.fd.push((hi, lo, 1.0 / diff));
            }
        }
        Ok(c)
    }
}

/// Network inputs and outputs of one set of offset samples (descriptor at another scale).
#[derive(Default)]
struct OffsetNets {
    inputs: Vec<[f32; INPUT_DIM]>,
    net: NetOutputs,
}

/// Reused per worker thread.
#[derive(Default)]
struct DiffBuffers {
    row: RowBuffers,
    fd: RowBuffers,
    /// σ_t + Δ, σ_t − Δ, α + Δα, α − Δα.
    off: [OffsetNets; 4],
    absorb: Vec<f32>,
    d_absorb: Vec<f32>,
    dsum_t: Vec<[f64; 3]>,
    dsum_a: Vec<[f64; 3]>,
}

/// The results of one row.
struct RowResult {
    value: Vec<[f32; 3]>,
    d_sigma_t: Vec<[f32; 3]>,
    d_albedo: Vec<[f32; 3]>,
    loss: f64,
    g_t: [f64; 3],
    g_a: [f64; 3],
}

#[allow(clippy::too_many_arguments)]
fn run(
    scene: &LearnedScene,
    camera: &Camera,
    light: &PointLight,
    rs: &RenderSettings,
    ds: &DiffSettings,
    target: Option<(&Image, Loss)>,
    keep_images: bool,
    progress: Option<&ProgressBar>,
) -> Result<LossGradient, RenderError> {
    let consts = Consts::new(scene, ds)?;
    let (w, h) = (camera.width, camera.height);
    let rows: Vec<RowResult> = (0..h)
        .into_par_iter()
        .map_init(DiffBuffers::default, |buf, y| {
            diff_row(scene, camera, light, rs, ds, &consts, y, buf)?;
            let mut r = RowResult {
                value: Vec::new(),
                d_sigma_t: Vec::new(),
                d_albedo: Vec::new(),
                loss: 0.0,
                g_t: [0.0; 3],
                g_a: [0.0; 3],
            };
            let inv = 1.0 / rs.spp.max(1) as f64;
            let value: Vec<[f32; 3]> = buf.row.sums[..w as usize]
                .iter()
                .map(|s| s.map(|v| (v * inv) as f32))
                .collect();
            let dt: Vec<[f32; 3]> = buf.dsum_t.iter().map(|s| s.map(|v| v as f32)).collect();
            let da: Vec<[f32; 3]> = buf.dsum_a.iter().map(|s| s.map(|v| v as f32)).collect();
            if let Some((t, loss)) = target {
                for x in 0..w as usize {
                    let tp = t.get(x as u32, y);
                    for c in 0..3 {
                        let (l, dl) = loss.element(value[x][c], tp[c]);
                        r.loss += l;
                        r.g_t[c] += dl * dt[x][c] as f64;
                        r.g_a[c] += dl * da[x][c] as f64;
                    }
                }
            }
            if keep_images {
                r.value = value;
                r.d_sigma_t = dt;
                r.d_albedo = da;
            }
            if let Some(pb) = progress {
                pb.inc(1);
            }
            Ok(r)
        })
        .collect::<Result<_, RenderError>>()?;

    let n_inv = 1.0 / (3.0 * w as f64 * h as f64).max(1.0);
    let mut out = LossGradient {
        loss: 0.0,
        d_sigma_t: [0.0; 3],
        d_albedo: [0.0; 3],
        images: None,
    };
    let mut images = keep_images.then(|| DiffImages {
        value: Image::new(w, h),
        d_sigma_t: Image::new(w, h),
        d_albedo: Image::new(w, h),
    });
    for (y, r) in rows.into_iter().enumerate() {
        out.loss += r.loss;
        for c in 0..3 {
            out.d_sigma_t[c] += r.g_t[c];
            out.d_albedo[c] += r.g_a[c];
        }
        if let Some(im) = images.as_mut() {
            let s = y * w as usize..(y + 1) * w as usize;
            im.value.data[s.clone()].copy_from_slice(&r.value);
            im.d_sigma_t.data[s.clone()].copy_from_slice(&r.d_sigma_t);
            im.d_albedo.data[s].copy_from_slice(&r.d_albedo);
        }
    }
    out.loss *= n_inv;
    out.d_sigma_t = out.d_sigma_t.map(|v| v * n_inv);
    out.d_albedo = out.d_albedo.map(|v| v * n_inv);
    out.images = images;
    Ok(out)
}

/// One row: values into `buf.row.sums` (sums over spp, exactly as [`render_row`]) and the
/// derivative means (already divided by spp) into `buf.dsum_t`, `buf.dsum_a`.
#[allow(clippy::too_many_arguments)]
fn diff_row(
    scene: &LearnedScene,
    camera: &Camera,
    light: &PointLight,
    rs: &RenderSettings,
    ds: &DiffSettings,
    k: &Consts,
    y: u32,
    buf: &mut DiffBuffers,
) -> Result<(), RenderError> {
    let w = camera.width as usize;
    let inv_spp = 1.0 / rs.spp.max(1) as f64;
    buf.dsum_t.clear();
    buf.dsum_t.resize(w, [0.0; 3]);
    buf.dsum_a.clear();
    buf.dsum_a.resize(w, [0.0; 3]);

    if ds.method == DiffMethod::Fd {
        render_row(scene, camera, light, rs, y, &mut buf.row)?;
        for (param, (hi, lo, inv_diff)) in k.fd.iter().enumerate() {
            let ch = param % 3;
            render_row(hi, camera, light, rs, y, &mut buf.fd)?;
            let plus: Vec<f64> = buf.fd.sums.iter().map(|s| s[ch]).collect();
            render_row(lo, camera, light, rs, y, &mut buf.fd)?;
            let out = if param < 3 {
                &mut buf.dsum_t
            } else {
                &mut buf.dsum_a
            };
            for x in 0..w {
                out[x][ch] = (plus[x] - buf.fd.sums[x][ch]) * inv_spp * inv_diff;
            }
        }
        return Ok(());
    }

    let row = &mut buf.row;
    prepare_row(scene, camera, rs, y, row);
    run_networks(scene, row)?;
    let n = row.pending.len();
    if n == 0 {
        return Ok(());
    }
    // Offset samples whose descriptor moves with σ_n: the networks again, same z.
    let sets = match ds.method {
        _ if !k.moving => 0,
        DiffMethod::Ours | DiffMethod::Naive => 2,
        DiffMethod::OursAlphaOffsets => 4,
        DiffMethod::Fd => unreachable!(),
    };
    for (j, off) in buf.off.iter_mut().enumerate().take(sets) {
        off.inputs.clear();
        off.inputs
            .extend(row.pending.iter().zip(&row.coeffs).map(|(p, coeffs)| {
                let c = p.channel as usize;
                let scale = if j < 2 { k.k_t[c][j] } else { k.k_a[c][j - 2] };
                scene.inputs_at(coeffs, c, scale)
            }));
        evaluate_networks(
            scene.model,
            &off.inputs,
            &row.z,
            &mut row.point,
            &mut off.net,
            &mut row.ws,
        )?;
    }
    buf.absorb.resize(n, 0.0);
    buf.d_absorb.resize(n, 0.0);
    scene.model.absorb_input_derivative_with(
        &row.inputs,
        ALBEDO_INPUT,
        &mut buf.absorb,
        &mut buf.d_absorb,
        &mut row.ws,
    )?;

    for s in 0..n {
        let p = &row.pending[s];
        let c = p.channel as usize;
        let yk = row.net.y[s];
        let s_abs = 1.0 - row.net.absorb[s];
        // (decoder output, S_abs) of offset set j: the main sample's when the descriptor is fixed.
        let at = |j: usize| -> ([f32; POSITION_DIM], f32) {
            if j < sets {
                (buf.off[j].net.y[s], 1.0 - buf.off[j].net.absorb[s])
            } else {
                (yk, s_abs)
            }
        };
        let main = place_and_project(scene, p, yk, scene.sigma_n[c]);
        let v = main.map_or(0.0, |hit| {
            light_contribution(scene, light, hit.p, hit.ns, hit.ng)
        });

        // Value: exactly the arithmetic of `render_row`.
        if v > 0.0 {
            let base = s_abs * p.t_cam * v;
            if base.is_finite() {
                let sum = &mut row.sums[p.pixel as usize];
                if scene.grey {
                    for (ch, acc) in sum.iter_mut().enumerate() {
                        *acc += (base * light.intensity[ch]) as f64;
                    }
                } else {
                    sum[c] += (3.0 * base * light.intensity[c]) as f64;
                }
            }
        }

        // ∂C/∂σ_t without the channel weight.
        let d_t = match ds.method {
            DiffMethod::Ours | DiffMethod::OursAlphaOffsets => {
                let [hi, lo] = k.sn_t[c];
                let ((yp, sp), (ym, sm)) = (at(0), at(1));
                let vp = offset_light(scene, light, p, yp, hi);
                let vm = offset_light(scene, light, p, ym, lo);
                p.t_cam * (sp * vp - sm * vm) * k.inv_2dt[c]
            }
            DiffMethod::Naive => match main {
                Some(hit) if v > 0.0 => {
                    let ((yp, sp), (ym, sm)) = (at(0), at(1));
                    let dy: [f32; POSITION_DIM] =
                        std::array::from_fn(|i| (yp[i] - ym[i]) * k.inv_2dt[c]);
                    let dl = naive_light_derivative(
                        scene,
                        light,
                        p,
                        (yk, dy),
                        (scene.sigma_n[c], k.dsn_dt[c]),
                        &hit,
                    );
                    p.t_cam * ((sp - sm) * k.inv_2dt[c] * v + s_abs * dl)
                }
                _ => 0.0,
            },
            DiffMethod::Fd => unreachable!(),
        };
        // ∂C/∂α without the channel weight: −∂Absorb/∂α · (1 − F) · L(x_i).
        let mut d_a = -buf.d_absorb[s] * k.din_da[c] * p.t_cam * v;
        if ds.method == DiffMethod::OursAlphaOffsets {
            let [hi, lo] = k.sn_a[c];
            let ((yp, sp), (ym, sm)) = (at(2), at(3));
            let vp = offset_light(scene, light, p, yp, hi);
            let vm = offset_light(scene, light, p, ym, lo);
            d_a += p.t_cam * (sp * vp - sm * vm) * k.inv_2da[c];
        }
        let (d_t, d_a) = (finite_or_zero(d_t), finite_or_zero(d_a));
        let (acc_t, acc_a) = (
            &mut buf.dsum_t[p.pixel as usize],
            &mut buf.dsum_a[p.pixel as usize],
        );
        if scene.grey {
            for ch in 0..3 {
                acc_t[ch] += (d_t * light.intensity[ch]) as f64;
                acc_a[ch] += (d_a * light.intensity[ch]) as f64;
            }
        } else {
            acc_t[c] += (3.0 * d_t * light.intensity[c]) as f64;
            acc_a[c] += (3.0 * d_a * light.intensity[c]) as f64;
        }
    }
    for d in buf.dsum_t.iter_mut().chain(buf.dsum_a.iter_mut()) {
        *d = d.map(|v| v * inv_spp);
    }
    Ok(())
}

#[inline]
fn finite_or_zero(v: f32) -> f32 {
    if v.is_finite() { v } else { 0.0 }
}

/// L(x_i) of an offset sample: x_i = Π(x_o + σ_n·R·y) with the same rule and polynomial, full
/// light evaluation (visibility included); 0 for a miss.
#[inline]
fn offset_light(
    scene: &LearnedScene,
    light: &PointLight,
    p: &Pending,
    y: [f32; POSITION_DIM],
    sigma_n: f32,
) -> f32 {
    place_and_project(scene, p, y, sigma_n).map_or(0.0, |hit| {
        light_contribution(scene, light, hit.p, hit.ns, hit.ng)
    })
}

/// ∇L̃(x_i)·dx_i/dσ_t of the Naive estimator (module docs): the surface motion of the projected
/// point for dx̃ = R·(∂σ_n/∂σ_t·y + σ_n·∂y/∂σ_t) along the detached direction d, and the central
/// difference of the smooth light term (no visibility) along it. `(y, dy)`: decoder output and
/// its σ_t derivative; `(sigma_n, dsigma_n)`: σ_n and ∂σ_n/∂σ_t.
fn naive_light_derivative(
    scene: &LearnedScene,
    light: &PointLight,
    p: &Pending,
    (y, dy): ([f32; POSITION_DIM], [f32; POSITION_DIM]),
    (sigma_n, dsigma_n): (f32, f32),
    hit: &Hit,
) -> f32 {
    let x_t = crate::render::proposed_point(p, y, sigma_n);
    let (grad, _) = projection_gradient(scene, p, x_t);
    let Some(d) = grad.try_normalize() else {
        return 0.0;
    };
    let dy_total = Vec3::from(y) * dsigma_n + Vec3::from(dy) * sigma_n;
    let dx_t = p.out_frame.to_world(dy_total);
    let nd = hit.ng.dot(d);
    if nd.abs() < 1e-6 {
        return 0.0;
    }
    // Intersection of the line x̃ + t·d with the plane of the hit triangle: the sign of d cancels.
    let dx_i = dx_t - d * (hit.ng.dot(dx_t) / nd);
    let len = dx_i.length();
    if len == 0.0 {
        return 0.0;
    }
    let u = dx_i / len;
    let mesh = scene.accel.mesh();
    let l = |x: Vec3| smooth_light(mesh, hit.tri, hit.ng, x, light.position, scene.medium.eta);
    len * (l(hit.p + NAIVE_STEP * u) - l(hit.p - NAIVE_STEP * u)) / (2.0 * NAIVE_STEP)
}

/// L̃(x) = Sw(n·w_l)·(n·w_l)/r² on the plane of triangle `tri` (no visibility, no clamping of the
/// cosine: a smooth extension), with the shading normal n interpolated at x.
fn smooth_light(mesh: &Mesh, tri: u32, ng: Vec3, x: Vec3, light: Vec3, eta: f32) -> f32 {
    let n = shading_normal_at(mesh, tri, ng, x);
    let to_l = light - x;
    let r2 = to_l.length_squared();
    let cos = n.dot(to_l) / r2.sqrt();
    sw(cos, eta) * cos / r2
}

/// The interpolated vertex normal of triangle `tri` at the point x of its plane (barycentrics
/// extended linearly outside the triangle), or `ng` for a mesh without normals.
fn shading_normal_at(mesh: &Mesh, tri: u32, ng: Vec3, x: Vec3) -> Vec3 {
    let Some(normals) = &mesh.normals else {
        return ng;
    };
    let [i0, i1, i2] = mesh.indices[tri as usize];
    let [v0, v1, v2] = mesh.triangle(tri as usize);
    let (e1, e2, q) = (v1 - v0, v2 - v0, x - v0);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (q1, q2) = (q.dot(e1), q.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det == 0.0 {
        return ng;
    }
    let b1 = (d22 * q1 - d12 * q2) / det;
    let b2 = (d11 * q2 - d12 * q1) / det;
    let n = normals[i0 as usize] * (1.0 - b1 - b2)
        + normals[i1 as usize] * b1
        + normals[i2 as usize] * b2;
    match n.try_normalize() {
        Some(n) if n.dot(ng) >= 0.0 => n,
        Some(n) => (n - 2.0 * n.dot(ng) * ng).try_normalize().unwrap_or(ng),
        None => ng,
    }
}
