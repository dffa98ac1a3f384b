//! The learned shape-adaptive BSSRDF as a [`ForwardModel`]: the vertex polynomials are fitted
//! by [`ForwardModel::prepare`] (at the start, at every refit, on resume) and kept; each
//! medium builds a [`LearnedScene`]; each view sets up its camera rays once
//! ([`ViewRays`], lazily, so a fused loss-gradient render does not build them twice). The
//! derivative estimator is the run's (`ours`, `ours-alpha-offsets`, `naive`, `fd`:
//! [`bssrdf::diff`]).

use std::cell::OnceCell;

use bssrdf::diff::{
    DiffImages, DiffSettings, Loss, LossGradient, render_diff_view, render_loss_gradient,
};
use bssrdf::nn::ShapeAdaptiveModel;
use bssrdf::render::{
    LearnedScene, LearnedSettings, RenderSettings, VertexFeatures, ViewRays, render_image_view,
};
use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};

use super::{ForwardModel, MediumRenderer, Progress, ViewRenderer};
use crate::error::InverseError;

/// What the learned model is built from ([`super::ModelSpec::Learned`]).
#[derive(Clone, Copy)]
pub struct LearnedSpec<'a> {
    /// The networks.
    pub networks: &'a ShapeAdaptiveModel,
    /// The renderer's settings (projection rule, descriptor handling, ablations).
    pub settings: LearnedSettings,
    /// The estimator and its offsets.
    pub diff: DiffSettings,
    /// Also fit dR/d ln σ_n ([`VertexFeatures::fit_with_derivative`]).
    pub fit_derivative: bool,
    /// The seed of the vertex polynomials' fit.
    pub seed: u64,
}

impl<'a> LearnedSpec<'a> {
    /// The paper's estimator and the default settings, fitted with `seed`.
    pub fn new(networks: &'a ShapeAdaptiveModel, settings: LearnedSettings, seed: u64) -> Self {
        LearnedSpec {
            networks,
            settings,
            diff: DiffSettings::default(),
            fit_derivative: false,
            seed,
        }
    }
}

/// The learned model with its fitted vertex polynomials.
pub struct Learned<'a> {
    accel: &'a Accel,
    spec: LearnedSpec<'a>,
    features: Option<VertexFeatures>,
}

impl<'a> Learned<'a> {
    /// The model over `accel`, not yet prepared.
    pub fn new(accel: &'a Accel, spec: LearnedSpec<'a>) -> Self {
        Learned {
            accel,
            spec,
            features: None,
        }
    }
}

impl ForwardModel for Learned<'_> {
    fn prepare(&mut self, medium: &Medium) -> Result<(), InverseError> {
        let s = &self.spec;
        let quirk = s.networks.info().c19_quirk;
        let t0 = std::time::Instant::now();
        self.features = Some(if s.fit_derivative {
            VertexFeatures::fit_with_derivative(self.accel, medium, quirk, s.seed)?
        } else {
            VertexFeatures::fit(self.accel, medium, quirk, s.seed)?
        });
        tracing::debug!(
            "fitted vertex polynomials in {:.2} s",
            t0.elapsed().as_secs_f64()
        );
        Ok(())
    }

    fn at<'s>(&'s self, medium: Medium) -> Result<Box<dyn MediumRenderer + 's>, InverseError> {
        let features = self
            .features
            .as_ref()
            .ok_or_else(|| InverseError::Invalid("the learned model was not prepared".into()))?;
        let s = &self.spec;
        let scene = LearnedScene::new(self.accel, s.networks, features, medium, s.settings)?;
        Ok(Box::new(LearnedAt {
            scene,
            diff: s.diff,
        }))
    }
}

struct LearnedAt<'s> {
    scene: LearnedScene<'s>,
    diff: DiffSettings,
}

impl MediumRenderer for LearnedAt<'_> {
    fn view<'v>(&'v self, camera: &'v Camera, light: &'v PointLight) -> Box<dyn ViewRenderer + 'v> {
        Box::new(LearnedView {
            at: self,
            camera,
            light,
            rays: OnceCell::new(),
        })
    }
}

struct LearnedView<'v> {
    at: &'v LearnedAt<'v>,
    camera: &'v Camera,
    light: &'v PointLight,
    rays: OnceCell<ViewRays<'v>>,
}

impl<'v> LearnedView<'v> {
    fn rays(&self) -> &ViewRays<'v> {
        self.rays
            .get_or_init(|| ViewRays::new(&self.at.scene, self.camera, self.light))
    }
}

impl ViewRenderer for LearnedView<'_> {
    fn value(&self, rs: &RenderSettings, progress: Progress) -> Result<Image, InverseError> {
        Ok(render_image_view(
            &self.at.scene,
            self.rays(),
            rs,
            progress,
        )?)
    }

    fn derivatives(
        &self,
        rs: &RenderSettings,
        progress: Progress,
    ) -> Result<DiffImages, InverseError> {
        Ok(render_diff_view(
            &self.at.scene,
            self.rays(),
            rs,
            &self.at.diff,
            progress,
        )?)
    }

    fn loss_gradient(
        &self,
        rs: &RenderSettings,
        target: &Image,
        loss: Loss,
    ) -> Result<LossGradient, InverseError> {
        Ok(render_loss_gradient(
            &self.at.scene,
            self.camera,
            self.light,
            rs,
            &self.at.diff,
            target,
            loss,
            false,
            None,
        )?)
    }
}
