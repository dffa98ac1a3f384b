//! # translucent-geometry
//!
//! Triangle meshes and the ray queries every renderer of `translucent` needs.
//!
//! * [`mesh`]: the [`Mesh`] type (positions, optional vertex normals, CCW-outward triangles) and its
//!   validation ([`mesh::validate`]): NaN/Inf vertices, out-of-range indices, degenerate triangles,
//!   open / non-manifold edges, negative signed volume.
//! * [`io`]: OBJ and PLY (ASCII and binary, as Mitsuba writes them) readers and writers.
//! * [`shapes`]: built-in procedural shapes usable by name (sphere, cone with a rounded tip, torus,
//!   box with rounded edges, bumpy blob).
//! * [`triangle`]: the watertight ray/triangle test of Woop, Benthin and Wald (JCGT 2013).
//! * [`bvh`]: [`Accel`], an 8-wide compressed BVH (obvhs CWBVH) over a mesh with closest hit,
//!   occlusion, all hits along a segment and the length of a segment inside the closed mesh.
//! * [`bins`]: [`PixelBins`], per-pixel triangle lists that answer a pinhole camera's primary
//!   rays exactly as [`Accel::closest`] does, with a few triangle tests instead of a BVH descent.
//! * [`light_bins`]: [`LightBins`], per-direction triangle lists around a point light that answer
//!   shadow rays ([`Accel::inside_length`], [`Accel::occluded`] toward the light) exactly, with a
//!   few triangle tests instead of an all-hits BVH traversal.
//! * [`remesh`]: a mesh as a scanner or a simplifier gives it (decimated, smoothed, noisy).
//! * [`sampling`]: area-uniform surface point sampling.
//! * [`frame`]: orthonormal frames (Duff et al. 2017).
//!
//! Conventions (see CONVENTIONS.md): right-handed, +Y up; triangles counter-clockwise seen from
//! outside, so `cross(v1 − v0, v2 − v0)` points out of the medium.

pub mod bins;
pub mod bvh;
pub mod error;
pub mod frame;
pub mod io;
pub mod light_bins;
pub mod mesh;
pub mod remesh;
pub mod sampling;
pub mod shapes;
pub mod triangle;

pub use bins::{FilmCursor, PixelBins};
pub use bvh::{Accel, Hit};
pub use error::GeometryError;
pub use frame::Frame;
pub use glam::{Mat3, Mat4, Vec2, Vec3, Vec3A};
pub use light_bins::LightBins;
pub use mesh::{Mesh, MeshWarning};
pub use sampling::{AreaSampler, SurfaceSample};
pub use shapes::{Shape, sharp_box};
