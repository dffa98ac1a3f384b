//! What a differentiable render of one view returns, whatever the model: the value image and
//! its derivative images ([`DiffImages`]); the image loss against a target ([`Loss`],
//! averaged over the 3·W·H pixel channels) and its gradient with respect to the six medium
//! parameters and, where the model differentiates it, the phase function's g ([`LossGradient`]).

use crate::Image;

/// The value image and the derivative images (channel c: ∂I_c/∂σ_t,c and ∂I_c/∂α_c; and
/// ∂I_c/∂g for the one g that all channels share, from the models that differentiate it).
#[derive(Clone, Debug, PartialEq)]
pub struct DiffImages {
    pub value: Image,
    pub d_sigma_t: Image,
    pub d_albedo: Image,
    /// ∂I_c/∂g, or `None` from a model that does not differentiate the phase function.
    pub d_g: Option<Image>,
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

/// The loss, its gradient with respect to (σ_t,R, σ_t,G, σ_t,B), (α_R, α_G, α_B) and g, and the
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
    /// Each colour channel's term of ∂ℓ/∂g: ∂ℓ/∂g_c for a g per channel, and their sum for one g
    /// shared by the channels; `None` where the derivative images have no ∂I/∂g.
    pub d_g: Option<[f64; 3]>,
    /// Each colour channel's share of ∂ℓ/∂ln k for a factor k on the light's intensity (the
    /// image is linear in it: ∂I/∂ln k = I); `None` where the render did not keep it.
    pub d_ln_light_scale: Option<[f64; 3]>,
    pub images: Option<DiffImages>,
}
