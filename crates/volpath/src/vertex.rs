//! What the tracer's path loop ([`crate::integrator::trace`]) does at a path's vertices: at a
//! real scattering, the next-event estimates (through an index-matched boundary by a shadow ray,
//! through a smooth dielectric by manifold NEE, through a rough one by a guided connection) and
//! Russian roulette; at the boundary, the crossing of a null or smooth dielectric interface.

use geometry::Hit;
use glam::Vec3;
use scene::PointLight;

use crate::fresnel::{fresnel_dielectric, reflect, refract};
use crate::guided::Dwivedi;
use crate::manifold;
use crate::phase::ChannelHg;
use crate::rng::Sampler;
use crate::rough;
use crate::settings::{SpawnOffset, VolpathScene, VolpathSettings};
use crate::shadow::ShadowTransmittance;
use crate::spectral::SpectralWeight;
use crate::tally::{PathScore, Tally};

/// The score of a contribution after `k` scatterings and `len` inside the medium, with
/// `phase_score` the path's Σ ∂ ln p_{g_c}/∂g_c so far per channel and `cos` the angle of a
/// connection's own phase-function factor at the last vertex (`None`: none) ([`PathScore`]).
#[inline(always)]
pub(crate) fn score<T: Tally>(
    phase: &ChannelHg,
    k: u32,
    len: f32,
    phase_score: [f32; 3],
    cos: Option<f32>,
) -> PathScore {
    PathScore {
        k,
        len,
        phase: match cos {
            Some(cos) if T::SCORES_PHASE => {
                let d = phase.d_log_dg(cos);
                std::array::from_fn(|c| phase_score[c] + d[c])
            }
            _ => phase_score,
        },
    }
}

/// What the estimates at a vertex read: the scene, the settings, the phase function and the
/// rough boundary's BSDF (`None`: a null or smooth boundary).
pub(crate) struct Estimates<'a, 'b> {
    pub scene: &'a VolpathScene<'b>,
    pub settings: &'a VolpathSettings,
    pub phase: &'a ChannelHg,
    pub rough: Option<&'a base::microfacet::RoughDielectric>,
    /// The guided walks' constants (`None`: classical walks, [`crate::guided`]).
    pub dwivedi: Option<&'a Dwivedi>,
}

impl Estimates<'_, '_> {
    /// At the scattering vertex `o`, reached along `d` at `depth`, the path scored `at` so far
    /// (its scatterings, its length inside and its phase-function score): the next-event
    /// estimate of the point light, then Russian roulette, then (behind a rough boundary) the
    /// guided connection, whose guide the path keeps until it meets the boundary. False when
    /// the roulette ends the path. `normal` is the path's entry normal (the guided walks').
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn at_scattering<T: Tally>(
        &self,
        o: Vec3,
        d: Vec3,
        normal: Vec3,
        at: PathScore,
        depth: u32,
        w: &mut SpectralWeight,
        guide: &mut Option<rough::Guide>,
        l: &mut T,
        s: &mut Sampler,
    ) -> bool {
        let (scene, settings, phase) = (self.scene, self.settings, self.phase);
        let m = &scene.medium;
        let (k, len, phase_score) = (at.k, at.len, at.phase);
        if let Some(light) = &scene.light {
            let nee = if m.eta == 1.0 {
                next_event(scene, settings.shadow, phase, light, o, d, w, s)
            } else if self.rough.is_none() {
                next_event_refracted(scene, phase, light, o, d, w)
            } else {
                // Behind a rough boundary the light is reached from its vertices.
                None
            };
            if let Some((c, shadow_len, cos)) = nee {
                let sc = score::<T>(phase, k, len + shadow_len, phase_score, Some(cos));
                l.record(c, sc, &m.sigma_t, &m.albedo);
            }
        }
        if depth > settings.rr_depth {
            // Roulette only paths whose weight fell below 1 (pbrt-v4): survival q = max β.
            // Unlike Mitsuba's q = min(max β, 0.95) this never inflates weights above 1, which
            // matters for long, weakly absorbing walks; the expectation is the same.
            let q = w.max();
            if q < 1.0 {
                if q <= 0.0 || s.next_f32() >= q {
                    return false;
                }
                w.scale(1.0 / q);
            }
        }
        *guide = None;
        if let (Some(bsdf), Some(light)) = (self.rough, &scene.light)
            && depth + 1 < settings.max_depth
        {
            *guide = rough::Guide::at(scene, bsdf, light, o, d);
            let spawn = settings.spawn_offset;
            if let Some(g) = &*guide
                && let Some((c, seg, cos)) = g.connect(
                    scene,
                    bsdf,
                    spawn,
                    phase,
                    self.dwivedi.map(|dw| (dw, normal)),
                    light,
                    o,
                    w,
                    s,
                )
            {
                let sc = score::<T>(phase, k, len + seg, phase_score, Some(cos));
                l.record(c, sc, &m.sigma_t, &m.albedo);
            }
        }
        true
    }

    /// The path leaves the scene (scored `sc`): the environment's radiance, if there is one.
    #[inline(always)]
    pub(crate) fn escape<T: Tally>(&self, sc: PathScore, w: &SpectralWeight, l: &mut T) {
        if let Some(env) = &self.scene.environment {
            let m = &self.scene.medium;
            let c = std::array::from_fn(|c| w.beta[c] * env.radiance[c]);
            l.record(c, sc, &m.sigma_t, &m.albedo);
        }
    }

    /// Where the path meets the boundary at `hit` (its contributions scored `sc`): a rough
    /// boundary counts as depth, estimates the point light from its own vertex (weighted by
    /// `flight_weight` against the guided connection) and is crossed by sampling its BSDF; a
    /// null or smooth one is crossed ([`cross_interface`]). Moves the ray (`o`, `d`, inside);
    /// false when the path ends there.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn at_boundary<T: Tally>(
        &self,
        hit: &Hit,
        sc: PathScore,
        depth: &mut u32,
        flight_weight: &mut f32,
        (o, d, inside): (&mut Vec3, &mut Vec3, &mut bool),
        w: &mut SpectralWeight,
        l: &mut T,
        s: &mut Sampler,
    ) -> bool {
        let (scene, settings) = (self.scene, self.settings);
        let m = &scene.medium;
        let spawn = settings.spawn_offset;
        let Some(bsdf) = self.rough else {
            return cross_interface(m.eta, spawn, hit, o, d, inside, w, s);
        };
        *depth += 1;
        if *depth >= settings.max_depth {
            return false;
        }
        if let Some(light) = &scene.light
            && let Some(c) = rough::next_event(scene, bsdf, spawn, light, hit, *d, w)
        {
            let c = c.map(|c| c * *flight_weight);
            l.record(c, sc, &m.sigma_t, &m.albedo);
        }
        *flight_weight = 1.0;
        rough::cross(bsdf, spawn, hit, o, d, inside, w, s)
    }
}

/// NEE to a point light from the scattering vertex `p` (inside, index-matched boundary):
/// β_c · f_{p,c}(d, ω_l) · T_c · I_c / r² per channel c, T an estimate of exp(−σ_t ℓ_inside) ([`crate::shadow`]),
/// ℓ_inside and the phase function's cos θ = d·ω_l (`None`: no contribution).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn next_event(
    scene: &VolpathScene,
    shadow: ShadowTransmittance,
    phase: &ChannelHg,
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
    let f = phase.eval(d, dir_l).map(|f| f / r2);
    let (tr, len) = shadow.estimate_with_length(
        scene.accel,
        scene.light_bins,
        &scene.medium.sigma_t,
        p,
        light.position,
        s,
    );
    Some((
        std::array::from_fn(|c| w.beta[c] * f[c] * tr[c] * light.intensity[c]),
        len,
        d.dot(dir_l),
    ))
}

/// NEE to a point light through the dielectric boundary (η ≠ 1) by manifold NEE
/// ([`crate::manifold`]): β_c · f_{p,c}(d, ω) · exp(−σ_t,c ℓ) · I_c · (1 − F) · dω_L/dA⊥ per
/// channel c, ℓ and the phase function's cos θ = d·ω.
#[inline]
pub(crate) fn next_event_refracted(
    scene: &VolpathScene,
    phase: &ChannelHg,
    light: &PointLight,
    p: Vec3,
    d: Vec3,
    w: &SpectralWeight,
) -> Option<([f32; 3], f32, f32)> {
    let c = manifold::connect(scene.accel, p, light.position, scene.medium.eta)?;
    let f = phase
        .eval(d, c.dir)
        .map(|f| f * c.transmittance * c.flux_factor);
    let st = &scene.medium.sigma_t;
    Some((
        std::array::from_fn(|k| {
            w.beta[k] * f[k] * (-st[k] * c.inside_length).exp() * light.intensity[k]
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
pub(crate) fn cross_interface(
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
