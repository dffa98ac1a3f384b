//! How much the images themselves change along the σ_t valley, measured with the volumetric
//! path tracer, against how much the learned model says they change.
//!
//! The intervals of [`crate::uncertainty`] take the loss's curvature from the learned model's
//! derivative images. Where the images barely constrain σ_t (a light at the camera trades σ_t
//! against α), the learned model can still be curved along that valley, since its error is not
//! the same at every σ_t: its interval is then narrow although the images would accept a medium
//! far away (measured: a flash capture whose estimate is 34 % off in σ_t, reported as
//! determined, while the volumetric path tracer renders the estimate within the targets' noise).
//!
//! Per channel c, with the valley's slope s_c = dα/d ln σ_t = −a01/a11 of the learned model's
//! Gauss–Newton A (α refitted as σ_t moves), the direction is u = (1, s_c) in (ln σ_t, α) and
//!
//!   learned curvature   k_L = uᵀ A u = a00 + 2 s a01 + s² a11, summed over the checked views;
//!   the tracer's        k_V = Σ_p (∂I_p/∂u)²,
//!
//! estimated without bias from two independent renders with derivatives
//! ([`volpath::render_derivatives`], the analytic derivative of each path): with
//! J_p = σ_t ∂I_p/∂σ_t + s ∂I_p/∂α = ∂I_p/∂u from seed 1 and seed 2, E[J¹_p J²_p] = (E J_p)², so
//! k̂_V = Σ_p J¹_p J²_p (Σ J² alone would add each pixel's variance). Its standard error is at
//! most √(Σ_p (J¹_p J²_p)²) (the second moment bounds the variance). The ratio used is
//! ρ = k_L / (k̂_V − 2·se), at least 1 and at most [`MAX_RATIO`]: the lower end of the tracer's
//! curvature, so a valley the tracer cannot tell from flat widens the interval the most.
//! [`crate::uncertainty::Uncertainty::with_sensitivity`] multiplies the profile variance of
//! ln σ_t by ρ.
//!
//! Measured against the central differences this replaced (two pairs of renders at θ ± δu,
//! δ = 0.1 in ln σ_t): half the renders, no step (which had to shrink where α neared 1, and
//! the noise with it), and standard errors 2–35× smaller on the robustness suite's cases
//! (docs/notes/uncertainty.md, item 5).

use crate::consistency::CheckView;
use crate::error::InverseError;
use geometry::Accel;
use scene::{Image, Medium};
use serde::{Deserialize, Serialize};

/// The largest widening of the ln σ_t variance (its standard deviation × 10).
pub const MAX_RATIO: f64 = 100.0;
/// Where α lies this close to 0 or 1 the direction is σ_t alone (the valley would leave [0, 1]).
pub const ALBEDO_MARGIN: f64 = 1e-3;

/// The measured sensitivity along the σ_t valley, per channel (module docs).
///
/// Where α lies at its bound ([`ALBEDO_MARGIN`]) the direction is σ_t alone (`slope` 0 in that
/// channel).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sensitivity {
    /// s: dα/d ln σ_t along the valley.
    pub slope: [f64; 3],
    /// k_L, the learned model's curvature along u over the checked views.
    pub learned: [f64; 3],
    /// k̂_V, the volumetric path tracer's, over the same views.
    pub volpath: [f64; 3],
    /// Its standard error (an upper bound).
    pub volpath_se: [f64; 3],
    /// ρ, the factor on the profile variance of ln σ_t (1: the learned model is not too sure).
    pub ratio: [f64; 3],
    /// The dataset views checked.
    pub views: Vec<usize>,
    /// Samples per pixel of each render.
    pub spp: u32,
}

/// The valley's slope s = −a01/a11 per channel of a bread A ([a00, a01, a11] per channel).
pub fn valley_slope(a: &[[f64; 3]; 3]) -> [f64; 3] {
    std::array::from_fn(|c| {
        let [_, a01, a11] = a[c];
        let s = -a01 / a11;
        if s.is_finite() { s } else { 0.0 }
    })
}

/// Measures the sensitivity at `medium` on `views`, each with the learned model's bread of that
/// view (`breads[i]` for `views[i]`), along the valleys of slope `slope`, with the tracer at
/// `spp` and the targets' path depth `max_depth`.
#[allow(clippy::too_many_arguments)]
pub fn measure(
    accel: &Accel,
    medium: &Medium,
    views: &[CheckView],
    breads: &[[[f64; 3]; 3]],
    slope: [f64; 3],
    spp: u32,
    max_depth: u32,
    seed: u64,
) -> Result<Sensitivity, InverseError> {
    assert_eq!(views.len(), breads.len(), "one bread per view");
    let slope: [f64; 3] = std::array::from_fn(|c| {
        let a = medium.albedo[c] as f64;
        if (ALBEDO_MARGIN..=1.0 - ALBEDO_MARGIN).contains(&a) {
            slope[c]
        } else {
            0.0
        }
    });
    let (volpath, volpath_se) =
        tracer_curvature(accel, medium, views, slope, spp, max_depth, seed)?;
    let learned: [f64; 3] = std::array::from_fn(|c| {
        let s = slope[c];
        breads
            .iter()
            .map(|a| {
                let [a00, a01, a11] = a[c];
                a00 + 2.0 * s * a01 + s * s * a11
            })
            .sum()
    });
    Ok(Sensitivity {
        ratio: std::array::from_fn(|c| widening(learned[c], volpath[c], volpath_se[c])),
        slope,
        learned,
        volpath,
        volpath_se,
        views: views.iter().map(|v| v.index).collect(),
        spp,
    })
}

/// The tracer's curvature k̂_V along the valleys of slope `slope` at `medium` from its
/// derivative images ([`volpath::render_derivatives`]): two independent renders per view give
/// J¹_p, J²_p with J = σ_t ∂I/∂σ_t + s ∂I/∂α = ∂I/∂u, and k̂_V = Σ_p J¹_p J²_p is unbiased
/// for Σ_p (∂I_p/∂u)² (E\[J¹J²\] = (E J)²), with no step and no finite-difference error. Returns
/// (k̂_V, its standard error bound √Σ(J¹J²)²) per channel.
pub fn tracer_curvature(
    accel: &Accel,
    medium: &Medium,
    views: &[CheckView],
    slope: [f64; 3],
    spp: u32,
    max_depth: u32,
    seed: u64,
) -> Result<([f64; 3], [f64; 3]), InverseError> {
    let mut sums = ProductSums::default();
    for v in views {
        let along = |s: u64| {
            let d = v.trace(accel, medium, max_depth, |view, rs| {
                view.derivatives(&rs(spp, s), None)
            })?;
            let mut j = d.d_sigma_t;
            for (j, da) in j.data.iter_mut().zip(&d.d_albedo.data) {
                for c in 0..3 {
                    j[c] =
                        (medium.sigma_t[c] as f64 * j[c] as f64 + slope[c] * da[c] as f64) as f32;
                }
            }
            Ok::<_, InverseError>(j)
        };
        sums.add(&along(seed)?, &along(seed + 1)?);
    }
    Ok((sums.product, sums.square.map(f64::sqrt)))
}

/// ρ from the learned curvature `learned` and the tracer's `volpath` ± `se` (module docs).
pub fn widening(learned: f64, volpath: f64, se: f64) -> f64 {
    let low = volpath - 2.0 * se;
    if !(learned.is_finite() && low.is_finite()) || learned <= 0.0 {
        return 1.0;
    }
    if low <= 0.0 {
        return MAX_RATIO;
    }
    (learned / low).clamp(1.0, MAX_RATIO)
}

/// Σ_p J¹_p J²_p and Σ_p (J¹_p J²_p)² per channel over the pixels where both are finite.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProductSums {
    pub product: [f64; 3],
    pub square: [f64; 3],
}

impl ProductSums {
    /// Adds one view: its derivative images along u from two independent renders.
    pub fn add(&mut self, j1: &Image, j2: &Image) {
        for (a, b) in j1.data.iter().zip(&j2.data) {
            for c in 0..3 {
                let x = a[c] as f64 * b[c] as f64;
                if x.is_finite() {
                    self.product[c] += x;
                    self.square[c] += x * x;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use base::rng::Sampler;

    fn gauss(rng: &mut Sampler) -> f64 {
        let (u1, u2) = (rng.next_f32().max(1e-7) as f64, rng.next_f32() as f64);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Derivative images J = g + independent noise per pixel: k̂_V estimates Σ g² without the
    /// noise's bias (Σ J² alone would add Var per pixel), within 3 of its standard errors, and
    /// the standard error bounds the estimate's spread over 200 trials.
    #[test]
    fn the_product_of_two_renders_is_unbiased_for_the_squared_derivative() {
        let (n, noise) = (2000usize, 0.5);
        let mut rng = Sampler::new(7, 8, 9, 10);
        let g: Vec<f64> = (0..n)
            .map(|i| 0.2 + 0.1 * ((i % 13) as f64 / 13.0))
            .collect();
        let truth: f64 = g.iter().map(|g| g * g).sum();
        let mut estimates = Vec::new();
        let mut ses = Vec::new();
        for _ in 0..200 {
            let mut img = || {
                let mut j = Image::new(n as u32, 1);
                for i in 0..n {
                    j.data[i] = [(g[i] + noise * gauss(&mut rng)) as f32; 3];
                }
                j
            };
            let (j1, j2) = (img(), img());
            let mut s = ProductSums::default();
            s.add(&j1, &j2);
            estimates.push(s.product[0]);
            ses.push(s.square[0].sqrt());
        }
        let k = estimates.len() as f64;
        let mean = estimates.iter().sum::<f64>() / k;
        let sd = (estimates.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt();
        let se_mean = sd / k.sqrt();
        assert!(
            (mean - truth).abs() < 3.0 * se_mean,
            "mean {mean} truth {truth} ± {se_mean}"
        );
        // Σ J² would be biased by noise²·n = 500, about 5.7× the truth here.
        let typical_se = ses.iter().sum::<f64>() / k;
        assert!(typical_se >= sd, "bound {typical_se} below the spread {sd}");
    }

    #[test]
    fn the_widening_is_the_curvature_ratio_at_the_tracer_s_lower_end() {
        assert_eq!(widening(10.0, 10.0, 0.0), 1.0);
        assert_eq!(widening(10.0, 20.0, 0.0), 1.0, "never narrower");
        assert!((widening(10.0, 2.0, 0.5) - 10.0).abs() < 1e-12);
        assert_eq!(
            widening(10.0, 1.0, 0.5),
            MAX_RATIO,
            "undetectable curvature"
        );
        assert_eq!(widening(1e9, 1.0, 0.0), MAX_RATIO);
        assert_eq!(widening(f64::NAN, 1.0, 0.0), 1.0);
    }

    #[test]
    fn the_slope_refits_alpha() {
        // A = J Jᵀ with J = (2, 1): moving ln σ_t by 1 and α by −2 leaves J·u = 0.
        let s = valley_slope(&[[4.0, 2.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, 0.0]]);
        assert_eq!(s, [-2.0, 0.0, 0.0]);
    }
}
