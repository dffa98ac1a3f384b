//! What the tracer is given: the scene it sees (`VolpathScene`) and its settings
//! (`VolpathSettings`: depth, Russian roulette, how channels are sampled, where a ray continues
//! after the boundary, the shadow rays' transmittance).

use geometry::{Accel, LightBins, bvh::offset_origin};
use glam::Vec3;
use scene::{Environment, Medium, PointLight};

use crate::guided::WalkSampling;
use crate::shadow::ShadowTransmittance;
use crate::spectral::SpectralWeight;

/// How RGB extinction is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ChannelSampling {
    /// Hero channel with the balance heuristic over the three channels (default; bounded weights).
    #[default]
    SpectralMis,
    /// One channel per path with ratio reweighting (what Mitsuba 3's RGB volpath does).
    SingleChannel,
}

/// Where a ray continues after crossing the object's boundary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum SpawnOffset {
    /// The medium starts where the mesh says (default).
    ///
    /// [`offset_origin`]: a few hundred ulps off the surface (about 2·10⁻⁶ at |p| ≈ 0.1), the
    /// least that avoids self-intersection.
    #[default]
    Robust,
    /// Mitsuba 3's 10⁻⁴ ray offset, for like-for-like comparisons with its renders.
    ///
    /// What Mitsuba 3's `Interaction::spawn_ray` does: p + (1 + max_i |p_i|)·ε_ray·n, with
    /// ε_ray = 1500·2⁻²⁴ ≈ 8.9·10⁻⁵ and n the geometric normal on the ray's side (checked against
    /// Mitsuba 3.9.1: 9.99·10⁻⁵ at |p| = 0.125). A ray entering the medium skips a sliver of that
    /// thickness, so every path starts about 10⁻⁴ deeper and its light is attenuated by roughly
    /// exp(−σ_t·10⁻⁴/cos θ_light) more: Mitsuba's renders of the reference sphere are 0.9–2.2 %
    /// darker than exact single scattering and 0.1–0.7 % darker in total
    /// (docs/notes/tracer-mitsuba-agreement.md, "Our +0.1–0.7 %: Mitsuba's ray offset"). For
    /// like-for-like comparisons with Mitsuba only.
    Mitsuba,
}

/// Mitsuba 3's `math::RayEpsilon<float>` (1500 · 2⁻²⁴).
const MITSUBA_RAY_EPSILON: f32 = 1500.0 / 16_777_216.0;

impl ChannelSampling {
    /// A fresh path's weight with the hero channel `hero` (chosen uniformly by the caller).
    #[inline]
    pub fn start(self, hero: usize) -> SpectralWeight {
        match self {
            ChannelSampling::SpectralMis => SpectralWeight::new(hero),
            ChannelSampling::SingleChannel => SpectralWeight::new_single_channel(hero),
        }
    }
}

impl SpawnOffset {
    /// The origin of the ray leaving the surface point `p` (geometric normal `ng`, either
    /// orientation) in direction `dir`.
    #[inline]
    pub fn spawn(self, p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
        match self {
            SpawnOffset::Robust => offset_origin(p, ng, dir),
            SpawnOffset::Mitsuba => {
                let mag = (1.0 + p.abs().max_element()) * MITSUBA_RAY_EPSILON;
                let n = ng.normalize();
                p + if dir.dot(n) < 0.0 { -mag } else { mag } * n
            }
        }
    }
}

/// Integrator settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VolpathSettings {
    pub max_depth: u32,
    pub rr_depth: u32,
    pub channel_sampling: ChannelSampling,
    /// Estimator of the shadow rays' transmittance ([`crate::shadow`]).
    pub shadow: ShadowTransmittance,
    /// Let [`crate::render_image`] answer the exact shadow rays from per-direction triangle
    /// lists around the light ([`LightBins`]; the same values as the BVH, faster). Off: the BVH
    /// answers every shadow ray (the reference, for tests and benchmarks).
    pub light_lists: bool,
    /// Ray origins after boundary crossings ([`SpawnOffset`]).
    pub spawn_offset: SpawnOffset,
    /// How the walks inside the medium are sampled ([`WalkSampling`]: classical or guided).
    pub walks: WalkSampling,
}

/// The maximum depth of a render or dataset that states none (Mitsuba 3 `volpath`'s default
/// would be unbounded; 32 keeps high-albedo paths finite at a bias below the noise).
pub const DEFAULT_MAX_DEPTH: u32 = 32;

impl Default for VolpathSettings {
    fn default() -> Self {
        VolpathSettings {
            max_depth: DEFAULT_MAX_DEPTH,
            rr_depth: 5,
            channel_sampling: ChannelSampling::SpectralMis,
            shadow: ShadowTransmittance::default(),
            light_lists: true,
            spawn_offset: SpawnOffset::Robust,
            walks: WalkSampling::Classical,
        }
    }
}

/// What the tracer sees: geometry, medium and emitters.
#[derive(Clone, Copy)]
pub struct VolpathScene<'a> {
    pub accel: &'a Accel,
    pub medium: Medium,
    pub light: Option<PointLight>,
    pub environment: Option<Environment>,
    /// Shadow-ray lists around `light` ([`LightBins`], built for `light.position` over `accel`):
    /// the exact shadow transmittance reads its inside lengths from them (identical values, a
    /// few triangle tests instead of an all-hits traversal). [`crate::render_image`] builds them
    /// when this is `None` and [`VolpathSettings::light_lists`] is on.
    pub light_bins: Option<&'a LightBins>,
}
