//! Multi-view inverse rendering with the learned BSSRDF (Son et al. 2024 §5; docs/model.md §8.3,
//! A10–A12): Adam on the medium parameters with the gradient of the image loss from
//! [`bssrdf::diff::render_loss_gradient`].
//!
//! Iteration k: draw `views_per_iter` views (stream `hash(seed, k)`), render each at the current
//! parameters with `spp` samples per pixel and the iteration's seed (one render per view: the
//! single-render L2 gradient of SON24, A11), sum ∂ℓ/∂(σ_t, α) over the views, map it to the
//! optimiser's variables ([`crate::params`]), take one Adam step with per-parameter learning rates
//! (`lr_sigma_t` on σ_t/100 or ln σ_t, `lr_albedo` on α) decayed ×`decay` every `decay_every`
//! iterations, clamp. The vertex polynomials are fitted once at the initial parameters (A10) and,
//! if `refit_every` > 0, again every that many iterations at the current ones.
//!
//! Everything random derives from (seed, iteration, view, pixel), so a run is reproducible for a
//! given thread count and a resumed run continues exactly where the checkpoint left off.

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use base::optim::{Adam, AdamConfig, AdamState};
use base::rng::{Sampler, hash_key};
use bssrdf::diff::Loss;
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::render::RenderSettings;
use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};
use serde::{Deserialize, Serialize};

use crate::forward::{ForwardModel, ModelChoice};
use crate::params::{OneOrRgb, Params};

/// One row of the per-iteration history.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// Iteration (0-based).
    pub iteration: u32,
    /// Mean loss over the iteration's views.
    pub loss: f64,
    /// Parameters BEFORE the step.
    pub params: Params,
    /// ∂ℓ/∂σ_t per channel.
    pub d_sigma_t: [f64; 3],
    /// ∂ℓ/∂α per channel.
    pub d_albedo: [f64; 3],
    /// ∂ℓ/∂g where the run recovers g and the iteration's model differentiates it, one or one
    /// per channel as g (left out of the JSON otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d_g: Option<OneOrRgb<f64>>,
    /// ∂ℓ/∂ln k where the run recovers the light scale, one or one per channel as the scale
    /// (left out of the JSON otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub d_ln_light_scale: Option<OneOrRgb<f64>>,
    /// Views used.
    pub views: Vec<usize>,
    /// Top-left pixel (x0, y0) of each view's crop window (`--crop`; empty without crops).
    #[serde(default)]
    pub crop_origins: Vec<[u32; 2]>,
    /// Seconds of this iteration.
    pub seconds: f64,
    /// The misfit without the render's noise, [`cross_misfit`] (L2 with split samples only;
    /// `None` otherwise and in histories written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub misfit: Option<f64>,
}

/// The loss gradient of one iteration ([`Optimizer::gradient`]).
#[derive(Clone, Debug, PartialEq)]
pub struct IterationGradient {
    /// Mean (weighted) loss over the iteration's views.
    pub loss: f64,
    /// ∂ℓ/∂σ_t per channel.
    pub d_sigma_t: [f64; 3],
    /// ∂ℓ/∂α per channel.
    pub d_albedo: [f64; 3],
    /// ∂ℓ/∂g_c per channel (channel c's term; a g shared by the channels has their sum), where
    /// every view's derivative images had ∂I/∂g.
    pub d_g: Option<[f64; 3]>,
    /// ∂ℓ/∂ln k_c per channel of a factor k_c on the lights' channel c, where every view's
    /// gradient had it (a factor shared by the channels has their sum).
    pub d_ln_light_scale: Option<[f64; 3]>,
    /// Views used.
    pub views: Vec<usize>,
    /// Crop origins (empty without crops).
    pub crop_origins: Vec<[u32; 2]>,
    /// Mean (weighted) [`cross_misfit`] over the iteration's views, where the gradient has it.
    pub misfit: Option<f64>,
}

/// A run in progress.
pub struct Optimizer<'a> {
    config: OptimizeConfig,
    forward: Box<dyn ForwardModel + 'a>,
    /// Which model `forward` is ([`OptimizeConfig::model_at`]).
    forward_kind: ModelChoice,
    accel: &'a Accel,
    /// The learned model's networks, where the run has them.
    networks: Option<&'a ShapeAdaptiveModel>,
    base: Medium,
    targets: Vec<TargetView<'a>>,
    adam: Adam,
    u: Vec<f32>,
    history: Vec<IterationRecord>,
    /// Per-view, per-channel loss weights ([`view_weights`]).
    weights: Vec<[f64; 3]>,
}

mod checkpoint;
mod config;
pub(crate) mod gradient;
mod intervals;
mod target;

pub use crate::error::InverseError;
pub use checkpoint::Checkpoint;
pub(crate) use config::model_spec;
pub use config::{DEFAULT_REFINE_SHARE, MAX_VIEWS_PER_ITER, OptimizeConfig};
pub use gradient::{cross_misfit, split_sample_gradient, view_weights};
pub(crate) use gradient::{decorrelated_gradient, non_finite_part};
pub use target::TargetView;

impl<'a> Optimizer<'a> {
    /// A new run. `base` supplies g and η (the parameters come from `config.init`); `config.model`
    /// chooses the forward model over `accel` (`networks`: the learned model's, needed by it
    /// alone).
    pub fn new(
        config: OptimizeConfig,
        accel: &'a Accel,
        networks: Option<&'a ShapeAdaptiveModel>,
        base: Medium,
        targets: Vec<TargetView<'a>>,
    ) -> Result<Self, InverseError> {
        config.check().map_err(InverseError::Invalid)?;
        let forward = model_spec(&config, config.model_at(0), networks)?.build(accel);
        Self::with_forward(config, accel, forward, networks, base, targets)
    }

    /// A new run that renders with `forward`, any [`ForwardModel`] over `accel`, in place of
    /// the one `config.model` names (until a refinement hands the run to the tracer).
    pub fn with_forward(
        config: OptimizeConfig,
        accel: &'a Accel,
        mut forward: Box<dyn ForwardModel + 'a>,
        networks: Option<&'a ShapeAdaptiveModel>,
        base: Medium,
        targets: Vec<TargetView<'a>>,
    ) -> Result<Self, InverseError> {
        if targets.is_empty() {
            return Err(InverseError::Invalid("no target views".into()));
        }
        config.check().map_err(InverseError::Invalid)?;
        let mut config = config;
        if config.params.free_g && config.init.g.is_none() {
            // A free g starts at the object's stated value: its channels' own where each
            // channel has a g, their mean where they share one.
            let g = base.g.channels().map(f64::from);
            config.init.g = Some(if config.params.g_per_channel {
                OneOrRgb::Rgb(g)
            } else {
                OneOrRgb::One(base.g.mean() as f64)
            });
        }
        let init_medium = config.init.medium(&base);
        init_medium
            .validate("initial parameters")
            .map_err(|e| InverseError::Invalid(e.to_string()))?;
        let forward_kind = config.model_at(0);
        forward.prepare(&init_medium)?;
        let u = config.params.encode(&config.init);
        let adam = Adam::new(u.len(), adam_config(&config));
        let parts = Parts {
            forward,
            forward_kind,
            accel,
            networks,
            adam,
            u,
            history: Vec::new(),
        };
        Ok(Self::assemble(config, base, targets, parts))
    }

    /// The run from its configuration, inputs and state.
    fn assemble(
        config: OptimizeConfig,
        base: Medium,
        targets: Vec<TargetView<'a>>,
        p: Parts<'a>,
    ) -> Self {
        let images: Vec<&Image> = targets.iter().map(|t| t.image).collect();
        let weights = view_weights(
            &images,
            config.loss,
            config.normalize_views,
            config.view_weight_floor,
        );
        Self {
            weights,
            config,
            forward: p.forward,
            forward_kind: p.forward_kind,
            accel: p.accel,
            networks: p.networks,
            base,
            targets,
            adam: p.adam,
            u: p.u,
            history: p.history,
        }
    }

    /// Iterations done.
    pub fn iteration(&self) -> u32 {
        self.history.len() as u32
    }

    /// Current parameters.
    pub fn params(&self) -> Params {
        self.config.params.decode(&self.u)
    }

    /// The history.
    pub fn history(&self) -> &[IterationRecord] {
        &self.history
    }

    /// The configuration.
    pub fn config(&self) -> &OptimizeConfig {
        &self.config
    }

    /// The image of one view rendered by the run's forward model at `p` (no derivatives).
    pub fn render(
        &self,
        p: &Params,
        camera: &Camera,
        light: &PointLight,
        rs: &RenderSettings,
    ) -> Result<Image, InverseError> {
        let at = self.forward.at(p.medium(&self.base))?;
        at.view(camera, &p.light(light)).value(rs, None)
    }

    /// The loss and its gradient of iteration `k` at the parameters `p` (the views, crops and
    /// random numbers of that iteration; no step). [`Optimizer::step`] at iteration k is this
    /// at the current parameters followed by the Adam step.
    pub fn gradient(&self, k: u32, p: &Params) -> Result<IterationGradient, InverseError> {
        let c = &self.config;
        let at = self.forward.at(p.medium(&self.base))?;
        let mut rng = Sampler::new(c.seed, 0x0AD1_0E55, k as u64, 0);
        let n = self.targets.len() as u32;
        let views: Vec<usize> = (0..c.views_per_iter)
            .map(|_| rng.next_below(n) as usize)
            .collect();
        // Crop windows, drawn after the views (so the views do not depend on the crop).
        let crops: Vec<Option<(Camera, Image, [u32; 2])>> = views
            .iter()
            .map(|&v| {
                let t = &self.targets[v];
                let Some(size) = c.crop else {
                    return Ok(None);
                };
                let (w, h) = (size.min(t.camera.width), size.min(t.camera.height));
                let x0 = rng.next_below(t.camera.width - w + 1);
                let y0 = rng.next_below(t.camera.height - h + 1);
                let camera = t
                    .camera
                    .cropped(x0, y0, w, h)
                    .map_err(|e| InverseError::Invalid(format!("view {v}: {e}")))?;
                Ok(Some((camera, t.image.crop(x0, y0, w, h), [x0, y0])))
            })
            .collect::<Result<_, InverseError>>()?;
        let (mut loss, mut ds_t, mut da) = (0.0, [0.0; 3], [0.0; 3]);
        let (mut misfit, mut d_g, mut d_k) = (Some(0.0), Some([0.0; 3]), Some([0.0; 3]));
        for (&v, crop) in views.iter().zip(&crops) {
            let full = &self.targets[v];
            // The light as the run has it (a recovered scale on its stated intensity).
            let light = p.light(full.light);
            let t = match crop {
                Some((camera, image, _)) => TargetView {
                    camera,
                    light: &light,
                    image,
                },
                None => TargetView {
                    light: &light,
                    ..*full
                },
            };
            let (g, view_misfit) = self.view_gradient(&*at, &t, k, v)?;
            if let Some(what) = non_finite_part(&g) {
                return Err(InverseError::NonFinite {
                    iteration: k,
                    view: Some(v),
                    what,
                });
            }
            let w = self.weights[v];
            misfit = match (misfit, view_misfit) {
                (Some(m), Some(x)) => Some(
                    m + (0..3)
                        .map(|ch| w[ch] * x[ch] / views.len() as f64)
                        .sum::<f64>(),
                ),
                _ => None,
            };
            for ch in 0..3 {
                loss += w[ch] * g.loss_channels[ch] / views.len() as f64;
                ds_t[ch] += w[ch] * g.d_sigma_t[ch] / views.len() as f64;
                da[ch] += w[ch] * g.d_albedo[ch] / views.len() as f64;
            }
            let per_channel = |sum: [f64; 3], d: [f64; 3]| {
                std::array::from_fn(|ch| sum[ch] + w[ch] * d[ch] / views.len() as f64)
            };
            d_g = d_g.zip(g.d_g).map(|(sum, d)| per_channel(sum, d));
            d_k = d_k
                .zip(g.d_ln_light_scale)
                .map(|(sum, d)| per_channel(sum, d));
        }
        if !loss.is_finite() || ds_t.iter().chain(&da).any(|g| !g.is_finite()) {
            return Err(InverseError::NonFinite {
                iteration: k,
                view: None,
                what: format!("the loss or its gradient over the views (loss {loss})"),
            });
        }
        Ok(IterationGradient {
            loss,
            misfit,
            d_sigma_t: ds_t,
            d_albedo: da,
            d_g,
            d_ln_light_scale: d_k,
            views,
            crop_origins: crops.iter().flatten().map(|c| c.2).collect(),
        })
    }

    /// The loss gradient of target view `t` (index `v`) in iteration `k` by the configured
    /// estimator, and the view's noise-free misfit where the estimator has it.
    fn view_gradient(
        &self,
        at: &dyn crate::forward::MediumRenderer,
        t: &TargetView,
        k: u32,
        v: usize,
    ) -> Result<(bssrdf::diff::LossGradient, Option<[f64; 3]>), InverseError> {
        let c = &self.config;
        let spp = c.spp_at(k);
        let rs = RenderSettings {
            spp,
            seed: hash_key(&[c.seed, k as u64]),
            view: v as u64,
        };
        let mut view_misfit = None;
        let g = if c.two_renders && c.split_samples && spp >= 2 {
            // Two derivative renders with half the samples each and independent seeds:
            // ∂ℓ/∂θ = ½[∂ℓ/∂I(I_A)·∂I_B/∂θ + ∂ℓ/∂I(I_B)·∂I_A/∂θ], no covariance bias, the
            // cost of one render at `spp`.
            let half = spp / 2;
            let rs_a = RenderSettings { spp: half, ..rs };
            let rs_b = RenderSettings {
                spp: spp - half,
                seed: hash_key(&[c.seed, k as u64, 0xB]),
                ..rs
            };
            let view = at.view(t.camera, t.light);
            let da = view.derivatives(&rs_a, None)?;
            let db = view.derivatives(&rs_b, None)?;
            if c.loss == Loss::L2 {
                view_misfit = Some(cross_misfit(&da.value, &db.value, t.image));
            }
            split_sample_gradient(&da, &db, t.image, c.loss)
        } else if c.two_renders {
            // I₁ (seed A) gives ∂ℓ/∂I, the derivative images of a render with seed B give
            // ∂I/∂θ: two renders, independent samples (no covariance bias).
            let rs_b = RenderSettings {
                seed: hash_key(&[c.seed, k as u64, 0xB]),
                ..rs
            };
            // One set of camera rays (the view's triangle lists) for both renders.
            let view = at.view(t.camera, t.light);
            let i1 = view.value(&rs, None)?;
            let d2 = view.derivatives(&rs_b, None)?;
            decorrelated_gradient(&i1, &d2, t.image, c.loss)
        } else {
            at.view(t.camera, t.light)
                .loss_gradient(&rs, t.image, c.loss)?
        };
        Ok((g, view_misfit))
    }

    /// One iteration.
    pub fn step(&mut self) -> Result<&IterationRecord, InverseError> {
        let t0 = Instant::now();
        let k = self.iteration();
        let p = self.params();
        let c = &self.config;
        let kind = c.model_at(k);
        if kind != self.forward_kind {
            // The refinement begins: the tracer from here on, at the current parameters.
            let mut forward = model_spec(c, kind, self.networks)?.build(self.accel);
            forward.prepare(&p.medium(&self.base))?;
            (self.forward, self.forward_kind) = (forward, kind);
        } else if c.refit_every > 0 && k > 0 && k.is_multiple_of(c.refit_every) {
            self.forward.prepare(&p.medium(&self.base))?;
        }
        // On the refinement's first iteration, whether the run started before it or resumed
        // exactly there (its checkpoint then already holds the tracer, and `kind` matches).
        let restart_moments = c.refine_restarts_moments
            && c.refine_iterations > 0
            && k == c.iterations - c.refine_iterations;
        let IterationGradient {
            loss,
            misfit,
            d_sigma_t: ds_t,
            d_albedo: da,
            d_g,
            d_ln_light_scale: d_k,
            views,
            crop_origins,
        } = self.gradient(k, &p)?;
        let c = &self.config;
        // A free g moves where the iteration's model differentiates it, after the α-first
        // iterations; elsewhere it keeps its value (zero gradient, no Adam moment).
        let moves_g = c.params.free_g && k >= c.effective_albedo_warmup();
        let d_g = d_g.filter(|_| moves_g);
        // A free light scale moves once σ_t and α have fitted the images under the lights as
        // stated ([`OptimizeConfig::light_scale_start`]). Both α and k set the brightness:
        // moved together from a start far darker than the images (α = 0.5), k took up the
        // deficit and the flat α–k valley never gave it back. From the valley's floor k moves
        // along it. (An α at its clamp does not release k earlier: high-albedo media touch it
        // on the way, and k then took up the deficit again.)
        let moves_k = c.params.free_light_scale && k >= c.light_scale_start();
        let d_k = d_k.filter(|_| moves_k);
        let mut g = c.params.chain(
            &p,
            ds_t,
            da,
            d_g.unwrap_or([0.0; 3]),
            d_k.unwrap_or([0.0; 3]),
        );
        let lr_t = if k < c.effective_albedo_warmup() {
            g[..3].fill(0.0);
            0.0
        } else {
            c.lr_sigma_t
        };
        let lr_g = if d_g.is_some() { c.lr_g } else { 0.0 };
        let lr_k = if d_k.is_some() { c.lr_light_scale } else { 0.0 };
        let mut scale = vec![lr_t, lr_t, lr_t, c.lr_albedo, c.lr_albedo, c.lr_albedo];
        scale.extend(c.params.g_indices().map(|_| lr_g));
        scale.extend(c.params.light_scale_indices().map(|_| lr_k));
        let scale = &scale[..];
        // The step is taken on copies and kept only when it is finite, so that a failure
        // leaves the optimiser (and a checkpoint written after it) at the last good state.
        let (mut adam, mut u) = (self.adam.clone(), self.u.clone());
        if restart_moments {
            adam.restart_moments();
        }
        adam.step_scaled(&mut u, &mut g, scale);
        c.params.clamp(&mut u);
        if let Some(i) = u.iter().position(|x| !x.is_finite()) {
            return Err(InverseError::NonFinite {
                iteration: k,
                view: None,
                what: format!("parameter variable {i} after the Adam step ({})", u[i]),
            });
        }
        (self.adam, self.u) = (adam, u);
        self.history.push(IterationRecord {
            iteration: k,
            loss,
            params: p,
            d_sigma_t: ds_t,
            d_albedo: da,
            d_g: d_g.map(|d| OneOrRgb::summed(c.params.g_per_channel, d)),
            d_ln_light_scale: d_k.map(|d| OneOrRgb::summed(c.params.light_scale_per_channel, d)),
            views,
            crop_origins,
            seconds: t0.elapsed().as_secs_f64(),
            misfit,
        });
        Ok(self.history.last().expect("just pushed"))
    }

    /// Runs to `config.iterations`, writing a checkpoint every `checkpoint_every` iterations
    /// (and at the end) when a path is given; `on_iter` sees every record.
    pub fn run(
        &mut self,
        checkpoint: Option<(&Path, u32)>,
        mut on_iter: impl FnMut(&IterationRecord, &Params),
    ) -> Result<(), InverseError> {
        self.run_until(checkpoint, |r, p| {
            on_iter(r, p);
            ControlFlow::Continue(())
        })
        .map(|_| ())
    }

    /// [`Optimizer::run`], stopped early where `on_iter` breaks: the run then ends after that
    /// iteration with a checkpoint (when a path is given), so that it resumes from there.
    pub fn run_until(
        &mut self,
        checkpoint: Option<(&Path, u32)>,
        mut on_iter: impl FnMut(&IterationRecord, &Params) -> ControlFlow<()>,
    ) -> Result<Ran, InverseError> {
        while self.iteration() < self.config.iterations {
            self.step()?;
            let p = self.params();
            let flow = on_iter(self.history.last().expect("stepped"), &p);
            let k = self.iteration();
            let due = |every: u32| k.is_multiple_of(every.max(1)) || k == self.config.iterations;
            if let Some((path, _)) = checkpoint.filter(|&(_, e)| due(e) || flow.is_break()) {
                self.save_checkpoint(path)?;
            }
            if flow.is_break() && self.iteration() < self.config.iterations {
                return Ok(Ran::Stopped);
            }
        }
        Ok(Ran::Completed)
    }
}

/// How [`Optimizer::run_until`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ran {
    /// Every configured iteration ran.
    Completed,
    /// The caller stopped it before the last iteration.
    Stopped,
}

/// The state of a run (what a fresh start and a resume provide differently).
struct Parts<'a> {
    forward: Box<dyn ForwardModel + 'a>,
    forward_kind: ModelChoice,
    accel: &'a Accel,
    networks: Option<&'a ShapeAdaptiveModel>,
    adam: Adam,
    u: Vec<f32>,
    history: Vec<IterationRecord>,
}

/// Adam with learning rate 1 (the per-parameter rates are factors), the step decay, no clipping.
fn adam_config(c: &OptimizeConfig) -> AdamConfig {
    AdamConfig {
        lr: 1.0,
        decay: c.decay,
        decay_every: c.decay_every.max(1) as u64,
        floor_fraction: 0.0,
        clip_norm: 0.0,
        ..AdamConfig::default()
    }
}

/// Adam state accessors for the checkpoint module.
fn adam_parts(o: &Optimizer) -> AdamState {
    o.adam.state()
}
