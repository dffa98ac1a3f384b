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
//! estimated without bias from two independent pairs of renders at θ ± δu (common random
//! numbers within a pair): with D¹ = I(θ + δu; seed 1) − I(θ − δu; seed 1) and D² the same with
//! seed 2, E[D¹_p D²_p] = (E D_p)², so k̂_V = Σ_p D¹_p D²_p / (2δ)² (unbiased for the central
//! difference, whose error in ∂I/∂u is O(δ²)). Its standard error is at most
//! √(Σ_p (D¹_p D²_p)²) / (2δ)² (the second moment bounds the variance). The ratio used is
//! ρ = k_L / (k̂_V − 2·se), at least 1 and at most [`MAX_RATIO`]: the lower end of the tracer's
//! curvature, so a valley the tracer cannot tell from flat widens the interval the most.
//! [`crate::uncertainty::Uncertainty::with_sensitivity`] multiplies the profile variance of
//! ln σ_t by ρ.

use crate::consistency::CheckView;
use geometry::Accel;
use scene::{Image, Medium};
use serde::{Deserialize, Serialize};
use volpath::{RenderSettings, VolpathScene, VolpathSettings, render_image, shadow_lists};

/// δ: the half-step along u, in ln σ_t (±10 % in σ_t).
pub const STEP: f64 = 0.1;
/// The largest widening of the ln σ_t variance (its standard deviation × 10).
pub const MAX_RATIO: f64 = 100.0;
/// α stays inside [ALBEDO_MARGIN, 1 − ALBEDO_MARGIN] at the two ends of the step (δ shrinks).
const ALBEDO_MARGIN: f64 = 1e-3;

/// The measured sensitivity along the σ_t valley, per channel (module docs).
///
/// Where α lies at its bound the direction is σ_t alone (`slope` 0 in that channel).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sensitivity {
    /// s: dα/d ln σ_t along the valley.
    pub slope: [f64; 3],
    /// δ per channel (smaller than [`STEP`] where α would leave (0, 1)).
    pub step: [f64; 3],
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
/// view (`breads[i]` for `views[i]`), along the valleys of slope `slope`.
pub fn measure(
    accel: &Accel,
    medium: &Medium,
    views: &[CheckView],
    breads: &[[[f64; 3]; 3]],
    slope: [f64; 3],
    spp: u32,
    seed: u64,
) -> Sensitivity {
    assert_eq!(views.len(), breads.len(), "one bread per view");
    // δ shrinks where α would leave (0, 1); where that leaves less than a tenth of the step
    // (α at its bound), the direction is σ_t alone.
    let mut slope = slope;
    let step: [f64; 3] = std::array::from_fn(|c| {
        let (a, s) = (medium.albedo[c] as f64, slope[c].abs());
        let room = (a - ALBEDO_MARGIN).min(1.0 - ALBEDO_MARGIN - a).max(0.0);
        if s * STEP <= room {
            STEP
        } else if room >= 0.1 * s * STEP {
            room / s
        } else {
            slope[c] = 0.0;
            STEP
        }
    });
    let shifted = |sign: f64| Medium {
        sigma_t: std::array::from_fn(|c| {
            (medium.sigma_t[c] as f64 * (sign * step[c]).exp()) as f32
        }),
        albedo: std::array::from_fn(|c| {
            (medium.albedo[c] as f64 + sign * step[c] * slope[c]) as f32
        }),
        ..*medium
    };
    let (plus, minus) = (shifted(1.0), shifted(-1.0));
    let settings = VolpathSettings::default();
    let mut sums = ProductSums::default();
    for v in views {
        let render = |m: &Medium, s: u64| {
            let mut scene = VolpathScene {
                accel,
                medium: *m,
                light: Some(*v.light),
                environment: None,
                light_bins: None,
            };
            let lists = shadow_lists(&scene, &settings);
            scene.light_bins = lists.as_ref();
            let rs = RenderSettings {
                spp,
                seed: s,
                view: v.index as u64,
            };
            render_image(&scene, &settings, v.camera, &rs, None)
        };
        let pair = |s: u64| [render(&plus, s), render(&minus, s)];
        let ([p1, m1], [p2, m2]) = (pair(seed), pair(seed + 1));
        sums.add(&p1, &m1, &p2, &m2);
    }
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
    let d2 = step.map(|d| 4.0 * d * d);
    let volpath: [f64; 3] = std::array::from_fn(|c| sums.product[c] / d2[c]);
    let volpath_se: [f64; 3] = std::array::from_fn(|c| sums.square[c].sqrt() / d2[c]);
    Sensitivity {
        ratio: std::array::from_fn(|c| widening(learned[c], volpath[c], volpath_se[c])),
        slope,
        step,
        learned,
        volpath,
        volpath_se,
        views: views.iter().map(|v| v.index).collect(),
        spp,
    }
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

/// Σ_p D¹_p D²_p and Σ_p (D¹_p D²_p)² per channel over the pixels where all four renders are
/// finite.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProductSums {
    pub product: [f64; 3],
    pub square: [f64; 3],
}

impl ProductSums {
    /// Adds one view: renders at θ + δu and θ − δu with seed 1 (`p1`, `m1`) and seed 2.
    pub fn add(&mut self, p1: &Image, m1: &Image, p2: &Image, m2: &Image) {
        for i in 0..p1.data.len() {
            for c in 0..3 {
                let d1 = p1.data[i][c] as f64 - m1.data[i][c] as f64;
                let d2 = p2.data[i][c] as f64 - m2.data[i][c] as f64;
                let x = d1 * d2;
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
    use volpath::rng::Sampler;

    fn gauss(rng: &mut Sampler) -> f64 {
        let (u1, u2) = (rng.next_f32().max(1e-7) as f64, rng.next_f32() as f64);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Images I(θ ± δ) = b + (±δ)·g per pixel plus independent noise: k̂_V estimates Σ g²
    /// without the noise's bias (Σ D² alone would add 2·Var per pixel), within 3 of its
    /// standard errors, and the standard error bounds the estimate's spread over 200 trials.
    #[test]
    fn the_product_of_two_pairs_is_unbiased_for_the_squared_derivative() {
        let (n, delta, noise) = (2000usize, 0.1, 0.05);
        let mut rng = Sampler::new(7, 8, 9, 10);
        let g: Vec<f64> = (0..n)
            .map(|i| 0.2 + 0.1 * ((i % 13) as f64 / 13.0))
            .collect();
        let truth: f64 = g.iter().map(|g| g * g).sum();
        let mut estimates = Vec::new();
        let mut ses = Vec::new();
        for _ in 0..200 {
            let mut img = || {
                let mut p = Image::new(n as u32, 1);
                let mut m = Image::new(n as u32, 1);
                for i in 0..n {
                    let e = [gauss(&mut rng), gauss(&mut rng)].map(|e| (noise * e) as f32);
                    p.data[i] = [(1.0 + delta * g[i]) as f32 + e[0]; 3];
                    m.data[i] = [(1.0 - delta * g[i]) as f32 + e[1]; 3];
                }
                (p, m)
            };
            let ((p1, m1), (p2, m2)) = (img(), img());
            let mut s = ProductSums::default();
            s.add(&p1, &m1, &p2, &m2);
            let d2 = 4.0 * delta * delta;
            estimates.push(s.product[0] / d2);
            ses.push(s.square[0].sqrt() / d2);
        }
        let k = estimates.len() as f64;
        let mean = estimates.iter().sum::<f64>() / k;
        let sd = (estimates.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt();
        let se_mean = sd / k.sqrt();
        assert!(
            (mean - truth).abs() < 3.0 * se_mean,
            "mean {mean} truth {truth} ± {se_mean}"
        );
        // Σ D² / (2δ)² would be biased by 2·noise²·n/(2δ)² = 250 ≈ 2.7× the truth here.
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
