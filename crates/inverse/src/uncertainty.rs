//! The uncertainty of a recovered medium, from the images themselves: a sandwich
//! (Gauss–Newton / cluster-robust) covariance of the L2 estimate, per channel.
//!
//! Channel c of every image depends only on θ_c = (ln σ_t,c, α_c), so the covariance is block
//! diagonal with one 2×2 block per channel. The estimate minimises L(θ) = Σ_v Σ_p (I_p(θ) − T_p)²
//! over the views v and their pixels p. With J_p = ∂I_p/∂θ_c (per pixel, from the derivative
//! images: ∂I/∂ln σ_t = σ_t·∂I/∂σ_t) and the residuals r_p = I_p(θ̂) − T_p:
//!
//!   A = Σ_v Σ_p J_p J_pᵀ                       (Gauss–Newton: half the Hessian of L)
//!   g_v = Σ_p J_p r_p                           (half the gradient of view v's loss)
//!   B = V/(V − 1) · Σ_v (g_v − ḡ)(g_v − ḡ)ᵀ     (the views as independent draws of the capture)
//!   Cov(θ̂) ≈ A⁻¹ B A⁻¹ + C_step + s_b²·d dᵀ + C_opt + C_drift (+ C_capture),
//!   d = A⁻¹ Σ_v Σ_p J_p I_p,   C_step = Δ Δᵀ,   Δ = A⁻¹ Σ_v g_v
//!
//! B and the remaining Gauss–Newton step Δ are each taken from the two independent renders of
//! every view, one render's values against the other's derivatives, so that neither holds those
//! renders' own Monte Carlo noise ([`meat`]); C_step allows for a run that stops short of the
//! loss's minimum. (C_capture, for a stated capture error such as a scanned mesh's accuracy:
//! [`capture`]).
//!
//! (the M-estimator sandwich with views as clusters: White 1980, Liang & Zeger 1986). B holds
//! whatever makes the views disagree at the estimate: the targets' noise, the renderer's noise
//! and the model's error where it differs from view to view, so the interval widens where the
//! learned model fits some views worse than others, which a noise-only Fisher interval would
//! not. Where the images barely constrain a direction of θ_c (a light beside the camera makes
//! σ_t and α trade along a valley), A is nearly singular along it and the interval is wide.
//! The middle term is the learned model's brightness error, which is common to all views and so
//! invisible to B: if every image of the model were too bright by a factor (1 + b), the
//! Gauss–Newton step moves the estimate by b·d. With b of standard deviation s_b
//! ([`UncertaintySettings::model_brightness_sd`], from the model's measured brightness error
//! against the volumetric path tracer) it adds s_b²·d dᵀ. Along a valley of the loss (light
//! beside the camera) d is long, and the interval says so.
//! J_p J_pᵀ is taken as the symmetrised product of two independent renders' derivatives
//! (½(J¹J²ᵀ + J²J¹ᵀ)), whose expectation is J̄J̄ᵀ without the Monte Carlo noise that J¹J¹ᵀ
//! would add to A. C_opt is the covariance of the optimiser's iterates over the last third of
//! the run: with one view and few samples per iteration Adam's steps are a random walk of about
//! the learning rate around the minimum, and the estimate (the last iterate) is a draw from it.
//! A short tail underestimates that walk's spread (on a case whose model is exact, the last
//! tenth covered the truth in 79 % of pairs, the last third in 93 %). C_drift = d dᵀ, with d the
//! mean of the window's second half minus that of its first ([`iterate_drift`]), allows for a
//! run that has not stopped moving: along a flat valley the iterates drift steadily towards a
//! minimum they have not reached, and the estimate is at least that movement from its limit
//! (docs/notes/default-model.md, "Intervals of a refined run").
//!
//! The 95 % interval is θ̂ ± 1.96·sd in (ln σ_t, α): σ_t·exp(±1.96·sd) and α ± 1.96·sd clamped
//! to [0, 1]. A parameter is reported *determined* when the images constrain it: the interval
//! from A⁻¹BA⁻¹ + C_opt + C_drift alone (without the model-error terms) has σ_t's upper bound at most
//! [`DETERMINED_SIGMA_T_RATIO`] times its lower one, or α's half-width at most
//! [`DETERMINED_ALBEDO_HALF_WIDTH`]. The reported interval itself includes the model's error.
//!
//! All of this takes the loss's curvature from the learned model. Where the model is more
//! curved along the σ_t–α valley than the images are, [`Uncertainty::with_sensitivity`]
//! widens the intervals by the volumetric path tracer's measured curvature along that valley
//! ([`crate::sensitivity`]); *determined* is decided after that widening.
//!
//! A run that also recovers g takes the sandwich over all its variables at once ([`joint`]):
//! seven with one g, nine with one per channel (channel c's images depend on g_c alone). Each
//! g's interval is g ± 1.96·sd clamped to (−1, 1), and it is *determined* where its half-width
//! from the images alone is at most [`DETERMINED_G_HALF_WIDTH`].

use crate::params::OneOrRgb;
use crate::sensitivity::Sensitivity;
use scene::Image;
use serde::{Deserialize, Serialize};

/// z of a two-sided 95 % normal interval.
pub const Z95: f64 = 1.959_963_984_540_054;
/// σ_t counts as determined when hi/lo of its 95 % interval is at most this (about ±10 %).
pub const DETERMINED_SIGMA_T_RATIO: f64 = 1.2;
/// The widest standard deviation of ln σ_t that [`Uncertainty::with_sensitivity`] widens to:
/// a 95 % interval of a factor 10 either way.
pub const WIDEST_SD_LN_SIGMA_T: f64 = std::f64::consts::LN_10 / Z95;
/// α counts as determined when the half-width of its 95 % interval is at most this.
pub const DETERMINED_ALBEDO_HALF_WIDTH: f64 = 0.02;
/// g counts as determined when the half-width of its 95 % interval is at most this.
pub const DETERMINED_G_HALF_WIDTH: f64 = 0.05;

pub mod capture;
pub mod iterates;
pub mod joint;
pub mod meat;

pub use iterates::{iterate_covariance, iterate_drift};

pub use joint::SharedUncertainty;

/// Settings of the uncertainty estimate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UncertaintySettings {
    /// Views used (evenly spread over the targets; all when there are fewer).
    pub views: usize,
    /// Samples per pixel of each of the two derivative renders per view.
    pub spp: u32,
    /// Fraction of the run's last iterations whose spread gives C_opt.
    pub tail_fraction: f64,
    /// s_b: standard deviation of the learned model's relative brightness error, common to all
    /// views (module docs).
    pub model_brightness_sd: f64,
    /// The mesh's stated accuracy: the RMS displacement of its vertices along their normals as
    /// a fraction of its bounding box's diagonal (a scan's noise), whose effect on the estimate
    /// joins the intervals ([`capture`]); `None`: the mesh is taken as exact.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh_error: Option<f64>,
}

/// The perturbations drawn for a stated capture error ([`capture`]).
pub const CAPTURE_DRAWS: usize = 8;

impl Default for UncertaintySettings {
    fn default() -> Self {
        Self {
            views: 16,
            spp: 32,
            tail_fraction: 1.0 / 3.0,
            model_brightness_sd: 0.03,
            mesh_error: None,
        }
    }
}

/// Per-channel sums over the views (module docs).
#[derive(Clone, Debug, Default)]
pub struct Accumulator {
    /// A per channel, [a00, a01, a11] in (ln σ_t, α).
    a: [[f64; 3]; 3],
    /// g_v per view and channel, from each render's values and the other's derivatives
    /// ([`meat`]).
    g: [Vec<[[f64; 2]; 3]>; 2],
    /// Σ_p J_p I_p per channel (the direction of a common brightness error).
    ji: [[f64; 2]; 3],
    /// Each view's share of A, in the order the views were added.
    view_a: Vec<[[f64; 3]; 3]>,
    /// Σ_p J_p δI_p per channel of each draw of a stated capture error ([`capture`]).
    capture: Vec<[[f64; 2]; 3]>,
}

/// One view's derivative renders at the estimate: value and ∂I/∂σ_t, ∂I/∂α images of two
/// independent renders, and the target.
pub struct ViewRenders<'a> {
    pub value: [&'a Image; 2],
    pub d_sigma_t: [&'a Image; 2],
    pub d_albedo: [&'a Image; 2],
    pub target: &'a Image,
}

impl Accumulator {
    /// Adds one view at σ_t = `sigma_t` (per channel).
    pub fn add_view(&mut self, r: &ViewRenders, sigma_t: [f64; 3]) {
        let n = r.target.data.len();
        self.add_rows((0..n).flat_map(|p| {
            (0..3).map(move |c| {
                let j = |k: usize| {
                    [
                        sigma_t[c] * r.d_sigma_t[k].data[p][c] as f64,
                        r.d_albedo[k].data[p][c] as f64,
                    ]
                };
                let v = [0, 1].map(|k| r.value[k].data[p][c] as f64);
                (c, [j(0), j(1)], v, r.target.data[p][c] as f64)
            })
        }));
    }

    /// Adds one view from its pixel rows: channel, two independent estimates of the Jacobian
    /// row in (ln σ_t, α) and of the value, and the target. J J^T and J·I each take their two
    /// factors from different estimates (no Monte Carlo covariance between them).
    pub fn add_rows(&mut self, rows: impl Iterator<Item = (usize, [[f64; 2]; 2], [f64; 2], f64)>) {
        let mut g = [[[0.0; 2]; 3]; 2];
        let mut view_a = [[0.0; 3]; 3];
        for (c, [j1, j2], [v1, v2], t) in rows {
            let (r1, r2) = (v1 - t, v2 - t);
            if !(r1.is_finite() && r2.is_finite() && j1.iter().chain(&j2).all(|x| x.is_finite())) {
                continue;
            }
            let a = &mut view_a[c];
            a[0] += j1[0] * j2[0];
            a[1] += 0.5 * (j1[0] * j2[1] + j1[1] * j2[0]);
            a[2] += j1[1] * j2[1];
            for k in 0..2 {
                g[0][c][k] += j2[k] * r1;
                g[1][c][k] += j1[k] * r2;
                self.ji[c][k] += 0.5 * (j1[k] * v2 + j2[k] * v1);
            }
        }
        for c in 0..3 {
            for k in 0..3 {
                self.a[c][k] += view_a[c][k];
            }
        }
        for (all, view) in self.g.iter_mut().zip(g) {
            all.push(view);
        }
        self.view_a.push(view_a);
    }

    /// Each added view's share of A per channel, [a00, a01, a11] in (ln σ_t, α), in the order
    /// the views were added.
    pub fn view_breads(&self) -> &[[[f64; 3]; 3]] {
        &self.view_a
    }

    /// The covariance A⁻¹BA⁻¹ + C_step + s_b²·d dᵀ per channel in (ln σ_t, α) as [c00, c01, c11]
    /// (`model_brightness_sd` = s_b), or `None` for a channel whose A is not positive definite
    /// or with fewer than two views.
    pub fn covariance(&self, model_brightness_sd: f64) -> [Option<[f64; 3]>; 3] {
        self.covariance_fixed(model_brightness_sd, [false, false])
    }

    /// [`Accumulator::covariance`] when the run keeps a parameter fixed (`fixed`: [σ_t, α]): the
    /// other one's variance is then its own, B_kk/A_kk² + s_b²·(j_k/A_kk)², not the marginal of
    /// the pair (which would add the valley along which the fixed parameter cannot move). The
    /// fixed parameter's entries are 0.
    pub fn covariance_fixed(
        &self,
        model_brightness_sd: f64,
        fixed: [bool; 2],
    ) -> [Option<[f64; 3]>; 3] {
        let v = self.g[0].len();
        std::array::from_fn(|c| {
            if v < 2 {
                return None;
            }
            let [a00, a01, a11] = self.a[c];
            let det = a00 * a11 - a01 * a01;
            let inv = match fixed {
                [true, true] => return None,
                [false, true] if a00 > 0.0 && a00.is_finite() => [1.0 / a00, 0.0, 0.0],
                [true, false] if a11 > 0.0 && a11.is_finite() => [0.0, 0.0, 1.0 / a11],
                [false, false] if a00 > 0.0 && a11 > 0.0 && det > 0.0 && det.is_finite() => {
                    [a11 / det, -a01 / det, a00 / det]
                }
                _ => return None,
            };
            let [g1, g2] = [0, 1].map(|k| {
                self.g[k]
                    .iter()
                    .map(|g| nalgebra::DVector::from_row_slice(&g[c]))
                    .collect::<Vec<_>>()
            });
            let b = meat::to_packed(&meat::cross_meat(&g1, &g2)?);
            let step = meat::to_packed(&meat::remaining_step(&meat::from_packed(inv), &g1, &g2));
            let ji = self.ji[c];
            let d = [
                inv[0] * ji[0] + inv[1] * ji[1],
                inv[1] * ji[0] + inv[2] * ji[1],
            ];
            let s2 = model_brightness_sd * model_brightness_sd;
            let m = sandwich(inv, b);
            let cap = capture::channel_term(inv, self.capture.iter().map(|s| s[c]));
            Some([
                m[0] + step[0] + s2 * d[0] * d[0] + cap[0],
                m[1] + step[1] + s2 * d[0] * d[1] + cap[1],
                m[2] + step[2] + s2 * d[1] * d[1] + cap[2],
            ])
        })
    }
}

/// S·B·S for symmetric 2×2 matrices stored as [m00, m01, m11].
fn sandwich(s: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    // M = S·B
    let m00 = s[0] * b[0] + s[1] * b[1];
    let m01 = s[0] * b[1] + s[1] * b[2];
    let m10 = s[1] * b[0] + s[2] * b[1];
    let m11 = s[1] * b[1] + s[2] * b[2];
    [
        m00 * s[0] + m01 * s[1],
        m00 * s[1] + m01 * s[2],
        m10 * s[1] + m11 * s[2],
    ]
}

/// 95 % intervals, standard deviations and whether each parameter is determined.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Uncertainty {
    /// [lo, hi] of σ_t per channel (`None`: the images give no finite interval).
    pub sigma_t: [Option<[f64; 2]>; 3],
    /// [lo, hi] of α per channel.
    pub albedo: [Option<[f64; 2]>; 3],
    /// Standard deviation of ln σ_t per channel.
    pub sd_ln_sigma_t: [Option<f64>; 3],
    /// Standard deviation of α per channel.
    pub sd_albedo: [Option<f64>; 3],
    /// Correlation of ln σ_t and α per channel.
    pub correlation: [Option<f64>; 3],
    /// σ_t is determined by the images (module docs).
    pub determined_sigma_t: [bool; 3],
    /// α is determined by the images.
    pub determined_albedo: [bool; 3],
    /// Views the estimate used.
    pub views: usize,
    /// How the covariance was made.
    pub method: String,
    /// The covariance per channel in (ln σ_t, α) as [c00, c01, c11].
    #[serde(skip)]
    pub covariance: [Option<[f64; 3]>; 3],
    /// Its part from the images and the optimiser alone (no model-error allowance).
    #[serde(skip)]
    pub images: [Option<[f64; 3]>; 3],
    /// The optimiser's part of `images` per channel in (ln σ_t, α), [c00, c01, c11]: the spread
    /// and drift of the last iterates (C_opt + C_drift), which more views would not narrow.
    #[serde(skip)]
    pub optimiser: [[f64; 3]; 3],
    /// The learned model's Gauss–Newton A of each view used: (target index, [a00, a01, a11]
    /// per channel in (ln σ_t, α)).
    #[serde(skip)]
    pub view_bread: Vec<(usize, [[f64; 3]; 3])>,
    /// The parameters the run kept fixed, [σ_t, α]: they have no interval, and are not
    /// "undetermined".
    #[serde(skip)]
    pub fixed: [bool; 2],
    /// g's interval where the run recovers g (one, or one per channel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g: Option<OneOrRgb<SharedUncertainty>>,
    /// The light scale's interval where the run recovers it (one, or one per channel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_scale: Option<OneOrRgb<SharedUncertainty>>,
    /// The mesh's stated error that the intervals include ([`capture`]), where one was stated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh_error: Option<f64>,
}

impl Uncertainty {
    /// The intervals around `sigma_t`, `albedo` from per-channel covariances (sandwich plus
    /// optimiser) in (ln σ_t, α).
    ///
    /// `images` is the part of the covariance the images and the optimiser make (no allowance
    /// for the model's error): a parameter is *determined* when that part alone gives a narrow
    /// interval, i.e. when the images constrain it, whatever the model's error adds.
    pub fn new(
        sigma_t: [f64; 3],
        albedo: [f64; 3],
        cov: [Option<[f64; 3]>; 3],
        images: [Option<[f64; 3]>; 3],
        views: usize,
    ) -> Self {
        let narrow = |c: usize| -> (bool, bool) {
            images[c].map_or((false, false), |m| {
                let (st, sa) = (m[0].sqrt(), m[2].sqrt());
                (
                    (2.0 * Z95 * st).exp() <= DETERMINED_SIGMA_T_RATIO,
                    Z95 * sa <= DETERMINED_ALBEDO_HALF_WIDTH,
                )
            })
        };
        let sd_t: [Option<f64>; 3] =
            std::array::from_fn(|c| cov[c].map(|m| m[0].sqrt()).filter(|v| v.is_finite()));
        let sd_a: [Option<f64>; 3] =
            std::array::from_fn(|c| cov[c].map(|m| m[2].sqrt()).filter(|v| v.is_finite()));
        let si: [Option<[f64; 2]>; 3] = std::array::from_fn(|c| {
            sd_t[c].map(|s| [sigma_t[c] * (-Z95 * s).exp(), sigma_t[c] * (Z95 * s).exp()])
        });
        let ai: [Option<[f64; 2]>; 3] = std::array::from_fn(|c| {
            sd_a[c].map(|s| {
                [
                    (albedo[c] - Z95 * s).max(0.0),
                    (albedo[c] + Z95 * s).min(1.0),
                ]
            })
        });
        Self {
            determined_sigma_t: std::array::from_fn(|c| si[c].is_some() && narrow(c).0),
            determined_albedo: std::array::from_fn(|c| ai[c].is_some() && narrow(c).1),
            correlation: std::array::from_fn(|c| {
                cov[c]
                    .map(|m| m[1] / (m[0] * m[2]).sqrt())
                    .filter(|v| v.is_finite())
            }),
            sigma_t: si,
            albedo: ai,
            sd_ln_sigma_t: sd_t,
            sd_albedo: sd_a,
            views,
            covariance: cov,
            images,
            optimiser: [[0.0; 3]; 3],
            view_bread: Vec::new(),
            fixed: [false, false],
            g: None,
            light_scale: None,
            mesh_error: None,
            method: "sandwich: Gauss-Newton bread, per-view gradient meat from two independent \
                     renders, the remaining Gauss-Newton step, the model's brightness error, the \
                     spread and drift of the last iterates"
                .into(),
        }
    }

    /// The intervals of a bias-corrected estimate `corrected` of the estimate `estimate` (this
    /// uncertainty's): the bootstrap recovery has the estimate's covariance C, the corrected
    /// value θ̂ − (θ̂₂ − θ_at) that of the difference of two such recoveries (2C), and the
    /// correction b = corrected − estimate, which the bias may differ by between the estimate
    /// and the truth, enters as a further b bᵀ (a correction of size |b| is uncertain by about
    /// |b|: the bias's change between the estimate and the truth is of the order of the bias).
    pub fn corrected(
        &self,
        estimate: &crate::params::Params,
        corrected: &crate::params::Params,
    ) -> Self {
        let cov = std::array::from_fn(|c| {
            self.covariance[c].map(|m| {
                let b = [
                    (corrected.sigma_t[c] / estimate.sigma_t[c]).ln(),
                    corrected.albedo[c] - estimate.albedo[c],
                ];
                [
                    2.0 * m[0] + b[0] * b[0],
                    2.0 * m[1] + b[0] * b[1],
                    2.0 * m[2] + b[1] * b[1],
                ]
            })
        });
        let images = self.images.map(|m| m.map(|m| m.map(|v| 2.0 * v)));
        let mut u = Self::new(corrected.sigma_t, corrected.albedo, cov, images, self.views);
        u.method = format!(
            "{}; bias-corrected: twice that covariance plus the correction's square",
            self.method
        );
        u.keep_from(self);
        u.optimiser = self.optimiser.map(|m| m.map(|v| 2.0 * v));
        u
    }

    /// The learned model's A summed over the views used, per channel.
    pub fn bread(&self) -> [[f64; 3]; 3] {
        let mut a = [[0.0; 3]; 3];
        for (_, v) in &self.view_bread {
            for c in 0..3 {
                for k in 0..3 {
                    a[c][k] += v[c][k];
                }
            }
        }
        a
    }

    /// The intervals around `at` (this uncertainty's centre) once the images' own sensitivity
    /// along the σ_t valley is known ([`crate::sensitivity`]).
    ///
    /// In the coordinates x = ln σ_t, y = α − s·x, with s the valley's slope dα/d ln σ_t
    /// (−a01/a11 of the learned model's A), the Gauss–Newton bread is diagonal: x is σ_t
    /// with α refitted. Where the volumetric path tracer's images curve a factor ρ less along
    /// x than the learned model's, a covariance C(x, y) becomes D C D with D = diag(√ρ, 1): the
    /// profile variance of ln σ_t grows by ρ, that of y stays. This applies to the part of the
    /// covariance the images and the optimiser make (so *determined* follows); the allowances
    /// for the model's error (its brightness error, the bias correction's size) are measured
    /// magnitudes, not curvatures, and are added unchanged. The widening stops where the
    /// images' interval of σ_t spans a factor of 10 either way ([`WIDEST_SD_LN_SIGMA_T`]):
    /// beyond that a linearised interval says no more than "not determined".
    pub fn with_sensitivity(&self, at: &crate::params::Params, s: &Sensitivity) -> Self {
        let rho: [Option<f64>; 3] = std::array::from_fn(|c| {
            self.images[c].map(|m| {
                // No wider than WIDEST_SD_LN_SIGMA_T by the widening itself.
                let room = (WIDEST_SD_LN_SIGMA_T.powi(2) / m[0]).max(1.0);
                if room.is_finite() {
                    s.ratio[c].min(room)
                } else {
                    s.ratio[c]
                }
            })
        });
        let images: [Option<[f64; 3]>; 3] =
            std::array::from_fn(|c| Some(along_valley(self.images[c]?, s.slope[c], rho[c]?)));
        // The model-error allowances (cov − images) are magnitudes, not curvatures: they stay.
        let cov = std::array::from_fn(|c| match (self.covariance[c], self.images[c], images[c]) {
            (Some(m), Some(old), Some(new)) => {
                Some(std::array::from_fn(|k| m[k] - old[k] + new[k]))
            }
            (m, _, _) => m,
        });
        let mut u = Self::new(at.sigma_t, at.albedo, cov, images, self.views);
        u.method = format!(
            "{}; widened along the σ_t valley by the volumetric path tracer's sensitivity",
            self.method
        );
        u.keep_from(self);
        u.optimiser = std::array::from_fn(|c| {
            along_valley(self.optimiser[c], s.slope[c], rho[c].unwrap_or(1.0))
        });
        u
    }

    /// Keeps `from`'s missing intervals missing (a fixed parameter), which parameters it kept
    /// fixed, and its views' breads.
    fn keep_from(&mut self, from: &Self) {
        self.fixed = from.fixed;
        self.g = from.g;
        self.light_scale = from.light_scale;
        for c in 0..3 {
            if from.sigma_t[c].is_none() {
                self.sigma_t[c] = None;
                self.sd_ln_sigma_t[c] = None;
                self.determined_sigma_t[c] = false;
            }
            if from.albedo[c].is_none() {
                self.albedo[c] = None;
                self.sd_albedo[c] = None;
                self.determined_albedo[c] = false;
            }
        }
        self.view_bread = from.view_bread.clone();
        self.optimiser = from.optimiser;
    }

    /// `result.json`'s `interval95` and `determined` fields.
    pub fn to_json(&self) -> serde_json::Value {
        let mut j = serde_json::json!({
            "interval95": {
                "sigma_t": self.sigma_t,
                "albedo": self.albedo,
            },
            "determined": {
                "sigma_t": self.determined_sigma_t,
                "albedo": self.determined_albedo,
            },
            "uncertainty": {
                "sd_ln_sigma_t": self.sd_ln_sigma_t,
                "sd_albedo": self.sd_albedo,
                "correlation_ln_sigma_t_albedo": self.correlation,
                "views": self.views,
                "method": self.method,
            },
        });
        if let Some(g) = &self.g {
            j["interval95"]["g"] = serde_json::json!(g.map(|g| g.interval));
            j["determined"]["g"] = serde_json::json!(g.map(|g| g.determined));
            j["uncertainty"]["sd_g"] = serde_json::json!(g.map(|g| g.sd));
        }
        if let Some(f) = self.mesh_error {
            j["uncertainty"]["mesh_error"] =
                serde_json::json!({ "fraction": f, "draws": CAPTURE_DRAWS });
        }
        if let Some(k) = &self.light_scale {
            j["interval95"]["light_scale"] = serde_json::json!(k.map(|k| k.interval));
            j["determined"]["light_scale"] = serde_json::json!(k.map(|k| k.determined));
            j["uncertainty"]["sd_ln_light_scale"] = serde_json::json!(k.map(|k| k.sd));
        }
        j
    }
}

/// The covariance m = [c00, c01, c11] in (ln σ_t, α) with the profile variance of ln σ_t
/// along the valley of slope `slope` = dα/d ln σ_t scaled by `ratio`
/// ([`Uncertainty::with_sensitivity`]).
pub fn along_valley(m: [f64; 3], slope: f64, ratio: f64) -> [f64; 3] {
    let [c00, c01, c11] = m;
    // C(x, y) with y = α − s·x.
    let (xx, xy, yy) = (
        c00,
        c01 - slope * c00,
        c11 - 2.0 * slope * c01 + slope * slope * c00,
    );
    let (xx, xy) = (ratio * xx, ratio.sqrt() * xy);
    [
        xx,
        xy + slope * xx,
        yy + 2.0 * slope * xy + slope * slope * xx,
    ]
}

/// Adds two per-channel covariances (a missing one stays missing).
pub fn add_covariances(a: [Option<[f64; 3]>; 3], b: [[f64; 3]; 3]) -> [Option<[f64; 3]>; 3] {
    std::array::from_fn(|c| a[c].map(|m| std::array::from_fn(|k| m[k] + b[c][k])))
}

#[cfg(test)]
mod tests;
