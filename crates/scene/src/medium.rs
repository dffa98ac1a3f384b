//! The homogeneous medium (CONVENTIONS.md): per RGB channel extinction σ_t [1/unit] and
//! single-scattering albedo α (σ_s = α σ_t), Henyey–Greenstein g, and the boundary that holds
//! it: relative IOR η = n_in/n_out and the surface's roughness as a GGX α (Walter et al. 2007;
//! Mitsuba 3 `roughdielectric`'s `alpha`; 0 = smooth).

use serde::{Deserialize, Serialize};

use crate::{Anisotropy, SceneError};

/// Homogeneous medium parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Medium {
    pub sigma_t: [f32; 3],
    pub albedo: [f32; 3],
    /// Henyey–Greenstein anisotropy per channel, (−1, 1); 0 = isotropic (the paper's setting).
    /// One number in files when the channels share it ([`Anisotropy`]).
    #[serde(default)]
    pub g: Anisotropy,
    /// Relative index of refraction η ≥ 1; 1 = index-matched (null) boundary (the paper's data).
    #[serde(default = "one")]
    pub eta: f32,
    /// Roughness of the boundary as the GGX α of its microfacets (Walter et al. 2007, the
    /// `alpha` of Mitsuba 3's `roughdielectric`), [0, 1]; 0 = a smooth surface. Only a
    /// refractive boundary (η > 1) can be rough.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub roughness: f32,
}

/// Serde: a smooth boundary's roughness is not written.
pub(crate) fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

/// Serde default of η (index-matched boundary), shared with the file specs.
pub(crate) fn one() -> f32 {
    1.0
}

impl Medium {
    /// Check ranges: σ_t > 0 and finite, α ∈ [0, 1), g ∈ (−1, 1), η ≥ 1, roughness ∈ [0, 1]
    /// and 0 unless η > 1. `context` (file and field path, e.g. "scene.toml: medium") goes into
    /// the error.
    pub fn validate(&self, context: &str) -> Result<(), SceneError> {
        let bad = |field: String, value: f32, reason: &str| SceneError::Invalid {
            location: format!("{context}.{field} = {value}"),
            reason: reason.to_string(),
        };
        for c in 0..3 {
            let s = self.sigma_t[c];
            if !(s.is_finite() && s > 0.0) {
                return Err(bad(
                    format!("sigma_t[{c}]"),
                    s,
                    "extinction must be > 0 and finite (1/scene unit); fix: use a positive value, \
                     e.g. 30–100 for an object about 1 unit across",
                ));
            }
        }
        for c in 0..3 {
            let a = self.albedo[c];
            if !(a.is_finite() && (0.0..1.0).contains(&a)) {
                return Err(bad(
                    format!("albedo[{c}]"),
                    a,
                    "single-scattering albedo must be in [0, 1) (1 would mean no absorption at \
                     all); fix: use a value such as 0.9 (at most 0.9999)",
                ));
            }
        }
        if let Some((c, g)) = self.g.out_of_range() {
            return Err(bad(
                self.g.field(c),
                g,
                "Henyey–Greenstein anisotropy must be in (−1, 1); fix: use 0 for isotropic \
                 scattering (the paper's setting)",
            ));
        }
        if !(self.eta.is_finite() && self.eta >= 1.0) {
            return Err(bad(
                "eta".into(),
                self.eta,
                "relative index of refraction n_inside/n_outside must be ≥ 1 and finite; fix: \
                 use 1 for the index-matched (null) boundary, or e.g. 1.5 for glass-like media",
            ));
        }
        if !(self.roughness.is_finite() && (0.0..=1.0).contains(&self.roughness)) {
            return Err(bad(
                "roughness".into(),
                self.roughness,
                "the boundary's roughness is the GGX α of its microfacets, in [0, 1]; fix: use 0 \
                 for a smooth surface, 0.05–0.3 for the usual polished to matte objects",
            ));
        }
        if self.roughness > 0.0 && self.eta == 1.0 {
            return Err(bad(
                "roughness".into(),
                self.roughness,
                "an index-matched boundary (eta = 1) has no surface to be rough; fix: give the \
                 object's index of refraction as eta (e.g. 1.5), or roughness 0",
            ));
        }
        Ok(())
    }
    /// σ_s per channel.
    pub fn sigma_s(&self) -> [f32; 3] {
        [0, 1, 2].map(|c| self.sigma_t[c] * self.albedo[c])
    }
}

#[cfg(test)]
#[allow(clippy::excessive_precision, clippy::type_complexity)] // numbers copied verbatim from Mitsuba's scene.json
mod tests {
    use super::*;

    fn ok() -> Medium {
        Medium {
            sigma_t: [50.0, 60.0, 70.0],
            albedo: [0.95, 0.9, 0.85],
            g: Anisotropy::ISOTROPIC,
            eta: 1.0,
            roughness: 0.0,
        }
    }

    #[test]
    fn valid_medium_passes() {
        ok().validate("scene.toml: medium").unwrap();
        Medium {
            albedo: [0.0; 3],
            g: Anisotropy::uniform(-0.9),
            eta: 1.5,
            ..ok()
        }
        .validate("m")
        .unwrap();
    }

    #[test]
    fn each_range_error_names_its_field() {
        let cases = [
            (
                Medium {
                    sigma_t: [50.0, -3.0, 70.0],
                    ..ok()
                },
                "scene.toml: medium.sigma_t[1] = -3: extinction must be > 0",
            ),
            (
                Medium {
                    sigma_t: [0.0, 1.0, 1.0],
                    ..ok()
                },
                "medium.sigma_t[0] = 0",
            ),
            (
                Medium {
                    sigma_t: [1.0, 1.0, f32::INFINITY],
                    ..ok()
                },
                "medium.sigma_t[2] = inf",
            ),
            (
                Medium {
                    albedo: [0.5, 1.0, 0.5],
                    ..ok()
                },
                "medium.albedo[1] = 1",
            ),
            (
                Medium {
                    albedo: [-0.1, 0.5, 0.5],
                    ..ok()
                },
                "medium.albedo[0] = -0.1",
            ),
            (
                Medium {
                    g: Anisotropy::uniform(1.0),
                    ..ok()
                },
                "medium.g = 1",
            ),
            (
                Medium {
                    g: Anisotropy::uniform(-1.5),
                    ..ok()
                },
                "medium.g = -1.5",
            ),
            (
                Medium {
                    g: Anisotropy([0.5, 0.7, 1.2]),
                    ..ok()
                },
                "medium.g[2] = 1.2",
            ),
            (Medium { eta: 0.9, ..ok() }, "medium.eta = 0.9"),
            (
                Medium {
                    eta: 1.5,
                    roughness: -0.1,
                    ..ok()
                },
                "medium.roughness = -0.1",
            ),
            (
                Medium {
                    eta: 1.5,
                    roughness: 1.5,
                    ..ok()
                },
                "medium.roughness = 1.5",
            ),
            (
                Medium {
                    roughness: 0.2,
                    ..ok()
                },
                "medium.roughness = 0.2: an index-matched boundary",
            ),
            (
                Medium {
                    eta: f32::NAN,
                    ..ok()
                },
                "medium.eta = NaN",
            ),
        ];
        for (m, want) in cases {
            let msg = m.validate("scene.toml: medium").unwrap_err().to_string();
            assert!(msg.contains(want), "{msg:?} should contain {want:?}");
            assert!(msg.contains("fix"), "{msg:?} should say how to fix it");
        }
    }
}
