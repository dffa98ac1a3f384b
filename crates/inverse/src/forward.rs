//! The forward models of the recovery behind one interface: what the inverse loop renders with.
//!
//! A [`ForwardModel`] turns a medium into a [`MediumRenderer`], which turns a view (camera and
//! point light) into a [`ViewRenderer`]: the view's image, its derivative images with respect to
//! the medium (∂I_c/∂σ_t,c and ∂I_c/∂α_c per pixel, [`DiffImages`]), or one render's loss and
//! gradient against a target accumulated without storing images. The optimiser
//! ([`crate::optimize`]), its intervals ([`crate::uncertainty`]) and its final renders use only
//! this interface, so every model goes through the same loop, checkpoints and reports.
//!
//! | model ([`ModelKind`]) | file | estimators (`DiffMethod`) |
//! |---|---|---|
//! | `learned`: the learned shape-adaptive BSSRDF | [`learned`] | `ours`, `ours-alpha-offsets`, `naive`, `fd` ([`bssrdf::diff`]) |
//! | `dipole`: the planar dipole baseline (DLW22) | [`dipole`] | `ad`: the profile differentiated at fixed sample positions ([`bssrdf::dipole`]); `fd` ([`fd`]) |
//! | `volpath`: the volumetric path tracer | [`volpath`] | `ad`: each path differentiated analytically ([`::volpath::derivative`]); `fd` ([`fd`]) |
//!
//! Adding a model is a file implementing the three traits and an arm of [`ModelKind`] (with its
//! valid estimators in [`ModelKind::estimators`]).

pub mod dipole;
pub mod fd;
pub mod learned;
pub mod volpath;

use bssrdf::diff::{DiffImages, DiffMethod, Loss, LossGradient};
use bssrdf::render::RenderSettings;
use scene::{Camera, Image, Medium, PointLight};
use serde::{Deserialize, Serialize};

use crate::optimize::InverseError;

/// A forward model of the images.
pub trait ForwardModel: Send + Sync {
    /// Prepares what depends on the medium but is kept across iterations (the learned model's
    /// vertex polynomials, fitted at `medium`); nothing for a model without such state.
    fn prepare(&mut self, medium: &Medium) -> Result<(), InverseError>;
    /// The renderer at `medium`.
    fn at<'s>(&'s self, medium: Medium) -> Result<Box<dyn MediumRenderer + 's>, InverseError>;
}

/// A forward model at one medium.
pub trait MediumRenderer: Sync {
    /// One view, set up once for several renders (camera rays, triangle lists).
    fn view<'v>(&'v self, camera: &'v Camera, light: &'v PointLight) -> Box<dyn ViewRenderer + 'v>;
}

/// One view of a forward model at one medium.
pub trait ViewRenderer {
    /// The image.
    fn value(&self, rs: &RenderSettings) -> Result<Image, InverseError>;
    /// The image and its derivatives with respect to σ_t and α.
    fn derivatives(&self, rs: &RenderSettings) -> Result<DiffImages, InverseError>;
    /// One render's loss against `target` and its gradient, accumulated per pixel (the loss
    /// derivative and the image derivatives from the same samples; for L2 the product carries
    /// their covariance: the single-render estimator of `--single-render`, where the default
    /// split-sample gradient has none). By default from one derivative render; a model with a
    /// fused loss render overrides it.
    fn loss_gradient(
        &self,
        rs: &RenderSettings,
        target: &Image,
        loss: Loss,
    ) -> Result<LossGradient, InverseError> {
        let d = self.derivatives(rs)?;
        Ok(crate::optimize::decorrelated_gradient(
            &d.value, &d, target, loss,
        ))
    }
}

/// Which forward model a recovery renders with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// The learned shape-adaptive BSSRDF (the paper's method).
    #[default]
    Learned,
    /// The volumetric path tracer, differentiated per path (the volumetric baseline).
    Volpath,
    /// The classical dipole between the camera point and probe-ray entry points (the planar
    /// baseline of Deng et al. 2022).
    Dipole,
}

impl ModelKind {
    /// All models.
    pub const ALL: [ModelKind; 3] = [ModelKind::Learned, ModelKind::Volpath, ModelKind::Dipole];

    /// The name on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Learned => "learned",
            ModelKind::Volpath => "volpath",
            ModelKind::Dipole => "dipole",
        }
    }

    /// The estimators this model has; the first is its default.
    pub fn estimators(self) -> &'static [DiffMethod] {
        match self {
            ModelKind::Learned => &DiffMethod::LEARNED,
            ModelKind::Volpath | ModelKind::Dipole => &[DiffMethod::Ad, DiffMethod::Fd],
        }
    }

    /// Checks that `method` is one of this model's estimators, naming the valid ones.
    pub fn check_estimator(self, method: DiffMethod) -> Result<(), String> {
        let valid = self.estimators();
        if valid.contains(&method) {
            return Ok(());
        }
        let names: Vec<&str> = valid.iter().map(|m| m.name()).collect();
        Err(format!(
            "the {} model has no estimator {:?}; its estimators: {}",
            self.name(),
            method.name(),
            names.join(", ")
        ))
    }

    /// Whether this model is the default (for files that leave it out).
    pub fn is_default(&self) -> bool {
        *self == ModelKind::default()
    }
}

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ModelKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        ModelKind::ALL
            .into_iter()
            .find(|m| m.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                let names: Vec<&str> = ModelKind::ALL.iter().map(|m| m.name()).collect();
                format!("unknown model {s:?} (expected {})", names.join(", "))
            })
    }
}
