//! The covariance of a recovery that also frees parameters shared by the channels: the phase
//! function's g, a factor k on the lights (or one factor k_c per channel: it is not shared, but
//! it trades against that channel's α, so it joins the same sandwich).
//!
//! With a shared parameter free the channels are no longer independent: every channel's image
//! depends on it, so the sandwich of the module above is taken over all variables at once,
//!
//!   θ = (ln σ_t,R, α_R, ln σ_t,G, α_G, ln σ_t,B, α_B, s_1, …, s_m),
//!
//! s_j the shared ones (g; ln k), where the pixel row of channel c has 2 + m entries,
//! J = (σ_t,c·∂I_c/∂σ_t,c at 2c, ∂I_c/∂α_c at 2c + 1, ∂I_c/∂s_j at 6 + j; ∂I/∂ln k = I, and
//! ∂I_c/∂ln k_c' = δ_cc'·I_c for a per-channel factor).
//! A, B, d, C_opt and C_drift are as in the per-channel case (White 1980's sandwich with the
//! views as clusters, the model's common brightness error along d = A⁻¹ Σ J I, the spread and
//! drift of the last iterates), now (6 + m) × (6 + m). Each channel's (ln σ_t, α) block of the
//! result is that channel's marginal covariance, the shared parameters' uncertainty included;
//! the last diagonal entries are their variances. A fixed σ_t or α is conditioned on (its rows
//! and columns left out before A is inverted), as in [`super::Accumulator::covariance_fixed`].
//! A shared parameter's interval and *determined* flag are a [`SharedUncertainty`].

use nalgebra::{DMatrix, DVector};
use scene::Image;

use super::{DETERMINED_G_HALF_WIDTH, DETERMINED_SIGMA_T_RATIO, ViewRenders, Z95};
use crate::params::Params;
use serde::{Deserialize, Serialize};

/// A symmetric matrix over θ.
pub type Joint = DMatrix<f64>;

/// A shared parameter of θ ([`theta`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shared {
    /// The phase function's g: every channel's (`None`), or channel c's alone (`Some(c)`, one
    /// g per channel).
    G(Option<usize>),
    /// ln k of the factor k on the lights: every channel's (`None`), or channel c's alone
    /// (`Some(c)`, one factor per channel).
    LnLightScale(Option<usize>),
}

impl Shared {
    /// Whether channel `c`'s images depend on it.
    pub fn acts_on(self, c: usize) -> bool {
        match self {
            Shared::G(Some(k)) | Shared::LnLightScale(Some(k)) => k == c,
            _ => true,
        }
    }
}

/// Sums over the views of the joint sandwich.
#[derive(Clone, Debug)]
pub struct JointAccumulator {
    shared: Vec<Shared>,
    a: Joint,
    /// g_v per view, from each render's values and the other's derivatives ([`super::meat`]).
    g: [Vec<DVector<f64>>; 2],
    /// Σ_p J_p I_p.
    ji: DVector<f64>,
    /// Σ_p J_p δI_p of each draw of a stated capture error ([`super::capture`]).
    pub(super) capture: Vec<DVector<f64>>,
}

impl JointAccumulator {
    /// The sums over θ with the shared parameters `shared`, in that order.
    pub fn new(shared: Vec<Shared>) -> Self {
        let n = 6 + shared.len();
        Self {
            shared,
            a: DMatrix::zeros(n, n),
            g: [Vec::new(), Vec::new()],
            ji: DVector::zeros(n),
            capture: Vec::new(),
        }
    }

    /// The shared parameters, in θ's order.
    pub fn shared(&self) -> &[Shared] {
        &self.shared
    }

    /// The number of variables.
    pub fn len(&self) -> usize {
        6 + self.shared.len()
    }

    /// Always false: θ has at least six variables.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Adds one view at σ_t = `sigma_t`, with the derivative images of the shared parameters
    /// `d_shared` (one pair per shared parameter, of the same two renders as `r`'s; the value
    /// images for ln k).
    pub fn add_view(&mut self, r: &ViewRenders, d_shared: &[[&Image; 2]], sigma_t: [f64; 3]) {
        let n = self.len();
        assert_eq!(
            d_shared.len(),
            self.shared.len(),
            "one image pair per shared parameter"
        );
        let mut gv = [DVector::zeros(n), DVector::zeros(n)];
        let mut a = DMatrix::zeros(n, n);
        let mut idx = vec![0; n - 4];
        let (mut j1, mut j2) = (vec![0.0; n - 4], vec![0.0; n - 4]);
        for p in 0..r.target.data.len() {
            for c in 0..3 {
                idx[0] = 2 * c;
                idx[1] = 2 * c + 1;
                for (j, k) in idx[2..].iter_mut().enumerate() {
                    *k = 6 + j;
                }
                for (k, row) in [&mut j1, &mut j2].into_iter().enumerate() {
                    row[0] = sigma_t[c] * r.d_sigma_t[k].data[p][c] as f64;
                    row[1] = r.d_albedo[k].data[p][c] as f64;
                    for (j, (d, s)) in d_shared.iter().zip(&self.shared).enumerate() {
                        row[2 + j] = if s.acts_on(c) {
                            d[k].data[p][c] as f64
                        } else {
                            0.0
                        };
                    }
                }
                let [v1, v2] = [0, 1].map(|k| r.value[k].data[p][c] as f64);
                let t = r.target.data[p][c] as f64;
                let (r1, r2) = (v1 - t, v2 - t);
                if !(r1.is_finite()
                    && r2.is_finite()
                    && j1.iter().chain(&j2).all(|x| x.is_finite()))
                {
                    continue;
                }
                for x in 0..idx.len() {
                    for y in 0..idx.len() {
                        a[(idx[x], idx[y])] += 0.5 * (j1[x] * j2[y] + j2[x] * j1[y]);
                    }
                    gv[0][idx[x]] += j2[x] * r1;
                    gv[1][idx[x]] += j1[x] * r2;
                    self.ji[idx[x]] += 0.5 * (j1[x] * v2 + j2[x] * v1);
                }
            }
        }
        self.a += a;
        for (all, view) in self.g.iter_mut().zip(gv) {
            all.push(view);
        }
    }

    /// A⁻¹BA⁻¹ + C_step + s_b²·d dᵀ (+ C_capture, [`super::capture`]; B and C_step:
    /// [`super::meat`]) over the variables the run moves (`fixed`: [σ_t, α]; their rows and
    /// columns are 0), or `None` with fewer than two views or where A is not positive definite
    /// over them.
    pub fn covariance(&self, model_brightness_sd: f64, fixed: [bool; 2]) -> Option<Joint> {
        let v = self.g[0].len();
        let n_all = self.len();
        if v < 2 {
            return None;
        }
        let free: Vec<usize> = (0..n_all).filter(|&i| i >= 6 || !fixed[i % 2]).collect();
        let n = free.len();
        let a = DMatrix::from_fn(n, n, |i, j| self.a[(free[i], free[j])]);
        if a.iter().any(|x| !x.is_finite()) {
            return None;
        }
        let s = a.cholesky()?.inverse();
        let [g1, g2] = [0, 1].map(|k| {
            self.g[k]
                .iter()
                .map(|g| DVector::from_fn(n, |i, _| g[free[i]]))
                .collect::<Vec<_>>()
        });
        let b = super::meat::cross_meat(&g1, &g2)?;
        let step = super::meat::remaining_step(&s, &g1, &g2);
        let d = &s * DVector::from_fn(n, |i, _| self.ji[free[i]]);
        let mut m = &s * b * &s + step + model_brightness_sd.powi(2) * &d * d.transpose();
        for shift in &self.capture {
            let d = &s * DVector::from_fn(n, |i, _| shift[free[i]]);
            m += &d * d.transpose() / self.capture.len() as f64;
        }
        let mut out = DMatrix::zeros(n_all, n_all);
        for (i, &fi) in free.iter().enumerate() {
            for (j, &fj) in free.iter().enumerate() {
                out[(fi, fj)] = m[(i, j)];
            }
        }
        out.iter().all(|x| x.is_finite()).then_some(out)
    }
}

/// θ of `p` with the shared parameters `shared` (g 0 and k 1 where `p` has none).
pub fn theta(p: &Params, shared: &[Shared]) -> DVector<f64> {
    let mut x = DVector::zeros(6 + shared.len());
    for c in 0..3 {
        x[2 * c] = p.sigma_t[c].ln();
        x[2 * c + 1] = p.albedo[c];
    }
    for (j, s) in shared.iter().enumerate() {
        x[6 + j] = match s {
            Shared::G(c) => p.g.map_or(0.0, |g| g.channel(c.unwrap_or(0))),
            Shared::LnLightScale(c) => p.light_scale_of(c.unwrap_or(0)).ln(),
        };
    }
    x
}

/// The covariance of the iterates `params` over θ (C_opt).
pub fn iterate_covariance(params: &[Params], shared: &[Shared]) -> Joint {
    let n_all = 6 + shared.len();
    let n = params.len();
    let mut out = DMatrix::zeros(n_all, n_all);
    if n < 2 {
        return out;
    }
    let x: Vec<DVector<f64>> = params.iter().map(|p| theta(p, shared)).collect();
    let m = x.iter().fold(DVector::zeros(n_all), |acc, v| acc + v) / n as f64;
    for v in &x {
        let d = v - &m;
        out += &d * d.transpose() / (n as f64 - 1.0);
    }
    out
}

/// The drift of the iterates `params` over θ as d dᵀ, d the mean of their second half minus
/// that of their first (C_drift).
pub fn iterate_drift(params: &[Params], shared: &[Shared]) -> Joint {
    let n_all = 6 + shared.len();
    let n = params.len();
    if n < 2 {
        return DMatrix::zeros(n_all, n_all);
    }
    let (first, second) = params.split_at(n / 2);
    let mean = |part: &[Params]| -> DVector<f64> {
        part.iter()
            .map(|p| theta(p, shared))
            .fold(DVector::zeros(n_all), |acc, v| acc + v)
            / part.len() as f64
    };
    let d = mean(second) - mean(first);
    &d * d.transpose()
}

/// Each channel's (ln σ_t, α) block as [c00, c01, c11], and the shared parameters' variances.
pub fn blocks(m: &Joint) -> ([[f64; 3]; 3], Vec<f64>) {
    let ch = std::array::from_fn(|c| {
        let (s, a) = (2 * c, 2 * c + 1);
        [m[(s, s)], m[(s, a)], m[(a, a)]]
    });
    (ch, (6..m.nrows()).map(|i| m[(i, i)]).collect())
}

/// The interval of a recovered parameter that the channels share: g, or the light scale k.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SharedUncertainty {
    /// [lo, hi] of the 95 % interval (g within (−1, 1); `None`: no finite interval).
    pub interval: Option<[f64; 2]>,
    /// The standard deviation of g, or of ln k.
    pub sd: Option<f64>,
    /// Determined by the images: g's half-width from the images alone at most
    /// [`super::DETERMINED_G_HALF_WIDTH`]; k's hi/lo at most [`super::DETERMINED_SIGMA_T_RATIO`].
    pub determined: bool,
}

impl SharedUncertainty {
    /// The interval around `g` of variance `var` (images, optimiser and model error) whose
    /// part from the images and the optimiser alone is `images_var`.
    pub fn g(g: f64, var: Option<f64>, images_var: Option<f64>) -> Self {
        let sd = var.map(f64::sqrt).filter(|v| v.is_finite());
        let limit = 1.0 - 1e-6;
        SharedUncertainty {
            interval: sd.map(|s| [(g - Z95 * s).max(-limit), (g + Z95 * s).min(limit)]),
            sd,
            determined: sd.is_some()
                && images_var
                    .map(f64::sqrt)
                    .is_some_and(|s| Z95 * s <= DETERMINED_G_HALF_WIDTH),
        }
    }

    /// The interval k·exp(±1.96·sd) around the light scale `k`, from the variances of ln k.
    pub fn light_scale(k: f64, var: Option<f64>, images_var: Option<f64>) -> Self {
        let sd = var.map(f64::sqrt).filter(|v| v.is_finite());
        SharedUncertainty {
            interval: sd.map(|s| [k * (-Z95 * s).exp(), k * (Z95 * s).exp()]),
            sd,
            determined: sd.is_some()
                && images_var
                    .map(f64::sqrt)
                    .is_some_and(|s| (2.0 * Z95 * s).exp() <= DETERMINED_SIGMA_T_RATIO),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uncertainty::Accumulator;

    /// One render used as both of a view's two renders.
    fn renders<'a>(
        value: &'a Image,
        d_sigma_t: &'a Image,
        d_albedo: &'a Image,
        target: &'a Image,
    ) -> ViewRenders<'a> {
        ViewRenders {
            value: [value, value],
            d_sigma_t: [d_sigma_t, d_sigma_t],
            d_albedo: [d_albedo, d_albedo],
            target,
        }
    }

    /// `value` plus uniform noise of width 0.01 per pixel and channel: a view's target.
    fn noisy(value: &Image, rng: &mut base::rng::Sampler) -> Image {
        let mut t = value.clone();
        for x in t.data.iter_mut().flatten() {
            *x += 0.01 * (rng.next_f32() - 0.5);
        }
        t
    }

    /// Renders of a linear model I_c = J_c·θ with known Jacobians and independent target noise
    /// per view: where ∂I/∂g is zero the joint blocks equal the per-channel sandwich (g then
    /// has no information and A is singular, so g is left out by giving it its own pixels);
    /// and g's variance is B_gg/A_gg² for a g constrained by pixels of its own.
    #[test]
    fn with_g_decoupled_the_blocks_are_the_per_channel_sandwich() {
        let (w, h) = (8u32, 8u32);
        let mut rng = base::rng::Sampler::new(5, 0, 0, 0);
        let mut joint = JointAccumulator::new(vec![Shared::G(None)]);
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
            let target = noisy(&value, &mut rng);
            let r = renders(&value, &d_sigma_t, &d_albedo, &target);
            joint.add_view(&r, &[[&d_g, &d_g]], sigma_t);
            per_channel.add_view(&r, sigma_t);
        }
        let m = joint
            .covariance(0.03, [false, false])
            .expect("positive definite");
        let (ch, var) = blocks(&m);
        let var_g = var[0];
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
            assert_eq!(f[(2 * c, 2 * c)], 0.0);
            let want = want[c].unwrap()[2];
            let got = f[(2 * c + 1, 2 * c + 1)];
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "channel {c}: {got} vs {want}"
            );
        }
    }

    /// One light factor per channel acts on its own channel alone: A has no entry between one
    /// channel's (ln σ_t, α, ln k_c) and another's, so (without the model's brightness term)
    /// each channel's block of the covariance is its own 3 × 3 sandwich A_c⁻¹B_cc A_c⁻¹; a
    /// single factor instead ties every channel's α to it.
    #[test]
    fn per_channel_light_scales_keep_the_channels_apart() {
        let (w, h) = (8u32, 8u32);
        let mut rng = base::rng::Sampler::new(9, 0, 0, 0);
        let per = vec![
            Shared::LnLightScale(Some(0)),
            Shared::LnLightScale(Some(1)),
            Shared::LnLightScale(Some(2)),
        ];
        let mut rgb = JointAccumulator::new(per.clone());
        let mut one = JointAccumulator::new(vec![Shared::LnLightScale(None)]);
        let sigma_t = [40.0, 60.0, 80.0];
        let img = |f: &dyn Fn(usize, usize) -> f32| {
            let mut im = Image::new(w, h);
            for (p, px) in im.data.iter_mut().enumerate() {
                *px = std::array::from_fn(|c| f(p, c));
            }
            im
        };
        for view in 0..12 {
            let d_sigma_t = img(&|p, c| (0.002 * (1 + (p + view) % 5 + c) as f64) as f32);
            let d_albedo = img(&|p, c| (0.3 + 0.1 * ((p * 3 + c) % 4) as f64) as f32);
            let value = img(&|p, c| 0.1 + 0.01 * ((p + c + view) % 7) as f32);
            let target = noisy(&value, &mut rng);
            let r = renders(&value, &d_sigma_t, &d_albedo, &target);
            rgb.add_view(&r, &[[&value, &value]; 3], sigma_t);
            one.add_view(&r, &[[&value, &value]], sigma_t);
        }
        let m = rgb
            .covariance(0.0, [false, false])
            .expect("positive definite");
        let vars = |c: usize| [2 * c, 2 * c + 1, 6 + c];
        for c in 0..3 {
            for c2 in (0..3).filter(|&c2| c2 != c) {
                for i in vars(c) {
                    for j in vars(c2) {
                        assert_eq!(rgb.a[(i, j)], 0.0, "channels {c} and {c2}");
                    }
                }
            }
            assert!(m[(6 + c, 6 + c)] > 0.0 && m[(6 + c, 6 + c)].is_finite());
            // The channel's own sandwich, from its rows of A and of each view's g_v.
            let idx = vars(c);
            let a = DMatrix::from_fn(3, 3, |i, j| rgb.a[(idx[i], idx[j])]);
            let s = a.cholesky().unwrap().inverse();
            let [g1, g2] = [0, 1].map(|k| {
                rgb.g[k]
                    .iter()
                    .map(|g| DVector::from_fn(3, |i, _| g[idx[i]]))
                    .collect::<Vec<_>>()
            });
            let b = crate::uncertainty::meat::cross_meat(&g1, &g2).unwrap();
            let want = &s * b * &s + crate::uncertainty::meat::remaining_step(&s, &g1, &g2);
            for i in 0..3 {
                for j in 0..3 {
                    let got = m[(idx[i], idx[j])];
                    assert!((got - want[(i, j)]).abs() <= 1e-9 * want[(i, i)].abs().max(1e-30));
                }
            }
        }
        assert!((0..3).all(|c| one.a[(2 * c + 1, 6)] != 0.0));
    }

    /// The iterates' covariance and drift include g as the seventh variable.
    #[test]
    fn the_iterates_spread_includes_g() {
        let it: Vec<Params> = (0..10)
            .map(|k| Params {
                g: Some(crate::params::OneOrRgb::One(0.5 + 0.01 * k as f64)),
                ..Params::new([50.0; 3], [0.9; 3])
            })
            .collect();
        let c = iterate_covariance(&it, &[Shared::G(None)]);
        let d = iterate_drift(&it, &[Shared::G(None)]);
        assert!(
            (c[(6, 6)] - 0.01f64.powi(2) * 55.0 / 6.0).abs() < 1e-12,
            "{}",
            c[(6, 6)]
        );
        assert!((d[(6, 6)] - 0.05f64.powi(2)).abs() < 1e-12, "{}", d[(6, 6)]);
        assert!(c[(0, 0)].abs() < 1e-20, "{}", c[(0, 0)]);
    }
}
