//! Seconds per iteration of every forward model × estimator on one workload (the comparison of
//! Son et al. 2024, Table 1): each pair runs the inverse loop with `optimize`'s defaults from the
//! same start for a few iterations on the same targets, and reports the mean time of an
//! iteration after the first (which also builds the per-view lists and warms the caches), with
//! its standard error over the iterations.

use bssrdf::nn::ShapeAdaptiveModel;
use geometry::Accel;
use scene::Medium;
use serde::{Deserialize, Serialize};

use crate::error::InverseError;
use crate::forward::{ModelChoice, ModelKind};
use crate::optimize::{OptimizeConfig, Optimizer, TargetView};
use crate::params::Params;

/// The workload of a timing run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TimingSettings {
    /// Iterations per pair (at least 2: the first is not counted).
    pub iterations: u32,
    /// Samples per pixel per iteration (the learned model's default estimator also runs at
    /// twice this, as the paper's Table 1 does).
    pub spp: u32,
    /// Seed of the runs.
    pub seed: u64,
    /// Path depth of the volumetric model.
    pub volpath_max_depth: u32,
}

/// The iteration times of one model × estimator.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TimingRow {
    pub model: ModelKind,
    /// The estimator's name ([`DiffMethod::name`]).
    pub method: String,
    /// Samples per pixel per iteration.
    pub spp: u32,
    /// Seconds of every iteration.
    pub seconds: Vec<f64>,
}

impl TimingRow {
    /// The iterations after the first.
    fn counted(&self) -> &[f64] {
        if self.seconds.len() > 1 {
            &self.seconds[1..]
        } else {
            &self.seconds
        }
    }

    /// Mean seconds per iteration (module docs).
    pub fn mean(&self) -> f64 {
        let s = self.counted();
        s.iter().sum::<f64>() / s.len().max(1) as f64
    }

    /// Standard error of [`TimingRow::mean`].
    pub fn std_error(&self) -> f64 {
        let s = self.counted();
        let n = s.len() as f64;
        if n < 2.0 {
            return f64::NAN;
        }
        let m = self.mean();
        (s.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt()
    }
}

/// Every model × estimator pair, each model's default estimator first.
pub fn all_pairs() -> Vec<ModelChoice> {
    ModelKind::ALL
        .iter()
        .flat_map(|&m| {
            m.estimators()
                .iter()
                .map(move |e| ModelChoice::new(m, Some(e)).expect("the model's own estimator"))
        })
        .collect()
}

/// Times `settings.iterations` iterations of the loop with `model` × `method` at `spp` samples
/// per pixel on `targets` (`nets`: the learned model's networks; `base`: g and η of the
/// medium), from σ_t = 50, α = 0.5 with `optimize`'s defaults otherwise.
#[allow(clippy::too_many_arguments)]
pub fn measure(
    accel: &Accel,
    nets: &ShapeAdaptiveModel,
    base: Medium,
    targets: &[TargetView],
    model: ModelChoice,
    spp: u32,
    settings: &TimingSettings,
) -> Result<TimingRow, InverseError> {
    let mut c = OptimizeConfig::new(Params {
        sigma_t: [50.0; 3],
        albedo: [0.5; 3],
        g: None,
        light_scale: None,
    });
    c.model = model;
    c.spp = spp;
    c.iterations = settings.iterations;
    // One forward model's iterations: no refinement by another.
    c.refine_iterations = 0;
    c.seed = settings.seed;
    if model.kind() == ModelKind::Volpath {
        c.volpath_max_depth = Some(settings.volpath_max_depth);
    }
    let row = time_iterations(accel, nets, base, targets, c)?;
    Ok(TimingRow {
        model: model.kind(),
        method: model.estimator_name().to_string(),
        ..row
    })
}

/// The name of [`measure_defaults`]'s row.
pub const DEFAULTS: &str = "defaults";

/// Times `settings.iterations` iterations of `optimize`'s defaults at `spp` (the learned model,
/// then the volumetric path tracer for the default share of the iterations:
/// [`OptimizeConfig::default_refinement`]), counted as in [`measure`]: the mean over a run of
/// this length is the defaults' seconds per iteration over any length (the share is the same),
/// up to the refinement's first iteration, which also builds the tracer's per-view lists.
pub fn measure_defaults(
    accel: &Accel,
    nets: &ShapeAdaptiveModel,
    base: Medium,
    targets: &[TargetView],
    spp: u32,
    settings: &TimingSettings,
) -> Result<TimingRow, InverseError> {
    let mut c = OptimizeConfig::default().with_iterations(settings.iterations);
    c.spp = spp;
    c.seed = settings.seed;
    c.volpath_max_depth = Some(settings.volpath_max_depth);
    let row = time_iterations(accel, nets, base, targets, c)?;
    Ok(TimingRow {
        method: DEFAULTS.to_string(),
        ..row
    })
}

/// Runs the iterations of `c` on `targets` and records each one's seconds.
fn time_iterations(
    accel: &Accel,
    nets: &ShapeAdaptiveModel,
    base: Medium,
    targets: &[TargetView],
    c: OptimizeConfig,
) -> Result<TimingRow, InverseError> {
    let (model, spp, iterations) = (c.model.kind(), c.spp, c.iterations);
    let views = targets
        .iter()
        .map(|t| TargetView {
            camera: t.camera,
            light: t.light,
            image: t.image,
        })
        .collect();
    let method = c.model.estimator_name().to_string();
    let mut opt = Optimizer::new(c, accel, Some(nets), base, views)?;
    for _ in 0..iterations {
        opt.step()?;
    }
    Ok(TimingRow {
        model,
        method,
        spp,
        seconds: opt.history().iter().map(|r| r.seconds).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_and_statistics() {
        let pairs = all_pairs();
        assert_eq!(pairs.len(), 8);
        assert_eq!(pairs[0], ModelChoice::default());
        let r = TimingRow {
            model: ModelKind::Dipole,
            method: "ad".into(),
            spp: 32,
            seconds: vec![9.0, 1.0, 2.0, 3.0],
        };
        assert_eq!(r.mean(), 2.0);
        assert!((r.std_error() - (1.0f64 / 3.0).sqrt()).abs() < 1e-12);
    }
}
