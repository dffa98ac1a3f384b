//! The differentiable learned renderer: per-pixel values and their derivatives with respect to
//! the six medium parameters σ_t,c and α_c (c = R, G, B), docs/model.md §8, ARCHITECTURE.md, "Gradient estimators",
//! Son et al. 2024 §4 (eq. 6–17).
//!
//! Channel c of the image depends only on (σ_t,c, α_c) (docs/model.md §1, §2), so the derivatives
//! fit in two RGB images: `d_sigma_t` holds ∂I_c/∂σ_t,c in channel c and `d_albedo` holds
//! ∂I_c/∂α_c. The pixel estimator is the one of [`crate::render`] (docs/model.md §7.3):
//!
//!   I_c ≈ (1/spp) Σ_s w_c · S_abs · (1 − F(cos θ_cam)) · L(x_i),
//!   L(x) = Sw(w_l) · max(0, n·w_l) · V · I / r²  (without I in the code: w_c carries it),
//!
//! with w_c = w·I_c·[c = channel of the sample] (w the channel weight of the pixel-sampling
//! scheme, [`crate::render::PixelSampling`]: spp/n_c stratified, 3 one-hot as docs/model.md A13) or
//! w_c = I_c for a grey medium (one sample serves every channel), S_abs = 1 − Absorb(features(α)), x_i = Π(x̃),
//! x̃ = x_o + σ_n(σ_t, α)·R·y and y = decoder(z, features). The vertex polynomials are those of
//! the [`VertexFeatures`](crate::render::VertexFeatures) fit, kept fixed (docs/model.md A10); the
//! projection direction is the detached gradient of that fixed polynomial at x̃ (A5).
//!
//! The shape descriptor the networks see: the fitted polynomial in units of σ_n,fit, rescaled to
//! the current σ_n (`Poly3::rescaled`, c_m·k^(deg m − 1), k = σ_n/σ_n,fit), unless
//! `LearnedSettings::frozen_descriptor` (SON24's fixed features). A rescaled descriptor depends on
//! σ_t (and α) through σ_n; measured on the shipped model this term dominates ∂I/∂σ_t and has the
//! opposite sign of the position term (docs/notes/recovery-recipe.md, "The descriptor follows
//! σ_n"), and with it the loss landscape is that of a refit at every σ_t.
//!
//! Estimators ([`DiffMethod`]):
//!
//! * [`DiffMethod::Ours`] (paper §4.2–4.3, eq. 15–17; docs/model.md §8.1–8.2, A6): for σ_t the
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
//! * [`DiffMethod::OursAlphaOffsets`] (docs/model.md A6, option): σ_t as `Ours`; α entirely by
//!   offset samples, as σ_t: the networks run again with the albedo input and the descriptor at
//!   α ± Δα (y^±, S_abs^±, z reused), x_i^± = Π(x_o + σ_n(α ± Δα)·R·y^±), and the light side
//!   (exit law, incidence factor) at α ± Δα: ∂C/∂α = (1 − F)·(S_abs⁺·L⁺(x_i⁺) − S_abs⁻·L⁻(x_i⁻))/(2Δα).
//!   Unlike `Ours` it keeps the dependence of the sample positions on α.
//! * [`DiffMethod::Naive`] (paper §4.1, the "naive" baseline; ARCHITECTURE.md, "Gradient estimators"): σ_t by the
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
//! the zero-valued term σ_t·D − detach(σ_t)·D of docs/model.md §8.1); derivative images are
//! kept only on request.
//!
//! Batched and parallel like [`crate::render`]: rows in parallel, one network batch per row,
//! per-thread buffers; every random number comes from the (seed, view, pixel) stream and the row
//! results are reduced in row order, so results do not depend on the thread count. With
//! [`Primal::Sample`] the value image is bit-identical to
//! [`render_image`](crate::render::render_image) for the same settings; with the default
//! [`Primal::OffsetMean`] `Ours` takes it from the σ_t offset pair (O(Δ²) bias, no unperturbed
//! projection, shadow ray or network pass), and ∂Absorb/∂α is evaluated only for the samples whose
//! light term is not zero.

mod consts;
mod naive;
mod settings;

pub use settings::{
    DiffImages, DiffMethod, DiffSettings, Loss, LossGradient, NAIVE_STEP, Primal, UnknownMethod,
    UnknownPrimal,
};

use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::{Camera, Image, PointLight};

use crate::medium::{ReducedMedium, sigma_n_derivatives};
use crate::nn::INPUT_DIM;
use crate::nn::{ALBEDO_INPUT, POSITION_DIM};
use crate::render::{
    EntrySampler, LearnedScene, NetOutputs, Pending, RenderError, RenderSettings, RowBuffers,
    ViewRays, evaluate_networks, light_contribution, place_and_project, prepare_row, render_row,
    run_networks, walk_entries, walk_media, walk_medium,
};
use crate::walk::WalkMedium;
use consts::Consts;
use naive::naive_light_derivative;

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
    render_diff_view(
        scene,
        &ViewRays::new(scene, camera, light),
        rs,
        ds,
        progress,
    )
}

/// [`render_diff`] of a view whose rays are already set up (`view` built over `scene.accel`).
pub fn render_diff_view(
    scene: &LearnedScene,
    view: &ViewRays,
    rs: &RenderSettings,
    ds: &DiffSettings,
    progress: Option<&ProgressBar>,
) -> Result<DiffImages, RenderError> {
    let out = run(scene, view, rs, ds, None, true, progress)?;
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
    let view = ViewRays::new(scene, camera, light);
    let target = Some((target, loss));
    run(scene, &view, rs, ds, target, keep_images, progress)
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
    /// (sample, (1 − F)·L(x_i)) of the samples with L(x_i) > 0, and their network inputs.
    lit: Vec<(u32, f32)>,
    lit_inputs: Vec<[f32; INPUT_DIM]>,
    dsum_t: Vec<[f64; 3]>,
    dsum_a: Vec<[f64; 3]>,
}

/// The results of one row.
struct RowResult {
    value: Vec<[f32; 3]>,
    d_sigma_t: Vec<[f32; 3]>,
    d_albedo: Vec<[f32; 3]>,
    loss: [f64; 3],
    g_t: [f64; 3],
    g_a: [f64; 3],
}

#[allow(clippy::too_many_arguments)]
fn run(
    scene: &LearnedScene,
    view: &ViewRays,
    rs: &RenderSettings,
    ds: &DiffSettings,
    target: Option<(&Image, Loss)>,
    keep_images: bool,
    progress: Option<&ProgressBar>,
) -> Result<LossGradient, RenderError> {
    if ds.method == DiffMethod::Ad {
        return Err(RenderError::Estimator(
            "`ad` is the volumetric path tracer's derivative; the learned model's estimators are \
             ours, ours-alpha-offsets, naive and fd"
                .into(),
        ));
    }
    let consts = Consts::new(scene, ds)?;
    let (w, h) = (view.camera.width, view.camera.height);
    let rows: Vec<RowResult> = (0..h)
        .into_par_iter()
        .map_init(DiffBuffers::default, |buf, y| {
            diff_row(scene, view, rs, ds, &consts, y, buf)?;
            let mut r = RowResult {
                value: Vec::new(),
                d_sigma_t: Vec::new(),
                d_albedo: Vec::new(),
                loss: [0.0; 3],
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
                        r.loss[c] += l;
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
        loss_channels: [0.0; 3],
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
        for c in 0..3 {
            out.loss_channels[c] += r.loss[c];
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
    out.loss_channels = out.loss_channels.map(|v| v * n_inv);
    out.loss = out.loss_channels.iter().sum();
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
    view: &ViewRays,
    rs: &RenderSettings,
    ds: &DiffSettings,
    k: &Consts,
    y: u32,
    buf: &mut DiffBuffers,
) -> Result<(), RenderError> {
    let w = view.camera.width as usize;
    let light = view.light;
    let inv_spp = 1.0 / rs.spp.max(1) as f64;
    buf.dsum_t.clear();
    buf.dsum_t.resize(w, [0.0; 3]);
    buf.dsum_a.clear();
    buf.dsum_a.resize(w, [0.0; 3]);

    if ds.method == DiffMethod::Fd {
        render_row(scene, view, rs, y, &mut buf.row)?;
        for (param, (hi, lo, inv_diff)) in k.fd.iter().enumerate() {
            let ch = param % 3;
            render_row(hi, view, rs, y, &mut buf.fd)?;
            let plus: Vec<f64> = buf.fd.sums.iter().map(|s| s[ch]).collect();
            render_row(lo, view, rs, y, &mut buf.fd)?;
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
    prepare_row(scene, view, rs, y, row);
    let n = row.pending.len();
    if n == 0 {
        return Ok(());
    }
    // Offset samples whose descriptor moves with σ_n: the networks again, same z.
    let sets = match ds.method {
        // The α offsets change the network inputs (albedo) even with a fixed descriptor.
        DiffMethod::OursAlphaOffsets => 4,
        _ if !k.moving => 0,
        DiffMethod::Ours | DiffMethod::Naive => 2,
        DiffMethod::Fd | DiffMethod::Ad => unreachable!(),
    };
    // The value from the σ_t offset pair: no unperturbed sample to place (module docs).
    let pair_primal = ds.primal == Primal::OffsetMean
        && matches!(ds.method, DiffMethod::Ours | DiffMethod::OursAlphaOffsets);
    // The unperturbed decoder output and S_abs are needed unless every use reads an offset set.
    let main_nets = !(pair_primal && sets >= 2);
    if main_nets {
        run_networks(scene, row)?;
    }
    for (j, off) in buf.off.iter_mut().enumerate().take(sets) {
        off.inputs.clear();
        off.inputs
            .extend(
                row.pending
                    .iter()
                    .zip(&row.coeffs)
                    .enumerate()
                    .map(|(i, (p, coeffs))| {
                        let c = p.channel as usize;
                        let dc = row.dcoeffs.get(i);
                        if j < 2 {
                            scene.inputs_at(coeffs, dc, c, k.k_t[c][j])
                        } else {
                            // The scene at α_c ± Δα: its albedo input and descriptor scale.
                            let a = &k.alpha[c][j - 2];
                            a.inputs_at(coeffs, dc, c, a.descriptor_scale[c])
                        }
                    }),
            );
        evaluate_networks(
            scene.model,
            &off.inputs,
            &row.z,
            &mut row.point,
            &mut off.net,
            &mut row.ws,
        )?;
        if scene.settings.entry == EntrySampler::Walks {
            // The same walks (each sample's stream) in the offset set's descriptor and medium:
            // σ_t ± Δ at σ_n(σ_t ± Δ), or channel c's scene at α_c ± Δα.
            let m = &scene.medium;
            let (media, kj): ([WalkMedium; 3], [f32; 3]) = if j < 2 {
                (
                    std::array::from_fn(|c| walk_medium(m, c, k.st_t[c][j], k.sn_t[c][j])),
                    std::array::from_fn(|c| k.k_t[c][j]),
                )
            } else {
                let a: [&LearnedScene; 3] = std::array::from_fn(|c| &k.alpha[c][j - 2]);
                (
                    std::array::from_fn(|c| walk_media(a[c])[c]),
                    std::array::from_fn(|c| a[c].descriptor_scale[c]),
                )
            };
            let (p, cf, dc) = (&row.pending, &row.coeffs, &row.dcoeffs);
            walk_entries(&media, p, cf, dc, |c| kj[c], &mut off.net.y);
        }
    }
    // Samples whose light term is not zero: only they need ∂Absorb/∂α (after the loop).
    buf.lit.clear();
    buf.lit_inputs.clear();

    for s in 0..n {
        let p = &row.pending[s];
        let c = p.channel as usize;
        let (yk, s_abs) = if main_nets {
            (row.net.y[s], 1.0 - row.net.absorb[s])
        } else {
            ([0.0; POSITION_DIM], 0.0)
        };
        // (decoder output, S_abs) of offset set j: the main sample's when the descriptor is fixed.
        let at = |j: usize| -> ([f32; POSITION_DIM], f32) {
            if j < sets {
                (buf.off[j].net.y[s], 1.0 - buf.off[j].net.absorb[s])
            } else {
                (yk, s_abs)
            }
        };
        // σ_t offset pair (Ours, OursAlphaOffsets): S_abs^±·L(x_i^±).
        let pair =
            matches!(ds.method, DiffMethod::Ours | DiffMethod::OursAlphaOffsets).then(|| {
                let ([hi, lo], [st_hi, st_lo]) = (k.sn_t[c], k.st_t[c]);
                let ((yp, sp), (ym, sm)) = (at(0), at(1));
                let (vp, dvp) = offset_light(scene, view, p, yp, (hi, st_hi));
                let (vm, dvm) = offset_light(scene, view, p, ym, (lo, st_lo));
                (
                    sp * vp,
                    sm * vm,
                    0.5 * (vp + vm),
                    0.5 * (sp * dvp + sm * dvm),
                )
            });
        // v = L(x_i); dv_law = S_abs·∂L/∂α through the exit law (the α-dependence of the
        // light side, [`crate::exit`]), from the pair when it gives the value.
        let (main, v, dv_law) = match pair {
            Some((_, _, v_mean, dv_mean)) if pair_primal => (None, v_mean, dv_mean),
            _ => {
                let main = place_and_project(scene, p, yk, scene.sigma_n[c]);
                let (v, dv) = main.map_or((0.0, 0.0), |hit| {
                    light_contribution(scene, view, p, &hit, scene.medium.sigma_t[c])
                });
                (main, v, s_abs * dv)
            }
        };

        // Value: with the unperturbed sample exactly the arithmetic of `render_row`.
        let base = match pair {
            Some((cp, cm, _, _)) if pair_primal => 0.5 * (cp + cm) * p.t_cam,
            _ => s_abs * p.t_cam * v,
        };
        if v > 0.0 && base.is_finite() {
            let sum = &mut row.sums[p.pixel as usize];
            if scene.grey {
                for (ch, acc) in sum.iter_mut().enumerate() {
                    *acc += (base * light.intensity[ch]) as f64;
                }
            } else {
                sum[c] += (p.weight * base * light.intensity[c]) as f64;
            }
        }

        // ∂C/∂σ_t without the channel weight.
        let d_t = match ds.method {
            DiffMethod::Ours | DiffMethod::OursAlphaOffsets => {
                let (cp, cm, _, _) = pair.expect("offset pair of Ours");
                p.t_cam * (cp - cm) * k.inv_2dt[c]
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
            DiffMethod::Fd | DiffMethod::Ad => unreachable!(),
        };
        let d_a = if ds.method == DiffMethod::OursAlphaOffsets {
            // Every α-dependence by the offset pair at α ± Δα (same z): networks, σ_n and the
            // light-side tables of the offset scenes.
            let [hi, lo] = k.sn_a[c];
            let ((yp, sp), (ym, sm)) = (at(2), at(3));
            let st = scene.medium.sigma_t[c];
            let (vp, _) = offset_light(&k.alpha[c][0], view, p, yp, (hi, st));
            let (vm, _) = offset_light(&k.alpha[c][1], view, p, ym, (lo, st));
            p.t_cam * (sp * vp - sm * vm) * k.inv_2da[c]
        } else {
            // ∂C/∂α without the channel weight: −∂Absorb/∂α · (1 − F) · L(x_i) after the loop,
            // and the light side's ∂L/∂α here.
            if v > 0.0 {
                buf.lit.push((s as u32, p.t_cam * v));
                buf.lit_inputs.push(row.inputs[s]);
            }
            p.t_cam * dv_law
        };
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
            acc_t[c] += (p.weight * d_t * light.intensity[c]) as f64;
            acc_a[c] += (p.weight * d_a * light.intensity[c]) as f64;
        }
    }
    // The S_abs term of ∂C/∂α, one tangent pass over the lit samples.
    let m = buf.lit.len();
    buf.absorb.resize(m, 0.0);
    buf.d_absorb.resize(m, 0.0);
    scene.model.absorb_input_derivative_with(
        &buf.lit_inputs,
        ALBEDO_INPUT,
        &mut buf.absorb,
        &mut buf.d_absorb,
        &mut row.ws,
    )?;
    for (&(s, tv), &da) in buf.lit.iter().zip(&buf.d_absorb) {
        let p = &row.pending[s as usize];
        let c = p.channel as usize;
        let d_a = finite_or_zero(-da * k.din_da[c] * tv);
        let acc_a = &mut buf.dsum_a[p.pixel as usize];
        if scene.grey {
            for ch in 0..3 {
                acc_a[ch] += (d_a * light.intensity[ch]) as f64;
            }
        } else {
            acc_a[c] += (p.weight * d_a * light.intensity[c]) as f64;
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

/// L(x_i) and ∂L/∂α (exit law and incidence factor) of an offset sample: x_i = Π(x_o + σ_n·R·y)
/// with the same rule and polynomial, full light evaluation (visibility included) at the offset
/// extinction σ_t; 0 for a miss.
#[inline]
fn offset_light(
    scene: &LearnedScene,
    view: &ViewRays,
    p: &Pending,
    y: [f32; POSITION_DIM],
    (sigma_n, sigma_t): (f32, f32),
) -> (f32, f32) {
    place_and_project(scene, p, y, sigma_n).map_or((0.0, 0.0), |hit| {
        light_contribution(scene, view, p, &hit, sigma_t)
    })
}
