//! What a traced path adds up (`Tally`), and what each of its contributions depends on the
//! medium by (`PathScore`).

/// What a contribution's weight depends on the medium by: the real scatterings `k` before it,
/// its length `len` inside the medium up to the light (its free flights, plus the shadow
/// segment's inside length for a next-event estimate), and `phase`, per channel c the sum of
/// ∂ ln p_{g_c}/∂g_c over its phase-function factors ([`crate::phase::ChannelHg::d_log_dg`]; 0
/// unless the tally asks for it, [`Tally::SCORES_PHASE`]). The path's throughput depends on σ_t
/// and α only through (α σ_t)^k e^{−σ_t ℓ}, and on g only through its phase-function factors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathScore {
    pub k: u32,
    pub len: f32,
    pub phase: [f32; 3],
}

/// What a traced path adds up: the radiance alone (`[f32; 3]`) or the radiance with its
/// derivatives with respect to the medium ([`crate::derivative::PathDerivatives`]). Every
/// contribution of a path (a next-event estimate or the environment at its escape) is handed
/// over with its [`PathScore`], which is what the derivatives need.
pub trait Tally: Copy + Default + Send + Sync {
    /// A pixel's running sum of tallies.
    type Sum: Copy + Default + Send + Sync;
    /// Whether [`PathScore::phase`] is wanted (the value alone skips its arithmetic).
    const SCORES_PHASE: bool;
    /// Adds this tally to a pixel's sum.
    fn add_to(&self, sum: &mut Self::Sum);
    /// Adds the contribution `c` (per channel, the estimator's weight included) of a path with
    /// `score`, in a medium of `sigma_t`, `albedo`.
    fn record(&mut self, c: [f32; 3], score: PathScore, sigma_t: &[f32; 3], albedo: &[f32; 3]);
    /// Replaces non-finite values by 0 (a path that lost its numbers contributes nothing).
    fn finish(&mut self);
}

impl Tally for [f32; 3] {
    type Sum = [f64; 3];
    const SCORES_PHASE: bool = false;

    #[inline]
    fn add_to(&self, sum: &mut [f64; 3]) {
        for (s, v) in sum.iter_mut().zip(self) {
            *s += *v as f64;
        }
    }

    #[inline]
    fn record(&mut self, c: [f32; 3], _score: PathScore, _st: &[f32; 3], _al: &[f32; 3]) {
        for (l, c) in self.iter_mut().zip(c) {
            *l += c;
        }
    }

    #[inline]
    fn finish(&mut self) {
        for v in self {
            if !v.is_finite() {
                *v = 0.0;
            }
        }
    }
}
