//! Next-event estimation to a point light through ONE smooth refractive boundary ("manifold
//! next-event estimation", Hanika, Droske and Fascione 2015, specialised to a single refraction).
//!
//! A shadow ray cannot connect a vertex x inside a dielectric (η > 1) to a point light L: light
//! reaches x only along the refracted path L → y → x where y on the boundary satisfies Snell's law.
//! We find y by Newton's method over the direction ω of the inside segment x → y (y(ω) = first
//! boundary hit from x), driving the residual r(ω) = refract(ω, n_s(y), 1/η) − normalize(L − y)
//! to zero (2-D, finite-difference Jacobian, backtracking). The light then arrives at x as a
//! collimated beam of perpendicular flux density
//!
//!   E⊥(x) = I · (1 − F(y)) · dω_L / dA⊥(x),
//!
//! where dω_L/dA⊥ is the ratio of the solid angle of a thin tube of rays leaving the light to its
//! perpendicular cross-section at x after refraction (flux is conserved along the tube; the η²
//! radiance scaling is implicit). We measure it by tracing the central ray and four rays rotated by
//! ±δ from the light, refracting them and intersecting them with the plane through x perpendicular
//! to the central ray: dA⊥/dω_L ≈ |(p₊ₛ − p₋ₛ) × (p₊ₜ − p₋ₜ)| / 4δ² (central differences). The same central ray checks that
//! y is visible from the light.
//!
//! Limitations (documented in CONVENTIONS.md): one refraction solution is found (exact for
//! convex objects; non-convex objects can have more, which are missed), and light that enters the
//! medium after other specular events (an outside reflection, an internal reflection before the
//! first scattering) is not included; in dense media (σ_t·size ≫ 1) the latter is negligible.

use geometry::{Accel, Frame};
use glam::Vec3;

use crate::fresnel::{fresnel_dielectric, refract};

/// A converged refraction connection from an inside point to a point light.
#[derive(Clone, Copy, Debug)]
pub struct Connection {
    /// Unit direction from x towards the boundary point y.
    pub dir: Vec3,
    /// Length of the inside segment x → y.
    pub inside_length: f32,
    /// Fresnel transmittance 1 − F at y.
    pub transmittance: f32,
    /// dω_L / dA⊥ at x: multiply by the light intensity to get the perpendicular flux density.
    pub flux_factor: f32,
}

/// How far a solve goes: the residual it stops at (≈ an angle in radians) and its Newton steps.
#[derive(Clone, Copy, Debug)]
pub struct Precision {
    pub tolerance: f32,
    pub max_iters: usize,
}

/// The smooth boundary's connection: exact to 2·10⁻⁵.
const EXACT: Precision = Precision {
    tolerance: 2e-5,
    max_iters: 24,
};
const FD_STEP: f32 = 2e-4; // radians, for the Newton Jacobian
const TUBE_STEP: f32 = 5e-4; // radians, for the flux tube (central differences)

/// Boundary point hit from inside along `dir`, with the outgoing refracted direction.
struct Exit {
    y: Vec3,
    t: f32,
    out: Vec3,
    cos_in: f32,
}

#[inline]
fn exit(accel: &Accel, x: Vec3, dir: Vec3, eta: f32) -> Option<Exit> {
    let h = accel.closest(x, dir, 0.0, f32::INFINITY)?;
    if h.entering(dir) {
        return None; // x is not inside, or the mesh is not closed
    }
    let out = refract(dir, h.ns, 1.0 / eta)?;
    if out.dot(h.ng) <= 0.0 {
        return None;
    }
    Some(Exit {
        y: h.p,
        t: h.t,
        out,
        cos_in: dir.dot(h.ns).abs(),
    })
}

/// Residual of direction `dir`: (out − target) in the frame `f` (2-D).
#[inline]
fn residual(e: &Exit, light: Vec3, f: &Frame) -> Option<[f32; 2]> {
    let target = (light - e.y).try_normalize()?;
    let r = e.out - target;
    Some([r.dot(f.s), r.dot(f.t)])
}

/// Solve for the refraction point connecting the inside point `x` to the light at `light`.
pub fn connect(accel: &Accel, x: Vec3, light: Vec3, eta: f32) -> Option<Connection> {
    let (dir, cur) = solve(accel, x, light, eta, EXACT)?;
    let flux_factor = flux_factor(accel, x, dir, &cur, light, eta)?;
    let transmittance = 1.0 - fresnel_dielectric(cur.cos_in, 1.0 / eta);
    Some(Connection {
        dir,
        inside_length: cur.t,
        transmittance,
        flux_factor,
    })
}

/// The direction from the inside point `x` whose smooth refraction reaches the light, to
/// `precision`: the peak of a rough boundary's transmission towards it ([`crate::rough`] guides
/// its connections by it, and needs it only to a fraction of the lobe's width). `None` when the
/// solve does not get there.
pub fn refracted_direction(
    accel: &Accel,
    x: Vec3,
    light: Vec3,
    eta: f32,
    precision: Precision,
) -> Option<Vec3> {
    solve(accel, x, light, eta, precision).map(|(dir, _)| dir)
}

/// Newton's method on the exit direction (module docs), to `p`: the direction and its exit.
fn solve(accel: &Accel, x: Vec3, light: Vec3, eta: f32, p: Precision) -> Option<(Vec3, Exit)> {
    // Seed: the straight line to the light; if it meets the boundary beyond the critical angle,
    // tilt it towards that point's normal until it refracts.
    let straight = (light - x).try_normalize()?;
    let h = accel.closest(x, straight, 0.0, f32::INFINITY)?;
    let mut seed = None;
    for tilt in [0.0f32, 0.25, 0.5, 1.0, 2.0, 4.0] {
        let d = (straight + tilt * h.ns).normalize();
        if let Some(e) = exit(accel, x, d, eta) {
            seed = Some((d, e));
            break;
        }
    }
    let (mut dir, mut cur) = seed?;
    let mut converged = false;
    for _ in 0..p.max_iters {
        // Residual frame: around the current target direction (fixed within one iteration).
        let rf = Frame::from_normal((light - cur.y).try_normalize()?);
        let r0 = residual(&cur, light, &rf)?;
        let norm0 = (r0[0] * r0[0] + r0[1] * r0[1]).sqrt();
        if norm0 < p.tolerance {
            converged = true;
            break;
        }
        // Finite-difference Jacobian over the direction parameters (a, b) around `dir`.
        let df = Frame::from_normal(dir);
        let mut jac = [[0.0f32; 2]; 2];
        for (k, axis) in [df.s, df.t].into_iter().enumerate() {
            let e = exit(accel, x, (dir + FD_STEP * axis).normalize(), eta)?;
            let r = residual(&e, light, &rf)?;
            jac[0][k] = (r[0] - r0[0]) / FD_STEP;
            jac[1][k] = (r[1] - r0[1]) / FD_STEP;
        }
        let det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
        if !det.is_finite() || det.abs() < 1e-12 {
            return None;
        }
        let da = -(jac[1][1] * r0[0] - jac[0][1] * r0[1]) / det;
        let db = -(-jac[1][0] * r0[0] + jac[0][0] * r0[1]) / det;
        // Backtracking: accept the first step that reduces the residual.
        let mut step = 1.0f32;
        let mut accepted = false;
        for _ in 0..6 {
            let cand = (dir + step * (da * df.s + db * df.t)).normalize();
            if let Some(e) = exit(accel, x, cand, eta)
                && let Some(r) = residual(&e, light, &rf)
                && (r[0] * r[0] + r[1] * r[1]).sqrt() < norm0
            {
                dir = cand;
                cur = e;
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if !accepted {
            return None;
        }
    }
    converged.then_some((dir, cur))
}

/// dω_L/dA⊥ at x by a tube of three rays from the light (see module docs). Returns `None` when the
/// central ray from the light does not reach y first (y is occluded from the light).
fn flux_factor(accel: &Accel, x: Vec3, dir: Vec3, e: &Exit, light: Vec3, eta: f32) -> Option<f32> {
    let to_y = e.y - light;
    let dist = to_y.length();
    let u0 = to_y / dist;
    // Plane through x perpendicular to the inside propagation direction (−dir).
    let plane_n = -dir;
    let land = |u: Vec3| -> Option<(Vec3, Vec3)> {
        let h = accel.closest(light, u, 0.0, f32::INFINITY)?;
        if !h.entering(u) {
            return None;
        }
        let v = refract(u, h.ns, eta)?;
        let denom = v.dot(plane_n);
        if denom <= 1e-6 {
            return None;
        }
        let s = (x - h.p).dot(plane_n) / denom;
        Some((h.p + s * v, h.p))
    };
    let (_, y0) = land(u0)?;
    // Visibility of y from the light: the first hit must be y itself.
    if (y0 - e.y).length() > 1e-4 * dist.max(1e-3) {
        return None;
    }
    let f = Frame::from_normal(u0);
    let (ps, _) = land((u0 + TUBE_STEP * f.s).normalize())?;
    let (ms, _) = land((u0 - TUBE_STEP * f.s).normalize())?;
    let (pt, _) = land((u0 + TUBE_STEP * f.t).normalize())?;
    let (mt, _) = land((u0 - TUBE_STEP * f.t).normalize())?;
    // Central differences: ∂p/∂a ≈ (p₊ − p₋)/2δ; dA⊥/dω = |∂p/∂a × ∂p/∂b| (the rotation by a, b
    // about u0 maps the unit square to solid angle da·db to first order).
    let area = (ps - ms).cross(pt - mt).length();
    if !(area > 0.0 && area.is_finite()) {
        return None;
    }
    Some(4.0 * TUBE_STEP * TUBE_STEP / area)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slab |x|,|z| ≤ 5, −3 ≤ y ≤ 0 (top face at y = 0), closed and CCW-outward.
    fn slab() -> Accel {
        let mut mesh = geometry::sharp_box(Vec3::new(-5.0, -3.0, -5.0), Vec3::new(5.0, 0.0, 5.0));
        let w = geometry::mesh::validate(&mut mesh, "slab").unwrap();
        assert!(w.is_empty(), "{w:?}");
        Accel::new(mesh)
    }

    /// Closed form for a flat interface: light at height h above it, x at depth z and horizontal
    /// distance ρ_x from the light's foot. With θ₁ (outside) and θ₂ (inside) angles from the
    /// normal, sin θ₁ = η sin θ₂ and ρ_x = h tan θ₁ + z tan θ₂; by rotational symmetry
    /// dω_L/dA⊥ = sin θ₁ / (ρ_x cos θ₂ · dρ_x/dθ₁), dρ_x/dθ₁ = h/cos²θ₁ + z/cos²θ₂ · cos θ₁/(η cos θ₂).
    fn flat_interface(h: f64, z: f64, rho_x: f64, eta: f64) -> (f64, f64) {
        // Solve for θ₁ by bisection on ρ(θ₁) (monotone).
        let rho = |t1: f64| {
            let t2 = (t1.sin() / eta).asin();
            h * t1.tan() + z * t2.tan()
        };
        let (mut lo, mut hi) = (0.0f64, std::f64::consts::FRAC_PI_2 - 1e-9);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if rho(mid) < rho_x { lo = mid } else { hi = mid }
        }
        let t1 = 0.5 * (lo + hi);
        let t2 = (t1.sin() / eta).asin();
        let drho = h / t1.cos().powi(2) + z / t2.cos().powi(2) * t1.cos() / (eta * t2.cos());
        (t1, t1.sin() / (rho_x * t2.cos() * drho))
    }

    #[test]
    fn flat_interface_matches_closed_form() {
        let accel = slab();
        let light = Vec3::new(0.0, 2.0, 0.0);
        for &eta in &[1.0001f32, 1.33, 1.5] {
            for &(rx, z) in &[(0.3f32, 0.05f32), (1.0, 0.2), (2.5, 0.5), (0.01, 0.1)] {
                let x = Vec3::new(rx * 0.6, -z, rx * 0.8);
                let c = connect(&accel, x, light, eta)
                    .unwrap_or_else(|| panic!("no convergence η={eta} ρ={rx} z={z}"));
                let (t1, expect) = flat_interface(2.0, z as f64, rx as f64, eta as f64);
                let rel = (c.flux_factor as f64 - expect).abs() / expect;
                assert!(
                    rel < 2e-3,
                    "η={eta} ρ={rx} z={z}: {} vs {expect} (rel {rel:.2e})",
                    c.flux_factor
                );
                let f = fresnel_dielectric(t1.cos() as f32, eta);
                assert!((c.transmittance - (1.0 - f)).abs() < 1e-3);
                assert!(
                    (c.inside_length as f64 - z as f64 / ((t1.sin() / eta as f64).asin()).cos())
                        .abs()
                        < 1e-4
                );
            }
        }
        // η → 1 reduces to the inverse-square law.
        let x = Vec3::new(0.5, -0.2, 0.1);
        let c = connect(&accel, x, light, 1.0001).unwrap();
        let r2 = (light - x).length_squared();
        assert!((c.flux_factor * r2 - 1.0).abs() < 2e-3);
    }

    #[test]
    fn points_outside_the_medium_do_not_connect() {
        let accel = slab();
        assert!(
            connect(
                &accel,
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, 2.0, 0.0),
                1.5
            )
            .is_none()
        );
    }
}
