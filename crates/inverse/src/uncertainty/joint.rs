//! The covariance of a recovery that also frees the phase function's g.
//!
//! With g free the channels are no longer independent: every channel's image depends on the one
//! g, so the sandwich of the module above is taken over all seven variables at once,
//!
//!   θ = (ln σ_t,R, α_R, ln σ_t,G, α_G, ln σ_t,B, α_B, g),
//!
//! where the pixel row of channel c has three non-zero entries, J = (σ_t,c·∂I_c/∂σ_t,c at 2c,
//! ∂I_c/∂α_c at 2c + 1, ∂I_c/∂g at 6). A, B, d, C_opt and C_drift are as in the per-channel case
//! (White 1980's sandwich with the views as clusters, the model's common brightness error along
//! d = A⁻¹ Σ J I, the spread and drift of the last iterates), now 7 × 7. Each channel's
//! (ln σ_t, α) block of the result is that channel's marginal covariance, g's uncertainty
//! included; the last diagonal entry is g's variance. A fixed σ_t or α is conditioned on (its
//! rows and columns left out before A is inverted), as in [`super::Accumulator::covariance_fixed`].

use nalgebra::{DMatrix, DVector};
use scene::Image;

use super::ViewRenders;
use crate::params::Params;

/// The number of joint variables.
pub const N: usize = 7;
/// The index of g among them.
pub const G: usize = 6;

/// A symmetric 7 × 7 matrix over θ.
pub type Joint = [[f64; N]; N];

/// Sums over the views of the joint sandwich.
#[derive(Clone, Debug)]
pub struct JointAccumulator {
    a: Joint,
    /// g_v per view.
    g: Vec<[f64; N]>,
    /// Σ_p J_p I_p.
    ji: [f64; N],
}

impl Default for JointAccumulator {
    fn default() -> Self {
        Self {
            a: [[0.0; N]; N],
            g: Vec::new(),
            ji: [0.0; N],
        }
    }
}

impl JointAccumulator {
    /// Adds one view at σ_t = `sigma_t`, with the ∂I/∂g images `d_g` of the same two renders
    /// as `r`'s.
    pub fn add_view(&mut self, r: &ViewRenders, d_g: [&Image; 2], sigma_t: [f64; 3]) {
        let mut gv = [0.0; N];
        let mut a = [[0.0; N]; N];
        for p in 0..r.target.data.len() {
            for c in 0..3 {
                let idx = [2 * c, 2 * c + 1, G];
                let j = |k: usize| {
                    [
                        sigma_t[c] * r.d_sigma_t[k].data[p][c] as f64,
                        r.d_albedo[k].data[p][c] as f64,
                        d_g[k].data[p][c] as f64,
                    ]
                };
                let (j1, j2) = (j(0), j(1));
                let [v1, v2] = [0, 1].map(|k| r.value[k].data[p][c] as f64);
                let res = 0.5 * (v1 + v2) - r.target.data[p][c] as f64;
                if !(res.is_finite() && j1.iter().chain(&j2).all(|x| x.is_finite())) {
                    continue;
                }
                for x in 0..3 {
                    for y in 0..3 {
                        a[idx[x]][idx[y]] += 0.5 * (j1[x] * j2[y] + j2[x] * j1[y]);
                    }
                    gv[idx[x]] += 0.5 * (j1[x] + j2[x]) * res;
                    self.ji[idx[x]] += 0.5 * (j1[x] * v2 + j2[x] * v1);
                }
            }
        }
        for (row, add) in self.a.iter_mut().zip(&a) {
            for (v, d) in row.iter_mut().zip(add) {
                *v += d;
            }
        }
        self.g.push(gv);
    }

    /// A⁻¹BA⁻¹ + s_b²·d dᵀ over the variables the run moves (`fixed`: [σ_t, α]; their rows and
    /// columns are 0), or `None` with fewer than two views or where A is not positive definite
    /// over them.
    pub fn covariance(&self, model_brightness_sd: f64, fixed: [bool; 2]) -> Option<Joint> {
        let v = self.g.len();
        if v < 2 {
            return None;
        }
        let free: Vec<usize> = (0..N).filter(|&i| i == G || !fixed[i % 2]).collect();
        let n = free.len();
        let a = DMatrix::from_fn(n, n, |i, j| self.a[free[i]][free[j]]);
        if a.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let s = a.cholesky()?.inverse();
        let mean: Vec<f64> = free
            .iter()
            .map(|&i| self.g.iter().map(|g| g[i]).sum::<f64>() / v as f64)
            .collect();
        let mut b = DMatrix::zeros(n, n);
        for g in &self.g {
            let d = DVector::from_fn(n, |i, _| g[free[i]] - mean[i]);
            b += &d * d.transpose();
        }
        b *= v as f64 / (v as f64 - 1.0);
        let d = &s * DVector::from_fn(n, |i, _| self.ji[free[i]]);
        let m = &s * b * &s + model_brightness_sd.powi(2) * &d * d.transpose();
        let mut out = [[0.0; N]; N];
        for (i, &fi) in free.iter().enumerate() {
            for (j, &fj) in free.iter().enumerate() {
                out[fi][fj] = m[(i, j)];
            }
        }
        out.iter().flatten().all(|x| x.is_finite()).then_some(out)
    }
}

/// θ of `p` (its g 0 where it has none).
fn theta(p: &Params) -> [f64; N] {
    let mut x = [0.0; N];
    for c in 0..3 {
        x[2 * c] = p.sigma_t[c].ln();
        x[2 * c + 1] = p.albedo[c];
    }
    x[G] = p.g.unwrap_or(0.0);
    x
}

/// The covariance of the iterates `params` over θ (C_opt).
pub fn iterate_covariance(params: &[Params]) -> Joint {
    let n = params.len();
    let mut out = [[0.0; N]; N];
    if n < 2 {
        return out;
    }
    let x: Vec<[f64; N]> = params.iter().map(theta).collect();
    let m: [f64; N] = std::array::from_fn(|k| x.iter().map(|v| v[k]).sum::<f64>() / n as f64);
    for v in &x {
        for i in 0..N {
            for j in 0..N {
                out[i][j] += (v[i] - m[i]) * (v[j] - m[j]) / (n as f64 - 1.0);
            }
        }
    }
    out
}

/// The drift of the iterates `params` over θ as d dᵀ, d the mean of their second half minus
/// that of their first (C_drift).
pub fn iterate_drift(params: &[Params]) -> Joint {
    let n = params.len();
    let mut out = [[0.0; N]; N];
    if n < 2 {
        return out;
    }
    let (first, second) = params.split_at(n / 2);
    let mean = |part: &[Params]| -> [f64; N] {
        let x: Vec<[f64; N]> = part.iter().map(theta).collect();
        std::array::from_fn(|k| x.iter().map(|v| v[k]).sum::<f64>() / x.len() as f64)
    };
    let (a, b) = (mean(first), mean(second));
    let d: [f64; N] = std::array::from_fn(|k| b[k] - a[k]);
    for i in 0..N {
        for j in 0..N {
            out[i][j] = d[i] * d[j];
        }
    }
    out
}

/// The sum of two joint covariances.
pub fn add(a: &Joint, b: &Joint) -> Joint {
    std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] + b[i][j]))
}

/// Each channel's (ln σ_t, α) block as [c00, c01, c11], and g's variance.
pub fn blocks(m: &Joint) -> ([[f64; 3]; 3], f64) {
    let ch = std::array::from_fn(|c| {
        let (s, a) = (2 * c, 2 * c + 1);
        [m[s][s], m[s][a], m[a][a]]
    });
    (ch, m[G][G])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uncertainty::Accumulator;

    /// Renders of a linear model I_c = J_c·θ with known Jacobians and independent target noise
    /// per view: where ∂I/∂g is zero the joint blocks equal the per-channel sandwich (g then
    /// has no information and A is singular, so g is left out by giving it its own pixels);
    /// and g's variance is B_gg/A_gg² for a g constrained by pixels of its own.
    #[test]
    fn with_g_decoupled_the_blocks_are_the_per_channel_sandwich() {
        let (w, h) = (8u32, 8u32);
        let mut rng = base::rng::Sampler::new(5, 0, 0, 0);
        let mut joint = JointAccumulator::default();
        let mut per_channel = Accumulator::default();
        let sigma_t = [40.0, 60.0, 80.0];
        for view in 0..12 {
            let img = |f: &dyn Fn(usize, usize) -> f32| {
                let mut im = Image::new(w, h);
                for (p, px) in im.data.iter_mut().enumerate() {
                    *px = std::array::from_fn(|c| f(p, c));
                }
                im
            };
            // Pixels 0..32 see σ_t and α; pixels 32..64 see g alone.
            let lower = |p: usize| p < 32;
            let d_sigma_t = img(&|p, c| {
                if lower(p) {
                    (0.002 * (1 + p % 5 + c) as f64) as f32
                } else {
                    0.0
                }
            });
            let d_albedo = img(&|p, c| {
                if lower(p) {
                    (0.3 + 0.1 * ((p + c) % 3) as f64) as f32
                } else {
                    0.0
                }
            });
            let d_g = img(&|p, _| if lower(p) { 0.0 } else { 0.5 });
            let value = img(&|p, c| 0.1 + 0.01 * ((p + c + view) % 7) as f32);
            let noise: Vec<f32> = (0..3 * value.data.len())
                .map(|_| 0.01 * (rng.next_f32() - 0.5))
                .collect();
            let target = img(&|p, c| value.data[p][c] + noise[3 * p + c]);
            let r = ViewRenders {
                value: [&value, &value],
                d_sigma_t: [&d_sigma_t, &d_sigma_t],
                d_albedo: [&d_albedo, &d_albedo],
                target: &target,
            };
            joint.add_view(&r, [&d_g, &d_g], sigma_t);
            per_channel.add_view(&r, sigma_t);
        }
        let m = joint
            .covariance(0.03, [false, false])
            .expect("positive definite");
        let (ch, var_g) = blocks(&m);
        let want = per_channel.covariance(0.03);
        for c in 0..3 {
            let want = want[c].expect("per-channel");
            for k in 0..3 {
                // The brightness term couples the blocks through d; with d_g = 0 on the σ_t/α
                // pixels that coupling is exact, so the blocks agree to rounding.
                assert!(
                    (ch[c][k] - want[k]).abs() <= 1e-9 * want[0].abs().max(want[2].abs()),
                    "channel {c}, entry {k}: {} vs {}",
                    ch[c][k],
                    want[k]
                );
            }
        }
        assert!(var_g > 0.0 && var_g.is_finite());
        // Fixing σ_t conditions on it, as the per-channel sandwich does.
        let f = joint.covariance(0.03, [true, false]).unwrap();
        let want = per_channel.covariance_fixed(0.03, [true, false]);
        for c in 0..3 {
            assert_eq!(f[2 * c][2 * c], 0.0);
            let want = want[c].unwrap()[2];
            let got = f[2 * c + 1][2 * c + 1];
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "channel {c}: {got} vs {want}"
            );
        }
    }

    /// The iterates' covariance and drift include g as the seventh variable.
    #[test]
    fn the_iterates_spread_includes_g() {
        let it: Vec<Params> = (0..10)
            .map(|k| Params {
                g: Some(0.5 + 0.01 * k as f64),
                ..Params::new([50.0; 3], [0.9; 3])
            })
            .collect();
        let c = iterate_covariance(&it);
        let d = iterate_drift(&it);
        assert!(
            (c[G][G] - 0.01f64.powi(2) * 55.0 / 6.0).abs() < 1e-12,
            "{}",
            c[G][G]
        );
        assert!((d[G][G] - 0.05f64.powi(2)).abs() < 1e-12, "{}", d[G][G]);
        assert!(c[0][0].abs() < 1e-20, "{}", c[0][0]);
    }
}
