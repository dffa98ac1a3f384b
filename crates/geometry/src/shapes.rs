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

//!
//! The mesh builders live in submodules: `sphere` (icosphere, bumpy blob), `revolution`
//! (surfaces of revolution: rounded cone, torus) and `boxes` (rounded box, sharp box).

mod boxes;
mod revolution;
mod sphere;

pub use boxes::sharp_box;

use boxes::rounded_box;
use revolution::{ConeProfile, revolve, torus};
use sphere::{blob, icosphere};

use crate::{GeometryError, Mesh};

/// Largest icosphere subdivision level accepted (20·4⁸ ≈ 1.3 M triangles).
pub const MAX_SUBDIVISIONS: u32 = 8;
/// Largest `segments` accepted (a 4096 × 2048 torus has 16.8 M triangles).
pub const MAX_SEGMENTS: u32 = 4096;
/// Icosphere subdivisions of [`Shape::coarse`].
pub const COARSE_SUBDIVISIONS: u32 = 4;
/// Segments of [`Shape::coarse`].
pub const COARSE_SEGMENTS: u32 = 32;
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

    /// The same shape at a smoke test's resolution: icosphere subdivisions at most
    /// [`COARSE_SUBDIVISIONS`], segments at most [`COARSE_SEGMENTS`] (sizes unchanged). The blob's
    /// 6 subdivisions (40 962 vertices) become 4 (2 562), the torus's 128 × 64 segments 32 × 16:
    /// the per-vertex work of the learned renderer (its shape descriptors) falls with them.
    pub fn coarse(&self) -> Shape {
        let mut out = self.clone();
        match &mut out {
            Shape::Sphere { subdivisions, .. } | Shape::Blob { subdivisions, .. } => {
                *subdivisions = (*subdivisions).min(COARSE_SUBDIVISIONS)
            }
            Shape::Cone { segments, .. }
            | Shape::Torus { segments, .. }
            | Shape::RoundedBox { segments, .. } => *segments = (*segments).min(COARSE_SEGMENTS),
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
