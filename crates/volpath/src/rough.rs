//! The rough dielectric boundary in the tracer: a surface of GGX microfacets between the object
//! (η = n_inside/n_outside) and the outside, as Mitsuba 3's `roughdielectric`
//! ([`base::microfacet::RoughDielectric`]).
//!
//! At every boundary vertex, from either side, the path
//!
//! 1. connects to the point light through the BSDF (next-event estimation):
//!    β · f(ω_i, ω_l)|cos θ_l| · I / r², when the segment to the light meets the mesh nowhere
//!    (from outside through the reflection: the highlight; from inside through the
//!    transmission);
//! 2. continues in a direction drawn from the BSDF (visible normals, then reflection with
//!    probability F or refraction), its weight f|cos θ_o|/pdf multiplying β.
//!
//! Light leaving the object through a tilted microfacet turns by (1 − 1/η)·δ for a tilt δ, so
//! seen from inside the transmission lobe towards a point light is narrow (about α(1 − 1/η)),
//! and a path whose last scattering sent it elsewhere carries none of it: (1) alone is unbiased
//! but very noisy (docs/notes/rough-boundary.md). So each scattering vertex x near the surface
//! also
//!
//! 3. connects through the surface by a [`Guide`]: a direction ω drawn around ω₀, the direction
//!    whose smooth refraction reaches the light (a few Newton steps of
//!    [`crate::manifold`]), the boundary point it meets, and (1) there. The two ways of reaching
//!    that boundary point from x (the free flight after phase sampling, and the guide) are
//!    combined by the balance heuristic, over the channels as the path's spectral weights mix
//!    them: both contribute β·f_p(ω)·e^{−σ_t d}·f_s·I/r² / (p_phase(ω)·P̄_pass(d) + p_guide(ω)).
//!
//! The scattering vertices do no other next-event estimation (a shadow ray through a rough
//! surface has no single direction; Mitsuba 3's `volpath` blocks it). The shading normal is the
//! macro normal; a direction on different sides of the shading and the geometric normal ends the
//! path (no light leaks through the surface).

use base::microfacet::RoughDielectric;
use geometry::{Frame, Hit};
use glam::Vec3;
use scene::PointLight;

use crate::guided::Dwivedi;
use crate::phase::ChannelHg;
use crate::rng::Sampler;
use crate::settings::{SpawnOffset, VolpathScene};
use crate::spectral::SpectralWeight;

/// The local frame of the boundary at `hit` (z: the outward shading normal) and `-d` in it, or
/// `None` when `d` meets the shading and the geometric surface from different sides.
#[inline]
fn frame_at(hit: &Hit, d: Vec3) -> Option<(Frame, Vec3)> {
    let frame = Frame::from_normal(hit.ns);
    let wi = frame.to_local(-d);
    (wi.z * -d.dot(hit.ng) > 0.0).then_some((frame, wi))
}

/// NEE to `light` from the boundary vertex `hit` reached along `d`, through the BSDF
/// ([module docs](self), 1): the contribution per channel, or `None` when the light is hidden
/// or the BSDF is zero.
#[inline]
pub(crate) fn next_event(
    scene: &VolpathScene,
    bsdf: &RoughDielectric,
    spawn: SpawnOffset,
    light: &PointLight,
    hit: &Hit,
    d: Vec3,
    w: &SpectralWeight,
) -> Option<[f32; 3]> {
    let (frame, wi) = frame_at(hit, d)?;
    let to_l = light.position - hit.p;
    let r2 = to_l.length_squared();
    if r2.is_nan() || r2 <= 0.0 {
        return None;
    }
    let wl = to_l / r2.sqrt();
    let wl_local = frame.to_local(wl);
    if wl_local.z * wl.dot(hit.ng) <= 0.0 {
        return None;
    }
    let f = bsdf.eval(wi, wl_local);
    if f.is_nan() || f <= 0.0 {
        return None;
    }
    let origin = spawn.spawn(hit.p, hit.ng, wl);
    let dist = (light.position - origin).length();
    if scene.accel.closest(origin, wl, 0.0, dist).is_some() {
        return None;
    }
    let f = f / r2;
    Some(std::array::from_fn(|c| w.beta[c] * f * light.intensity[c]))
}

/// The guided connection from a scattering vertex x through the rough boundary to the light
/// ([module docs](self), 3): directions ω drawn around ω₀, the direction whose smooth refraction
/// reaches the light ([`crate::manifold::refracted_direction`]), by a Gaussian of angular scale
/// s in the plane tangent to ω₀ (gnomonic: ω = normalize(ω₀ + u t + v b), (u, v) ~ N(0, s²),
/// density N(u, v)·(1 + u² + v²)^{3/2} per solid angle).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Guide {
    frame: Frame,
    s: f32,
    /// The direction the path arrived at x in (the phase function's argument).
    d_in: Vec3,
}

impl Guide {
    /// The guide at the scattering vertex `x` (reached along `d_in`), or `None` when the
    /// refracted connection does not exist or does not converge.
    #[inline]
    pub(crate) fn at(
        scene: &VolpathScene,
        bsdf: &RoughDielectric,
        light: &PointLight,
        x: Vec3,
        d_in: Vec3,
    ) -> Option<Guide> {
        // Deep inside, the light the connection could carry is negligible: the free flight's
        // next-event estimates alone (weight 1) cover those vertices, at no solve's cost.
        let to_light = (light.position - x).try_normalize()?;
        let wall = scene.accel.closest(x, to_light, 0.0, f32::INFINITY)?;
        let st = &scene.medium.sigma_t;
        if st[0].min(st[1]).min(st[2]) * wall.t > GUIDE_DEPTH {
            return None;
        }
        let s = (GUIDE_SCALE * bsdf.ggx.alpha * (1.0 - 1.0 / bsdf.eta)).max(1e-3);
        let w0 = crate::manifold::refracted_direction(
            scene.accel,
            x,
            light.position,
            bsdf.eta,
            crate::manifold::Precision {
                tolerance: GUIDE_TOLERANCE * s,
                max_iters: GUIDE_ITERATIONS,
            },
        )?;
        Some(Guide {
            frame: Frame::from_normal(w0),
            s,
            d_in,
        })
    }

    /// The density of [`Guide::sample`] per solid angle at the unit direction `w`.
    #[inline]
    pub(crate) fn pdf(&self, w: Vec3) -> f32 {
        let l = self.frame.to_local(w);
        if l.z <= 0.0 {
            return 0.0;
        }
        let (u, v) = (l.x / l.z, l.y / l.z);
        let r2 = u * u + v * v;
        let s2 = self.s * self.s;
        (-r2 / (2.0 * s2)).exp() / (2.0 * std::f32::consts::PI * s2) * (1.0 + r2).powf(1.5)
    }

    /// A direction around ω₀ from two uniform numbers (Box–Muller).
    #[inline]
    fn sample(&self, u1: f32, u2: f32) -> Vec3 {
        let r = self.s * (-2.0 * (1.0 - u1).max(f32::MIN_POSITIVE).ln()).sqrt();
        let phi = std::f32::consts::TAU * u2;
        self.frame
            .to_world(Vec3::new(r * phi.cos(), r * phi.sin(), 1.0))
            .normalize()
    }

    /// The direction the path arrived at x in (the phase function's argument).
    #[inline]
    pub(crate) fn d_in(&self) -> Vec3 {
        self.d_in
    }

    /// The balance-heuristic weight of the other strategy, the free flight from x along `w`
    /// that passed the boundary, against this guide; `pa` is that flight's density (the
    /// direction's times the spectral pass probability: [`free_flight_density`]).
    #[inline]
    pub(crate) fn flight_weight(&self, pa: f32, w: Vec3) -> f32 {
        let pb = self.pdf(w);
        if pa + pb > 0.0 { pa / (pa + pb) } else { 1.0 }
    }

    /// The guided connection's contribution from x ([module docs](self), 3), the inside
    /// length of its segment and its phase function's cos θ: β·f_p(ω)·e^{−σ_t d}·f_s·|cos θ_l|·I/r² / (p_phase(ω)·P̄_pass(d) +
    /// p_guide(ω)), the balance heuristic over the two strategies (and the channels).
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn connect(
        &self,
        scene: &VolpathScene,
        bsdf: &RoughDielectric,
        spawn: SpawnOffset,
        phase: &ChannelHg,
        walk: Option<(&Dwivedi, Vec3)>,
        light: &PointLight,
        x: Vec3,
        w: &SpectralWeight,
        s: &mut Sampler,
    ) -> Option<([f32; 3], f32, f32)> {
        let dir = self.sample(s.next_f32(), s.next_f32());
        let hit = scene.accel.closest(x, dir, 0.0, f32::INFINITY)?;
        if hit.entering(dir) {
            return None;
        }
        let st = &scene.medium.sigma_t;
        let pb = self.pdf(dir);
        let fp = phase.eval(self.d_in, dir);
        let denom = free_flight_density(walk, w, st, fp, dir, hit.t) + pb;
        if denom.is_nan() || denom <= 0.0 {
            return None;
        }
        let unit = SpectralWeight::new(w.hero);
        let fs = next_event(scene, bsdf, spawn, light, &hit, dir, &unit)?;
        Some((
            std::array::from_fn(|c| w.beta[c] * (fp[c] / denom) * (-st[c] * hit.t).exp() * fs[c]),
            hit.t,
            self.d_in.dot(dir),
        ))
    }
}

/// The density of the walk's own way to the boundary point at distance `t` along `dir` from a
/// scattering vertex: the direction (phase-function density `fp` per channel) and a flight that
/// passes `t`, mixed over the channels as `w` mixes them; with guided walks (`walk`: their
/// constants and the path's entry normal) both are [`crate::guided`]'s mixtures.
#[inline]
pub(crate) fn free_flight_density(
    walk: Option<(&Dwivedi, Vec3)>,
    w: &SpectralWeight,
    sigma_t: &[f32; 3],
    fp: [f32; 3],
    dir: Vec3,
    t: f32,
) -> f32 {
    match walk {
        Some((dw, n)) => dw.flight_density(w, sigma_t, fp, dir.dot(n), t),
        None if fp[0] == fp[1] && fp[1] == fp[2] => fp[0] * w.pass_probability(sigma_t, t),
        None => w.mixture([std::array::from_fn(|j| fp[j] * (-sigma_t[j] * t).exp()); 2]),
    }
}

/// The guide's angular scale in units of α(1 − 1/η): a microfacet tilt δ turns light leaving
/// the object by (1 − 1/η)δ… as seen from inside, so the transmission lobe towards the light is
/// about α(1 − 1/η) wide in the direction from x; the factor widens the guide to cover the lobe's
/// tails (the free flight covers the rest).
const GUIDE_SCALE: f32 = 1.5;

/// How closely the guide's centre solves the smooth connection, in units of its scale (the
/// residual is an angle of the refracted ray; a tenth of the guide's width is ample), and the
/// Newton steps allowed: a faceted mesh (face normals) makes the residual jump between facets,
/// where a solve to the smooth case's 2·10⁻⁵ would spend every step.
const GUIDE_TOLERANCE: f32 = 0.1;
const GUIDE_ITERATIONS: usize = 6;

/// Mean free paths (of the least extinguishing channel) towards the light beyond which a
/// scattering vertex gets no guided connection: its light would be attenuated by e^{−4} ≈ 2 %
/// or more on the way to the surface.
const GUIDE_DEPTH: f32 = 4.0;

/// Continues the path at the boundary vertex `hit` in a direction drawn from the BSDF
/// ([module docs](self), 2): updates the origin, the direction, the inside flag and the weight.
/// False when the path ends (no valid direction).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn cross(
    bsdf: &RoughDielectric,
    spawn: SpawnOffset,
    hit: &Hit,
    o: &mut Vec3,
    d: &mut Vec3,
    inside: &mut bool,
    w: &mut SpectralWeight,
    s: &mut Sampler,
) -> bool {
    let Some((frame, wi)) = frame_at(hit, *d) else {
        return false;
    };
    let (u_lobe, u1, u2) = (s.next_f32(), s.next_f32(), s.next_f32());
    let Some(x) = bsdf.sample(wi, u_lobe, u1, u2) else {
        return false;
    };
    let wo = frame.to_world(x.wo).normalize();
    let side = wo.dot(hit.ng);
    if side * x.wo.z <= 0.0 {
        return false;
    }
    w.scale(x.weight);
    *d = wo;
    *o = spawn.spawn(hit.p, hit.ng, wo);
    *inside = side < 0.0;
    true
}
