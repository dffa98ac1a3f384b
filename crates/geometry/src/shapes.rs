//! Built-in procedural shapes, usable by name (`sphere`, `cone`, `torus`, `rounded-box`, `blob`).
//! All are closed, CCW-outward, centred at the origin, with smooth vertex normals.
//!
//! SKELETON: helper H1 owns this file.

use crate::{GeometryError, Mesh};

/// A procedural shape with its size and resolution parameters.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Sphere of `radius`, icosphere subdivided `subdivisions` times (20·4^s triangles).
    Sphere { radius: f32, subdivisions: u32 },
    /// Cone along +Y of `height` and base `radius`, tip rounded with `tip_radius`, closed base
    /// with rounded rim; `segments` around the axis.
    Cone { height: f32, radius: f32, tip_radius: f32, segments: u32 },
    /// Torus in the XZ plane: `major` radius of the centre circle, `minor` tube radius.
    Torus { major: f32, minor: f32, segments: u32 },
    /// Box of full extents `size` with edges rounded by `radius`.
    RoundedBox { size: [f32; 3], radius: f32, segments: u32 },
    /// Sphere of `radius` displaced by smooth bumps and dents of relative `amplitude`
    /// (deterministic from `seed`), the kind of detail of the paper's Head/Croissant scenes.
    Blob { radius: f32, amplitude: f32, bumps: u32, seed: u64, subdivisions: u32 },
}

impl Shape {
    /// Names accepted by [`Shape::from_name`].
    pub const NAMES: [&'static str; 5] = ["sphere", "cone", "torus", "rounded-box", "blob"];

    /// The shape with default parameters (objects about 1 unit across).
    pub fn from_name(name: &str) -> Result<Shape, GeometryError> {
        todo!()
    }

    /// The canonical name of this shape kind.
    pub fn name(&self) -> &'static str {
        todo!()
    }

    /// Multiply every length parameter by `s`.
    pub fn scaled(&self, s: f32) -> Shape {
        todo!()
    }

    /// Build the triangle mesh (validated: errors on bad parameters such as radius ≤ 0).
    pub fn build(&self) -> Result<Mesh, GeometryError> {
        todo!()
    }
}
