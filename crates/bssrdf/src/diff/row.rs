//! What the sample-based estimators share (`ours`, `ours-alpha-offsets`, `naive`): the row's
//! samples prepared as for the image ([`prepare_row`]), the networks run again on the offset
//! descriptors (same latent z), the value accumulated exactly as [`crate::render`] does, and the
//! S_abs term of ∂C/∂α by one tangent pass over the lit samples (module docs of [`super`]). An
//! estimator says which offset sets it needs and how a sample's ∂C/∂σ_t and ∂C/∂α follow from
//! them ([`SampleEstimator`]); [`offset_row`] does the rest.

use super::consts::Consts;
use super::{DiffSettings, Primal};
use crate::nn::{ALBEDO_INPUT, INPUT_DIM, POSITION_DIM};
use crate::render::{
    EntrySampler, LearnedScene, NetOutputs, Pending, RenderError, RenderSettings, RowBuffers,
    ViewRays, evaluate_networks, light_contribution, place_and_project, prepare_row, run_networks,
    walk_entries, walk_media, walk_medium,
};
use crate::walk::WalkMedium;

/// Network inputs and outputs of one set of offset samples (descriptor at another scale).
#[derive(Default)]
pub(super) struct OffsetNets {
    inputs: Vec<[f32; INPUT_DIM]>,
    net: NetOutputs,
}

/// Reused per worker thread.
#[derive(Default)]
pub(super) struct DiffBuffers {
    pub(super) row: RowBuffers,
    pub(super) fd: RowBuffers,
    /// σ_t + Δ, σ_t − Δ, α + Δα, α − Δα.
    off: [OffsetNets; 4],
    absorb: Vec<f32>,
    d_absorb: Vec<f32>,
    /// (sample, (1 − F)·L(x_i)) of the samples with L(x_i) > 0, and their network inputs.
    lit: Vec<(u32, f32)>,
    lit_inputs: Vec<[f32; INPUT_DIM]>,
    /// Per pixel of the row: the ∂/∂σ_t and ∂/∂α means (divided by spp once the row is done).
    pub(super) dsum_t: Vec<[f64; 3]>,
    pub(super) dsum_a: Vec<[f64; 3]>,
}

impl DiffBuffers {
    /// Zeroed derivative sums for a row of `w` pixels.
    pub(super) fn clear_sums(&mut self, w: usize) {
        self.dsum_t.clear();
        self.dsum_t.resize(w, [0.0; 3]);
        self.dsum_a.clear();
        self.dsum_a.resize(w, [0.0; 3]);
    }
}

/// One row of an estimator: values into `buf.row.sums` (sums over spp, exactly as
/// [`crate::render::render_row`]) and the derivative means (divided by spp) into `buf.dsum_t`,
/// `buf.dsum_a`.
pub(super) type RowFn = fn(
    &LearnedScene,
    &ViewRays,
    &RenderSettings,
    &DiffSettings,
    &Consts,
    u32,
    &mut DiffBuffers,
) -> Result<(), RenderError>;

/// One sample of a row as the sample-based estimators see it.
pub(super) struct Sample<'a, 's> {
    pub(super) scene: &'a LearnedScene<'s>,
    pub(super) view: &'a ViewRays<'a>,
    pub(super) p: &'a Pending,
    /// The sample's channel.
    pub(super) c: usize,
    pub(super) k: &'a Consts<'s>,
    /// The unperturbed decoder output and S_abs (zero when no estimator use reads them).
    pub(super) y: [f32; POSITION_DIM],
    pub(super) s_abs: f32,
    /// (decoder output, S_abs) of offset set j (σ_t + Δ, σ_t − Δ, α + Δα, α − Δα): the
    /// unperturbed sample's where the set is not run.
    pub(super) offsets: [([f32; POSITION_DIM], f32); 4],
    /// The σ_t offset pair, when the estimator uses it: (S_abs⁺·L(x_i⁺), S_abs⁻·L(x_i⁻)).
    pub(super) pair: Option<(f32, f32)>,
    /// The unperturbed exit point, when it was placed.
    pub(super) hit: Option<geometry::Hit>,
    /// L(x_i) (from the pair when it gives the value).
    pub(super) v: f32,
}

/// A sample-based estimator of the learned renderer: one file each, run by [`offset_row`].
pub(super) trait SampleEstimator {
    /// Whether it uses the σ_t offset pair x_i^± (and so may take the value from it,
    /// [`Primal::OffsetMean`]).
    const PAIR: bool;
    /// How many offset sets of network outputs it needs (in the order σ_t + Δ, σ_t − Δ,
    /// α + Δα, α − Δα); `moving`: the descriptor follows σ_n.
    fn offset_sets(moving: bool) -> usize;
    /// ∂C/∂σ_t of the sample without the channel weight.
    fn d_sigma_t(s: &Sample) -> f32;
    /// ∂C/∂α of the sample without the channel weight; `None`: the shared form
    /// −∂Absorb/∂α·(1 − F)·L(x_i) + S_abs·(1 − F)·∂L/∂α.
    fn d_albedo(s: &Sample) -> Option<f32>;
}

/// One row of a [`SampleEstimator`] (the [`RowFn`] of `E`).
pub(super) fn offset_row<E: SampleEstimator>(
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
    buf.clear_sums(w);

    let row = &mut buf.row;
    prepare_row(scene, view, rs, y, row);
    let n = row.pending.len();
    if n == 0 {
        return Ok(());
    }
    // Offset samples whose descriptor moves with σ_n: the networks again, same z.
    let sets = E::offset_sets(k.moving);
    // The value from the σ_t offset pair: no unperturbed sample to place (module docs).
    let pair_primal = ds.primal == Primal::OffsetMean && E::PAIR;
    // The unperturbed decoder output and S_abs are needed unless every use reads an offset set.
    let main_nets = !(pair_primal && sets >= 2);
    if main_nets {
        run_networks(scene, row)?;
    }
    for (j, off) in buf.off.iter_mut().enumerate().take(sets) {
        run_offset_set(scene, k, row, j, off)?;
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
        let offsets = std::array::from_fn(|j| {
            if j < sets {
                (buf.off[j].net.y[s], 1.0 - buf.off[j].net.absorb[s])
            } else {
                (yk, s_abs)
            }
        });
        let pair = E::PAIR.then(|| offset_pair(scene, view, p, k, &offsets));
        // v = L(x_i); dv_law = S_abs·∂L/∂α through the exit law (the α-dependence of the
        // light side, [`crate::exit`]), from the pair when it gives the value.
        let (hit, v, dv_law) = match pair {
            Some((_, _, v_mean, dv_mean)) if pair_primal => (None, v_mean, dv_mean),
            _ => {
                let hit = place_and_project(scene, p, yk, scene.sigma_n[c]);
                let (v, dv) = hit.map_or((0.0, 0.0), |hit| {
                    light_contribution(scene, view, p, &hit, scene.medium.sigma_t[c])
                });
                (hit, v, s_abs * dv)
            }
        };

        // Value: with the unperturbed sample exactly the arithmetic of `render_row`.
        let base = match pair {
            Some((cp, cm, _, _)) if pair_primal => 0.5 * (cp + cm) * p.t_cam,
            _ => s_abs * p.t_cam * v,
        };
        if v > 0.0 && base.is_finite() {
            add(&mut row.sums[p.pixel as usize], scene.grey, p, light, base);
        }

        let sample = Sample {
            scene,
            view,
            p,
            c,
            k,
            y: yk,
            s_abs,
            offsets,
            pair: pair.map(|(cp, cm, _, _)| (cp, cm)),
            hit,
            v,
        };
        let d_t = E::d_sigma_t(&sample);
        let d_a = E::d_albedo(&sample).unwrap_or_else(|| {
            // −∂Absorb/∂α · (1 − F) · L(x_i) after the loop, and the light side's ∂L/∂α here.
            if v > 0.0 {
                buf.lit.push((s as u32, p.t_cam * v));
                buf.lit_inputs.push(row.inputs[s]);
            }
            p.t_cam * dv_law
        });
        let px = p.pixel as usize;
        add(
            &mut buf.dsum_t[px],
            scene.grey,
            p,
            light,
            finite_or_zero(d_t),
        );
        add(
            &mut buf.dsum_a[px],
            scene.grey,
            p,
            light,
            finite_or_zero(d_a),
        );
    }
    absorb_term(scene, view, k, buf)?;
    for d in buf.dsum_t.iter_mut().chain(buf.dsum_a.iter_mut()) {
        *d = d.map(|v| v * inv_spp);
    }
    Ok(())
}

/// The σ_t offset pair of sample `p` from its offset sets 0 and 1 (decoder output, S_abs):
/// S_abs^±·L(x_i^±), and the means of L and of S_abs·∂L/∂α over the pair.
#[inline]
fn offset_pair(
    scene: &LearnedScene,
    view: &ViewRays,
    p: &Pending,
    k: &Consts,
    offsets: &[([f32; POSITION_DIM], f32); 4],
) -> (f32, f32, f32, f32) {
    let c = p.channel as usize;
    let ([hi, lo], [st_hi, st_lo]) = (k.sn_t[c], k.st_t[c]);
    let ((yp, sp), (ym, sm)) = (offsets[0], offsets[1]);
    let (vp, dvp) = offset_light(scene, view, p, yp, (hi, st_hi));
    let (vm, dvm) = offset_light(scene, view, p, ym, (lo, st_lo));
    (
        sp * vp,
        sm * vm,
        0.5 * (vp + vm),
        0.5 * (sp * dvp + sm * dvm),
    )
}

/// The networks of offset set `j` on the row's samples (same z): the descriptor (and, for the α
/// sets, the albedo input) at σ_t ± Δ or α_c ± Δα; with the walk entry sampler, the same walks
/// in the offset medium.
fn run_offset_set(
    scene: &LearnedScene,
    k: &Consts,
    row: &mut RowBuffers,
    j: usize,
    off: &mut OffsetNets,
) -> Result<(), RenderError> {
    off.inputs.clear();
    off.inputs.extend(
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
    Ok(())
}

/// The S_abs term of ∂C/∂α, −∂Absorb/∂α·(1 − F)·L(x_i), by one tangent pass over the lit
/// samples ([`crate::nn::ShapeAdaptiveModel::absorb_input_derivative_with`]).
fn absorb_term(
    scene: &LearnedScene,
    view: &ViewRays,
    k: &Consts,
    buf: &mut DiffBuffers,
) -> Result<(), RenderError> {
    let light = view.light;
    let m = buf.lit.len();
    buf.absorb.resize(m, 0.0);
    buf.d_absorb.resize(m, 0.0);
    scene.model.absorb_input_derivative_with(
        &buf.lit_inputs,
        ALBEDO_INPUT,
        &mut buf.absorb,
        &mut buf.d_absorb,
        &mut buf.row.ws,
    )?;
    for (&(s, tv), &da) in buf.lit.iter().zip(&buf.d_absorb) {
        let p = &buf.row.pending[s as usize];
        let c = p.channel as usize;
        let d_a = finite_or_zero(-da * k.din_da[c] * tv);
        add(&mut buf.dsum_a[p.pixel as usize], scene.grey, p, light, d_a);
    }
    Ok(())
}

/// Adds a sample's contribution `x` (without the channel weight and the light's intensity) to
/// its pixel's sums: to every channel for a grey medium (one sample serves all three), else to
/// the sample's channel with its weight.
#[inline]
fn add(sum: &mut [f64; 3], grey: bool, p: &Pending, light: &scene::PointLight, x: f32) {
    if grey {
        for (ch, acc) in sum.iter_mut().enumerate() {
            *acc += (x * light.intensity[ch]) as f64;
        }
    } else {
        let c = p.channel as usize;
        sum[c] += (p.weight * x * light.intensity[c]) as f64;
    }
}

#[inline]
fn finite_or_zero(v: f32) -> f32 {
    if v.is_finite() { v } else { 0.0 }
}

/// L(x_i) and ∂L/∂α (exit law and incidence factor) of an offset sample: x_i = Π(x_o + σ_n·R·y)
/// with the same rule and polynomial, full light evaluation (visibility included) at the offset
/// extinction σ_t; 0 for a miss.
#[inline]
pub(super) fn offset_light(
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
