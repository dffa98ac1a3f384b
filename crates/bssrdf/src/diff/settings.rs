//! The settings and result types of the differentiable renderer ([`super`]): the estimator
//! ([`DiffMethod`]), the source of the value image ([`Primal`]), the offsets ([`DiffSettings`]),
//! the image loss ([`Loss`]) and what a render returns ([`DiffImages`], [`LossGradient`]).

use std::str::FromStr;

use scene::Image;
/// Step (scene units) of the central difference of the smooth light term in
/// [`DiffMethod::Naive`]; the light term varies on the scale of the light distance.
pub const NAIVE_STEP: f32 = 1e-3;

/// How the derivatives are estimated (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum DiffMethod {
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
    /// Analytic derivatives of each sample (the volumetric path tracer, the dipole).
    ///
    /// The volumetric path tracer's analytic derivative of each path (`volpath::derivative`):
    /// not an estimator of the learned model, which refuses it.
    Ad,
}

impl DiffMethod {
    /// The learned model's estimators (all but [`DiffMethod::Ad`]).
    pub const LEARNED: [DiffMethod; 4] = [
        DiffMethod::Ours,
        DiffMethod::OursAlphaOffsets,
        DiffMethod::Naive,
        DiffMethod::Fd,
    ];

    /// All methods, in the order of their names.
    pub const ALL: [DiffMethod; 5] = [
        DiffMethod::Ours,
        DiffMethod::OursAlphaOffsets,
        DiffMethod::Naive,
        DiffMethod::Fd,
        DiffMethod::Ad,
    ];

    /// The name accepted by [`FromStr`].
    pub fn name(self) -> &'static str {
        match self {
            DiffMethod::Ours => "ours",
            DiffMethod::OursAlphaOffsets => "ours-alpha-offsets",
            DiffMethod::Naive => "naive",
            DiffMethod::Fd => "fd",
            DiffMethod::Ad => "ad",
        }
    }
}

/// An unknown [`DiffMethod`] name.
#[derive(Debug, thiserror::Error)]
#[error("unknown derivative method {0:?} (expected ours, ours-alpha-offsets, naive, fd or ad)")]
pub struct UnknownMethod(pub String);

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

named_option!(DiffMethod, UnknownMethod);

/// Settings of the differentiable renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffSettings {
    pub method: DiffMethod,
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
            method: DiffMethod::Ours,
            delta_rel: 0.02,
            delta_albedo: 0.01,
            fd_fixed_sigma_n: false,
            primal: Primal::OffsetMean,
        }
    }
}

/// The value image and the two derivative images (channel c: ∂I_c/∂σ_t,c and ∂I_c/∂α_c).
#[derive(Clone, Debug, PartialEq)]
pub struct DiffImages {
    pub value: Image,
    pub d_sigma_t: Image,
    pub d_albedo: Image,
}

/// Image loss, averaged over the 3·W·H pixel channels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Loss {
    /// Mean squared difference (default).
    ///
    /// ℓ = (1/N) Σ (I − T)²; ∂ℓ/∂I = 2(I − T)/N.
    #[default]
    L2,
    /// Mean absolute difference.
    ///
    /// ℓ = (1/N) Σ |I − T|; ∂ℓ/∂I = sign(I − T)/N (0 at I = T).
    L1,
}

impl Loss {
    /// Per pixel channel: (ℓ, ∂ℓ/∂I) before the 1/N normalisation.
    #[inline]
    pub fn element(self, value: f32, target: f32) -> (f64, f64) {
        let r = value as f64 - target as f64;
        match self {
            Loss::L2 => (r * r, 2.0 * r),
            Loss::L1 => (
                r.abs(),
                if r > 0.0 {
                    1.0
                } else if r < 0.0 {
                    -1.0
                } else {
                    0.0
                },
            ),
        }
    }
}

/// The loss, its gradient with respect to (σ_t,R, σ_t,G, σ_t,B) and (α_R, α_G, α_B), and the
/// images when asked for.
#[derive(Clone, Debug, PartialEq)]
pub struct LossGradient {
    /// ℓ, the sum of `loss_channels`.
    pub loss: f64,
    /// The loss's share of each colour channel (each averaged over all 3·W·H pixel channels,
    /// like `loss`), for per-channel weights such as the optimiser's view normalisation.
    pub loss_channels: [f64; 3],
    pub d_sigma_t: [f64; 3],
    pub d_albedo: [f64; 3],
    pub images: Option<DiffImages>,
}
