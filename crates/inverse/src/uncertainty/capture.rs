//! A stated capture error in the intervals: what an error of the capture that the images cannot
//! show (a scanned mesh's inaccuracy) would move the estimate by.
//!
//! The estimate solves Σ_v Σ_p J_p (I_p(θ̂) − T_p) = 0. Were the scene behind the renders wrong
//! by a perturbation that changes the images by δI at θ̂, the solution would move by the
//! Gauss–Newton step
//!
//!   δθ = −A⁻¹ Σ_v Σ_p J_p δI_p ,
//!
//! A the sandwich's bread ([`super`]). The capture's actual error is unknown, but its size is
//! stated (a mesh accurate to 0.2 % of its size): K perturbations of that size are drawn
//! (another mesh of the same noise), each one's δI rendered at the estimate with the same
//! random numbers as the unperturbed render (so that δI is the perturbation's, not the
//! renderer's noise), and
//!
//!   C_capture = (1/K) Σ_k δθ_k δθ_kᵀ
//!
//! is added to the covariance beside A⁻¹BA⁻¹ and the model's brightness term s_b²·d dᵀ (which is
//! the same construction for one perturbation, δI = s_b·I). The draws measure the size of the
//! estimate's response to an error of the stated size, whichever way the actual one points; a
//! systematic response (noise on a mesh makes its surface rougher, whatever the draw) shows as
//! shifts of one sign and is counted in full.

use nalgebra::DVector;
use scene::Image;

use super::joint::JointAccumulator;
use super::{Accumulator, ViewRenders};

impl Accumulator {
    /// Adds view `r`'s part of draw `draw`'s shift: Σ_p J_p δI_p with `delta` the image change
    /// the perturbation makes at the estimate (J the mean of the two renders' derivatives).
    /// The views of every draw must be those added by [`Accumulator::add_view`].
    pub fn add_capture(&mut self, draw: usize, r: &ViewRenders, delta: &Image, sigma_t: [f64; 3]) {
        if self.capture.len() <= draw {
            self.capture.resize(draw + 1, [[0.0; 2]; 3]);
        }
        let s = &mut self.capture[draw];
        for (p, d) in delta.data.iter().enumerate() {
            for c in 0..3 {
                let j = [sigma_t[c] * mean(r.d_sigma_t, p, c), mean(r.d_albedo, p, c)];
                let d = d[c] as f64;
                if d.is_finite() && j.iter().all(|x| x.is_finite()) {
                    s[c][0] += j[0] * d;
                    s[c][1] += j[1] * d;
                }
            }
        }
    }

    /// The number of capture draws added.
    pub fn capture_draws(&self) -> usize {
        self.capture.len()
    }
}

/// The mean of the two renders' pixel `p`, channel `c`.
fn mean(images: [&Image; 2], p: usize, c: usize) -> f64 {
    0.5 * (images[0].data[p][c] as f64 + images[1].data[p][c] as f64)
}

/// C_capture of one channel as [c00, c01, c11] from A⁻¹ (`inv`, [i00, i01, i11]) and each draw's
/// Σ J δI of that channel; zero without draws.
pub(super) fn channel_term(inv: [f64; 3], shifts: impl Iterator<Item = [f64; 2]>) -> [f64; 3] {
    let (mut m, mut k) = ([0.0; 3], 0usize);
    for s in shifts {
        let d = [inv[0] * s[0] + inv[1] * s[1], inv[1] * s[0] + inv[2] * s[1]];
        m[0] += d[0] * d[0];
        m[1] += d[0] * d[1];
        m[2] += d[1] * d[1];
        k += 1;
    }
    if k > 0 { m.map(|x| x / k as f64) } else { m }
}

impl JointAccumulator {
    /// [`Accumulator::add_capture`] over all variables: `d_shared` the shared parameters'
    /// derivative images, as given to [`JointAccumulator::add_view`].
    pub fn add_capture(
        &mut self,
        draw: usize,
        r: &ViewRenders,
        d_shared: &[[&Image; 2]],
        delta: &Image,
        sigma_t: [f64; 3],
    ) {
        let n = self.len();
        if self.capture.len() <= draw {
            self.capture.resize(draw + 1, DVector::zeros(n));
        }
        let shared = self.shared().to_vec();
        let s = &mut self.capture[draw];
        for (p, d) in delta.data.iter().enumerate() {
            for c in 0..3 {
                let d = d[c] as f64;
                let j0 = sigma_t[c] * mean(r.d_sigma_t, p, c);
                let j1 = mean(r.d_albedo, p, c);
                if !(d.is_finite() && j0.is_finite() && j1.is_finite()) {
                    continue;
                }
                s[2 * c] += j0 * d;
                s[2 * c + 1] += j1 * d;
                for (j, (ds, sh)) in d_shared.iter().zip(&shared).enumerate() {
                    let js = mean(*ds, p, c);
                    if sh.acts_on(c) && js.is_finite() {
                        s[6 + j] += js * d;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::joint::Shared;
    use super::*;

    /// The renders of `v` ([`renders`]) as both of a view's two renders.
    fn view(v: &[Image; 4]) -> ViewRenders<'_> {
        let [value, ds, da, _] = v;
        ViewRenders {
            value: [value, value],
            d_sigma_t: [ds, ds],
            d_albedo: [da, da],
            target: value,
        }
    }

    /// A view whose renders are exact (no noise): the value, ∂I/∂σ_t, ∂I/∂α and ∂I/∂g per
    /// pixel (g's in another direction, so that the joint A stays invertible).
    fn renders(w: usize, seed: u32) -> [Image; 4] {
        let mut out = [0; 4].map(|_| Image::new(w as u32, 1));
        for p in 0..w {
            let x = (p as f32 + 1.0 + seed as f32) / w as f32;
            out[0].data[p] = [x; 3];
            out[1].data[p] = [-x * x, -0.5 * x, -0.2 * x];
            out[2].data[p] = [1.0 - x, 0.5 + x * x, 0.3 + x * x];
            out[3].data[p] = [x * x + 0.1; 3];
        }
        out
    }

    /// A perturbation that moves the images by exactly ε·∂I/∂σ_t (in ln σ_t: ε/σ_t·J₀) moves
    /// the estimate by −ε/σ_t in ln σ_t and not in α: C_capture's (0, 0) entry is (ε/σ_t)², and
    /// the joint sandwich gives the same block.
    #[test]
    fn a_perturbation_along_a_derivative_moves_that_parameter_by_its_size() {
        let sigma_t = [40.0; 3];
        let eps = 0.8f64;
        let mut acc = Accumulator::default();
        let mut joint = JointAccumulator::new(vec![Shared::G(None)]);
        let views: Vec<_> = (0..3).map(|v| renders(16, v)).collect();
        for v in &views {
            acc.add_view(&view(v), sigma_t);
            joint.add_view(&view(v), &[[&v[3], &v[3]]], sigma_t);
        }
        for (draw, sign) in [1.0, -1.0].into_iter().enumerate() {
            for v in &views {
                let f = (sign * eps) as f32;
                let delta = Image {
                    data: v[1].data.iter().map(|d| d.map(|x| f * x)).collect(),
                    ..v[1].clone()
                };
                acc.add_capture(draw, &view(v), &delta, sigma_t);
                joint.add_capture(draw, &view(v), &[[&v[3], &v[3]]], &delta, sigma_t);
            }
        }
        assert_eq!(acc.capture_draws(), 2);
        let want = (eps / sigma_t[0]).powi(2);
        let cov = acc.covariance(0.0);
        let j = joint.covariance(0.0, [false, false]).unwrap();
        for c in 0..3 {
            let m = cov[c].unwrap();
            // The images are f32: agreement to their precision.
            assert!((m[0] / want - 1.0).abs() < 1e-6, "channel {c}: {m:?}");
            assert!(m[1].abs() < 1e-6 * want && m[2].abs() < 1e-12, "{m:?}");
            assert!((j[(2 * c, 2 * c)] / want - 1.0).abs() < 1e-6, "{j}");
            assert!(j[(2 * c + 1, 2 * c + 1)].abs() < 1e-10, "{j}");
        }
        assert!(j[(6, 6)].abs() < 1e-10, "{j}");
    }
}
