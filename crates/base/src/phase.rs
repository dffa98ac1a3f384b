//! Henyey–Greenstein phase function.
//!
//! p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}), with θ the angle between the propagation
//! direction before and after scattering (g > 0 = forward scattering). Sampling inverts the CDF:
//! cos θ = (1 + g² − ((1 − g²)/(1 − g + 2g u))²)/(2g) (isotropic 1 − 2u when |g| < 1e-3), as in
//! docs/model.md §5 and pbrt-v4. Sampling is exact, so the sample weight p/pdf is 1.
//!
//! The derivative with respect to g that the tracer's ∂I/∂g needs is that of ln p:
//!
//!   ∂ ln p/∂g = −2g/(1 − g²) − 3(g − cos θ)/(1 + g² − 2g cos θ)   (3 cos θ at g = 0).
//!
//! A chromatic medium has one g per RGB channel ([`ChannelHg`]): channel c's radiance sees
//! p_{g_c}. A path samples its directions with one channel's phase function (the tracer's hero
//! channel) and weighs the others by the ratio of their densities, as it does its free flights.

use geometry::Frame;
use glam::Vec3;

const INV_4PI: f32 = 1.0 / (4.0 * std::f32::consts::PI);

/// Henyey–Greenstein phase function with anisotropy `g` ∈ (−1, 1).
#[derive(Clone, Copy, Debug)]
pub struct HenyeyGreenstein {
    pub g: f32,
}

impl HenyeyGreenstein {
    /// Density per steradian of scattering from propagation direction `d_in` into `d_out`.
    #[inline]
    pub fn eval(&self, d_in: Vec3, d_out: Vec3) -> f32 {
        self.eval_cos(d_in.dot(d_out))
    }

    /// Density as a function of cos θ between the old and new propagation directions.
    #[inline]
    pub fn eval_cos(&self, cos_theta: f32) -> f32 {
        let g = self.g;
        let denom = 1.0 + g * g - 2.0 * g * cos_theta;
        INV_4PI * (1.0 - g * g) / (denom * denom.max(1e-12).sqrt())
    }

    /// ∂ ln p/∂g at cos θ (module docs): the score of one phase-function factor of a path.
    #[inline]
    pub fn d_log_dg(&self, cos_theta: f32) -> f32 {
        let g = self.g;
        let denom = (1.0 + g * g - 2.0 * g * cos_theta).max(1e-12);
        -2.0 * g / (1.0 - g * g) - 3.0 * (g - cos_theta) / denom
    }

    /// Sample cos θ by inverting the CDF with one uniform.
    #[inline]
    pub fn sample_cos(&self, u: f32) -> f32 {
        let g = self.g;
        if g.abs() < 1e-3 {
            1.0 - 2.0 * u
        } else {
            let sq = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
            ((1.0 + g * g - sq * sq) / (2.0 * g)).clamp(-1.0, 1.0)
        }
    }

    /// Sample a new propagation direction around `d_in` (unit). Its pdf is `eval(d_in, ·)`.
    #[inline]
    pub fn sample(&self, d_in: Vec3, u1: f32, u2: f32) -> Vec3 {
        let cos_t = self.sample_cos(u1);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u2;
        let f = Frame::from_normal(d_in);
        f.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t))
            .normalize()
    }
}

/// A Henyey–Greenstein phase function per RGB channel ([module docs](self)). With one g for
/// all channels every method returns the same value in each channel, computed once.
#[derive(Clone, Copy, Debug)]
pub struct ChannelHg {
    hg: [HenyeyGreenstein; 3],
    uniform: bool,
}

impl ChannelHg {
    /// The phase functions of anisotropies `g` (R, G, B).
    pub fn new(g: [f32; 3]) -> Self {
        ChannelHg {
            hg: g.map(|g| HenyeyGreenstein { g }),
            uniform: g[0] == g[1] && g[1] == g[2],
        }
    }

    /// Whether every channel has the same g.
    #[inline]
    pub fn is_uniform(&self) -> bool {
        self.uniform
    }

    /// The phase function of channel `c`.
    #[inline]
    pub fn channel(&self, c: usize) -> &HenyeyGreenstein {
        &self.hg[c]
    }

    /// Density per steradian of each channel for scattering from `d_in` into `d_out`.
    #[inline]
    pub fn eval(&self, d_in: Vec3, d_out: Vec3) -> [f32; 3] {
        self.eval_cos(d_in.dot(d_out))
    }

    /// Density of each channel as a function of cos θ.
    #[inline]
    pub fn eval_cos(&self, cos_theta: f32) -> [f32; 3] {
        self.per_channel(|p| p.eval_cos(cos_theta))
    }

    /// ∂ ln p_{g_c}/∂g_c at cos θ, per channel.
    #[inline]
    pub fn d_log_dg(&self, cos_theta: f32) -> [f32; 3] {
        self.per_channel(|p| p.d_log_dg(cos_theta))
    }

    /// `f` of each channel's phase function; computed once where the channels share one g.
    #[inline(always)]
    fn per_channel(&self, f: impl Fn(&HenyeyGreenstein) -> f32) -> [f32; 3] {
        if self.uniform {
            [f(&self.hg[0]); 3]
        } else {
            [f(&self.hg[0]), f(&self.hg[1]), f(&self.hg[2])]
        }
    }

    /// A new propagation direction around `d_in` from channel `c`'s phase function.
    #[inline]
    pub fn sample(&self, c: usize, d_in: Vec3, u1: f32, u2: f32) -> Vec3 {
        self.hg[c].sample(d_in, u1, u2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each channel of a chromatic phase function is that channel's HG, and a uniform one
    /// computes exactly what one HG does.
    #[test]
    fn channels_are_their_own_phase_functions() {
        let chromatic = ChannelHg::new([0.2, 0.5, 0.9]);
        let uniform = ChannelHg::new([0.5; 3]);
        assert!(!chromatic.is_uniform() && uniform.is_uniform());
        for cos in [-1.0f32, -0.2, 0.4, 0.95] {
            let (p, s) = (chromatic.eval_cos(cos), chromatic.d_log_dg(cos));
            for (c, g) in [0.2f32, 0.5, 0.9].into_iter().enumerate() {
                let hg = HenyeyGreenstein { g };
                assert_eq!(p[c], hg.eval_cos(cos));
                assert_eq!(s[c], hg.d_log_dg(cos));
            }
            let one = HenyeyGreenstein { g: 0.5 };
            assert_eq!(uniform.eval_cos(cos), [one.eval_cos(cos); 3]);
            assert_eq!(uniform.d_log_dg(cos), [one.d_log_dg(cos); 3]);
        }
        let d = Vec3::new(0.0, 0.6, 0.8);
        assert_eq!(
            chromatic.sample(2, d, 0.3, 0.7),
            HenyeyGreenstein { g: 0.9 }.sample(d, 0.3, 0.7)
        );
    }

    /// ∂ ln p/∂g against a central difference of ln p, forward and backward scattering.
    #[test]
    fn log_derivative_matches_a_central_difference() {
        let h = 1e-3f64;
        for g in [-0.5f32, 0.0, 0.3, 0.9] {
            for cos in [-1.0f32, -0.3, 0.0, 0.5, 0.99, 1.0] {
                let ln_p = |g: f64| {
                    let denom = 1.0 + g * g - 2.0 * g * cos as f64;
                    ((1.0 - g * g) / (4.0 * std::f64::consts::PI * denom.powf(1.5))).ln()
                };
                let fd = (ln_p(g as f64 + h) - ln_p(g as f64 - h)) / (2.0 * h);
                let ad = HenyeyGreenstein { g }.d_log_dg(cos) as f64;
                assert!(
                    (ad - fd).abs() <= 1e-3 * (1.0 + fd.abs()),
                    "g {g}, cos {cos}: {ad} against {fd}"
                );
            }
        }
    }
}
