//! A forward model with one of its own estimators ([`ModelChoice`]): the learned model's
//! estimators ([`bssrdf::diff::Estimator`]) and those of the tracer and the dipole
//! ([`TracerEstimator`]) are different types, so a model cannot be paired with another's
//! estimator. Names come in as strings (files, command lines) through [`ModelChoice::new`],
//! whose error names the valid ones.

use bssrdf::diff::Estimator;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::ModelKind;

/// The estimator of the volumetric path tracer and of the dipole.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum TracerEstimator {
    /// Each sample differentiated analytically: a path's throughput (`volpath::derivative`), the
    /// dipole's profile at fixed sample positions.
    #[default]
    Ad,
    /// Central differences of full renders with the value's random numbers ([`super::fd`]).
    Fd,
}

impl TracerEstimator {
    /// The name on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            TracerEstimator::Ad => "ad",
            TracerEstimator::Fd => "fd",
        }
    }
}

/// A model and one of its estimators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModelChoice {
    Learned(Estimator),
    Volpath(TracerEstimator),
    Dipole(TracerEstimator),
}

impl Default for ModelChoice {
    fn default() -> Self {
        ModelChoice::Learned(Estimator::default())
    }
}

/// A name that is not an estimator of the model.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("the {model} model has no estimator {name:?}; its estimators: {}", model.estimators().join(", "))]
pub struct UnknownEstimatorOf {
    pub model: ModelKind,
    pub name: String,
}

impl ModelChoice {
    /// `model` with the estimator named `estimator` (case-insensitive, `_` read as `-`), or its
    /// default estimator (the first of [`ModelKind::estimators`]) for `None`.
    pub fn new(model: ModelKind, estimator: Option<&str>) -> Result<Self, UnknownEstimatorOf> {
        let name = estimator.unwrap_or(model.estimators()[0]);
        let k = name.trim().to_ascii_lowercase().replace('_', "-");
        let unknown = || UnknownEstimatorOf {
            model,
            name: name.to_string(),
        };
        let tracer = || match k.as_str() {
            "ad" => Ok(TracerEstimator::Ad),
            "fd" => Ok(TracerEstimator::Fd),
            _ => Err(unknown()),
        };
        Ok(match model {
            ModelKind::Learned => ModelChoice::Learned(k.parse().map_err(|_| unknown())?),
            ModelKind::Volpath => ModelChoice::Volpath(tracer()?),
            ModelKind::Dipole => ModelChoice::Dipole(tracer()?),
        })
    }

    /// Whether this estimator gives ∂I/∂g (the phase function's g): the tracer's `ad`, which
    /// differentiates each path's phase-function factors. The learned model was trained at
    /// g = 0; the dipole and the `fd` estimators do not difference g.
    pub fn differentiates_g(self) -> bool {
        self == ModelChoice::Volpath(TracerEstimator::Ad)
    }

    /// `model` with its default estimator.
    pub fn default_of(model: ModelKind) -> Self {
        Self::new(model, None).expect("a model's first estimator is its own")
    }

    /// Which model.
    pub fn kind(self) -> ModelKind {
        match self {
            ModelChoice::Learned(_) => ModelKind::Learned,
            ModelChoice::Volpath(_) => ModelKind::Volpath,
            ModelChoice::Dipole(_) => ModelKind::Dipole,
        }
    }

    /// The estimator's name.
    pub fn estimator_name(self) -> &'static str {
        match self {
            ModelChoice::Learned(e) => e.name(),
            ModelChoice::Volpath(e) | ModelChoice::Dipole(e) => e.name(),
        }
    }
}

/// In files: `model` (left out for the learned model, so files written before there was a choice
/// read alike) and the estimator as `method`.
impl Serialize for ModelChoice {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let kind = self.kind();
        let mut m = s.serialize_map(None)?;
        if !kind.is_default() {
            m.serialize_entry("model", &kind)?;
        }
        m.serialize_entry("method", self.estimator_name())?;
        m.end()
    }
}

impl<'de> Deserialize<'de> for ModelChoice {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        struct Named {
            #[serde(default)]
            model: ModelKind,
            method: String,
        }
        let n = Named::deserialize(d)?;
        ModelChoice::new(n.model, Some(&n.method)).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every model takes each of its named estimators and refuses the others' with a message
    /// listing its own; the JSON form reads back.
    #[test]
    fn names_pair_only_with_their_model() {
        for kind in ModelKind::ALL {
            for name in kind.estimators() {
                let c = ModelChoice::new(kind, Some(name)).unwrap();
                assert_eq!((c.kind(), c.estimator_name()), (kind, *name));
                let json = serde_json::to_value(c).unwrap();
                assert_eq!(serde_json::from_value::<ModelChoice>(json).unwrap(), c);
            }
        }
        let e = ModelChoice::new(ModelKind::Learned, Some("ad")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the learned model has no estimator \"ad\"; its estimators: ours, ours-alpha-offsets, naive, fd"
        );
        let e = ModelChoice::new(ModelKind::Volpath, Some("ours")).unwrap_err();
        assert!(e.to_string().ends_with("its estimators: ad, fd"), "{e}");
        assert_eq!(
            ModelChoice::default(),
            ModelChoice::default_of(ModelKind::Learned)
        );
        let learned = serde_json::to_string(&ModelChoice::default()).unwrap();
        assert_eq!(learned, r#"{"method":"ours"}"#);
    }
}
