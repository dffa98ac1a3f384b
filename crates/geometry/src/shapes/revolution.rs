//! Surfaces of revolution about the Y axis: the generic profile revolver with the rounded-cone
//! profile ([`Shape::Cone`]), and the torus ([`Shape::Torus`]).
//!
//! [`Shape::Cone`]: super::Shape::Cone
//! [`Shape::Torus`]: super::Shape::Torus

use std::f64::consts::{FRAC_PI_2, TAU};

use glam::{DVec3, Vec3};

use crate::Mesh;

/// One sample of a profile curve in the (ρ, y) half-plane: position and unit outward normal.
#[derive(Clone, Copy, Debug)]
pub(super) struct ProfilePoint {
    rho: f64,
    y: f64,
    n_rho: f64,
    n_y: f64,
}

/// Surface of revolution of a profile about the Y axis.
///
/// `profile` runs from a pole on the axis (ρ = 0) to another pole on the axis; the points in
/// between (ρ > 0) become rings of `segments` vertices at azimuths φ_j = 2πj/segments, placed at
/// `(ρ cos φ, y, ρ sin φ)` with normal `(n_ρ cos φ, n_y, n_ρ sin φ)`. The profile must run from
/// the bottom pole over the outside to the top pole: then, with `t` the profile direction and
/// `e_φ` the direction of increasing φ, `t × e_φ` points outward (at φ = 0 on a flank going up and
/// inward, `(−R, H, 0) × (0, 0, 1) = (H, R, 0)`), and the quads `(k, j), (k+1, j), (k+1, j+1),
/// (k, j+1)` are wound CCW seen from outside.
pub(super) fn revolve(profile: &[ProfilePoint], segments: u32) -> Mesh {
    let n = segments as usize;
    let rings = &profile[1..profile.len() - 1];
    let (first, last) = (profile[0], profile[profile.len() - 1]);
    let mut positions = Vec::with_capacity(rings.len() * n + 2);
    let mut normals = Vec::with_capacity(rings.len() * n + 2);
    positions.push(DVec3::new(0.0, first.y, 0.0));
    normals.push(DVec3::new(0.0, first.n_y.signum(), 0.0));
    let trig: Vec<(f64, f64)> = (0..n)
        .map(|j| (TAU * j as f64 / n as f64).sin_cos())
        .collect();
    for p in rings {
        for &(s, c) in &trig {
            positions.push(DVec3::new(p.rho * c, p.y, p.rho * s));
            normals.push(DVec3::new(p.n_rho * c, p.n_y, p.n_rho * s).normalize());
        }
    }
    positions.push(DVec3::new(0.0, last.y, 0.0));
    normals.push(DVec3::new(0.0, last.n_y.signum(), 0.0));

    let ring = |k: usize, j: usize| (1 + k * n + j % n) as u32;
    let top = (positions.len() - 1) as u32;
    let mut indices = Vec::with_capacity(2 * n * rings.len());
    for j in 0..n {
        indices.push([0, ring(0, j), ring(0, j + 1)]);
    }
    for k in 0..rings.len() - 1 {
        for j in 0..n {
            let (a, b, c, d) = (
                ring(k, j),
                ring(k + 1, j),
                ring(k + 1, j + 1),
                ring(k, j + 1),
            );
            indices.push([a, b, c]);
            indices.push([a, c, d]);
        }
    }
    let k = rings.len() - 1;
    for j in 0..n {
        indices.push([ring(k, j), top, ring(k, j + 1)]);
    }
    Mesh {
        positions: positions.iter().map(|p| p.as_vec3()).collect(),
        normals: Some(normals.iter().map(|p| p.as_vec3()).collect()),
        indices,
    }
}

/// The profile of the rounded cone in the (ρ, y) half-plane, base at y = 0.
///
/// Sharp cone: base disc of radius R at y = 0, apex at (0, H); flank length L = √(H² + R²),
/// half-angle α at the apex (sin α = R/L, cos α = H/L), outward flank normal (cos α, sin α).
/// * Tip: circle of radius r centred at (0, y_c), y_c = H − r/sin α, tangent to the flank at
///   (0, y_c) + r·(cos α, sin α), i.e. r/tan α below the apex along the flank; arc over normal
///   angles θ ∈ [α, π/2]. Top of the shape: y_c + r = H − r(csc α − 1).
/// * Rim: circle of radius r tangent to the base and the flank; the base/flank corner has the
///   interior angle γ = π/2 − α, so the tangent points are t = r/tan(γ/2) = r(L + R)/H from the
///   corner; centre (R − t, r); arc over normal angles θ ∈ [−π/2, α]. Widest radius:
///   R − t + r = R − r(sec α + tan α − 1).
/// * Flat base from the axis to (R − t, 0), straight flank between the two tangent points.
///
/// Given the wanted outer height h and radius ρ, the two extents above and R = H tan α give
/// `tan α = (ρ − r)/(h − 2r)`, H = h + r(csc α − 1), R = H tan α (see [`ConeProfile::fit`]).
pub(super) struct ConeProfile {
    rho_fillet: f64,
    r: f64,
    alpha: f64,
    y_tip_centre: f64,
    flank_len: f64,
    base_len: f64,
    outer_radius: f64,
}

impl ConeProfile {
    /// The rounded cone with outer height `h`, outer (base) radius `rho` and rounding radius `r`,
    /// or `None` when the tip and rim roundings do not fit (overlap on the flank, or the rim
    /// fillet reaches the axis).
    pub(super) fn fit(h: f64, rho: f64, r: f64) -> Option<ConeProfile> {
        if !(h > 2.0 * r && rho > r && r > 0.0) {
            return None;
        }
        let alpha = ((rho - r) / (h - 2.0 * r)).atan();
        let big_h = h + r * (1.0 / alpha.sin() - 1.0);
        let big_r = big_h * alpha.tan();
        let l = (big_h * big_h + big_r * big_r).sqrt();
        let t_rim = r * (l + big_r) / big_h;
        let t_tip = r / alpha.tan();
        let flank_len = l - t_rim - t_tip;
        let base_len = big_r - t_rim;
        if flank_len < -1e-9 * l || base_len <= 1e-6 * big_r || !flank_len.is_finite() {
            return None;
        }
        Some(ConeProfile {
            rho_fillet: big_r - t_rim,
            r,
            alpha,
            y_tip_centre: big_h - r / alpha.sin(),
            flank_len: flank_len.max(0.0),
            base_len,
            outer_radius: rho,
        })
    }

    /// The largest rounding radius for which [`ConeProfile::fit`] succeeds (bisection; only used
    /// for error messages).
    pub(super) fn max_rounding(h: f64, rho: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, rho.min(0.5 * h));
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if ConeProfile::fit(h, rho, mid).is_some() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// Sample the profile from the bottom pole to the top pole, centred vertically. Straight parts
    /// get steps of about the ring spacing 2πR/segments at the rim; arcs get at least one step per
    /// 2π/segments of turning angle.
    pub(super) fn sample(&self, segments: u32) -> Vec<ProfilePoint> {
        let step = TAU * self.outer_radius / f64::from(segments);
        let dtheta = TAU / f64::from(segments);
        let arc_steps = |angle: f64| ((angle / dtheta).ceil() as usize).max(1);
        let line_steps = |len: f64| ((len / step).ceil() as usize).max(1);
        let (sa, ca) = self.alpha.sin_cos();

        let mut p = vec![ProfilePoint {
            rho: 0.0,
            y: 0.0,
            n_rho: 0.0,
            n_y: -1.0,
        }];
        // Flat base, outward from the axis.
        let nb = line_steps(self.base_len);
        for k in 1..=nb {
            p.push(ProfilePoint {
                rho: self.base_len * k as f64 / nb as f64,
                y: 0.0,
                n_rho: 0.0,
                n_y: -1.0,
            });
        }
        // Rim fillet, θ from −π/2 (exclusive) to 0 (the widest ring, exactly `outer_radius`)
        // and on to α.
        let n_low = arc_steps(FRAC_PI_2);
        let n_high = arc_steps(self.alpha);
        let thetas = (1..=n_low)
            .map(|k| -FRAC_PI_2 + FRAC_PI_2 * k as f64 / n_low as f64)
            .chain((1..=n_high).map(|k| self.alpha * k as f64 / n_high as f64));
        for theta in thetas {
            let (s, c) = theta.sin_cos();
            p.push(ProfilePoint {
                rho: if theta == 0.0 {
                    self.outer_radius
                } else {
                    self.rho_fillet + self.r * c
                },
                y: self.r + self.r * s,
                n_rho: c,
                n_y: s,
            });
        }
        // Straight flank up to the tip tangent point.
        let start = *p.last().expect("profile has points");
        if self.flank_len > 1e-9 * self.outer_radius {
            let nl = line_steps(self.flank_len);
            for k in 1..nl {
                let s = self.flank_len * k as f64 / nl as f64;
                p.push(ProfilePoint {
                    rho: start.rho - sa * s,
                    y: start.y + ca * s,
                    n_rho: ca,
                    n_y: sa,
                });
            }
            p.push(ProfilePoint {
                rho: self.r * ca,
                y: self.y_tip_centre + self.r * sa,
                n_rho: ca,
                n_y: sa,
            });
        }
        // Tip cap, θ from α (exclusive) to π/2 (the top pole).
        let span = FRAC_PI_2 - self.alpha;
        let nt = arc_steps(span).max(2);
        for k in 1..=nt {
            let theta = self.alpha + span * k as f64 / nt as f64;
            let (s, c) = theta.sin_cos();
            let rho = if k == nt { 0.0 } else { self.r * c };
            p.push(ProfilePoint {
                rho,
                y: self.y_tip_centre + self.r * s,
                n_rho: if k == nt { 0.0 } else { c },
                n_y: if k == nt { 1.0 } else { s },
            });
        }
        let y_mid = 0.5 * (self.y_tip_centre + self.r);
        for q in &mut p {
            q.y -= y_mid;
        }
        p
    }
}

/// Torus `((R + r cos v) cos u, r sin v, (R + r cos v) sin u)`, normal
/// `(cos v cos u, sin v, cos v sin u)`; `segments` steps in u, max(3, segments/2) in v.
/// Triangles follow `∂/∂v × ∂/∂u`, the outward direction.
pub(super) fn torus(major: f64, minor: f64, segments: u32) -> Mesh {
    let nu = segments as usize;
    let nv = (segments as usize / 2).max(3);
    let mut positions = Vec::with_capacity(nu * nv);
    let mut normals = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let (su, cu) = (TAU * i as f64 / nu as f64).sin_cos();
        for j in 0..nv {
            let (sv, cv) = (TAU * j as f64 / nv as f64).sin_cos();
            let rho = major + minor * cv;
            positions.push(Vec3::new(
                (rho * cu) as f32,
                (minor * sv) as f32,
                (rho * su) as f32,
            ));
            normals.push(DVec3::new(cv * cu, sv, cv * su).normalize().as_vec3());
        }
    }
    let idx = |i: usize, j: usize| ((i % nu) * nv + j % nv) as u32;
    let mut indices = Vec::with_capacity(2 * nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (idx(i, j), idx(i, j + 1), idx(i + 1, j + 1), idx(i + 1, j));
            indices.push([a, b, c]);
            indices.push([a, c, d]);
        }
    }
    Mesh {
        positions,
        normals: Some(normals),
        indices,
    }
}
