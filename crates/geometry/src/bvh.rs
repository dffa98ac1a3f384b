//! Ray queries over a triangle mesh: an obvhs CWBVH (8-wide) with the watertight triangle test of
//! [`crate::triangle`]. Triangles are stored reordered in BVH order for locality; every result
//! reports the ORIGINAL triangle index.
//!
//! The tree is built by obvhs (PLOC + reinsertion, `medium_build`, parallel). Traversal uses the
//! obvhs `traverse!` macro with our own child-box test instead of `CwBvh::ray_traverse*`, because
//! the obvhs box test (0.4.0) is not conservative enough for a watertight tracer:
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
//! approximates `1/d` by anything larger than `|d| = 1e-18`.

use glam::{UVec2, Vec2, Vec3, Vec3A, Vec4};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris, node::CwBvhNode, node::extract_byte64},
    triangle::Triangle,
};

use crate::Mesh;
use crate::triangle::{TriHit, WatertightRay};

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

/// Per-ray data of the conservative child-box test.
#[derive(Clone, Copy)]
struct BoxRay {
    org: Vec3A,
    /// `1/d` with `|d|` clamped to at least 1e-18 (sign kept).
    inv: Vec3A,
    /// Which component of `inv` is negative (selects near/far planes).
    neg: [bool; 3],
    tmin: f32,
}

/// Relative inflation of the child boxes (see the module doc).
const BOX_SLACK: f32 = 4.0 * f32::EPSILON;

impl BoxRay {
    #[inline(always)]
    fn new(org: Vec3A, dir: Vec3A, tmin: f32) -> Self {
        const TINY: f32 = 1e-18;
        let small = dir.abs().cmplt(Vec3A::splat(TINY));
        let inv = Vec3A::select(small, Vec3A::splat(TINY).copysign(dir), dir).recip();
        BoxRay {
            org,
            inv,
            neg: [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0],
            tmin,
        }
    }

    /// Hit mask of the children of `node` in the obvhs `traverse!` format.
    #[inline(always)]
    fn intersect(&self, node: &CwBvhNode, oct_inv4: u32, tmax: f32) -> u32 {
        let e = node.compute_extent();
        let po = Vec3A::from(node.p) - self.org;
        let scale = e * self.inv;
        let off = po * self.inv;
        let slack = (e * 255.0 + po.abs()) * self.inv.abs() * BOX_SLACK;
        let lo = off - slack;
        let hi = off + slack;
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);

        #[inline(always)]
        fn q4(v: &[u8; 8], i: usize) -> Vec4 {
            Vec4::new(
                v[i] as f32,
                v[i + 1] as f32,
                v[i + 2] as f32,
                v[i + 3] as f32,
            )
        }
        #[inline(always)]
        fn near_far(lo: &[u8; 8], hi: &[u8; 8], i: usize, neg: bool) -> (Vec4, Vec4) {
            let (l, h) = (q4(lo, i), q4(hi, i));
            if neg { (h, l) } else { (l, h) }
        }

        let mut hit_mask = 0u32;
        for i in [0usize, 4] {
            let (nx, fx) = near_far(&node.child_min_x, &node.child_max_x, i, self.neg[0]);
            let (ny, fy) = near_far(&node.child_min_y, &node.child_max_y, i, self.neg[1]);
            let (nz, fz) = near_far(&node.child_min_z, &node.child_max_z, i, self.neg[2]);
            let t0 = (nx * scale.x + Vec4::splat(lo.x))
                .max(ny * scale.y + Vec4::splat(lo.y))
                .max(nz * scale.z + Vec4::splat(lo.z))
                .max(Vec4::splat(self.tmin));
            let t1 = (fx * scale.x + Vec4::splat(hi.x))
                .min(fy * scale.y + Vec4::splat(hi.y))
                .min(fz * scale.z + Vec4::splat(hi.z))
                .min(Vec4::splat(tmax));
            let mask = t0.cmple(t1).bitmask();
            for j in 0..4 {
                if mask & (1 << j) != 0 {
                    let child_bits = extract_byte64(child_bits8, i + j);
                    let bit_index = extract_byte64(bit_index8, i + j);
                    hit_mask |= child_bits << bit_index;
                }
            }
        }
        hit_mask
    }
}

/// Acceleration structure over one mesh. `Send + Sync`; build once, query from many threads.
pub struct Accel {
    mesh: Mesh,
    bvh: CwBvh,
    /// Triangle corners in BVH order (`tris[k]` is mesh triangle `prim_tri[k]`); 36 bytes each
    /// (`Vec3`, not `Vec3A`: traversal is memory bound).
    tris: Vec<[Vec3; 3]>,
    /// BVH order → original triangle index (obvhs `primitive_indices`).
    prim_tri: Vec<u32>,
}

/// Fixed, irrational-looking direction used by [`Accel::contains`] (avoids axis-aligned edges).
const CONTAINS_DIR: Vec3 = Vec3::new(0.548_546_7, 0.627_302_6, 0.552_787_9);

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
        let tris = prim_tri.iter().map(|&i| corners[i as usize]).collect();
        Accel {
            mesh,
            bvh,
            tris,
            prim_tri,
        }
    }
    /// The mesh this accel was built over (original triangle order).
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Number of BVH nodes (for statistics).
    pub fn node_count(&self) -> usize {
        self.bvh.nodes.len()
    }

    /// Closest hit with `tmin < t < tmax` along `origin + t·dir` (`dir` unit length).
    #[inline]
    pub fn closest(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let (prim, th) = self.closest_prim(origin, dir, tmin, tmax)?;
        Some(self.make_hit(prim, th, dir))
    }

    /// Closest hit as (BVH primitive, triangle-test result), without positions and normals.
    #[inline]
    fn closest_prim(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<(u32, TriHit)> {
        if !valid_ray(dir, tmin, tmax) || self.tris.is_empty() {
            return None;
        }
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        let mut best_t = tmax;
        let mut best: Option<(u32, TriHit)> = None;
        let mut state = self.bvh.new_traversal(d);
        let mut node: &CwBvhNode;
        obvhs::traverse!(
            self.bvh,
            node,
            state,
            br.intersect(node, state.oct_inv4, best_t),
            {
                let prim = state.primitive_id;
                let [v0, v1, v2] = self.tris[prim as usize].map(Vec3A::from);
                if let Some(th) = wr.intersect_hit(v0, v1, v2, tmin, best_t) {
                    best_t = th.t;
                    best = Some((prim, th));
                }
            }
        );
        best
    }

    /// True when anything is hit with `tmin < t < tmax`.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if !valid_ray(dir, tmin, tmax) || self.tris.is_empty() {
            return false;
        }
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        let mut hit = false;
        let mut state = self.bvh.new_traversal(d);
        let mut node: &CwBvhNode;
        // A plain `break` would only leave the macro's inner primitive loop.
        'outer: {
            obvhs::traverse!(
                self.bvh,
                node,
                state,
                br.intersect(node, state.oct_inv4, tmax),
                {
                    let [v0, v1, v2] = self.tris[state.primitive_id as usize].map(Vec3A::from);
                    if wr.intersect(v0, v1, v2, tmin, tmax).is_some() {
                        hit = true;
                        break 'outer;
                    }
                }
            );
        }
        hit
    }

    /// Call `f(prim, hit)` for every hit with `tmin < t < tmax`, in traversal order.
    #[inline]
    fn for_each_hit(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        mut f: impl FnMut(u32, TriHit),
    ) {
        if !valid_ray(dir, tmin, tmax) || self.tris.is_empty() {
            return;
        }
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        let mut state = self.bvh.new_traversal(d);
        let mut node: &CwBvhNode;
        obvhs::traverse!(
            self.bvh,
            node,
            state,
            br.intersect(node, state.oct_inv4, tmax),
            {
                let prim = state.primitive_id;
                let [v0, v1, v2] = self.tris[prim as usize].map(Vec3A::from);
                if let Some(th) = wr.intersect_hit(v0, v1, v2, tmin, tmax) {
                    f(prim, th);
                }
            }
        );
    }

    /// All hits with `tmin < t < tmax`, appended to `out` sorted by `t` (`out` is cleared first;
    /// pass a reused buffer to stay allocation-free).
    ///
    /// Each crossing of the surface is reported once, also through shared edges and vertices (the
    /// tie-break of [`crate::triangle`]), so no de-duplication is needed or done: hits at equal `t`
    /// are distinct crossings (e.g. entering and leaving at a silhouette edge). Along a full line
    /// through a closed mesh the numbers of entering and leaving hits ([`Hit::entering`]) are
    /// exactly equal. Equal `t` are ordered by triangle index; hits whose `t` differ by rounding
    /// only (a ray grazing a vertex) may come out in either order.
    pub fn all_hits(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, out: &mut Vec<Hit>) {
        out.clear();
        self.for_each_hit(origin, dir, tmin, tmax, |prim, th| {
            out.push(self.make_hit(prim, th, dir));
        });
        out.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.tri.cmp(&b.tri)));
    }

    /// Total length of the segment `a → b` that lies inside the closed mesh. Whether `a` is inside
    /// is decided by the crossings along the ray from `a` through `b`: the number of leaving minus
    /// entering hits on the whole ray (to infinity) is 1 inside and 0 outside, exactly, for a
    /// closed mesh (the triangle test reports each crossing once with an exactly consistent
    /// facing); when that count is neither (open mesh) the facing of the first hit decides (a
    /// back-face hit means inside). Every crossing on the segment then toggles.
    ///
    /// Computed without sorting as `s(a)·L + Σ δᵢ·(L − tᵢ)` over the crossings `tᵢ < L` (δ = +1
    /// entering, −1 leaving), clamped to [0, L], so two crossings whose order is decided by
    /// rounding (a ray grazing a vertex) cost at most their distance. Allocation-free.
    pub fn inside_length(&self, a: Vec3, b: Vec3) -> f32 {
        let seg = b - a;
        let len = seg.length();
        if !(len > 0.0 && len.is_finite()) {
            return 0.0;
        }
        let dir = seg / len;
        let lenf = len as f64;
        let mut winding = 0i32; // leaving − entering on (0, ∞)
        let mut first = (f32::INFINITY, false); // (t, front) of the first hit
        let mut sum = 0.0f64; // Σ δᵢ (L − tᵢ) over tᵢ < L
        self.for_each_hit(a, dir, 0.0, f32::INFINITY, |_, th| {
            winding += if th.front { -1 } else { 1 };
            if th.t < first.0 {
                first = (th.t, th.front);
            }
            if th.t < len {
                let delta = if th.front { 1.0 } else { -1.0 };
                sum += delta * (lenf - th.t as f64);
            }
        });
        let inside_a = match winding {
            0 => 0.0,
            1 => 1.0,
            _ => (first.0.is_finite() && !first.1) as u8 as f64,
        };
        (inside_a * lenf + sum).clamp(0.0, lenf) as f32
    }

    /// True when `p` is inside the closed mesh: leaving minus entering hits along a fixed direction
    /// is 1 (exact for closed meshes, see [`inside_length`](Self::inside_length)); falls back to
    /// the facing of the first hit along that direction when the count is neither 0 nor 1.
    pub fn contains(&self, p: Vec3) -> bool {
        let dir = CONTAINS_DIR.normalize();
        let mut winding = 0i32;
        let mut first = (f32::INFINITY, false);
        self.for_each_hit(p, dir, 0.0, f32::INFINITY, |_, th| {
            winding += if th.front { -1 } else { 1 };
            if th.t < first.0 {
                first = (th.t, th.front);
            }
        });
        match winding {
            0 => false,
            1 => true,
            _ => first.0.is_finite() && !first.1,
        }
    }

    /// Full hit record from a BVH-order primitive and the test's results.
    #[inline]
    fn make_hit(&self, prim: u32, th: TriHit, dir: Vec3) -> Hit {
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
fn valid_ray(dir: Vec3, tmin: f32, tmax: f32) -> bool {
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
