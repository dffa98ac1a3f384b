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
//! Estimators ([`Estimator`]), one file each over the shared row ([`row`]: samples, offset
//! networks, value, the S_abs term of ∂/∂α):
//!
//! | estimator | file | ∂/∂σ_t | ∂/∂α |
//! |---|---|---|---|
//! | `ours` (the paper's, §4.2–4.3, eq. 15–17) | [`ours`] | correlated offset samples x_i^± | −∂Absorb/∂α·(1 − F)·L(x_i), positions detached |
//! | `ours-alpha-offsets` (A6) | [`ours_alpha_offsets`] | as `ours` | offset samples at α ± Δα |
//! | `naive` (§4.1) | [`naive`] | sample-position derivative, visibility fixed | as `ours` |
//! | `fd` | [`fd`] | central differences of full renders | as for σ_t |
//!
//! Adding an estimator is a file implementing [`row::SampleEstimator`] (or a [`row::RowFn`] of
//! its own) and an arm of [`Estimator`] with its row in [`Estimator::row`].
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
mod fd;
mod naive;
mod ours;
mod ours_alpha_offsets;
mod row;
mod settings;
#[cfg(test)]
mod toy;

pub use scene::loss::{DiffImages, Loss, LossGradient};
pub use settings::{DiffSettings, Estimator, NAIVE_STEP, Primal, UnknownEstimator, UnknownPrimal};

use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::{Camera, Image, PointLight};

use crate::medium::{ReducedMedium, sigma_n_derivatives};
use crate::render::{EntrySampler, LearnedScene, RenderError, RenderSettings, ViewRays};
use consts::Consts;
use row::{DiffBuffers, RowFn, offset_row};

impl Estimator {
    /// The estimator's row ([`row::RowFn`]).
    fn row(self) -> RowFn {
        match self {
            Estimator::Ours => offset_row::<ours::Ours>,
            Estimator::OursAlphaOffsets => offset_row::<ours_alpha_offsets::OursAlphaOffsets>,
            Estimator::Naive => offset_row::<naive::Naive>,
            Estimator::Fd => fd::row,
        }
    }
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
    let out = run(
        scene,
        view,
        rs,
        ds,
        ds.estimator.row(),
        None,
        true,
        progress,
    )?;
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
    run(
        scene,
        &view,
        rs,
        ds,
        ds.estimator.row(),
        target,
        keep_images,
        progress,
    )
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
    estimator_row: RowFn,
    target: Option<(&Image, Loss)>,
    keep_images: bool,
    progress: Option<&ProgressBar>,
) -> Result<LossGradient, RenderError> {
    let consts = Consts::new(scene, ds)?;
    let (w, h) = (view.camera.width, view.camera.height);
    let rows: Vec<RowResult> = (0..h)
        .into_par_iter()
        .map_init(DiffBuffers::default, |buf, y| {
            estimator_row(scene, view, rs, ds, &consts, y, buf)?;
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
        d_g: None,
        d_ln_light_scale: None,
        images: None,
    };
    let mut images = keep_images.then(|| DiffImages {
        value: Image::new(w, h),
        d_sigma_t: Image::new(w, h),
        d_albedo: Image::new(w, h),
        d_g: None,
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
