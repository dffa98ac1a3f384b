//! The light scale profiled out of the loss ([`crate::params::LightScaleFit::Profile`]).
//!
//! The images are linear in a factor k on the lights: I = k·I₁. For the L2 loss
//! ℓ(k) = Σ_v Σ_p w_v (k·I₁ − T)², the optimum at the current σ_t and α is
//!
//!   k* = Σ w T·I₁ / Σ w I₁² = k · Σ w T·I / Σ w I²   (I rendered with the current k),
//!
//! per channel for a factor per channel, over the channels for one factor. σ_t and α that
//! descend ℓ(θ, k*(θ)) see ∂ℓ/∂θ at fixed k (∂ℓ/∂k = 0 at k*): variable projection (Golub and
//! Pereyra 1973). The brightness is then never what the fit of σ_t and α has to make up for.
//!
//! Each iteration sees one view (or a few), and a render is noisy, so:
//!
//! * Σ I² comes from the cross product of the two independent renders of the split-sample
//!   gradient, Σ I_a·I_b, whose expectation is Σ E[I]² (Σ I_a² would add the render's variance
//!   and bias k* low); Σ T·I from their mean;
//! * one iteration's match moves ln k only part of the way, ln k ← ln k + β·ln(Σ w T·I / Σ w I²)
//!   with β = [`PROFILE_RATE`]: an exponential average of the views' matches over about
//!   2/β − 1 iterations. Where a view's model errs in brightness (the learned model, by a few per
//!   cent view to view), the average is over views, as the loss's optimum is.
//!
//! Pixels outside the measurement render black and add nothing to either sum.

use scene::Image;

/// The share of one iteration's brightness match that ln k takes (the exponential average's
/// weight): an average over about 19 iterations' views.
pub const PROFILE_RATE: f64 = 0.1;

/// The sums of one iteration's brightness match, per channel, weighted as the loss is.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BrightnessMatch {
    /// Σ w T·I: the targets against the render (mean of the two renders).
    pub target_dot_render: [f64; 3],
    /// Σ w I²: the render's square, from the product of two independent renders.
    pub render_sq: [f64; 3],
}

impl BrightnessMatch {
    /// The sums of one view from its two independent renders `a`, `b` (of the same view, the
    /// same light and the same k) against `target`, unweighted.
    pub fn of_renders(a: &Image, b: &Image, target: &Image) -> Self {
        let mut m = Self::default();
        for ((x, y), t) in a.data.iter().zip(&b.data).zip(&target.data) {
            for ch in 0..3 {
                let (x, y, t) = (x[ch] as f64, y[ch] as f64, t[ch] as f64);
                m.target_dot_render[ch] += t * 0.5 * (x + y);
                m.render_sq[ch] += x * y;
            }
        }
        m
    }

    /// Adds `other` with the per-channel weights `w`.
    pub fn add_weighted(&mut self, other: &Self, w: [f64; 3]) {
        for ch in 0..3 {
            self.target_dot_render[ch] += w[ch] * other.target_dot_render[ch];
            self.render_sq[ch] += w[ch] * other.render_sq[ch];
        }
    }

    /// ln(k*/k) per channel (`per_channel`) or, for one factor, the same value in every entry
    /// from the sums over the channels; `None` for a channel (or the factor) whose sums do not
    /// define a match (a view that renders black, or a cross product that noise made ≤ 0).
    pub fn ln_ratio(&self, per_channel: bool) -> [Option<f64>; 3] {
        let ratio = |num: f64, den: f64| {
            let r = (num / den).ln();
            (num > 0.0 && den > 0.0 && r.is_finite()).then_some(r)
        };
        if per_channel {
            std::array::from_fn(|ch| ratio(self.target_dot_render[ch], self.render_sq[ch]))
        } else {
            let r = ratio(
                self.target_dot_render.iter().sum(),
                self.render_sq.iter().sum(),
            );
            [r; 3]
        }
    }

    /// Moves the ln k variables `ln_k` (one, or three per channel) a share `rate` of the way to
    /// this match.
    pub fn step(&self, ln_k: &mut [f32], rate: f64) {
        let r = self.ln_ratio(ln_k.len() == 3);
        for (v, r) in ln_k.iter_mut().zip(r) {
            if let Some(r) = r {
                *v = (*v as f64 + rate * r) as f32;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use base::rng::Sampler;

    /// Two noisy renders of an image whose mean is the target over k_true: the match's ratio
    /// estimates k_true without the bias a render's own square gives (E[I²] = E[I]² + Var),
    /// checked over 40 000 pixels against its delta-method standard error.
    #[test]
    fn the_match_is_unbiased_by_the_render_noise() {
        let (w, h) = (200u32, 200u32);
        let mut rng = Sampler::new(3, 0, 0, 0);
        let mut normal = || {
            let u1 = (rng.next_f32() as f64).max(1e-12);
            let u2 = rng.next_f32() as f64;
            ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
        };
        let k_true = [2.0f32, 1.0, 0.5];
        let (mut t, mut a, mut b) = (Image::new(w, h), Image::new(w, h), Image::new(w, h));
        let sd = 0.3f32;
        for i in 0..t.data.len() {
            // A spread of brightness over the image, so the match weighs bright pixels more.
            let mean = 0.2 + 0.6 * (i % 97) as f32 / 96.0;
            for ch in 0..3 {
                t.data[i][ch] = k_true[ch] * mean;
                a.data[i][ch] = mean + sd * normal();
                b.data[i][ch] = mean + sd * normal();
            }
        }
        let m = BrightnessMatch::of_renders(&a, &b, &t);
        let r = m.ln_ratio(true);
        let n = t.data.len() as f64;
        // ln(ΣTI/ΣI_aI_b): relative sd of the numerator ≈ sd/(√2·rms·√n), of the denominator
        // ≈ √2·sd/(rms·√n) (rms of the means ≈ 0.55); together about 1.6·sd/(0.55·√n).
        let se = 1.6 * sd as f64 / (0.55 * n.sqrt());
        for ch in 0..3 {
            let got = r[ch].unwrap();
            let want = (k_true[ch] as f64).ln();
            assert!((got - want).abs() < 4.0 * se, "channel {ch}: {got} vs {want} ± {se}");
        }
        // A render's own square is biased low by Var/E[I]² ≈ 0.09/0.33 ≈ 27 %: the test sees it.
        let own = BrightnessMatch::of_renders(&a, &a, &t).ln_ratio(true);
        assert!((own[1].unwrap() - 0.0).abs() > 20.0 * se);
        // One factor: the sums over the channels, the same ratio in every entry.
        let one = m.ln_ratio(false);
        assert!(one.iter().all(|r| *r == one[0]) && one[0].is_some());
    }

    /// A black view defines no match and leaves k where it is; a step moves ln k a share of
    /// the way.
    #[test]
    fn a_black_view_leaves_k_alone() {
        let t = Image::new(4, 4);
        let m = BrightnessMatch::of_renders(&t, &t, &t);
        assert_eq!(m.ln_ratio(true), [None; 3]);
        let mut ln_k = [0.3f32];
        m.step(&mut ln_k, PROFILE_RATE);
        assert_eq!(ln_k, [0.3]);
        let m = BrightnessMatch {
            target_dot_render: [2.0; 3],
            render_sq: [1.0; 3],
        };
        let mut ln_k = [0.0f32; 3];
        m.step(&mut ln_k, 0.5);
        for v in ln_k {
            assert!((v as f64 - 0.5 * 2f64.ln()).abs() < 1e-6);
        }
    }
}
