//! Where a fit starts, and what the settings read from the dataset to decide it.
//!
//! The paper's start, σ_t = 50 and α = 0.5 per channel, is a number in the scene's units: about
//! 50 mean free paths across an object a unit across, the middle of the optical sizes the
//! defaults are measured on. A dataset that states its length unit (a capture in millimetres)
//! says more: its object is a real material, and real materials lie far from 50 mm⁻¹ (the
//! same number puts a 30 mm object at 1500 mean free paths, beyond what the learned model's
//! fit can hold). There σ_t starts at a typical real material's,
//!
//!   σ_t,0 = exp(mean over Jensen et al. 2001's 12 materials × 3 channels of ln σ_t)
//!         = 1.50 mm⁻¹ at g = 0, in the dataset's unit and at its stated g
//!
//! ([`scene::measured::typical_sigma_t`]; the materials span 0.17–20 mm⁻¹, so the start is within
//! a factor of 14 of each of them, and within 2.5 of marble, milks, skin and apple). A dataset
//! without a unit starts at 50 per unit, and a start given explicitly is never changed.

use std::path::Path;

use inverse::params::Params;
use scene::measured::{LengthUnit, typical_sigma_t};

use crate::RecoveryError;

/// The initial medium and the number of initialisations tried first.
#[derive(Clone, Debug, PartialEq)]
pub struct StartSettings {
    /// Initial σ_t and α (the paper's σ_t = 50, α = 0.5).
    pub init: Params,
    /// Start σ_t at a typical real material's where the dataset states its length unit
    /// (module docs); false when σ_t's start was given explicitly.
    pub sigma_t_from_units: bool,
    /// Initialisations tried first (1: none; [`crate::multi_start`]).
    pub starts: u32,
}

impl StartSettings {
    /// The start for the dataset `facts` describes: `init`, with σ_t a typical real material's
    /// when [`StartSettings::sigma_t_from_units`] and the dataset states its unit.
    pub fn init_for(&self, facts: &DatasetFacts) -> Params {
        let mut p = self.init;
        if let Some(unit) = facts.length_unit.filter(|_| self.sigma_t_from_units) {
            let s = f64::from(typical_sigma_t(facts.g, unit) as f32);
            p.sigma_t = [s; 3];
            tracing::info!(
                "σ_t starts at {s:.3} per {} (a typical real material's at g = {}: the geometric \
                 mean of Jensen et al. 2001's); give another start to change it",
                unit.name(),
                facts.g
            );
        }
        p
    }
}

/// What the settings read from the dataset.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DatasetFacts {
    /// The tracer depth the images were rendered with (`None`: not recorded).
    pub depth: Option<u32>,
    /// What one of its units is, when it says (`None`: unitless; σ_t starts at 50 per unit).
    pub length_unit: Option<LengthUnit>,
    /// The object's stated Henyey–Greenstein g, the channels' mean (0 when it states none).
    pub g: f64,
}

impl DatasetFacts {
    /// A dataset rendered at tracer depth `depth`, with no unit.
    pub fn at_depth(depth: u32) -> DatasetFacts {
        DatasetFacts {
            depth: Some(depth),
            ..DatasetFacts::default()
        }
    }

    /// The facts of the dataset at `path` (its file or folder).
    pub fn read(path: &Path) -> Result<DatasetFacts, RecoveryError> {
        let ds = scene::Dataset::load(path)?;
        Ok(DatasetFacts {
            depth: ds.render.max_depth,
            length_unit: ds.metadata.length_unit,
            g: ds.object.map_or(0.0, |o| f64::from(o.g.mean())),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dataset in millimetres starts at 1.50 mm⁻¹ (at its g); one without a unit, or a start
    /// given explicitly, is not changed.
    #[test]
    fn only_a_start_not_given_follows_the_stated_unit() {
        let init = Params::new([50.0, 60.0, 90.0], [0.5; 3]);
        let mut s = StartSettings {
            init,
            sigma_t_from_units: true,
            starts: 1,
        };
        let mm = DatasetFacts {
            depth: None,
            length_unit: Some(LengthUnit::Mm),
            g: 0.0,
        };
        let p = s.init_for(&mm);
        assert!(p.sigma_t.iter().all(|v| (v - 1.5009).abs() < 1e-3), "{p:?}");
        assert_eq!(p.albedo, init.albedo);
        let cm = s.init_for(&DatasetFacts {
            length_unit: Some(LengthUnit::Cm),
            ..mm
        });
        assert!((cm.sigma_t[0] / p.sigma_t[0] - 10.0).abs() < 1e-5);
        let forward = s.init_for(&DatasetFacts { g: 0.7, ..mm });
        assert!(forward.sigma_t[0] > 2.5 * p.sigma_t[0], "{forward:?}");
        assert_eq!(s.init_for(&DatasetFacts::default()), init);
        s.sigma_t_from_units = false;
        assert_eq!(s.init_for(&mm), init);
    }
}
