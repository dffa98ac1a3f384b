//! Entry points by probe rays (King et al. 2013, as DLW22 uses them; docs/model.md §9), with the
//! exact density of the multiple-importance combination.
//!
//! From the camera point x_o with shading frame (s, t, n), one sample:
//! - a channel c, uniform (1/3);
//! - a probe axis v_z: n with probability 1/2, s or t with 1/4 each; (v_x, v_y) the other two;
//! - a radius r = −ln(1 − u)/μ_c (density μ_c e^{−μ_c r}) and angle φ = 2πu' in the disk ⟂ v_z;
//!   r ≥ r_max,c = −ln(10⁻⁶)/μ_c is a miss;
//! - the probe segment through q = x_o + r(v_x cos φ + v_y sin φ) along v_z, of half-length
//!   √(r_max,c² − r²) (the chord of the ball of radius r_max,c about x_o);
//! - one of its first [`MAX_HITS`] surface crossings, uniformly.
//!
//! The density of x_i in area measure sums every (axis, channel) pair that could have produced
//! it (the one-sample MIS density):
//!
//!   p(x_i) = Σ_c (1/3) Σ_a P_a · μ_c e^{−μ_c r_a}/(2π r_a) · |n_g(x_i)·v_a| · [rank_{a,c} < 5] / min(N_{a,c}, 5),
//!
//! with r_a the distance from x_o to x_i in the plane ⟂ v_a, N_{a,c} the number of crossings of
//! the line through x_i along v_a inside the ball of radius r_max,c, and rank_{a,c} the number
//! of those before x_i. DLW22 divides by the crossing count of the probe that was drawn for all
//! pairs; counting each pair's own chord makes the density exact (and the estimator unbiased on
//! curved surfaces, where the tangent probes cross the surface twice and the normal probe once).

use std::f64::consts::PI;

use geometry::{Accel, Frame, Hit};
use glam::Vec3;

use super::DipoleProfile;

/// Crossings of one probe that can be picked (DLW22).
pub const MAX_HITS: usize = 5;

/// Probability of each probe axis: s, t, n.
pub const AXIS_PROB: [f64; 3] = [0.25, 0.25, 0.5];

/// The probe sampler of a medium's three channels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeSampler {
    /// μ_c, the radius rates.
    pub rate: [f64; 3],
    /// r_max,c.
    pub r_max: [f64; 3],
}

/// One sampled entry point with its density (area measure).
#[derive(Clone, Copy, Debug)]
pub struct ProbeSample {
    pub hit: Hit,
    pub pdf: f64,
}

/// The axes (v_x, v_y, v_z) of probe axis `a` (0: s, 1: t, 2: n) in `frame`.
#[inline]
fn axes(frame: &Frame, a: usize) -> [Vec3; 3] {
    match a {
        0 => [frame.t, frame.n, frame.s],
        1 => [frame.n, frame.s, frame.t],
        _ => [frame.s, frame.t, frame.n],
    }
}

impl ProbeSampler {
    /// The sampler of the channels' dipoles.
    pub fn new(profiles: &[DipoleProfile; 3]) -> Self {
        ProbeSampler {
            rate: profiles.map(|p| p.mu_tr()),
            r_max: profiles.map(|p| p.r_max()),
        }
    }

    /// One entry point from x_o with shading frame `frame`, from five uniforms (channel, axis,
    /// radius, angle, pick); `None` when the probe finds no surface. `buf` is scratch space.
    pub fn sample(
        &self,
        accel: &Accel,
        x_o: Vec3,
        frame: &Frame,
        u: [f32; 5],
        buf: &mut Vec<Hit>,
    ) -> Option<ProbeSample> {
        let c = ((u[0] * 3.0) as usize).min(2);
        let a = if u[1] < 0.25 {
            0
        } else if u[1] < 0.5 {
            1
        } else {
            2
        };
        let r = -(1.0 - u[2] as f64).ln() / self.rate[c];
        let r_max = self.r_max[c];
        if r >= r_max || r.is_nan() {
            return None;
        }
        let phi = 2.0 * PI * u[3] as f64;
        let [vx, vy, vz] = axes(frame, a);
        let half = (r_max * r_max - r * r).sqrt();
        let q = x_o + (vx * phi.cos() as f32 + vy * phi.sin() as f32) * r as f32;
        accel.all_hits(q - vz * half as f32, vz, 0.0, 2.0 * half as f32, buf);
        let n = buf.len().min(MAX_HITS);
        if n == 0 {
            return None;
        }
        let hit = buf[((u[4] * n as f32) as usize).min(n - 1)];
        let pdf = self.pdf(accel, x_o, frame, hit.p, hit.ng, buf);
        (pdf > 0.0 && pdf.is_finite()).then_some(ProbeSample { hit, pdf })
    }

    /// The density (area measure) of the entry point `x_i` with geometric normal `ng` from x_o
    /// (module docs). `buf` is scratch space.
    pub fn pdf(
        &self,
        accel: &Accel,
        x_o: Vec3,
        frame: &Frame,
        x_i: Vec3,
        ng: Vec3,
        buf: &mut Vec<Hit>,
    ) -> f64 {
        let d = x_i - x_o;
        let dd = d.length_squared() as f64;
        let reach = self.r_max.iter().fold(0.0f64, |m, &r| m.max(r));
        let mut total = 0.0;
        for (a, &p_axis) in AXIS_PROB.iter().enumerate() {
            let vz = axes(frame, a)[2];
            let cos = ng.dot(vz).abs() as f64;
            if cos == 0.0 {
                continue;
            }
            let along = d.dot(vz) as f64;
            let r_a = (dd - along * along).max(0.0).sqrt();
            if r_a >= reach {
                continue;
            }
            // The longest chord along this line; each channel's is a centred part of it.
            let half = (reach * reach - r_a * r_a).sqrt();
            let q = x_i - vz * along as f32;
            accel.all_hits(q - vz * half as f32, vz, 0.0, 2.0 * half as f32, buf);
            let t_i = half + along;
            let eps = 1e-6 * half;
            for c in 0..3 {
                let r_max = self.r_max[c];
                // x_i must lie on the chord: within r_max of x_o.
                if dd >= r_max * r_max {
                    continue;
                }
                let h_c = (r_max * r_max - r_a * r_a).sqrt();
                let (lo, hi) = (half - h_c, half + h_c);
                let on_chord = buf.iter().filter(|h| {
                    let t = h.t as f64;
                    t > lo && t < hi
                });
                let count = on_chord.clone().count();
                let rank = on_chord.filter(|h| (h.t as f64) < t_i - eps).count();
                if rank >= MAX_HITS {
                    continue;
                }
                let mu = self.rate[c];
                let radial = mu * (-mu * r_a).exp() / (2.0 * PI * r_a.max(1e-12 * r_max));
                total += p_axis / 3.0 * radial * cos / count.clamp(1, MAX_HITS) as f64;
            }
        }
        total
    }
}
