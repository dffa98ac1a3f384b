//! Adam (Kingma & Ba 2015) with a staircase learning-rate decay and global-norm gradient
//! clipping (docs/model.md §6).
//!
//! With g the (clipped) gradient at step t (1-based):
//! m ← β₁m + (1−β₁)g, v ← β₂v + (1−β₂)g², θ ← θ − lr_t · m̂/(√v̂ + ε) with m̂ = m/(1−β₁ᵗ),
//! v̂ = v/(1−β₂ᵗ). After [`Adam::restart_moments`] at step t₀, m and v start again from zero
//! and the bias corrections count t − t₀ (the learning-rate schedule keeps counting t). lr_t = max(lr·decay^⌊(t−1)/every⌋, lr·floor_fraction). Clipping: if
//! ‖g‖₂ > c, g ← g·c/‖g‖₂ (over all parameters together).

use serde::{Deserialize, Serialize};

/// Optimiser settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdamConfig {
    /// Initial learning rate.
    pub lr: f32,
    /// β₁.
    pub beta1: f32,
    /// β₂.
    pub beta2: f32,
    /// ε.
    pub eps: f32,
    /// Staircase decay factor.
    pub decay: f32,
    /// Steps between decays.
    pub decay_every: u64,
    /// Lower bound of the learning rate as a fraction of `lr`.
    pub floor_fraction: f32,
    /// Global-norm clipping threshold (≤ 0: off).
    pub clip_norm: f32,
}

impl Default for AdamConfig {
    /// VKJ19's settings (docs/model.md §6): lr 2e-4, ×0.8 every 100k steps, floor lr/8, clip 100.
    fn default() -> Self {
        Self {
            lr: 2e-4,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            decay: 0.8,
            decay_every: 100_000,
            floor_fraction: 0.125,
            clip_norm: 100.0,
        }
    }
}

/// Optimiser state (what a checkpoint stores).
#[derive(Clone, Debug, PartialEq)]
pub struct AdamState {
    /// Steps taken.
    pub step: u64,
    /// First moments.
    pub m: Vec<f32>,
    /// Second moments.
    pub v: Vec<f32>,
    /// The step count at which the moments last started from zero ([`Adam::restart_moments`]);
    /// 0 for a run that never restarted them.
    pub moments_from: u64,
}

/// Adam over a flat parameter vector.
#[derive(Clone, Debug)]
pub struct Adam {
    config: AdamConfig,
    state: AdamState,
}

impl Adam {
    /// A fresh optimiser for `n` parameters.
    pub fn new(n: usize, config: AdamConfig) -> Self {
        Self {
            config,
            state: AdamState {
                step: 0,
                m: vec![0.0; n],
                v: vec![0.0; n],
                moments_from: 0,
            },
        }
    }

    /// An optimiser continuing from `state`.
    pub fn from_state(config: AdamConfig, state: AdamState) -> Self {
        Self { config, state }
    }

    /// The state.
    pub fn state(&self) -> AdamState {
        self.state.clone()
    }

    /// Starts the moments again from zero, keeping the step count (and so the learning-rate
    /// schedule). For an objective whose gradient changes scale, e.g. a new forward model:
    /// without it, v remembers the old scale for ~1/(1−β₂) steps and the steps shrink or grow
    /// by the ratio of the scales.
    pub fn restart_moments(&mut self) {
        self.state.m.fill(0.0);
        self.state.v.fill(0.0);
        self.state.moments_from = self.state.step;
    }

    /// Learning rate of the step after `steps_done` steps.
    pub fn learning_rate(&self, steps_done: u64) -> f32 {
        let c = &self.config;
        let k = steps_done / c.decay_every.max(1);
        let lr = c.lr * c.decay.powi(k.min(i32::MAX as u64) as i32);
        lr.max(c.lr * c.floor_fraction)
    }

    /// One step: clips `grad` (in place) and updates `params`. Returns the gradient norm
    /// before clipping.
    ///
    /// # Panics
    /// If `params` or `grad` do not have the optimiser's length.
    pub fn step(&mut self, params: &mut [f32], grad: &mut [f32]) -> f32 {
        self.step_scaled(params, grad, &[])
    }

    /// As [`Adam::step`] with a per-parameter learning-rate factor (`scale[i]` multiplies the
    /// learning rate of parameter i; an empty slice means 1 for all).
    ///
    /// # Panics
    /// If the lengths differ from the optimiser's (or `scale` is neither empty nor as long).
    pub fn step_scaled(&mut self, params: &mut [f32], grad: &mut [f32], scale: &[f32]) -> f32 {
        assert!(
            scale.is_empty() || scale.len() == params.len(),
            "Adam: one learning-rate factor per parameter"
        );
        assert_eq!(
            params.len(),
            self.state.m.len(),
            "Adam: parameter count changed"
        );
        assert_eq!(
            grad.len(),
            self.state.m.len(),
            "Adam: gradient length differs"
        );
        let norm = grad.iter().map(|g| (*g as f64).powi(2)).sum::<f64>().sqrt() as f32;
        if self.config.clip_norm > 0.0 && norm > self.config.clip_norm {
            let s = self.config.clip_norm / norm;
            grad.iter_mut().for_each(|g| *g *= s);
        }
        let lr = self.learning_rate(self.state.step);
        // Saturating: the count may come from a checkpoint file. Past 2³¹ steps the bias
        // corrections are 1 to f32 precision, so clamping t changes nothing.
        self.state.step = self.state.step.saturating_add(1);
        let t = (self.state.step.saturating_sub(self.state.moments_from)).clamp(1, i32::MAX as u64)
            as i32;
        let c = &self.config;
        let bc1 = 1.0 - c.beta1.powi(t);
        let bc2 = 1.0 - c.beta2.powi(t);
        for (i, ((p, &g), (m, v))) in params
            .iter_mut()
            .zip(grad.iter())
            .zip(self.state.m.iter_mut().zip(self.state.v.iter_mut()))
            .enumerate()
        {
            let lr_i = if scale.is_empty() { lr } else { lr * scale[i] };
            *m = c.beta1 * *m + (1.0 - c.beta1) * g;
            *v = c.beta2 * *v + (1.0 - c.beta2) * g * g;
            *p -= lr_i * (*m / bc1) / ((*v / bc2).sqrt() + c.eps);
        }
        norm
    }
}

#[cfg(test)]
mod tests {

    /// A step count read from a damaged checkpoint (2⁶⁴ − 1) saturates instead of overflowing,
    /// and the step is the bias-corrected one of a long run.
    #[test]
    fn a_huge_step_count_saturates() {
        let mut adam = Adam::from_state(
            AdamConfig::default(),
            AdamState {
                step: u64::MAX,
                m: vec![0.0],
                v: vec![0.0],
                moments_from: 0,
            },
        );
        let mut p = [1.0f32];
        adam.step(&mut p, &mut [0.5]);
        assert_eq!(adam.state().step, u64::MAX);
        assert!(p[0].is_finite() && p[0] < 1.0);
    }

    use super::*;

    #[test]
    fn first_step_moves_every_parameter_by_lr_against_the_gradient_sign() {
        let mut adam = Adam::new(3, AdamConfig::default());
        let mut p = [1.0f32, -2.0, 0.5];
        let mut g = [0.3f32, -4.0, 1e-3];
        adam.step(&mut p, &mut g);
        // m̂ = g, v̂ = g² ⇒ Δ = −lr·g/(|g| + ε) ≈ −lr·sign(g).
        let lr = 2e-4;
        for (got, want) in p.iter().zip([1.0 - lr, -2.0 + lr, 0.5 - lr]) {
            assert!((got - want).abs() < 1e-6, "{got} vs {want}");
        }
    }

    /// After a restart the next step is a first step again (Δ = −lr_t·sign(g), whatever the
    /// old moments held), at the learning rate the schedule has reached by then.
    #[test]
    fn restarted_moments_step_like_a_first_step_on_the_running_schedule() {
        let cfg = AdamConfig {
            lr: 0.1,
            decay: 0.5,
            decay_every: 4,
            floor_fraction: 0.0,
            ..AdamConfig::default()
        };
        let mut adam = Adam::new(2, cfg);
        let mut p = [0.0f32, 0.0];
        for _ in 0..6 {
            adam.step(&mut p, &mut [100.0, -100.0]);
        }
        adam.restart_moments();
        assert_eq!(adam.state().moments_from, 6);
        let before = p;
        adam.step(&mut p, &mut [1e-3, -1e-3]);
        // Without the restart, v ≈ 1e4·(1−β₂⁶)… would shrink this step ~1e5-fold.
        let lr = 0.1 * 0.5; // the step after 6 steps: one decay
        assert!((p[0] - (before[0] - lr)).abs() < 1e-6, "{p:?}");
        assert!((p[1] - (before[1] + lr)).abs() < 1e-6, "{p:?}");
        assert_eq!(adam.state().step, 7);
    }

    /// A restart point after the step count (a damaged checkpoint) still gives finite steps.
    #[test]
    fn a_restart_point_past_the_step_count_stays_finite() {
        let mut adam = Adam::from_state(
            AdamConfig::default(),
            AdamState {
                step: 3,
                m: vec![0.0],
                v: vec![0.0],
                moments_from: 10,
            },
        );
        let mut p = [1.0f32];
        adam.step(&mut p, &mut [0.5]);
        assert!(p[0].is_finite() && p[0] < 1.0);
    }

    #[test]
    fn converges_on_a_quadratic() {
        let cfg = AdamConfig {
            lr: 0.05,
            ..AdamConfig::default()
        };
        let target = [3.0f32, -1.0, 0.25, 10.0];
        let scale = [1.0f32, 10.0, 0.1, 2.0];
        let mut p = [0.0f32; 4];
        let mut adam = Adam::new(4, cfg);
        for _ in 0..3000 {
            let mut g: Vec<f32> = (0..4)
                .map(|i| 2.0 * scale[i] * (p[i] - target[i]))
                .collect();
            adam.step(&mut p, &mut g);
        }
        for i in 0..4 {
            assert!((p[i] - target[i]).abs() < 1e-2, "{p:?}");
        }
    }

    #[test]
    fn clipping_scales_the_global_norm_and_schedule_is_staircase_with_floor() {
        let cfg = AdamConfig {
            clip_norm: 1.0,
            decay: 0.5,
            decay_every: 10,
            floor_fraction: 0.2,
            lr: 1.0,
            ..AdamConfig::default()
        };
        let mut adam = Adam::new(2, cfg);
        let mut g = [3.0f32, 4.0];
        let norm = adam.step(&mut [0.0, 0.0], &mut g);
        assert_eq!(norm, 5.0);
        assert!(((g[0] * g[0] + g[1] * g[1]).sqrt() - 1.0).abs() < 1e-6);
        assert_eq!(adam.learning_rate(0), 1.0);
        assert_eq!(adam.learning_rate(9), 1.0);
        assert_eq!(adam.learning_rate(10), 0.5);
        assert_eq!(adam.learning_rate(20), 0.25);
        assert_eq!(adam.learning_rate(30), 0.2);
        assert_eq!(adam.learning_rate(1000), 0.2);
    }
}
