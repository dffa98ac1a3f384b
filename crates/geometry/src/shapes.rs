//! Built-in procedural shapes, usable by name (`sphere`, `cone`, `torus`, `rounded-box`, `blob`).
//! All are closed, CCW-outward, centred at the origin, with smooth vertex normals.
//!
//! Every built mesh is watertight (each edge shared by exactly two triangles that traverse it in
//! opposite directions), has a positive signed volume and passes [`crate::mesh::validate`]
//! without warnings. Defaults (from [`Shape::from_name`]) are about 1 unit across:
//!
//! | name | default |
//! |---|---|
//! | `sphere` | radius 0.5, icosphere subdivided 5 times (20 480 triangles) |
//! | `cone` | height 1, base radius 0.4, tip radius 0.08, 128 segments |
//! | `torus` | major 0.35, minor 0.15, 128 × 64 segments |
//! | `rounded-box` (`box`) | size 0.8 × 0.6 × 0.7, edge radius 0.1, 32 segments per circle |
//! | `blob` (`bumpy-blob`) | radius 0.5, 12 bumps of relative amplitude 0.15, seed 7, 6 subdivisions |

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, TAU};

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};

use crate::{GeometryError, Mesh};

/// Largest icosphere subdivision level accepted (20·4⁸ ≈ 1.3 M triangles).
pub const MAX_SUBDIVISIONS: u32 = 8;
/// Largest `segments` accepted (a 4096 × 2048 torus has 16.8 M triangles).
pub const MAX_SEGMENTS: u32 = 4096;
/// Largest number of blob bumps accepted.
pub const MAX_BUMPS: u32 = 4096;

/// A procedural shape with its size and resolution parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Sphere of `radius`, icosphere subdivided `subdivisions` times (20·4^s triangles).
    Sphere { radius: f32, subdivisions: u32 },
    /// Cone along +Y of `height` and base `radius`, tip rounded with `tip_radius`, closed base
    /// with rounded rim; `segments` around the axis.
    ///
    /// A sharp cone rounded at the tip by a sphere of `tip_radius` tangent to the flank, and at
    /// the base rim by a torus fillet of the same radius tangent to the flank and to the flat
    /// base. `height` and `radius` are the extents of the rounded shape: its bounding box is
    /// `2·radius × height × 2·radius`, centred on the origin (the underlying sharp cone is a bit
    /// taller and wider). The surface of revolution is G¹ (tangent-continuous) everywhere; its
    /// profile is sampled with about one step per `2π/segments` of turning angle on the arcs
    /// and the ring spacing `2π·radius/segments` on the straight parts.
    Cone {
        height: f32,
        radius: f32,
        tip_radius: f32,
        segments: u32,
    },
    /// Torus in the XZ plane: `major` radius of the centre circle, `minor` tube radius.
    /// `segments` around the Y axis, `segments / 2` (at least 3) around the tube.
    Torus {
        major: f32,
        minor: f32,
        segments: u32,
    },
    /// Box of full extents `size` with edges rounded by `radius`.
    ///
    /// The exact Minkowski sum of the inner box `[−size/2 + radius, size/2 − radius]` and a ball
    /// of `radius`: flat faces, quarter-cylinder edges and sphere-octant corners. `segments` is
    /// the number of segments per full circle of the rounded edges (rounded up to a multiple
    /// of 8).
    RoundedBox {
        size: [f32; 3],
        radius: f32,
        segments: u32,
    },
    /// Sphere of `radius` displaced by smooth bumps and dents of relative `amplitude`
    /// (deterministic from `seed`), the kind of detail of the paper's Head/Croissant scenes.
    ///
    /// Each unit direction `d` of an icosphere (subdivided `subdivisions` times) is moved to
    /// `r(d)·d` with `r(d) = radius · exp(amplitude · Σ_i s_i·m_i·exp(−(1 − d·c_i)/w_i²))`:
    /// `bumps` Gaussian bumps (`s_i = +1`) or dents (`s_i = −1`) with uniformly random centres
    /// `c_i` on the sphere, magnitudes `m_i ∈ [0.5, 1]` and angular widths `w_i ∈ [0.2, 0.5]` rad
    /// (`1 − d·c ≈ θ²/2`), drawn from `rand_pcg::Pcg32` seeded with `seed`. The exponential keeps
    /// the radius positive, so the surface is star-shaped and never self-intersects. The result is
    /// translated so that its bounding box is centred on the origin. Normals are the area-weighted
    /// face normals.
    Blob {
        radius: f32,
        amplitude: f32,
        bumps: u32,
        seed: u64,
        subdivisions: u32,
    },
}

fn param_error(shape: &str, param: &str, reason: impl Into<String>) -> GeometryError {
    GeometryError::ShapeParam {
        shape: shape.to_string(),
        param: param.to_string(),
        reason: reason.into(),
    }
}

fn check_positive(shape: &str, param: &str, v: f32) -> Result<(), GeometryError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(param_error(
            shape,
            param,
            format!("must be a finite number > 0 (got {v})"),
        ))
    }
}

fn check_segments(shape: &str, segments: u32) -> Result<(), GeometryError> {
    if (3..=MAX_SEGMENTS).contains(&segments) {
        Ok(())
    } else {
        Err(param_error(
            shape,
            "segments",
            format!("must be between 3 and {MAX_SEGMENTS} (got {segments})"),
        ))
    }
}

fn check_subdivisions(shape: &str, subdivisions: u32) -> Result<(), GeometryError> {
    if subdivisions <= MAX_SUBDIVISIONS {
        Ok(())
    } else {
        Err(param_error(
            shape,
            "subdivisions",
            format!(
                "must be at most {MAX_SUBDIVISIONS} (got {subdivisions}; 20·4^{subdivisions} \
                 triangles would not fit in memory)"
            ),
        ))
    }
}

impl Shape {
    /// Names accepted by [`Shape::from_name`].
    pub const NAMES: [&'static str; 5] = ["sphere", "cone", "torus", "rounded-box", "blob"];

    /// The shape with default parameters (objects about 1 unit across).
    ///
    /// Case-insensitive; `_` and spaces count as `-`. Aliases: `box` and `roundedbox` for
    /// `rounded-box`, `bumpy-blob` for `blob`.
    pub fn from_name(name: &str) -> Result<Shape, GeometryError> {
        let key = name.trim().to_ascii_lowercase().replace(['_', ' '], "-");
        Ok(match key.as_str() {
            "sphere" => Shape::Sphere {
                radius: 0.5,
                subdivisions: 5,
            },
            "cone" => Shape::Cone {
                height: 1.0,
                radius: 0.4,
                tip_radius: 0.08,
                segments: 128,
            },
            "torus" => Shape::Torus {
                major: 0.35,
                minor: 0.15,
                segments: 128,
            },
            "rounded-box" | "box" | "roundedbox" => Shape::RoundedBox {
                size: [0.8, 0.6, 0.7],
                radius: 0.1,
                segments: 32,
            },
            "blob" | "bumpy-blob" => Shape::Blob {
                radius: 0.5,
                amplitude: 0.15,
                bumps: 12,
                seed: 7,
                subdivisions: 6,
            },
            _ => {
                return Err(param_error(
                    name,
                    "name",
                    "is not a known shape; valid names: sphere, cone, torus, rounded-box \
                     (or box), blob (or bumpy-blob)",
                ));
            }
        })
    }

    /// The canonical name of this shape kind.
    pub fn name(&self) -> &'static str {
        match self {
            Shape::Sphere { .. } => "sphere",
            Shape::Cone { .. } => "cone",
            Shape::Torus { .. } => "torus",
            Shape::RoundedBox { .. } => "rounded-box",
            Shape::Blob { .. } => "blob",
        }
    }

    /// Multiply every length parameter by `s` (resolutions, the blob's relative amplitude and
    /// its seed are unchanged). A non-positive `s` gives a shape that [`Shape::build`] rejects.
    pub fn scaled(&self, s: f32) -> Shape {
        let mut out = self.clone();
        match &mut out {
            Shape::Sphere { radius, .. } => *radius *= s,
            Shape::Cone {
                height,
                radius,
                tip_radius,
                ..
            } => {
                *height *= s;
                *radius *= s;
                *tip_radius *= s;
            }
            Shape::Torus { major, minor, .. } => {
                *major *= s;
                *minor *= s;
            }
            Shape::RoundedBox { size, radius, .. } => {
                for x in size.iter_mut() {
                    *x *= s;
                }
                *radius *= s;
            }
            Shape::Blob { radius, .. } => *radius *= s,
        }
        out
    }

    /// Check the parameters without building.
    pub fn check(&self) -> Result<(), GeometryError> {
        let name = self.name();
        match *self {
            Shape::Sphere {
                radius,
                subdivisions,
            } => {
                check_positive(name, "radius", radius)?;
                check_subdivisions(name, subdivisions)?;
            }
            Shape::Cone {
                height,
                radius,
                tip_radius,
                segments,
            } => {
                check_positive(name, "height", height)?;
                check_positive(name, "radius", radius)?;
                check_positive(name, "tip_radius", tip_radius)?;
                check_segments(name, segments)?;
                if tip_radius >= radius {
                    return Err(param_error(
                        name,
                        "tip_radius",
                        format!("must be smaller than the base radius {radius} (got {tip_radius})"),
                    ));
                }
                if 2.0 * tip_radius >= height {
                    return Err(param_error(
                        name,
                        "tip_radius",
                        format!("must be smaller than half the height {height} (got {tip_radius})"),
                    ));
                }
                let (h, rho, r) = (f64::from(height), f64::from(radius), f64::from(tip_radius));
                if ConeProfile::fit(h, rho, r).is_none() {
                    return Err(param_error(
                        name,
                        "tip_radius",
                        format!(
                            "is too large for a cone of height {height} and radius {radius}: the \
                             rounded tip and the rounded rim (same radius) would overlap (got \
                             {tip_radius}, must be < {:.6})",
                            ConeProfile::max_rounding(h, rho)
                        ),
                    ));
                }
            }
            Shape::Torus {
                major,
                minor,
                segments,
            } => {
                check_positive(name, "major", major)?;
                check_positive(name, "minor", minor)?;
                check_segments(name, segments)?;
                if minor >= major {
                    return Err(param_error(
                        name,
                        "minor",
                        format!(
                            "must be smaller than major = {major} (got {minor}); otherwise the \
                             tube self-intersects at the axis"
                        ),
                    ));
                }
            }
            Shape::RoundedBox {
                size,
                radius,
                segments,
            } => {
                for (axis, &s) in ["size[0]", "size[1]", "size[2]"].iter().zip(&size) {
                    check_positive(name, axis, s)?;
                }
                check_positive(name, "radius", radius)?;
                check_segments(name, segments)?;
                let min = size.iter().copied().fold(f32::INFINITY, f32::min);
                if radius > 0.5 * min {
                    return Err(param_error(
                        name,
                        "radius",
                        format!(
                            "must be at most half the smallest extent, {} (got {radius})",
                            0.5 * min
                        ),
                    ));
                }
            }
            Shape::Blob {
                radius,
                amplitude,
                bumps,
                seed: _,
                subdivisions,
            } => {
                check_positive(name, "radius", radius)?;
                if !(amplitude.is_finite() && (0.0..=1.0).contains(&amplitude)) {
                    return Err(param_error(
                        name,
                        "amplitude",
                        format!("must be in [0, 1] (relative to the radius; got {amplitude})"),
                    ));
                }
                if bumps > MAX_BUMPS {
                    return Err(param_error(
                        name,
                        "bumps",
                        format!("must be at most {MAX_BUMPS} (got {bumps})"),
                    ));
                }
                check_subdivisions(name, subdivisions)?;
            }
        }
        Ok(())
    }

    /// Build the triangle mesh (validated: errors on bad parameters such as radius ≤ 0).
    ///
    /// Parameter errors are [`GeometryError::ShapeParam`] naming the parameter; the mesh then
    /// goes through [`crate::mesh::validate`] (which logs any warning; the built-in shapes
    /// produce none).
    pub fn build(&self) -> Result<Mesh, GeometryError> {
        self.check()?;
        let mut mesh = match *self {
            Shape::Sphere {
                radius,
                subdivisions,
            } => {
                let (dirs, indices) = icosphere(subdivisions);
                Mesh {
                    positions: dirs
                        .iter()
                        .map(|&d| (d * f64::from(radius)).as_vec3())
                        .collect(),
                    normals: Some(dirs.iter().map(|d| d.as_vec3()).collect()),
                    indices,
                }
            }
            Shape::Cone {
                height,
                radius,
                tip_radius,
                segments,
            } => {
                let profile =
                    ConeProfile::fit(f64::from(height), f64::from(radius), f64::from(tip_radius))
                        .ok_or_else(|| param_error("cone", "tip_radius", "is too large"))?;
                revolve(&profile.sample(segments), segments)
            }
            Shape::Torus {
                major,
                minor,
                segments,
            } => torus(f64::from(major), f64::from(minor), segments),
            Shape::RoundedBox {
                size,
                radius,
                segments,
            } => rounded_box(size.map(f64::from), f64::from(radius), segments),
            Shape::Blob {
                radius,
                amplitude,
                bumps,
                seed,
                subdivisions,
            } => blob(
                f64::from(radius),
                f64::from(amplitude),
                bumps,
                seed,
                subdivisions,
            ),
        };
        crate::mesh::validate(&mut mesh, &format!("shape '{}'", self.name()))?;
        Ok(mesh)
    }
}

/// Unit icosphere: the regular icosahedron with every triangle split into four `subdivisions`
/// times, midpoints projected onto the unit sphere. Returns unit directions (which are also the
/// exact normals) and CCW-outward triangles: 10·4^s + 2 vertices, 20·4^s triangles.
fn icosphere(subdivisions: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| DVec3::from_array(p).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::with_capacity(faces.len() * 3 / 2);
        let mut next = Vec::with_capacity(faces.len() * 4);
        let mut mid = |a: u32, b: u32, verts: &mut Vec<DVec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *midpoints.entry(key).or_insert_with(|| {
                verts.push((verts[a as usize] + verts[b as usize]).normalize());
                (verts.len() - 1) as u32
            })
        };
        for &[a, b, c] in &faces {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    (verts, faces)
}

/// One sample of a profile curve in the (ρ, y) half-plane: position and unit outward normal.
#[derive(Clone, Copy, Debug)]
struct ProfilePoint {
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
fn revolve(profile: &[ProfilePoint], segments: u32) -> Mesh {
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
struct ConeProfile {
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
    fn fit(h: f64, rho: f64, r: f64) -> Option<ConeProfile> {
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
    fn max_rounding(h: f64, rho: f64) -> f64 {
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
    fn sample(&self, segments: u32) -> Vec<ProfilePoint> {
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
fn torus(major: f64, minor: f64, segments: u32) -> Mesh {
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

/// Rounded box as the Minkowski sum of the inner box `[−h, h]` (h = size/2 − radius) and a ball of
/// `radius`: every point p of a subdivided cube of half-extent e = size/2 is mapped to
/// `q + radius·normalize(p − q)` with `q = clamp(p, −h, h)`, normal `normalize(p − q)`.
///
/// Per axis the grid coordinates are: in the band [h, e], `h + radius·tan(θ)` with θ uniform in
/// [0, π/4] (so the fillet arc is sampled uniformly in angle: each 45° half of a quarter-circle
/// lies on one cube face), and uniform steps of about the arc step on the flat part [−h, h].
/// Cube vertices are shared between faces through their integer lattice coordinates, so the
/// mesh is watertight.
fn rounded_box(size: [f64; 3], radius: f64, segments: u32) -> Mesh {
    let k = (segments as usize).div_ceil(8).max(1);
    let arc_step = radius * FRAC_PI_4 / k as f64;
    let half = size.map(|s| 0.5 * s);
    let inner = half.map(|e| (e - radius).max(0.0));
    let grids: Vec<Vec<f64>> = (0..3)
        .map(|a| {
            let h = inner[a];
            let band = |m: usize| h + radius * (FRAC_PI_4 * m as f64 / k as f64).tan();
            let mut g: Vec<f64> = (0..=k).rev().map(|m| -band(m)).collect();
            // Flat part, skipped if the inner box is (numerically) flat along this axis.
            if h > 1e-9 * radius {
                let nflat = ((2.0 * h / arc_step).ceil() as usize).clamp(1, 4 * segments as usize);
                for m in 1..nflat {
                    g.push(-h + 2.0 * h * m as f64 / nflat as f64);
                }
                g.push(h);
            } else {
                // −h and +h coincide: share the point.
                if let Some(last) = g.last_mut() {
                    *last = 0.0;
                }
            }
            g.extend((1..=k).map(band));
            let e = half[a];
            if let Some(first) = g.first_mut() {
                *first = -e;
            }
            if let Some(last) = g.last_mut() {
                *last = e;
            }
            g
        })
        .collect();
    let n = [grids[0].len() - 1, grids[1].len() - 1, grids[2].len() - 1];

    let mut map: HashMap<[usize; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut vertex = |ijk: [usize; 3]| -> u32 {
        *map.entry(ijk).or_insert_with(|| {
            let p = DVec3::new(grids[0][ijk[0]], grids[1][ijk[1]], grids[2][ijk[2]]);
            let h = DVec3::from_array(inner);
            let q = p.clamp(-h, h);
            let d = (p - q).normalize();
            positions.push((q + radius * d).as_vec3());
            normals.push(d.as_vec3());
            (positions.len() - 1) as u32
        })
    };
    let mut indices = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for (fixed, outward) in [(0, false), (n[axis], true)] {
            for i in 0..n[u] {
                for j in 0..n[v] {
                    let at = |di: usize, dj: usize| {
                        let mut ijk = [0; 3];
                        ijk[axis] = fixed;
                        ijk[u] = i + di;
                        ijk[v] = j + dj;
                        ijk
                    };
                    let a = vertex(at(0, 0));
                    let b = vertex(at(1, 0));
                    let c = vertex(at(1, 1));
                    let d = vertex(at(0, 1));
                    // e_u × e_v = e_axis: (a, b, c) faces +axis.
                    if outward {
                        indices.push([a, b, c]);
                        indices.push([a, c, d]);
                    } else {
                        indices.push([a, c, b]);
                        indices.push([a, d, c]);
                    }
                }
            }
        }
    }
    Mesh {
        positions,
        normals: Some(normals),
        indices,
    }
}

/// Uniform number in (0, 1) from the raw 32-bit output (independent of `rand`'s distributions,
/// so blobs stay identical across `rand` versions).
fn uniform(rng: &mut rand_pcg::Pcg32) -> f64 {
    (f64::from(rng.next_u32()) + 0.5) / 4_294_967_296.0
}

/// The bumpy blob: see [`Shape::Blob`].
fn blob(radius: f64, amplitude: f64, bumps: u32, seed: u64, subdivisions: u32) -> Mesh {
    struct Bump {
        centre: DVec3,
        weight: f64,
        inv_w2: f64,
    }
    let mut rng = rand_pcg::Pcg32::seed_from_u64(seed);
    let bumps: Vec<Bump> = (0..bumps)
        .map(|_| {
            let z = 2.0 * uniform(&mut rng) - 1.0;
            let phi = TAU * uniform(&mut rng);
            let s = (1.0 - z * z).max(0.0).sqrt();
            let centre = DVec3::new(s * phi.cos(), z, s * phi.sin());
            let sign = if uniform(&mut rng) < 0.5 { -1.0 } else { 1.0 };
            let magnitude = 0.5 + 0.5 * uniform(&mut rng);
            let width = 0.2 + 0.3 * uniform(&mut rng);
            Bump {
                centre,
                weight: sign * magnitude,
                inv_w2: 1.0 / (width * width),
            }
        })
        .collect();
    let (dirs, indices) = icosphere(subdivisions);
    let positions = dirs
        .iter()
        .map(|&d| {
            let sum: f64 = bumps
                .iter()
                .map(|b| b.weight * (-(1.0 - d.dot(b.centre)) * b.inv_w2).exp())
                .sum();
            (d * radius * (amplitude * sum).exp()).as_vec3()
        })
        .collect();
    let mut mesh = Mesh {
        positions,
        normals: None,
        indices,
    };
    // The bumps make it asymmetric: centre the bounding box on the origin.
    let (lo, hi) = mesh.bounds();
    let centre = 0.5 * (lo + hi);
    for p in &mut mesh.positions {
        *p -= centre;
    }
    mesh.normals = Some(mesh.compute_vertex_normals());
    mesh
}

/// The axis-aligned box `[min, max]` with sharp edges: 8 corners, 12 triangles, CCW-outward,
/// no vertex normals (flat faces). A fixture for tests with flat faces and sharp edges.
pub fn sharp_box(min: Vec3, max: Vec3) -> Mesh {
    let (a, b) = (min, max);
    let p = Vec3::new;
    let positions = vec![
        p(a.x, b.y, a.z),
        p(b.x, b.y, a.z),
        p(b.x, b.y, b.z),
        p(a.x, b.y, b.z),
        p(a.x, a.y, a.z),
        p(b.x, a.y, a.z),
        p(b.x, a.y, b.z),
        p(a.x, a.y, b.z),
    ];
    let indices = vec![
        [0, 2, 1],
        [0, 3, 2], // top (+y)
        [4, 5, 6],
        [4, 6, 7], // bottom (−y)
        [0, 1, 5],
        [0, 5, 4], // −z
        [3, 7, 6],
        [3, 6, 2], // +z
        [0, 4, 7],
        [0, 7, 3], // −x
        [1, 2, 6],
        [1, 6, 5], // +x
    ];
    Mesh {
        positions,
        normals: None,
        indices,
    }
}
