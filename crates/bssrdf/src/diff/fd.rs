//! `fd`: brute-force central differences of two full renders at θ ± Δ with identical random
//! numbers (same seed, view and pixel streams), per parameter (12 extra renders of the row; a
//! reference):
//!
//!   ∂I_c/∂θ ≈ (I_c(θ + Δ) − I_c(θ − Δ))/(2Δ),  Δ = `delta_rel`·σ_t or Δα = `delta_albedo`,
//!
//! with the actual f32 difference of the two perturbed parameters as 2Δ. The perturbed scenes
//! are built once per render ([`super::consts::Consts`]); with
//! [`DiffSettings::fd_fixed_sigma_n`](super::DiffSettings::fd_fixed_sigma_n) they keep the
//! unperturbed σ_n (the differences through the networks only).

use super::DiffSettings;
use super::consts::Consts;
use super::row::DiffBuffers;
use crate::render::{LearnedScene, RenderError, RenderSettings, ViewRays, render_row};

/// One row of `fd` (a [`super::row::RowFn`]).
pub(super) fn row(
    scene: &LearnedScene,
    view: &ViewRays,
    rs: &RenderSettings,
    _ds: &DiffSettings,
    k: &Consts,
    y: u32,
    buf: &mut DiffBuffers,
) -> Result<(), RenderError> {
    let w = view.camera.width as usize;
    let inv_spp = 1.0 / rs.spp.max(1) as f64;
    buf.clear_sums(w);
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
    Ok(())
}
