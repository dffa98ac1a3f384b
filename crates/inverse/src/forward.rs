//! The forward models of the recovery behind one interface: what the inverse loop renders with.
//!
//! A [`ForwardModel`] turns a medium into a [`MediumRenderer`], which turns a view (camera and
//! point light) into a [`ViewRenderer`]: the view's image, its derivative images with respect to
//! the medium (∂I_c/∂σ_t,c and ∂I_c/∂α_c per pixel, [`DiffImages`]), or one render's loss and
//! gradient against a target accumulated without storing images. The optimiser
//! ([`crate::optimize`]), its intervals ([`crate::uncertainty`]) and its final renders use only
//! this interface, so every model goes through the same loop, checkpoints and reports.
//!
//! | model ([`ModelKind`]) | file | estimators ([`ModelChoice`]) |
//! |---|---|---|
//! | `learned`: the learned shape-adaptive BSSRDF | [`learned`] | `ours`, `ours-alpha-offsets`, `naive`, `fd` ([`bssrdf::diff::Estimator`], one file each) |
//! | `dipole`: the planar dipole baseline (DLW22) | [`dipole`] | `ad`: the profile differentiated at fixed sample positions ([`::dipole`]); `fd` ([`fd`]) |
//! | `volpath`: the volumetric path tracer | [`volpath`] | `ad`: each path differentiated analytically ([`::volpath::derivative`]); `fd` ([`fd`]) |
//!
//! A model builds itself from its typed description ([`ModelSpec::build`]); the tracer and the
//! dipole need no learned network. Adding a model is a file implementing the three traits and an
//! arm of [`ModelKind`], [`ModelChoice`] and [`ModelSpec`]; the optimiser also takes any
//! [`ForwardModel`] directly ([`crate::optimize::Optimizer::with_forward`]).

mod choice;
pub mod dipole;
pub mod fd;
pub mod learned;
pub mod volpath;

pub use choice::{ModelChoice, TracerEstimator, UnknownEstimatorOf};

use bssrdf::diff::{DiffImages, Loss, LossGradient};
use bssrdf::render::RenderSettings;
use geometry::Accel;
use indicatif::ProgressBar;
use scene::{Camera, Image, Medium, PointLight};
use serde::{Deserialize, Serialize};

use crate::error::InverseError;

/// The progress of a render: advanced by one per image row when given.
pub type Progress<'a> = Option<&'a ProgressBar>;

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
    /// The image; `progress` advances by one per row.
    fn value(&self, rs: &RenderSettings, progress: Progress) -> Result<Image, InverseError>;
    /// The image and its derivatives with respect to σ_t and α; `progress` advances by one per
    /// row.
    fn derivatives(
        &self,
        rs: &RenderSettings,
        progress: Progress,
    ) -> Result<DiffImages, InverseError>;
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
        let d = self.derivatives(rs, None)?;
        Ok(crate::optimize::gradient::decorrelated_gradient(
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

    /// The names of this model's estimators; the first is its default.
    pub fn estimators(self) -> &'static [&'static str] {
        match self {
            ModelKind::Learned => &["ours", "ours-alpha-offsets", "naive", "fd"],
            ModelKind::Volpath | ModelKind::Dipole => &["ad", "fd"],
        }
    }

    /// Whether this model is the default (for files that leave it out).
    pub fn is_default(&self) -> bool {
        *self == ModelKind::default()
    }

    /// What this model does not render of `object` as the object is: each a sentence for the
    /// log and `result.json`. The tracer renders every boundary and phase function. The learned
    /// model renders refractive and rough boundaries and media of any g, but anisotropic ones
    /// less accurately than the paper's (measured in BENCHMARKS.md, "The learned model over g,
    /// η and roughness"), and a g per channel with its boundary tables at the channels' mean g.
    /// The dipole has no rough boundary.
    pub fn physics_gaps(self, object: &scene::Object) -> Vec<String> {
        let mut gaps = Vec::new();
        if self == ModelKind::Learned && !object.g.is_isotropic() {
            gaps.push(format!(
                "the learned model renders an anisotropic medium (g {}) less accurately than \
                 an isotropic one: measured against the tracer, image means up to 16 % off at \
                 g 0.3–0.9 on front-lit spheres and blobs, and 32–234 % too bright on back-lit \
                 objects at g 0.9 (within 3 % at g 0); the tracer's refinement renders it exactly",
                object.g
            ));
        }
        if self == ModelKind::Learned && !object.g.is_uniform() {
            gaps.push(format!(
                "the learned model renders each channel's own g (g {} in R, G, B) in its \
                 networks, but its boundary and curvature tables at the channels' mean g {}; \
                 the tracer's refinement renders each channel's phase function exactly",
                object.g,
                object.g.mean()
            ));
        }
        if self == ModelKind::Dipole && object.roughness > 0.0 {
            gaps.push(format!(
                "the dipole renders the boundary as a smooth one: its roughness (GGX α {}) is \
                 not modelled",
                object.roughness
            ));
        }
        gaps
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

/// A forward model's typed description, from which it builds itself over a mesh.
pub enum ModelSpec<'a> {
    /// The learned BSSRDF with its networks, renderer settings and estimator.
    Learned(learned::LearnedSpec<'a>),
    /// The volumetric path tracer with its settings (the dataset's depth) and estimator.
    Volpath {
        settings: ::volpath::VolpathSettings,
        estimator: fd::Differencing,
    },
    /// The planar dipole with its estimator.
    Dipole { estimator: fd::Differencing },
}

impl<'a> ModelSpec<'a> {
    /// The learned model of `networks` with `settings` and the paper's estimator, its vertex
    /// polynomials fitted with `seed`.
    pub fn learned(
        networks: &'a bssrdf::nn::ShapeAdaptiveModel,
        settings: bssrdf::render::LearnedSettings,
        seed: u64,
    ) -> Self {
        ModelSpec::Learned(learned::LearnedSpec::new(networks, settings, seed))
    }

    /// The volumetric path tracer with `settings` and its analytic derivatives (`ad`).
    pub fn tracer(settings: ::volpath::VolpathSettings) -> Self {
        ModelSpec::Volpath {
            settings,
            estimator: fd::Differencing::default(),
        }
    }

    /// The planar dipole with its analytic derivatives (`ad`).
    pub fn dipole() -> Self {
        ModelSpec::Dipole {
            estimator: fd::Differencing::default(),
        }
    }

    /// The model over `accel`, not yet prepared ([`ForwardModel::prepare`]).
    pub fn build(self, accel: &'a Accel) -> Box<dyn ForwardModel + 'a> {
        match self {
            ModelSpec::Learned(spec) => Box::new(learned::Learned::new(accel, spec)),
            ModelSpec::Volpath {
                settings,
                estimator,
            } => Box::new(volpath::Volpath::new(accel, settings, estimator)),
            ModelSpec::Dipole { estimator } => Box::new(dipole::Dipole::new(accel, estimator)),
        }
    }

    /// Which model this is.
    pub fn kind(&self) -> ModelKind {
        match self {
            ModelSpec::Learned(_) => ModelKind::Learned,
            ModelSpec::Volpath { .. } => ModelKind::Volpath,
            ModelSpec::Dipole { .. } => ModelKind::Dipole,
        }
    }
}
