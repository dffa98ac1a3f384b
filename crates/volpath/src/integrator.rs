//! The volumetric path tracer: a homogeneous medium inside one closed mesh, lit by a point light
//! (next-event estimation) and/or a constant environment.
//!
//! | parameter | meaning |
//! |---|---|
//! | σ_t, α (RGB) | extinction [1/unit], single-scattering albedo; σ_s = α σ_t |
//! | g | Henyey–Greenstein anisotropy |
//! | η | boundary: 1 = index-matched `null` interface (the paper's data); > 1 = dielectric |
//! | roughness | the dielectric's GGX α; 0 = smooth, > 0 = rough ([`crate::rough`]) |
//! | max_depth | Mitsuba 3 `volpath` semantics: depth counts real scatterings; NEE at scattering vertex k only if k < max_depth |
//! | rr_depth | Russian roulette once depth > rr_depth, survival q = min(max_k β_k, 1) |
//!
//! Radiance along a camera ray is estimated by free-flight sampling (hero channel with spectral
//! MIS, [`crate::spectral`]), phase-function sampling, and NEE at every scattering vertex with
//! an unbiased estimate of the transmittance exp(−σ_t · ℓ) of the total length ℓ of the shadow
//! segment inside the mesh (re-entries included; [`crate::shadow`]). Boundary crossings do not
//! count as depth, except at a rough boundary, where each interaction does (Mitsuba 3's `volpath`
//! with `roughdielectric`).
//!
//! With η > 1 the camera side is exact (Fresnel reflection/refraction chosen with probability F,
//! total internal reflection, radiance scaled by 1/η_rel² across the interface). A point light
//! behind a smooth dielectric cannot be reached by a shadow ray (Mitsuba 3's `volpath` renders
//! such scenes black); we connect through the refraction by manifold NEE ([`crate::manifold`]),
//! which is exact for convex objects (see its limitations). A rough boundary is crossed by
//! sampling its BSDF and reaches the point light by next-event estimation at its own vertices,
//! as Mitsuba 3 does, combined with a connection from the scattering vertices near it guided by
//! the smooth refraction ([`crate::rough`]). Environment light works for every boundary.
//!
//! Queries. Free flights ask [`Accel::closest`] (which skips the BVH when the clearance grid
//! rules out a hit); the shadow rays read the light's lists ([`LightBins`]); a camera ray and
//! the path's queries along its line until the first scattering (index-matched boundary) read
//! the camera's per-pixel lists ([`CameraLine`]). Every list answers exactly as the BVH would.
//!
//! Limitations: the camera must be outside the object; the mesh must be closed.

use geometry::{Accel, FilmCursor, Hit, LightBins, PixelBins, bvh::offset_origin};
use glam::Vec3;
use scene::{Environment, Medium, PointLight};

use crate::fresnel::{fresnel_dielectric, reflect, refract};
use crate::manifold;
use crate::phase::HenyeyGreenstein;
use crate::rng::Sampler;
use crate::rough;
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

/// Upper bound on interface events per path (guards against numerical ping-pong).
const MAX_INTERFACE_EVENTS: u32 = 1024;

/// Estimate the radiance arriving at `origin` along `-dir` (one sample, RGB).
pub fn radiance(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    origin: Vec3,
    dir: Vec3,
    s: &mut Sampler,
) -> [f32; 3] {
    radiance_primary(scene, settings, origin, dir, None, s)
}

/// A camera ray that came through the camera's per-pixel triangle lists ([`PixelBins`]): they
/// answer its first hit and every later closest-hit query along the same line (the first free
/// flight inside an index-matched medium, the search for a re-entry behind it), bit for bit as
/// the BVH would ([`PixelBins::closest_first`], [`PixelBins::closest_next`]).
pub struct CameraLine<'a> {
    bins: &'a PixelBins,
    cursor: FilmCursor<'a>,
    project: &'a dyn Fn(Vec3) -> Option<(f32, f32, f32)>,
}

impl<'a> CameraLine<'a> {
    /// The ray through the film point `(fx, fy)` (pixels) of the view that `bins` were built
    /// for with the projector `project` (`(px, py, depth)` of a world point); the ray's
    /// direction must be generated from that film point.
    #[inline]
    pub fn new(
        bins: &'a PixelBins,
        fx: f32,
        fy: f32,
        project: &'a dyn Fn(Vec3) -> Option<(f32, f32, f32)>,
    ) -> Self {
        CameraLine {
            bins,
            cursor: bins.cursor(fx, fy),
            project,
        }
    }

    /// `accel.closest(o, d, 0, tmax)` from the lists, or `None` when they cannot answer it.
    #[inline]
    fn closest(&mut self, accel: &Accel, o: Vec3, d: Vec3, tmax: f32) -> Option<Option<Hit>> {
        let at = (self.project)(o)?;
        let c = &mut self.cursor;
        self.bins.closest_next(accel, c, o, at, d, 0.0, tmax)
    }
}

/// [`radiance`] for a camera ray: with `line`, its closest-hit queries along the camera ray's
/// line go through the camera's lists ([`CameraLine`]); `None` asks the BVH for everything.
/// The result is the same either way.
pub fn radiance_primary(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    origin: Vec3,
    dir: Vec3,
    line: Option<CameraLine>,
    s: &mut Sampler,
) -> [f32; 3] {
    trace::<[f32; 3]>(scene, settings, origin, dir, line, s)
}

/// What a contribution's weight depends on the medium by: the real scatterings `k` before it,
/// its length `len` inside the medium up to the light (its free flights, plus the shadow
/// segment's inside length for a next-event estimate), and `phase`, the sum of ∂ ln p/∂g over
/// its phase-function factors ([`HenyeyGreenstein::d_log_dg`]; 0 unless the tally asks for it,
/// [`Tally::SCORES_PHASE`]). The path's throughput depends on σ_t and α only through
/// (α σ_t)^k e^{−σ_t ℓ}, and on g only through its phase-function factors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathScore {
    pub k: u32,
    pub len: f32,
    pub phase: f32,
}

/// What a traced path adds up: the radiance alone (`[f32; 3]`) or the radiance with its
/// derivatives with respect to the medium ([`crate::derivative::PathDerivatives`]). Every
/// contribution of a path (a next-event estimate or the environment at its escape) is handed
/// over with its [`PathScore`], which is what the derivatives need.
pub trait Tally: Copy + Default + Send + Sync {
    /// A pixel's running sum of tallies.
    type Sum: Copy + Default + Send + Sync;
    /// Whether [`PathScore::phase`] is wanted (the value alone skips its arithmetic).
    const SCORES_PHASE: bool;
    /// Adds this tally to a pixel's sum.
    fn add_to(&self, sum: &mut Self::Sum);
    /// Adds the contribution `c` (per channel, the estimator's weight included) of a path with
    /// `score`, in a medium of `sigma_t`, `albedo`.
    fn record(&mut self, c: [f32; 3], score: PathScore, sigma_t: &[f32; 3], albedo: &[f32; 3]);
    /// Replaces non-finite values by 0 (a path that lost its numbers contributes nothing).
    fn finish(&mut self);
}

impl Tally for [f32; 3] {
    type Sum = [f64; 3];
    const SCORES_PHASE: bool = false;

    #[inline]
    fn add_to(&self, sum: &mut [f64; 3]) {
        for (s, v) in sum.iter_mut().zip(self) {
            *s += *v as f64;
        }
    }

    #[inline]
    fn record(&mut self, c: [f32; 3], _score: PathScore, _st: &[f32; 3], _al: &[f32; 3]) {
        for (l, c) in self.iter_mut().zip(c) {
            *l += c;
        }
    }

    #[inline]
    fn finish(&mut self) {
        for v in self {
            if !v.is_finite() {
                *v = 0.0;
            }
        }
    }
}

/// [`radiance_primary`] for any [`Tally`]: the path loop of the tracer.
pub fn trace<T: Tally>(
    scene: &VolpathScene,
    settings: &VolpathSettings,
    origin: Vec3,
    dir: Vec3,
    line: Option<CameraLine>,
    s: &mut Sampler,
) -> T {
    let m = &scene.medium;
    let phase = HenyeyGreenstein { g: m.g };
    let hero = s.next_below(3) as usize;
    let mut w = match settings.channel_sampling {
        ChannelSampling::SpectralMis => SpectralWeight::new(hero),
        ChannelSampling::SingleChannel => SpectralWeight::new_single_channel(hero),
    };
    let mut l = T::default();
    // The path's length inside the medium so far (its free flights).
    let mut len = 0.0f32;
    // Σ ∂ ln p/∂g over the phase-function directions sampled so far (with T::SCORES_PHASE).
    let mut phase_score = 0.0f32;
    // The score of a contribution after `k` scatterings and `len`, with `cos` the angle of a
    // connection's own phase-function factor at the last vertex (`None`: none).
    let score = |k: u32, len: f32, phase_score: f32, cos: Option<f32>| PathScore {
        k,
        len,
        phase: match cos {
            Some(cos) if T::SCORES_PHASE => phase_score + phase.d_log_dg(cos),
            _ => phase_score,
        },
    };
    let mut o = origin;
    let mut d = dir;
    let mut inside = false;
    // Real scatterings (what the path's throughput depends on the medium by) and the depth
    // (the scatterings, and the rough boundary's interactions, as Mitsuba 3's `volpath`
    // counts them).
    let mut k = 0u32;
    let mut depth = 0u32;
    let mut interface_events = 0u32;
    let rough = (m.eta != 1.0 && m.roughness > 0.0)
        .then(|| base::microfacet::RoughDielectric::new(m.eta, m.roughness));
    // The last scattering's guided connection through a rough boundary, until the path meets
    // the boundary, and then the weight of that meeting's next-event estimate against it.
    let mut guide: Option<rough::Guide> = None;
    let mut flight_weight = 1.0f32;
    // The path left the medium through a triangle whose plane has the whole mesh behind it
    // (`Accel::exit_is_final`) and moves away from that plane: it cannot meet the mesh again,
    // so the query for a re-entry is skipped (the BVH would answer "no hit").
    let mut escaped = false;
    // The path still runs along the camera ray (an index-matched boundary does not turn it; no
    // scattering yet), so the camera's lists can answer its queries.
    let mut line = line;
    let mut on_line = m.eta == 1.0;
    // The closest hit along `o + t·d`, `t < tmax`.
    let closest = |line: &mut Option<CameraLine>, on_line: bool, o: Vec3, d: Vec3, tmax: f32| {
        line.as_mut()
            .filter(|_| on_line)
            .and_then(|l| l.closest(scene.accel, o, d, tmax))
            .unwrap_or_else(|| scene.accel.closest(o, d, 0.0, tmax))
    };

    loop {
        // The boundary the path meets next, or a scattering event / the end of the path.
        let hit = if inside {
            let t = w.sample_distance(&m.sigma_t, s.next_f32());
            if let Some(hit) = closest(&mut line, on_line, o, d, t) {
                if let Some(g) = guide.take() {
                    let pass = w.pass_probability(&m.sigma_t, hit.t);
                    flight_weight = g.flight_weight(&phase, d, pass);
                }
                w.pass(&m.sigma_t, hit.t);
                len += hit.t;
                hit
            } else {
                // Real scattering event.
                o += t * d;
                on_line = false;
                w.scatter(&m.sigma_t, &m.albedo, t);
                len += t;
                k += 1;
                depth += 1;
                if depth >= settings.max_depth {
                    break;
                }
                if let Some(light) = &scene.light {
                    let nee = if m.eta == 1.0 {
                        next_event(scene, settings.shadow, &phase, light, o, d, &w, s)
                    } else if rough.is_none() {
                        next_event_refracted(scene, &phase, light, o, d, &w)
                    } else {
                        // Behind a rough boundary the light is reached from its vertices.
                        None
                    };
                    if let Some((c, shadow_len, cos)) = nee {
                        let sc = score(k, len + shadow_len, phase_score, Some(cos));
                        l.record(c, sc, &m.sigma_t, &m.albedo);
                    }
                }
                if depth > settings.rr_depth {
                    // Roulette only paths whose weight fell below 1 (pbrt-v4): survival
                    // q = max β. Unlike Mitsuba's q = min(max β, 0.95) this never inflates
                    // weights above 1, which matters for long, weakly absorbing walks; the
                    // expectation is the same.
                    let q = w.max();
                    if q < 1.0 {
                        if q <= 0.0 || s.next_f32() >= q {
                            break;
                        }
                        w.scale(1.0 / q);
                    }
                }
                guide = None;
                if let (Some(bsdf), Some(light)) = (&rough, &scene.light)
                    && depth + 1 < settings.max_depth
                {
                    guide = rough::Guide::at(scene, bsdf, light, o, d);
                    let spawn = settings.spawn_offset;
                    if let Some(g) = &guide
                        && let Some((c, seg, cos)) =
                            g.connect(scene, bsdf, spawn, &phase, light, o, &w, s)
                    {
                        let sc = score(k, len + seg, phase_score, Some(cos));
                        l.record(c, sc, &m.sigma_t, &m.albedo);
                    }
                }
                let (u1, u2) = (s.next_f32(), s.next_f32());
                let d_new = phase.sample(d, u1, u2);
                if T::SCORES_PHASE {
                    phase_score += phase.d_log_dg(d.dot(d_new));
                }
                d = d_new;
                continue;
            }
        } else {
            let hit = if escaped {
                None
            } else if interface_events == 0
                && let Some(l) = &mut line
            {
                l.bins
                    .closest_first(scene.accel, &mut l.cursor, d, 0.0, f32::INFINITY)
            } else {
                closest(&mut line, on_line, o, d, f32::INFINITY)
            };
            let Some(hit) = hit else {
                if let Some(env) = &scene.environment {
                    let c = std::array::from_fn(|c| w.beta[c] * env.radiance[c]);
                    l.record(c, score(k, len, phase_score, None), &m.sigma_t, &m.albedo);
                }
                break;
            };
            hit
        };
        interface_events += 1;
        let spawn = settings.spawn_offset;
        if interface_events > MAX_INTERFACE_EVENTS {
            break;
        }
        if let Some(bsdf) = &rough {
            depth += 1;
            if depth >= settings.max_depth {
                break;
            }
            if let Some(light) = &scene.light
                && let Some(c) = rough::next_event(scene, bsdf, spawn, light, &hit, d, &w)
            {
                let c = c.map(|c| c * flight_weight);
                l.record(c, score(k, len, phase_score, None), &m.sigma_t, &m.albedo);
            }
            flight_weight = 1.0;
            if !rough::cross(bsdf, spawn, &hit, &mut o, &mut d, &mut inside, &mut w, s) {
                break;
            }
        } else if !cross_interface(m.eta, spawn, &hit, &mut o, &mut d, &mut inside, &mut w, s) {
            break;
        }
        escaped = !inside && d.dot(hit.ng) > 0.0 && scene.accel.exit_is_final(hit.tri);
    }
    l.finish();
    l
}

/// NEE to a point light from the scattering vertex `p` (inside, index-matched boundary):
/// β · f_p(d, ω_l) · T · I / r², T an estimate of exp(−σ_t ℓ_inside) ([`crate::shadow`]),
/// ℓ_inside and the phase function's cos θ = d·ω_l (`None`: no contribution).
#[inline]
#[allow(clippy::too_many_arguments)]
fn next_event(
    scene: &VolpathScene,
    shadow: ShadowTransmittance,
    phase: &HenyeyGreenstein,
    light: &PointLight,
    p: Vec3,
    d: Vec3,
    w: &SpectralWeight,
    s: &mut Sampler,
) -> Option<([f32; 3], f32, f32)> {
    let to_l = light.position - p;
    let r2 = to_l.length_squared();
    if r2 <= 0.0 {
        return None;
    }
    let dir_l = to_l / r2.sqrt();
    let f = phase.eval(d, dir_l) / r2;
    let (tr, len) = shadow.estimate_with_length(
        scene.accel,
        scene.light_bins,
        &scene.medium.sigma_t,
        p,
        light.position,
        s,
    );
    Some((
        std::array::from_fn(|c| w.beta[c] * f * tr[c] * light.intensity[c]),
        len,
        d.dot(dir_l),
    ))
}

/// NEE to a point light through the dielectric boundary (η ≠ 1) by manifold NEE
/// ([`crate::manifold`]): β · f_p(d, ω) · exp(−σ_t ℓ) · I · (1 − F) · dω_L/dA⊥, ℓ and the
/// phase function's cos θ = d·ω.
#[inline]
fn next_event_refracted(
    scene: &VolpathScene,
    phase: &HenyeyGreenstein,
    light: &PointLight,
    p: Vec3,
    d: Vec3,
    w: &SpectralWeight,
) -> Option<([f32; 3], f32, f32)> {
    let c = manifold::connect(scene.accel, p, light.position, scene.medium.eta)?;
    let f = phase.eval(d, c.dir) * c.transmittance * c.flux_factor;
    let st = &scene.medium.sigma_t;
    Some((
        std::array::from_fn(|k| {
            w.beta[k] * f * (-st[k] * c.inside_length).exp() * light.intensity[k]
        }),
        c.inside_length,
        d.dot(c.dir),
    ))
}

/// Interaction with the boundary at `hit`. η = 1: the ray crosses unchanged. η > 1: specular
/// reflection with probability F (TIR: F = 1), otherwise refraction with the radiance factor
/// 1/η_rel². Updates position (offset off the surface), direction and the inside flag.
/// Returns false when the path must end (shading-normal inconsistency).
#[inline]
#[allow(clippy::too_many_arguments)]
fn cross_interface(
    eta: f32,
    spawn: SpawnOffset,
    hit: &Hit,
    o: &mut Vec3,
    d: &mut Vec3,
    inside: &mut bool,
    w: &mut SpectralWeight,
    s: &mut Sampler,
) -> bool {
    let entering = hit.entering(*d);
    if eta == 1.0 {
        *inside = entering;
        *o = spawn.spawn(hit.p, hit.ng, *d);
        return true;
    }
    let eta_rel = if entering { eta } else { 1.0 / eta };
    let n = hit.ns;
    let cos_i = d.dot(n).abs();
    let f = fresnel_dielectric(cos_i, eta_rel);
    let side_in = d.dot(hit.ng);
    if s.next_f32() < f {
        let r = reflect(*d, n);
        if r.dot(hit.ng) * side_in >= 0.0 {
            return false; // reflected through the surface: shading normal too far from ng
        }
        *d = r;
        *o = spawn.spawn(hit.p, hit.ng, r);
        *inside = !entering;
    } else {
        let Some(t) = refract(*d, n, eta_rel) else {
            return false;
        };
        if t.dot(hit.ng) * side_in <= 0.0 {
            return false;
        }
        w.scale(1.0 / (eta_rel * eta_rel));
        *d = t;
        *o = spawn.spawn(hit.p, hit.ng, t);
        *inside = entering;
    }
    true
}
