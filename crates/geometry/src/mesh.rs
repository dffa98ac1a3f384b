//! The triangle mesh type and its validation.
//!
//! SKELETON: helper H1 owns this file (fill in the `todo!()`s, keep the public signatures).

use glam::Vec3;

use crate::GeometryError;

/// An indexed triangle mesh. Triangles are counter-clockwise seen from outside:
/// `cross(v1 − v0, v2 − v0)` points out of the medium.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions (scene units).
    pub positions: Vec<Vec3>,
    /// Optional per-vertex unit normals (same length as `positions`), used as shading normals.
    pub normals: Option<Vec<Vec3>>,
    /// Triangles as vertex indices.
    pub indices: Vec<[u32; 3]>,
}

/// A non-fatal finding of [`validate`]: the mesh is usable but the user should know.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshWarning {
    /// Triangles with (near) zero area were removed.
    DroppedDegenerate { count: usize },
    /// Edges used by only one triangle: the mesh is open, the medium is ill-defined there.
    OpenEdges { count: usize },
    /// Edges used by more than two triangles, or inconsistently oriented neighbours.
    NonManifoldEdges { count: usize },
    /// The signed volume was negative; all triangles were flipped to point outward.
    Flipped { signed_volume_before: f64 },
    /// Normals contained NaN/zero vectors and were recomputed from the faces.
    RecomputedNormals,
}

impl std::fmt::Display for MeshWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        todo!()
    }
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
    /// Corner positions of triangle `i`.
    #[inline]
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }
    /// Unnormalised geometric normal `cross(v1 − v0, v2 − v0)` of triangle `i` (length = 2·area).
    #[inline]
    pub fn face_normal_raw(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.triangle(i);
        (b - a).cross(c - a)
    }
    /// Total surface area.
    pub fn area(&self) -> f64 {
        todo!()
    }
    /// Signed volume (divergence theorem, f64 accumulation); positive for CCW-outward closed meshes.
    pub fn signed_volume(&self) -> f64 {
        todo!()
    }
    /// Axis-aligned bounds (min, max).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        todo!()
    }
    /// Area-weighted vertex normals computed from the faces.
    pub fn compute_vertex_normals(&self) -> Vec<Vec3> {
        todo!()
    }
    /// Apply an affine transform to positions (and normals with the inverse transpose).
    pub fn transform(&mut self, m: glam::Mat4) {
        todo!()
    }
}

/// Validate a mesh in place. `source_name` (file path or shape name) goes into every message.
///
/// Fatal (error): empty mesh, NaN/Inf vertex (names the vertex index), out-of-range index (names
/// the face), normals array of wrong length. Repaired with a warning: degenerate triangles
/// (dropped), negative signed volume (flipped), broken normals (recomputed). Warned only: open or
/// non-manifold edges.
pub fn validate(mesh: &mut Mesh, source_name: &str) -> Result<Vec<MeshWarning>, GeometryError> {
    todo!()
}
