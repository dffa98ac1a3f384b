//! The triangle mesh type and its validation.
//!
//! Conventions (CONVENTIONS.md): triangles are counter-clockwise seen from outside, so the raw face
//! normal `cross(v1 − v0, v2 − v0)` points out of the medium and a closed mesh has a positive signed
//! volume. [`validate`] enforces what can be enforced and tells the user about the rest.

use std::collections::HashMap;

use glam::{DVec3, Vec3};

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
        match self {
            MeshWarning::DroppedDegenerate { count } => write!(
                f,
                "dropped {count} degenerate triangle{} (zero or near-zero area, or a vertex index \
                 repeated within the triangle); they carry no surface",
                plural(*count)
            ),
            MeshWarning::OpenEdges { count } => write!(
                f,
                "{count} open edge{} (used by a single triangle): the mesh is not closed, so inside \
                 and outside of the medium are ill-defined near the holes; close them in a mesh \
                 editor (e.g. MeshLab: Filters > Remeshing > Close Holes)",
                plural(*count)
            ),
            MeshWarning::NonManifoldEdges { count } => write!(
                f,
                "{count} non-manifold edge{} (shared by more than two triangles, or by two \
                 triangles that traverse it in the same direction, i.e. inconsistent winding): \
                 inside/outside tests may be unreliable there; repair the mesh (e.g. MeshLab: \
                 Filters > Cleaning and Repairing > Repair non Manifold Edges, then Re-Orient all \
                 faces coherently)",
                plural(*count)
            ),
            MeshWarning::Flipped {
                signed_volume_before,
            } => write!(
                f,
                "the closed mesh had a negative signed volume ({signed_volume_before:.6e}), i.e. \
                 its triangles were wound clockwise seen from outside; all triangles were flipped \
                 (and vertex normals pointing inward were negated) so that they face outward"
            ),
            MeshWarning::RecomputedNormals => write!(
                f,
                "some vertex normals were NaN, infinite or zero; all vertex normals were \
                 recomputed from the faces (area-weighted)"
            ),
        }
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}

/// Relative tolerance for degenerate triangles: a triangle is dropped by [`validate`] when
/// `|cross(v1 − v0, v2 − v0)| ≤ DEGENERATE_AREA_TOLERANCE · D²` (evaluated in f64), where `D` is
/// the diagonal of the mesh's bounding box. With f32 positions, areas below this are at the level
/// of rounding noise for any practical tessellation.
pub const DEGENERATE_AREA_TOLERANCE: f64 = 1e-12;

/// Edge topology of a mesh (see [`Mesh::edge_report`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeReport {
    /// Number of distinct undirected edges.
    pub edges: usize,
    /// Edges used by exactly one triangle.
    pub open: usize,
    /// Edges used by more than two triangles, or by two triangles traversing it in the same
    /// direction (inconsistent orientation).
    pub non_manifold: usize,
}

impl EdgeReport {
    /// True when every edge is used by exactly two triangles that traverse it in opposite
    /// directions: the mesh is a closed, consistently oriented 2-manifold (watertight).
    pub fn is_watertight(&self) -> bool {
        self.open == 0 && self.non_manifold == 0
    }
}

#[inline]
fn dvec(v: Vec3) -> DVec3 {
    v.as_dvec3()
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

    /// Twice the area of triangle `i`, `|cross(v1 − v0, v2 − v0)|`, evaluated in f64.
    fn double_area_f64(&self, i: usize) -> f64 {
        let [a, b, c] = self.triangle(i);
        let (a, b, c) = (dvec(a), dvec(b), dvec(c));
        (b - a).cross(c - a).length()
    }

    /// Total surface area `A = Σ_t ½·|cross(v1 − v0, v2 − v0)|` (f64 accumulation).
    ///
    /// Panics only if an index is out of range (never after [`validate`]).
    pub fn area(&self) -> f64 {
        0.5 * (0..self.indices.len())
            .map(|i| self.double_area_f64(i))
            .sum::<f64>()
    }

    /// Signed volume (divergence theorem, f64 accumulation); positive for CCW-outward closed meshes.
    ///
    /// `V = ⅙ Σ_t (v0 − c) · ((v1 − c) × (v2 − c))`, the sum of the signed volumes of the
    /// tetrahedra spanned by each triangle and a reference point `c`. For a closed mesh the result
    /// does not depend on `c`; it is taken as the centre of the bounding box, which avoids the
    /// cancellation error of evaluating far from the origin. For an open mesh the value is the
    /// signed volume of the cone from `c` over the surface (not meaningful as an enclosed volume).
    pub fn signed_volume(&self) -> f64 {
        if self.indices.is_empty() || self.positions.is_empty() {
            return 0.0;
        }
        let (lo, hi) = self.bounds();
        let c = 0.5 * (dvec(lo) + dvec(hi));
        let c = if c.is_finite() { c } else { DVec3::ZERO };
        let sum: f64 = self
            .indices
            .iter()
            .map(|&[a, b, d]| {
                let p0 = dvec(self.positions[a as usize]) - c;
                let p1 = dvec(self.positions[b as usize]) - c;
                let p2 = dvec(self.positions[d as usize]) - c;
                p0.dot(p1.cross(p2))
            })
            .sum();
        sum / 6.0
    }

    /// Axis-aligned bounds `(min, max)` over all vertex positions (referenced or not).
    ///
    /// For a mesh without vertices this is the empty box `(+∞, −∞)`.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// Area-weighted vertex normals computed from the faces:
    /// `n_v = normalize(Σ_{t ∋ v} cross(v1 − v0, v2 − v0))`. The raw cross product has length
    /// 2·area, so each incident triangle is weighted by its area.
    ///
    /// Vertices not referenced by any triangle of non-zero area (or where the incident face normals
    /// cancel exactly) get the direction from the bounding-box centre to the vertex, or +Y if that
    /// is zero too, so the result is always a finite unit vector.
    pub fn compute_vertex_normals(&self) -> Vec<Vec3> {
        let mut acc = vec![DVec3::ZERO; self.positions.len()];
        for &[a, b, c] in &self.indices {
            let (p0, p1, p2) = (
                dvec(self.positions[a as usize]),
                dvec(self.positions[b as usize]),
                dvec(self.positions[c as usize]),
            );
            let n = (p1 - p0).cross(p2 - p0);
            if !n.is_finite() {
                continue;
            }
            acc[a as usize] += n;
            acc[b as usize] += n;
            acc[c as usize] += n;
        }
        let (lo, hi) = self.bounds();
        let centre = 0.5 * (lo + hi);
        acc.iter()
            .zip(&self.positions)
            .map(|(n, &p)| {
                let n = n.normalize_or_zero().as_vec3();
                if n != Vec3::ZERO && n.is_finite() {
                    n
                } else {
                    (p - centre).try_normalize().unwrap_or(Vec3::Y)
                }
            })
            .collect()
    }

    /// Apply an affine transform `m` to the mesh.
    ///
    /// Positions: `p' = M·p` (affine; the projective row of `m` is ignored). Normals:
    /// `n' = normalize((M₃⁻¹)ᵀ·n)` with `M₃` the upper-left 3×3 block, which keeps them
    /// perpendicular to the transformed surface. If `det M₃ < 0` (a reflection) the winding of
    /// every triangle is reversed, so triangles stay counter-clockwise seen from outside. A
    /// singular `M₃` leaves no meaningful normal transform; normals are then recomputed from the
    /// (flattened) faces.
    pub fn transform(&mut self, m: glam::Mat4) {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        let m3 = glam::Mat3::from_mat4(m);
        let det = m3.determinant();
        if det < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
        let Some(normals) = &mut self.normals else {
            return;
        };
        let mut failed = false;
        if det != 0.0 && det.is_finite() {
            let nm = m3.inverse().transpose();
            for n in normals.iter_mut() {
                *n = (nm * *n).normalize_or_zero();
                failed |= *n == Vec3::ZERO || !n.is_finite();
            }
        } else {
            failed = true;
        }
        if failed {
            // Singular transform or broken input normals: fall back to the face normals there.
            let computed = self.compute_vertex_normals();
            if let Some(normals) = &mut self.normals {
                for (n, c) in normals.iter_mut().zip(computed) {
                    if *n == Vec3::ZERO || !n.is_finite() || det == 0.0 || !det.is_finite() {
                        *n = c;
                    }
                }
            }
        }
    }

    /// Edge topology: every undirected edge `{a, b}` with the number of triangles using it and
    /// the directions in which they traverse it (a hash map keyed by the sorted vertex pair).
    ///
    /// Vertices are identified by position: vertices at bit-identical positions count as one, so
    /// seams where a vertex is split for its normal or texture coordinates (as OBJ `single_index`
    /// loading and many exporters produce) do not count as open edges.
    pub fn edge_report(&self) -> EdgeReport {
        let canonical = self.position_ids();
        // (uses, uses traversing min → max)
        let mut edges: HashMap<(u32, u32), (u32, u32)> =
            HashMap::with_capacity(self.indices.len() * 3 / 2 + 16);
        for t in &self.indices {
            let t = t.map(|i| canonical.get(i as usize).copied().unwrap_or(i));
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let key = if a < b { (a, b) } else { (b, a) };
                let e = edges.entry(key).or_insert((0, 0));
                e.0 += 1;
                if a < b {
                    e.1 += 1;
                }
            }
        }
        let mut report = EdgeReport {
            edges: edges.len(),
            ..Default::default()
        };
        for &(uses, forward) in edges.values() {
            match uses {
                1 => report.open += 1,
                2 if forward == 1 => {}
                _ => report.non_manifold += 1,
            }
        }
        report
    }

    /// For every vertex, the smallest index of a vertex at the bit-identical position
    /// (`-0.0` and `+0.0` are the same).
    fn position_ids(&self) -> Vec<u32> {
        let mut first: HashMap<[u32; 3], u32> = HashMap::with_capacity(self.positions.len());
        self.positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let key = (*p + Vec3::ZERO).to_array().map(f32::to_bits);
                *first.entry(key).or_insert(i as u32)
            })
            .collect()
    }
}

fn invalid(
    source_name: &str,
    element: impl Into<String>,
    reason: impl Into<String>,
) -> GeometryError {
    GeometryError::Invalid {
        source_name: source_name.to_string(),
        element: element.into(),
        reason: reason.into(),
    }
}

/// Validate a mesh in place. `source_name` (file path or shape name) goes into every message.
///
/// Fatal (error): empty mesh, NaN/Inf vertex (names the vertex index), out-of-range index (names
/// the face), normals array of wrong length. Repaired with a warning: degenerate triangles
/// (dropped), negative signed volume (flipped), broken normals (recomputed). Warned only: open or
/// non-manifold edges.
///
/// In detail, in this order:
/// 1. errors: no vertices; no triangles; a non-finite vertex position; a triangle index
///    `≥ positions.len()`; `normals.len() ≠ positions.len()`;
/// 2. triangles with a repeated index or `|cross(v1 − v0, v2 − v0)| ≤ τ·D²`
///    ([`DEGENERATE_AREA_TOLERANCE`] τ, bounding-box diagonal `D`) are dropped
///    ([`MeshWarning::DroppedDegenerate`]); if that leaves none, it is an error;
/// 3. edges (hash map of undirected edges, see [`Mesh::edge_report`]): open edges
///    ([`MeshWarning::OpenEdges`]) and non-manifold or inconsistently oriented edges
///    ([`MeshWarning::NonManifoldEdges`]) are reported, not repaired;
/// 4. a mesh without open edges whose [`Mesh::signed_volume`] is negative is inside out: the
///    winding of every triangle is reversed (two indices swapped); given vertex normals are
///    negated if they pointed inward, i.e. agreed with the old winding
///    (`Σ_t Σ_corners n_v · cross(v1 − v0, v2 − v0) > 0` before the flip) ([`MeshWarning::Flipped`]);
/// 5. given normals that are NaN, infinite or (near) zero cause all normals to be recomputed
///    with [`Mesh::compute_vertex_normals`] ([`MeshWarning::RecomputedNormals`]); valid
///    non-unit normals are normalised silently.
///
/// Vertices are never removed or reordered (unreferenced vertices are kept). Every warning is also
/// logged with `tracing::warn!`.
pub fn validate(mesh: &mut Mesh, source_name: &str) -> Result<Vec<MeshWarning>, GeometryError> {
    check_structure(mesh, source_name)?;
    let mut warnings = Vec::new();
    drop_degenerate(mesh, source_name, &mut warnings)?;
    let edges = mesh.edge_report();
    if edges.open > 0 {
        warnings.push(MeshWarning::OpenEdges { count: edges.open });
    }
    if edges.non_manifold > 0 {
        warnings.push(MeshWarning::NonManifoldEdges {
            count: edges.non_manifold,
        });
    }
    if edges.open == 0 {
        orient_outward(mesh, &mut warnings);
    }
    repair_normals(mesh, &mut warnings);
    for w in &warnings {
        tracing::warn!(source = source_name, "{source_name}: {w}");
    }
    Ok(warnings)
}

/// Step 1 of [`validate`]: the errors that leave nothing to repair.
fn check_structure(mesh: &Mesh, source_name: &str) -> Result<(), GeometryError> {
    let n_vertices = mesh.positions.len();
    if n_vertices == 0 {
        return Err(invalid(
            source_name,
            "mesh",
            "has no vertices; a mesh needs vertices and triangles (is this the right file?)",
        ));
    }
    if mesh.indices.is_empty() {
        return Err(invalid(
            source_name,
            "mesh",
            format!(
                "has {n_vertices} vertices but no faces; a point cloud cannot bound a medium \
                 (export the surface with its faces)"
            ),
        ));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        let p = mesh.positions[i];
        let more = mesh.positions[i + 1..]
            .iter()
            .filter(|p| !p.is_finite())
            .count();
        let more = if more > 0 {
            format!(" ({more} more vertices are not finite either)")
        } else {
            String::new()
        };
        return Err(invalid(
            source_name,
            format!("vertex {i}"),
            format!(
                "position ({}, {}, {}) is not finite (NaN or infinite){more}; fix or remove the \
                 vertex in the source",
                p.x, p.y, p.z
            ),
        ));
    }
    for (f, t) in mesh.indices.iter().enumerate() {
        if let Some(&bad) = t.iter().find(|&&i| i as usize >= n_vertices) {
            return Err(invalid(
                source_name,
                format!("face {f}"),
                format!(
                    "vertex index {bad} is out of range (the mesh has {n_vertices} vertices, \
                     valid indices are 0..={}); the file is corrupt or truncated",
                    n_vertices - 1
                ),
            ));
        }
    }
    if let Some(normals) = &mesh.normals
        && normals.len() != n_vertices
    {
        return Err(invalid(
            source_name,
            "normals",
            format!(
                "{} normals for {n_vertices} vertices; every vertex needs exactly one normal \
                 (or leave normals out altogether)",
                normals.len()
            ),
        ));
    }

    Ok(())
}

/// Step 2 of [`validate`]: drops the degenerate triangles; an error if none is left.
fn drop_degenerate(
    mesh: &mut Mesh,
    source_name: &str,
    warnings: &mut Vec<MeshWarning>,
) -> Result<(), GeometryError> {
    let (lo, hi) = mesh.bounds();
    let diag = (dvec(hi) - dvec(lo)).length();
    let threshold = DEGENERATE_AREA_TOLERANCE * diag * diag;
    let before = mesh.indices.len();
    let keep: Vec<bool> = (0..before)
        .map(|i| {
            let [a, b, c] = mesh.indices[i];
            a != b && b != c && a != c && mesh.double_area_f64(i) > threshold
        })
        .collect();
    let dropped = keep.iter().filter(|k| !**k).count();
    if dropped == before {
        return Err(invalid(
            source_name,
            "faces",
            format!(
                "all {before} triangles are degenerate (zero area or a repeated vertex index); \
                 the mesh has no surface"
            ),
        ));
    }
    if dropped > 0 {
        let mut k = keep.iter();
        mesh.indices.retain(|_| *k.next().unwrap_or(&true));
        warnings.push(MeshWarning::DroppedDegenerate { count: dropped });
    }
    Ok(())
}

/// Step 4 of [`validate`] on a closed mesh: turns an inside-out mesh (negative signed volume)
/// outward, with its normals if they pointed inward.
fn orient_outward(mesh: &mut Mesh, warnings: &mut Vec<MeshWarning>) {
    let volume = mesh.signed_volume();
    if volume < 0.0 {
        let normals_inward = mesh.normals.as_ref().is_some_and(|normals| {
            let mut agreement = 0.0f64;
            for (i, t) in mesh.indices.iter().enumerate() {
                let fnrm = dvec(mesh.face_normal_raw(i));
                for &v in t {
                    let n = dvec(normals[v as usize]);
                    if n.is_finite() {
                        agreement += n.dot(fnrm);
                    }
                }
            }
            agreement > 0.0
        });
        for t in &mut mesh.indices {
            t.swap(1, 2);
        }
        if normals_inward && let Some(normals) = &mut mesh.normals {
            for n in normals.iter_mut() {
                *n = -*n;
            }
        }
        warnings.push(MeshWarning::Flipped {
            signed_volume_before: volume,
        });
    }
}

/// Step 5 of [`validate`]: recomputes broken normals, normalises the others.
fn repair_normals(mesh: &mut Mesh, warnings: &mut Vec<MeshWarning>) {
    if let Some(normals) = &mut mesh.normals {
        let broken = normals
            .iter()
            .any(|n| !n.is_finite() || n.length_squared() < 1e-24);
        if broken {
            warnings.push(MeshWarning::RecomputedNormals);
        } else {
            for n in normals.iter_mut() {
                // Leave unit normals bit-exact (round trips); fix the others.
                if (n.length_squared() - 1.0).abs() > 1e-6 {
                    *n = n.normalize();
                }
            }
        }
    }
    if warnings.contains(&MeshWarning::RecomputedNormals) {
        mesh.normals = Some(mesh.compute_vertex_normals());
    }
}
