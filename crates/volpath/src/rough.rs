//! The rough dielectric boundary in the tracer: a surface of GGX microfacets between the object
//! (η = n_inside/n_outside) and the outside, as Mitsuba 3's `roughdielectric`
//! ([`base::microfacet::RoughDielectric`]).
//!
//! At every boundary vertex, from either side, the path
//!
//! 1. connects to the point light through the BSDF (next-event estimation):
//!    β · f(ω_i, ω_l)|cos θ_l| · I / r², when the segment to the light meets the mesh nowhere
//!    (a light outside the object is reached from inside only through this vertex's
//!    transmission, from outside through its reflection: the highlight);
//! 2. continues in a direction drawn from the BSDF (visible normals, then reflection with
//!    probability F or refraction), its weight f|cos θ_o|/pdf multiplying β.
//!
//! A rough surface spreads the light it transmits over a solid angle, so unlike the smooth
//! boundary a point light is reached without manifold walks: the scattering vertices inside see
//! it only through the boundary (their shadow rays are blocked, as in Mitsuba 3's `volpath`),
//! and each boundary vertex makes the connection. The shading normal is the macro normal;
//! a direction on different sides of the shading and the geometric normal ends the path (no
//! light leaks through the surface).

use base::microfacet::RoughDielectric;
use geometry::{Frame, Hit};
use glam::Vec3;
use scene::PointLight;

use crate::integrator::{SpawnOffset, VolpathScene};
use crate::rng::Sampler;
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
