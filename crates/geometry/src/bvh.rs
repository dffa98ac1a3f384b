//! Ray queries over a triangle mesh: an obvhs CWBVH (8-wide) with the watertight triangle test of
//! [`crate::triangle`]. Triangles are stored reordered in BVH order for locality; every result
//! reports the ORIGINAL triangle index.
//!
//! The tree is built by obvhs (PLOC + reinsertion, `medium_build`, parallel). Traversal is our own
//! ([`Accel::bvh_traverse`]) with our own child-box test instead of `CwBvh::ray_traverse*`,
//! because the obvhs box test (0.4.0) is not conservative enough for a watertight tracer:
//! * it clamps the entry distance to `1e-4` (ignoring `ray.tmin`), so boxes the ray leaves before
//!   `t = 1e-4` are skipped: a ray starting just inside a (flat) face misses that face;
//! * it replaces `1/d` by `±1/f32::EPSILON` for `|d| ≤ f32::EPSILON`, which shrinks the slab of a
//!   nearly axis-parallel ray and can cull boxes the ray does cross;
//! * the slab distances carry rounding errors and the quantised boxes can be tight, so rays through
//!   vertices (always on a box face) can be culled.
//!
//! Our test inflates every child box by `4·ε·(255·e + |p − o|)` per axis (ε = f32 machine epsilon,
//! `e` the quantisation step, `p` the node origin, `o` the ray origin), which bounds the rounding of
//! the quantised box and of the slab distances, clamps to the caller's `tmin`, and never
//! approximates `1/d` by anything larger than `|d| = 1e-18`. The eight children's quantised planes
//! are widened to f32 with SSE2 byte unpacking (two lanes of four), and the hit mask is a plain
//! 8-bit mask: the traversal decodes leaves (primitive offset and unary count in the child's meta
//! byte) and inner children (index = base + inner children in lower slots) itself, visits inner
//! children in the build's octant order (slot XOR the inverse direction octant, highest first, as
//! obvhs does) from a fixed stack of (node, entry distance), and skips a popped node whose entry
//! distance is beyond the current closest hit. (Compared with the obvhs `traverse!` macro with the
//! same box test: 16–25 % fewer instructions and 30–38 % fewer mispredicted branches per query on
//! the path tracer's query stream, measured with callgrind.)
//!
//! On CPUs with AVX2 (detected at run time) the queries run a second instance of the same code,
//! compiled with AVX2 enabled, whose box test widens and tests all eight children in one 256-bit
//! lane; it performs the same IEEE operations in the same order as the portable two-lane kernel,
//! so every query returns the same bits either way (`traverse::tests::kernels_agree_bit_for_bit`;
//! renders compared with `cmp`). `TRANSLUCENT_ISA=portable` forces the portable kernel.
//!
//! Known limitation: boxes are culled by the ray's `t` range inside them, while the `t` the
//! watertight test reports for a triangle seen almost exactly edge-on may lie outside that range
//! by up to the triangle's depth along the ray (its barycentric weights are ill-conditioned; `t`
//! stays a convex combination of the corners' depths). Such a hit can be missed when its box lies
//! entirely before `tmin` or beyond the closest hit so far. Covering it (widening the culling
//! range by `1.75 ×` the largest triangle extent and adding the exact test on the box's
//! dominant-axis slab) cost 5–17 % more instructions per query, so it is not done; no test
//! exposes the case (the brute-force comparisons of `tests/bvh.rs` include edge-on rays).
//!
//! Short queries that start far from the surface (free flights and tracked shadow rays deep in a
//! dense medium) are answered without the BVH: a grid of lower bounds on the distance to the mesh
//! (`clearance`) shows that the segment cannot reach any triangle.
//!
//! Layout of the code: this module holds the hit record, the BVH build and the hit-record
//! construction; `traverse` the conservative SIMD child-box test and the depth-first CWBVH
//! traversal; `queries` the public ray queries built on it; `support` the supporting-plane flags
//! of [`Accel::exit_is_final`]; `clearance` the distance-bound grid.

mod clearance;
mod queries;
mod support;
mod traverse;

use std::sync::atomic::AtomicU8;

use glam::{Vec2, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    triangle::Triangle,
};

use crate::Mesh;
use crate::triangle::TriHit;

/// A ray/surface intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Original triangle index in the mesh.
    pub tri: u32,
    /// Barycentrics (b1, b2) of v1 and v2.
    pub bary: Vec2,
    /// Hit position.
    pub p: Vec3,
    /// Unit geometric normal, pointing OUT of the medium (CCW convention). When the ray lies in
    /// the triangle's plane up to rounding (edge-on hit at a vertex or edge), it is tilted by
    /// ~1e-5 rad so that [`Hit::entering`] agrees with the facing the triangle test decided.
    pub ng: Vec3,
    /// Unit shading normal (interpolated vertex normals, or `ng` when the mesh has none), made to
    /// lie in the same hemisphere as `ng`.
    pub ns: Vec3,
}

impl Hit {
    /// True when the ray arrived from outside the medium (`dir · ng < 0`).
    #[inline]
    pub fn entering(&self, dir: Vec3) -> bool {
        dir.dot(self.ng) < 0.0
    }
}

/// Move the surface point `p` (with geometric normal `ng`, either orientation) off the surface to
/// the side `dir` points to, by a scale-aware amount, so that a ray leaving from the result does
/// not hit the surface it starts on.
///
/// Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems
/// ch. 6 (2019): each coordinate is moved by `⌊256·n_i⌋` units in the last place (integer
/// arithmetic on the float bits, towards `n`), except near the origin (`|p_i| < 1/32`) where a
/// fixed `n_i/65536` is added, since ulps vanish there.
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let n = if dir.dot(ng) < 0.0 { -ng } else { ng };
    #[inline(always)]
    fn one(p: f32, n: f32) -> f32 {
        if p.abs() < ORIGIN {
            p + FLOAT_SCALE * n
        } else {
            let of = (INT_SCALE * n) as i32;
            // Moving the bits away from zero increases |p|; towards zero decreases it.
            let of = if p < 0.0 { -of } else { of };
            f32::from_bits((p.to_bits() as i32).wrapping_add(of) as u32)
        }
    }
    Vec3::new(one(p.x, n.x), one(p.y, n.y), one(p.z, n.z))
}

/// Acceleration structure over one mesh. `Send + Sync`; build once, query from many threads.
/// Among hits at equal `t` the closest-hit queries pick the smallest triangle index, and the
/// reductions of [`inside_length`](Self::inside_length) and [`contains`](Self::contains) do not
/// depend on the order in which hits are found.
pub struct Accel {
    mesh: Mesh,
    bvh: CwBvh,
    /// Triangle corners in BVH order (`tris[k]` is mesh triangle `prim_tri[k]`); 36 bytes each
    /// (`Vec3`, not `Vec3A`: traversal is memory bound).
    tris: Vec<[Vec3; 3]>,
    /// BVH order → original triangle index (obvhs `primitive_indices`).
    prim_tri: Vec<u32>,
    /// Per original triangle: whether its plane supports the mesh ([`Accel::exit_is_final`]),
    /// decided on first use.
    supporting: Vec<AtomicU8>,
    /// Lower bounds on the distance to the mesh, per grid cell (`clearance`).
    clearance: clearance::Clearance,
}

impl Accel {
    /// Build the BVH (parallel) over a validated mesh.
    pub fn new(mesh: Mesh) -> Self {
        let corners: Vec<[Vec3; 3]> = (0..mesh.triangle_count())
            .map(|i| mesh.triangle(i))
            .collect();
        if corners.is_empty() {
            return Accel {
                mesh,
                bvh: CwBvh::default(),
                tris: Vec::new(),
                prim_tri: Vec::new(),
                supporting: Vec::new(),
                clearance: clearance::Clearance::default(),
            };
        }
        let obvhs_tris: Vec<Triangle> = corners
            .iter()
            .map(|&[v0, v1, v2]| Triangle {
                v0: v0.into(),
                v1: v1.into(),
                v2: v2.into(),
            })
            .collect();
        let mut bvh = build_cwbvh_from_tris(
            &obvhs_tris,
            BvhBuildParams::medium_build(),
            &mut std::time::Duration::default(),
        );
        // Traversal indexes the reordered `tris` directly; the map is only needed for results.
        let prim_tri = std::mem::take(&mut bvh.primitive_indices);
        let tris: Vec<[Vec3; 3]> = prim_tri.iter().map(|&i| corners[i as usize]).collect();
        Accel {
            mesh,
            bvh,
            clearance: clearance::Clearance::build(&tris),
            tris,
            supporting: support::undecided(prim_tri.len()),
            prim_tri,
        }
    }

    /// The mesh this accel was built over (original triangle order).
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Triangle corners in BVH order (the primitive numbering of the traversal).
    pub(crate) fn bvh_triangles(&self) -> &[[Vec3; 3]] {
        &self.tris
    }

    /// Number of BVH nodes (for statistics).
    pub fn node_count(&self) -> usize {
        self.bvh.nodes.len()
    }

    /// Full hit record from a BVH-order primitive and the test's results.
    #[inline]
    pub(crate) fn make_hit(&self, prim: u32, th: TriHit, dir: Vec3) -> Hit {
        let TriHit { t, b1, b2, front } = th;
        let [v0, v1, v2] = self.tris[prim as usize].map(Vec3A::from);
        let b0 = 1.0 - b1 - b2;
        let p = Vec3::from(v0 * b0 + v1 * b1 + v2 * b2);
        let raw = (v1 - v0).cross(v2 - v0);
        let mut ng = match raw.try_normalize() {
            Some(n) => Vec3::from(n),
            None => {
                // Tiny triangle whose f32 cross product under/overflows: redo in f64.
                let (a, b, c) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
                (b - a).cross(c - a).normalize_or_zero().as_vec3()
            }
        };
        if (dir.dot(ng) < 0.0) != front {
            ng = consistent_normal(ng, dir, front);
        }
        let tri = self.prim_tri[prim as usize];
        let ns = match &self.mesh.normals {
            Some(normals) => {
                let [i0, i1, i2] = self.mesh.indices[tri as usize];
                match (
                    normals.get(i0 as usize),
                    normals.get(i1 as usize),
                    normals.get(i2 as usize),
                ) {
                    (Some(&n0), Some(&n1), Some(&n2)) => {
                        shading_normal(n0 * b0 + n1 * b1 + n2 * b2, ng)
                    }
                    _ => ng,
                }
            }
            None => ng,
        };
        Hit {
            t,
            tri,
            bary: Vec2::new(b1, b2),
            p,
            ng,
            ns,
        }
    }
}

/// `ng` tilted by about 1e-5 rad so that `dir · ng` has the sign the triangle test decided
/// (negative when `front`). Only reached when the ray lies in the triangle's plane up to rounding
/// (an edge-on triangle at a vertex or edge hit), where the sign of `dir · ng` is noise; keeps
/// [`Hit::entering`] consistent with the crossing parity of [`Accel::all_hits`].
#[cold]
fn consistent_normal(ng: Vec3, dir: Vec3, front: bool) -> Vec3 {
    let d = dir.normalize();
    let target = if front { -1e-5 } else { 1e-5 };
    let n = (ng + (target - d.dot(ng)) * d).normalize();
    debug_assert_eq!(dir.dot(n) < 0.0, front);
    n
}

/// Normalise an interpolated vertex normal and bring it into the hemisphere of `ng` by reflecting
/// it about the tangent plane (keeps its tangential tilt); falls back to `ng`.
#[inline]
pub(crate) fn shading_normal(n: Vec3, ng: Vec3) -> Vec3 {
    let Some(n) = n.try_normalize() else {
        return ng;
    };
    let c = n.dot(ng);
    if c >= 0.0 {
        n
    } else {
        (n - 2.0 * c * ng).try_normalize().unwrap_or(ng)
    }
}

#[inline(always)]
pub(crate) fn valid_ray(dir: Vec3, tmin: f32, tmax: f32) -> bool {
    let l2 = dir.length_squared();
    l2 > 0.0 && l2.is_finite() && tmin < tmax
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_origin_moves_to_the_right_side() {
        let ng = Vec3::new(0.3, -0.5, 0.8).normalize();
        for p in [
            Vec3::new(0.7, -1.3, 2.5),
            Vec3::new(1e-3, 0.02, -0.01),
            Vec3::new(-300.0, 1e4, 0.5),
        ] {
            for dir in [ng, -ng, Vec3::new(0.9, 0.1, 0.0).normalize()] {
                let q = offset_origin(p, ng, dir);
                let side = (q - p).dot(ng);
                assert!(side * dir.dot(ng) > 0.0, "p {p} dir {dir} q {q}");
                assert!((q - p).length() < 1e-3 * p.length().max(1.0));
            }
        }
    }

    #[test]
    fn empty_mesh_never_hits() {
        let accel = Accel::new(Mesh::default());
        assert!(
            accel
                .closest(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY)
                .is_none()
        );
        assert!(!accel.occluded(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY));
        assert!(!accel.contains(Vec3::ZERO));
        assert_eq!(accel.inside_length(Vec3::ZERO, Vec3::X), 0.0);
        let mut out = vec![];
        accel.all_hits(Vec3::ZERO, Vec3::X, 0.0, 1.0, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn single_triangle_and_degenerate_rays() {
        let mesh = Mesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            normals: None,
            indices: vec![[0, 1, 2]],
        };
        let accel = Accel::new(mesh);
        let h = accel
            .closest(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, f32::INFINITY)
            .unwrap();
        assert_eq!(h.t, 1.0);
        assert_eq!(h.tri, 0);
        assert_eq!(h.ng, Vec3::Z);
        assert_eq!(h.ns, Vec3::Z);
        assert!(h.entering(-Vec3::Z));
        assert!((h.p - Vec3::new(0.25, 0.25, 0.0)).length() < 1e-7);
        assert!(
            accel
                .closest(Vec3::new(0.25, 0.25, 1.0), Vec3::ZERO, 0.0, f32::INFINITY)
                .is_none()
        );
        assert!(
            accel
                .closest(Vec3::new(0.25, 0.25, 1.0), Vec3::NAN, 0.0, f32::INFINITY)
                .is_none()
        );
        assert!(!accel.occluded(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, 0.5));
        assert!(accel.occluded(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, 1.5));
    }
}
