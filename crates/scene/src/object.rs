//! What a capture states about the object apart from the parameters a recovery estimates: the
//! boundary (its index of refraction and roughness) and the medium's phase function.
//!
//! In `dataset.json` (DATASET.md, "object"):
//!
//! ```json
//! "object": {
//!   "boundary": { "type": "dielectric", "eta": 1.5, "roughness": 0.1 },
//!   "phase": { "type": "hg", "g": 0.3 }
//! }
//! ```
//!
//! | field | meaning | unit |
//! |---|---|---|
//! | `boundary.type` | `"null"`: index-matched, no surface (η = 1); `"dielectric"`: a refractive surface | |
//! | `boundary.eta` | relative index of refraction n_inside / n_outside, > 1 | none |
//! | `boundary.roughness` | GGX α of the surface's microfacets (Walter et al. 2007; Mitsuba 3's `alpha`), 0 = smooth, ≤ 1 | none |
//! | `phase.type` | `"isotropic"` or `"hg"` (Henyey–Greenstein) | |
//! | `phase.g` | mean cosine of the scattering angle, (−1, 1) | none |
//!
//! The recovery renders with these and estimates σ_t and α; the dataset's `truth` is never read
//! for them (it is a report of what made a synthetic dataset, nothing more).

use serde::{Deserialize, Serialize};

use crate::{Anisotropy, Medium, SceneError};

/// The known part of the object: boundary and phase function.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Object {
    /// Relative index of refraction n_inside / n_outside; 1 = index-matched (no surface).
    pub eta: f32,
    /// GGX α of the boundary's microfacets; 0 = smooth.
    pub roughness: f32,
    /// Henyey–Greenstein g per channel; 0 = isotropic.
    pub g: Anisotropy,
}

impl Object {
    /// An index-matched object of an isotropic medium: the paper's synthetic setting, and what a
    /// recovery assumes (and says it assumes) for a dataset that states nothing.
    pub const INDEX_MATCHED_ISOTROPIC: Object = Object {
        eta: 1.0,
        roughness: 0.0,
        g: Anisotropy::ISOTROPIC,
    };

    /// The boundary and phase function of `m`.
    pub fn of(m: &Medium) -> Object {
        Object {
            eta: m.eta,
            roughness: m.roughness,
            g: m.g,
        }
    }

    /// The medium of this object with the parameters `sigma_t`, `albedo`.
    pub fn medium(&self, sigma_t: [f32; 3], albedo: [f32; 3]) -> Medium {
        Medium {
            sigma_t,
            albedo,
            g: self.g,
            eta: self.eta,
            roughness: self.roughness,
        }
    }

    /// Check the ranges (those of [`Medium::validate`]); `context` is e.g. "dataset.json: object".
    pub fn validate(&self, context: &str) -> Result<(), SceneError> {
        let bad = |field: &str, value: f32, reason: &str| SceneError::Invalid {
            location: format!("{context}.{field} = {value}"),
            reason: reason.into(),
        };
        if !(self.eta.is_finite() && self.eta >= 1.0) {
            return Err(bad(
                "boundary.eta",
                self.eta,
                "the relative index of refraction n_inside/n_outside must be ≥ 1 and finite; \
                 fix: e.g. 1.5 for glass-like media, or boundary {\"type\": \"null\"} for an \
                 index-matched object",
            ));
        }
        if !(self.roughness.is_finite() && (0.0..=1.0).contains(&self.roughness)) {
            return Err(bad(
                "boundary.roughness",
                self.roughness,
                "the roughness is the GGX α of the surface's microfacets, in [0, 1]; fix: 0 for \
                 a smooth surface, 0.05–0.3 for polished to matte objects",
            ));
        }
        if let Some((c, g)) = self.g.out_of_range() {
            return Err(bad(
                &format!("phase.{}", self.g.field(c)),
                g,
                "the Henyey–Greenstein g must be in (−1, 1); fix: 0 for isotropic scattering, \
                 0.7–0.9 for milk or skin",
            ));
        }
        Ok(())
    }

    /// One line for logs and reports, e.g. "dielectric boundary η 1.5, GGX α 0.1; HG g 0.3".
    pub fn describe(&self) -> String {
        let boundary = if self.eta == 1.0 {
            "index-matched boundary (η 1)".to_string()
        } else if self.roughness == 0.0 {
            format!("smooth dielectric boundary (η {})", self.eta)
        } else {
            format!(
                "rough dielectric boundary (η {}, GGX α {})",
                self.eta, self.roughness
            )
        };
        let phase = if self.g.is_isotropic() {
            "isotropic medium (g 0)".to_string()
        } else if self.g.is_uniform() {
            format!("Henyey–Greenstein medium (g {})", self.g)
        } else {
            format!("Henyey–Greenstein medium (g {} in R, G, B)", self.g)
        };
        format!("{boundary}; {phase}")
    }
}

/// The `object` block as written ([module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    pub boundary: BoundarySpec,
    pub phase: PhaseSpec,
}

/// `object.boundary` as written.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum BoundarySpec {
    /// Index-matched: no surface.
    Null {},
    /// A refractive surface, smooth unless `roughness` (GGX α) is given.
    Dielectric {
        eta: f32,
        #[serde(default)]
        roughness: f32,
    },
}

/// `object.phase` as written.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum PhaseSpec {
    Isotropic {},
    /// Henyey–Greenstein: one g, or one per channel ([`Anisotropy`]).
    Hg {
        g: Anisotropy,
    },
}

impl ObjectSpec {
    /// The validated object; `context` is e.g. "dataset.json: object".
    pub fn to_object(&self, context: &str) -> Result<Object, SceneError> {
        let (eta, roughness) = match self.boundary {
            BoundarySpec::Null {} => (1.0, 0.0),
            BoundarySpec::Dielectric { eta, roughness } => {
                if eta == 1.0 {
                    return Err(SceneError::Invalid {
                        location: format!("{context}.boundary.eta = 1"),
                        reason: "a dielectric boundary with η = 1 has no surface; fix: \
                                 {\"type\": \"null\"} for an index-matched object, or the \
                                 object's index of refraction (e.g. 1.5)"
                            .into(),
                    });
                }
                (eta, roughness)
            }
        };
        let g = match self.phase {
            PhaseSpec::Isotropic {} => Anisotropy::ISOTROPIC,
            PhaseSpec::Hg { g } => g,
        };
        let object = Object { eta, roughness, g };
        object.validate(context)?;
        Ok(object)
    }
}

impl From<&Object> for ObjectSpec {
    fn from(o: &Object) -> Self {
        ObjectSpec {
            boundary: if o.eta == 1.0 {
                BoundarySpec::Null {}
            } else {
                BoundarySpec::Dielectric {
                    eta: o.eta,
                    roughness: o.roughness,
                }
            },
            phase: if o.g.is_isotropic() {
                PhaseSpec::Isotropic {}
            } else {
                PhaseSpec::Hg { g: o.g }
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(json: &str) -> Result<Object, String> {
        let spec: ObjectSpec = serde_json::from_str(json).map_err(|e| e.to_string())?;
        spec.to_object("dataset.json: object")
            .map_err(|e| e.to_string())
    }

    #[test]
    fn every_form_reads_and_writes_back() {
        for (json, want) in [
            (
                r#"{"boundary": {"type": "null"}, "phase": {"type": "isotropic"}}"#,
                Object::INDEX_MATCHED_ISOTROPIC,
            ),
            (
                r#"{"boundary": {"type": "dielectric", "eta": 1.5}, "phase": {"type": "hg", "g": 0.3}}"#,
                Object {
                    eta: 1.5,
                    roughness: 0.0,
                    g: Anisotropy::uniform(0.3),
                },
            ),
            (
                r#"{"boundary": {"type": "dielectric", "eta": 1.33, "roughness": 0.1}, "phase": {"type": "hg", "g": 0.9}}"#,
                Object {
                    eta: 1.33,
                    roughness: 0.1,
                    g: Anisotropy::uniform(0.9),
                },
            ),
            (
                r#"{"boundary": {"type": "null"}, "phase": {"type": "hg", "g": [0.7, 0.8, 0.9]}}"#,
                Object {
                    eta: 1.0,
                    roughness: 0.0,
                    g: Anisotropy([0.7, 0.8, 0.9]),
                },
            ),
        ] {
            let o = parse(json).unwrap();
            assert_eq!(o, want);
            let back = serde_json::to_string(&ObjectSpec::from(&o)).unwrap();
            assert_eq!(parse(&back).unwrap(), o, "{back}");
            assert_eq!(Object::of(&o.medium([1.0; 3], [0.5; 3])), o);
        }
    }

    #[test]
    fn bad_values_name_the_field_and_the_fix() {
        for (json, want) in [
            (
                r#"{"boundary": {"type": "dielectric", "eta": 0.8}, "phase": {"type": "isotropic"}}"#,
                "object.boundary.eta = 0.8",
            ),
            (
                r#"{"boundary": {"type": "dielectric", "eta": 1.0}, "phase": {"type": "isotropic"}}"#,
                "object.boundary.eta = 1",
            ),
            (
                r#"{"boundary": {"type": "dielectric", "eta": 1.4, "roughness": 2}, "phase": {"type": "isotropic"}}"#,
                "object.boundary.roughness = 2",
            ),
            (
                r#"{"boundary": {"type": "null"}, "phase": {"type": "hg", "g": 1.0}}"#,
                "object.phase.g = 1",
            ),
            (
                r#"{"boundary": {"type": "null"}, "phase": {"type": "hg", "g": [0.7, -1.0, 0.9]}}"#,
                "object.phase.g[1] = -1",
            ),
        ] {
            let msg = parse(json).unwrap_err();
            assert!(msg.contains(want), "{msg:?} should contain {want:?}");
            assert!(msg.contains("fix"), "{msg:?} should say how to fix it");
        }
        for json in [
            r#"{"boundary": {"type": "rough"}, "phase": {"type": "isotropic"}}"#,
            r#"{"boundary": {"type": "null"}, "phase": {"type": "hg"}}"#,
            r#"{"boundary": {"type": "null", "eta": 1.5}, "phase": {"type": "isotropic"}}"#,
            r#"{"boundary": {"type": "null"}}"#,
            r#"{"boundary": {"type": "null"}, "phase": {"type": "hg", "g": [0.7, 0.8]}}"#,
        ] {
            assert!(parse(json).is_err(), "{json} should be refused");
        }
    }
}
