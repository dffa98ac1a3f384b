//! The settings of the differentiable renderer ([`super`]): the estimator ([`Estimator`]), the
//! source of the value image ([`Primal`]) and the offsets ([`DiffSettings`]). The image loss and
//! what a render returns ([`scene::loss`]) sit below every model that uses them.

use std::str::FromStr;

/// Step (scene units) of the central difference of the smooth light term in
/// [`Estimator::Naive`]; the light term varies on the scale of the light distance.
pub const NAIVE_STEP: f32 = 1e-3;

/// The learned renderer's gradient estimator (module docs of [`super`]; one file each).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Estimator {
    /// Correlated offset samples for σ_t, S_abs derivative for α (the paper's method).
    #[default]
    Ours,
    /// As `ours`, with α also by offset samples (slower).
    ///
    /// σ_t as `Ours`; α by offset samples at α ± Δα (networks, σ_n and light side), keeping the
    /// α-dependence of the sample positions that `Ours` detaches.
    OursAlphaOffsets,
    /// Visibility held fixed: without the boundary term.
    ///
    /// Sample-position derivative with visibility held fixed (interior term only).
    Naive,
    /// Central differences of full renders (a reference, slow).
    Fd,
}

impl Estimator {
    /// All estimators, in the order of their names; the first is the default.
    pub const ALL: [Estimator; 4] = [
        Estimator::Ours,
        Estimator::OursAlphaOffsets,
        Estimator::Naive,
        Estimator::Fd,
    ];

    /// The name accepted by [`FromStr`].
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Ours => "ours",
            Estimator::OursAlphaOffsets => "ours-alpha-offsets",
            Estimator::Naive => "naive",
            Estimator::Fd => "fd",
        }
    }
}

/// An unknown [`Estimator`] name.
#[derive(Debug, thiserror::Error)]
#[error(
    "unknown estimator {0:?} of the learned model (expected ours, ours-alpha-offsets, naive or fd)"
)]
pub struct UnknownEstimator(pub String);

/// `FromStr` (the choice among `ALL` whose `name()` is the string, case-insensitive, `_` read
/// as `-`; otherwise the error type) and `Display` (`name()`) for a named option enum.
macro_rules! named_option {
    ($ty:ty, $err:ident) => {
        impl FromStr for $ty {
            type Err = $err;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                let k = s.trim().to_ascii_lowercase().replace('_', "-");
                <$ty>::ALL
                    .into_iter()
                    .find(|m| m.name() == k)
                    .ok_or_else(|| $err(s.to_string()))
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}

named_option!(Estimator, UnknownEstimator);

/// Settings of the differentiable renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffSettings {
    pub estimator: Estimator,
    /// Relative σ_t offset: Δ = `delta_rel`·σ_t,c (docs/model.md A7; default 0.02). Used by the
    /// offset samples and by `Fd`.
    pub delta_rel: f32,
    /// Absolute α offset Δα of `OursAlphaOffsets` and `Fd` (default 0.01), reduced where needed
    /// so that α ± Δα stays in [0, 1].
    pub delta_albedo: f32,
    /// `Fd` only: keep σ_n at its unperturbed value in the perturbed renders.
    pub fd_fixed_sigma_n: bool,
    /// Where the value image of `Ours` / `OursAlphaOffsets` comes from ([`Primal`]).
    pub primal: Primal,
}

/// The estimate of the pixel value I (the primal) next to the derivatives of the offset
/// estimators.
///
/// * [`Primal::Sample`]: the unperturbed sample x_i = Π(x_o + σ_n·R·y) with its own projection,
///   light evaluation and network pass; the value image is bit-identical to
///   [`render_image`](crate::render::render_image).
/// * [`Primal::OffsetMean`] (default): the mean of the two σ_t offset samples the derivative needs
///   anyway, I ≈ (1 − F)·(S_abs⁺·L(x_i⁺) + S_abs⁻·L(x_i⁻))/2, and L(x_i) ≈ (L(x_i⁺) + L(x_i⁻))/2
///   in the α derivative. Central differences of a smooth function of σ_t (the expectation over
///   z is smooth even where single samples jump), so the bias is
///   (Δ²/2)·∂²E[I]/∂σ_t² + O(Δ⁴) — with Δ = 0.02·σ_t a few 10⁻⁴ of I (tested in
///   `crates/bssrdf/tests/diff.rs`) — and it saves a third of the projections, shadow rays and
///   network passes of an iteration. `Naive` and `Fd` always use `Sample`.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Primal {
    /// An unperturbed sample of its own.
    Sample,
    /// The mean of the two σ_t offset samples (default: a third less work, O(Δ²) bias).
    #[default]
    OffsetMean,
}

impl Primal {
    /// All choices, in the order of their names.
    pub const ALL: [Primal; 2] = [Primal::Sample, Primal::OffsetMean];

    /// The name accepted by [`FromStr`].
    pub fn name(self) -> &'static str {
        match self {
            Primal::Sample => "sample",
            Primal::OffsetMean => "offset-mean",
        }
    }
}

/// An unknown [`Primal`] name.
#[derive(Debug, thiserror::Error)]
#[error("unknown primal {0:?} (expected sample or offset-mean)")]
pub struct UnknownPrimal(pub String);

named_option!(Primal, UnknownPrimal);

impl Default for DiffSettings {
    fn default() -> Self {
        DiffSettings {
            estimator: Estimator::Ours,
            delta_rel: 0.02,
            delta_albedo: 0.01,
            fd_fixed_sigma_n: false,
            primal: Primal::OffsetMean,
        }
    }
}
