//! The entry-point sampler: the decoder of the learned model (default), or the random walks it
//! was trained to imitate.
//!
//! The VAE decoder is trained on the exits of random walks inside the cubic fitted at the entry
//! point (docs/model.md §5, [`crate::walk`]); at render time it proposes y = Decoder(z, f), in
//! light space and units of σ_n, and the absorption network gives S_abs = 1 − Absorb. With
//! [`EntrySampler::Walks`] the proposal is instead the exit of a walk in the SAME descriptor the
//! networks see (the light-space cubic at the current σ_n, [`LearnedScene::descriptor_at`]),
//! started at the origin along −e₃ (the aligned incident direction) with the medium in units of
//! σ_n (σ_t·σ_n, α, g, η), conditioned on escape: walks are repeated with fresh random numbers
//! until one exits. So y follows exactly the distribution the decoder approximates, p(x_LS | exit),
//! while S_abs still comes from the absorption network: the decoder is replaced, nothing else.
//!
//! This is a diagnostic of the decoder's fidelity, not the paper's method: it isolates what the
//! decoder's approximation costs in the images and in the recovered parameters
//! (docs/notes/decoder-training.md, "The decoder is the cause"). Correlated offsets (Son et al.
//! 2024, eq. 15–17) stay correlated: every sample keeps its own random stream, so the walks at
//! σ_n(σ_t ± Δ) repeat the same random numbers in the rescaled descriptor. The `naive` estimator
//! needs ∂y/∂σ through the decoder and is not available with walks. A sample whose walks never
//! exit (after [`MAX_TRIES`]) proposes NaN, which [`crate::render::place_and_project`] treats as
//! an invalid sample (value 0).

use base::rng::Sampler;
use glam::Vec3;

use super::{LearnedScene, Pending};
use crate::nn::POSITION_DIM;
use crate::polynomial::Poly3;
use crate::walk::{WalkMedium, WalkOutcome, WalkSurface, random_walk};

/// Walks tried per sample before it counts as invalid (the escape probability of a
/// configuration is rarely below 1 %; the tries are cheap when the walks are short).
pub const MAX_TRIES: u32 = 1024;

/// Where the entry points come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum EntrySampler {
    /// The model's decoder (the paper's method).
    #[default]
    Decoder,
    /// Random walks, conditioned on escape: a diagnostic of the decoder, slower.
    ///
    /// Random walks in the light-space descriptor, conditioned on escape (module docs).
    Walks,
}

impl EntrySampler {
    /// All samplers.
    pub const ALL: [EntrySampler; 2] = [EntrySampler::Decoder, EntrySampler::Walks];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            EntrySampler::Decoder => "decoder",
            EntrySampler::Walks => "walks",
        }
    }

    /// The sampler called `name` ([`EntrySampler::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// The exit of the first escaping walk of stream `key` in `descriptor` (light space, units of
/// σ_n) for `medium` (σ_t in units of 1/σ_n), NaN when none of [`MAX_TRIES`] escapes.
pub fn walk_exit(descriptor: &Poly3, medium: &WalkMedium, key: u64) -> [f32; POSITION_DIM] {
    let surface = WalkSurface::new(descriptor, 1.0);
    for t in 0..MAX_TRIES {
        let mut rng = Sampler::new(key, 0x57A1C, t as u64, 0);
        if let WalkOutcome::Exited(e) = random_walk(&surface, medium, -Vec3::Z, &mut rng) {
            return e.position.as_vec3().to_array();
        }
    }
    [f32::NAN; POSITION_DIM]
}

/// The walk medium of channel `c` of `m` at extinction `sigma_t` and kernel scale `sigma_n`:
/// lengths in units of σ_n.
pub(crate) fn walk_medium(m: &scene::Medium, c: usize, sigma_t: f32, sigma_n: f32) -> WalkMedium {
    WalkMedium {
        sigma_t: sigma_t as f64 * sigma_n as f64,
        albedo: m.albedo[c] as f64,
        g: m.g.channels()[c] as f64,
        eta: m.eta as f64,
    }
}

/// [`walk_medium`] of every channel of `scene`.
pub(crate) fn walk_media(scene: &LearnedScene) -> [WalkMedium; 3] {
    let m = &scene.medium;
    std::array::from_fn(|c| walk_medium(m, c, m.sigma_t[c], scene.sigma_n[c]))
}

/// Replaces the decoder outputs `y` of the samples `pending` by walk exits: for a sample of
/// channel c in `media[c]` (units of σ_n) and the descriptor `coeffs` (light space, fit scale;
/// `dcoeffs` its fit derivative when there is one) rescaled by `k(c)`, as
/// [`LearnedScene::inputs_at`] gives it to the networks.
pub(crate) fn walk_entries(
    media: &[WalkMedium; 3],
    pending: &[Pending],
    coeffs: &[Poly3],
    dcoeffs: &[Poly3],
    k: impl Fn(usize) -> f32,
    y: &mut [[f32; POSITION_DIM]],
) {
    for (s, p) in pending.iter().enumerate() {
        let c = p.channel as usize;
        let d = LearnedScene::descriptor_at(&coeffs[s], dcoeffs.get(s), k(c));
        y[s] = walk_exit(&d, &media[c], p.key);
    }
}
