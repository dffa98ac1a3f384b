//! The optimised medium parameters and their parameterisation (Son et al. 2024 §5;
//! docs/model.md §8.3, A12–A13).
//!
//! The optimiser sees six unconstrained numbers u = (u_σ,R, u_σ,G, u_σ,B, u_α,R, u_α,G, u_α,B):
//!
//! * σ_t = 100·u_σ ([`Parameterisation::Scaled`], the paper's release: σ_t/100), or
//!   σ_t = exp(u_σ) ([`Parameterisation::Log`]); chain rule ∂ℓ/∂u_σ = ∂ℓ/∂σ_t · dσ_t/du_σ with
//!   dσ_t/du_σ = 100 or σ_t;
//! * α = u_α;
//!
//! then clamped after every step: α ∈ [ALBEDO_MIN, ALBEDO_MAX] (the paper's (0, 0.99995)),
//! σ_t ≥ SIGMA_T_MIN. A monochrome run shares one value per kind over the channels (the gradient is
//! the channel mean, docs/model.md A13); a fixed parameter keeps its value (zero gradient).

use scene::Medium;
use serde::{Deserialize, Serialize};

/// Smallest albedo after clamping.
pub const ALBEDO_MIN: f64 = 1e-4;
/// Largest albedo after clamping (Son et al.'s clamp).
pub const ALBEDO_MAX: f64 = 0.99995;
/// Smallest extinction after clamping (1/unit).
pub const SIGMA_T_MIN: f64 = 1e-3;

/// How σ_t is represented for the optimiser.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Parameterisation {
    /// u = σ_t/100.
    #[default]
    Scaled,
    /// u = ln σ_t.
    Log,
}

/// Which parameters move and how.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamSpec {
    /// σ_t representation.
    pub parameterisation: Parameterisation,
    /// One σ_t and one α shared by the channels.
    pub monochrome: bool,
    /// Keep σ_t at its initial value.
    pub fix_sigma_t: bool,
    /// Keep α at its initial value.
    pub fix_albedo: bool,
}

impl Default for ParamSpec {
    fn default() -> Self {
        Self {
            parameterisation: Parameterisation::Scaled,
            monochrome: false,
            fix_sigma_t: false,
            fix_albedo: false,
        }
    }
}

/// σ_t and α per channel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Params {
    /// Extinction per channel (1/unit).
    pub sigma_t: [f64; 3],
    /// Single-scattering albedo per channel.
    pub albedo: [f64; 3],
}

impl Params {
    /// The parameters of a medium.
    pub fn of(m: &Medium) -> Self {
        Self {
            sigma_t: m.sigma_t.map(|v| v as f64),
            albedo: m.albedo.map(|v| v as f64),
        }
    }

    /// A medium with these parameters and `base`'s g and η.
    pub fn medium(&self, base: &Medium) -> Medium {
        Medium {
            sigma_t: self.sigma_t.map(|v| v as f32),
            albedo: self.albedo.map(|v| v as f32),
            g: base.g,
            eta: base.eta,
            roughness: base.roughness,
        }
    }
}

impl ParamSpec {
    /// The optimiser's vector for `p`.
    pub fn encode(&self, p: &Params) -> Vec<f32> {
        let mut u = Vec::with_capacity(6);
        for &s in &p.sigma_t {
            u.push(match self.parameterisation {
                Parameterisation::Scaled => (s / 100.0) as f32,
                Parameterisation::Log => s.ln() as f32,
            });
        }
        u.extend(p.albedo.iter().map(|&a| a as f32));
        u
    }

    /// The parameters of the optimiser's vector (clamped).
    pub fn decode(&self, u: &[f32]) -> Params {
        let sigma = |v: f32| match self.parameterisation {
            Parameterisation::Scaled => 100.0 * v as f64,
            Parameterisation::Log => (v as f64).exp(),
        };
        Params {
            sigma_t: std::array::from_fn(|c| sigma(u[c]).max(SIGMA_T_MIN)),
            albedo: std::array::from_fn(|c| (u[3 + c] as f64).clamp(ALBEDO_MIN, ALBEDO_MAX)),
        }
    }

    /// Clamps `u` in place to the representable range (after an optimiser step).
    pub fn clamp(&self, u: &mut [f32]) {
        let p = self.decode(u);
        let e = self.encode(&p);
        u.copy_from_slice(&e);
    }

    /// ∂ℓ/∂u from ∂ℓ/∂σ_t and ∂ℓ/∂α (monochrome averaging and fixed parameters applied).
    pub fn chain(&self, p: &Params, d_sigma_t: [f64; 3], d_albedo: [f64; 3]) -> Vec<f32> {
        let mut gs: [f64; 3] = std::array::from_fn(|c| {
            d_sigma_t[c]
                * match self.parameterisation {
                    Parameterisation::Scaled => 100.0,
                    Parameterisation::Log => p.sigma_t[c],
                }
        });
        let mut ga = d_albedo;
        if self.monochrome {
            let m = gs.iter().sum::<f64>() / 3.0;
            gs = [m; 3];
            let m = ga.iter().sum::<f64>() / 3.0;
            ga = [m; 3];
        }
        if self.fix_sigma_t {
            gs = [0.0; 3];
        }
        if self.fix_albedo {
            ga = [0.0; 3];
        }
        gs.iter().chain(&ga).map(|&g| g as f32).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_decode_round_trip_and_clamps() {
        for parameterisation in [Parameterisation::Scaled, Parameterisation::Log] {
            let spec = ParamSpec {
                parameterisation,
                ..Default::default()
            };
            let p = Params {
                sigma_t: [30.0, 55.5, 100.0],
                albedo: [0.8, 0.9, 0.98],
            };
            let q = spec.decode(&spec.encode(&p));
            for c in 0..3 {
                assert!((q.sigma_t[c] / p.sigma_t[c] - 1.0).abs() < 1e-6);
                assert!((q.albedo[c] - p.albedo[c]).abs() < 1e-6);
            }
            let mut u = vec![-1.0, 0.5, 0.5, -0.2, 1.5, 0.5];
            spec.clamp(&mut u);
            let c = spec.decode(&u);
            assert!(c.albedo[0] >= ALBEDO_MIN && c.albedo[1] <= ALBEDO_MAX);
            assert!(c.sigma_t[0] >= SIGMA_T_MIN * 0.999);
        }
    }

    #[test]
    fn chain_rule_matches_finite_differences_and_options() {
        let p = Params {
            sigma_t: [40.0, 60.0, 80.0],
            albedo: [0.9; 3],
        };
        // ℓ(σ) = Σ σ_c² ⇒ ∂ℓ/∂σ_c = 2σ_c; check ∂ℓ/∂u by FD through decode.
        for parameterisation in [Parameterisation::Scaled, Parameterisation::Log] {
            let spec = ParamSpec {
                parameterisation,
                ..Default::default()
            };
            let g = spec.chain(&p, p.sigma_t.map(|s| 2.0 * s), [0.0; 3]);
            let u = spec.encode(&p);
            for c in 0..3 {
                let h = 1e-3f32;
                let mut up = u.clone();
                up[c] += h;
                let mut um = u.clone();
                um[c] -= h;
                let l = |v: &[f32]| spec.decode(v).sigma_t.iter().map(|s| s * s).sum::<f64>();
                let fd = (l(&up) - l(&um)) / (2.0 * h as f64);
                assert!((fd / g[c] as f64 - 1.0).abs() < 1e-3, "{fd} vs {}", g[c]);
            }
        }
        let mono = ParamSpec {
            monochrome: true,
            fix_albedo: true,
            ..Default::default()
        };
        let g = mono.chain(&p, [1.0, 2.0, 3.0], [1.0, 1.0, 1.0]);
        assert_eq!(g, vec![200.0, 200.0, 200.0, 0.0, 0.0, 0.0]);
    }
}
