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
//! Known limitation: boxes are culled by the ray's `t` range inside them, while the `t` the
//! watertight test reports for a triangle seen almost exactly edge-on may lie outside that range
//! by up to the triangle's depth along the ray (its barycentric weights are ill-conditioned; `t`
//! stays a convex combination of the corners' depths). Such a hit can be missed when its box lies
//! entirely before `tmin` or beyond the closest hit so far. Covering it (widening the culling
//! range by `1.75 ×` the largest triangle extent and adding the exact test on the box's
//! dominant-axis slab) cost 5–17 % more instructions per query, so it is not done; no test
//! exposes the case (the brute-force comparisons of `tests/bvh.rs` include edge-on rays).

use std::mem::MaybeUninit;

use glam::{Vec2, Vec3, Vec3A, Vec4};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris, node::CwBvhNode},
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

/// The eight bytes of a quantised CWBVH coordinate array as two `Vec4` (children 0–3, 4–7).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn bytes_to_f32(v: &[u8; 8]) -> [Vec4; 2] {
    use std::arch::x86_64::*;
    // Zero-extend 8 × u8 to 2 × 4 × i32 and convert.
    // SAFETY: SSE2 is part of the x86_64 baseline; these intrinsics only operate on values.
    unsafe {
        let x = _mm_cvtsi64_si128(i64::from_le_bytes(*v));
        let z = _mm_setzero_si128();
        let w = _mm_unpacklo_epi8(x, z);
        [
            Vec4::from(_mm_cvtepi32_ps(_mm_unpacklo_epi16(w, z))),
            Vec4::from(_mm_cvtepi32_ps(_mm_unpackhi_epi16(w, z))),
        ]
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn bytes_to_f32(v: &[u8; 8]) -> [Vec4; 2] {
    let f = v.map(f32::from);
    [
        Vec4::new(f[0], f[1], f[2], f[3]),
        Vec4::new(f[4], f[5], f[6], f[7]),
    ]
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

    /// The children of `node` whose (grown, see the module doc) box the ray meets for some `t`
    /// in `[tmin, tmax]` (bit `i` for child slot `i`; empty slots may be set), and their entry
    /// distances.
    #[inline(always)]
    fn intersect8(&self, node: &CwBvhNode, tmax: f32) -> (u32, [f32; 8]) {
        let e = node.compute_extent();
        let po = Vec3A::from(node.p) - self.org;
        let scale = e * self.inv;
        let off = po * self.inv;
        let slack = (e * 255.0 + po.abs()) * self.inv.abs() * BOX_SLACK;
        let lo = off - slack;
        let hi = off + slack;
        let halves = |neg: bool, lo: &[u8; 8], hi: &[u8; 8]| {
            let (l, h) = (bytes_to_f32(lo), bytes_to_f32(hi));
            if neg { (h, l) } else { (l, h) }
        };
        let (nx, fx) = halves(self.neg[0], &node.child_min_x, &node.child_max_x);
        let (ny, fy) = halves(self.neg[1], &node.child_min_y, &node.child_max_y);
        let (nz, fz) = halves(self.neg[2], &node.child_min_z, &node.child_max_z);
        let mut mask = 0u32;
        let mut near = [0.0f32; 8];
        for h in 0..2 {
            let t0 = (nx[h] * scale.x + Vec4::splat(lo.x))
                .max(ny[h] * scale.y + Vec4::splat(lo.y))
                .max(nz[h] * scale.z + Vec4::splat(lo.z))
                .max(Vec4::splat(self.tmin));
            let t1 = (fx[h] * scale.x + Vec4::splat(hi.x))
                .min(fy[h] * scale.y + Vec4::splat(hi.y))
                .min(fz[h] * scale.z + Vec4::splat(hi.z))
                .min(Vec4::splat(tmax));
            mask |= t0.cmple(t1).bitmask() << (4 * h);
            near[4 * h..4 * h + 4].copy_from_slice(&t0.to_array());
        }
        (mask, near)
    }
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
        let tris: Vec<[Vec3; 3]> = prim_tri.iter().map(|&i| corners[i as usize]).collect();
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

    /// Triangle corners in BVH order (the primitive numbering of the traversal).
    pub(crate) fn bvh_triangles(&self) -> &[[Vec3; 3]] {
        &self.tris
    }

    /// Number of BVH nodes (for statistics).
    pub fn node_count(&self) -> usize {
        self.bvh.nodes.len()
    }

    /// Depth-first traversal of the CWBVH: `leaf(first, count)` is called for every leaf whose
    /// box the ray meets within `[tmin, tmax]` (primitives `first..first + count` of `tris`) and
    /// returns the new `tmax` (−∞ ends the traversal). Inner children are visited in the octant
    /// order of the build (front to back for the ray's direction octant), and a child popped from
    /// the stack is skipped when its entry distance exceeds the current `tmax`.
    #[inline(always)]
    fn bvh_traverse(
        &self,
        br: &BoxRay,
        d: Vec3A,
        mut tmax: f32,
        mut leaf: impl FnMut(u32, u32) -> f32,
    ) {
        let nodes = &self.bvh.nodes;
        if nodes.is_empty() {
            return;
        }
        // Inverse octant of the direction (obvhs' traversal priority: slot ^ oct_inv, highest
        // first).
        let oct_inv = (if d.x < 0.0 { 0 } else { 4 })
            | (if d.y < 0.0 { 0 } else { 2 })
            | (if d.z < 0.0 { 0 } else { 1 });
        let mut stack = NodeStack::new();
        let mut cur = 0u32;
        loop {
            let node = &nodes[cur as usize];
            let (hits, near) = br.intersect8(node, tmax);
            let imask = node.imask as u32;
            // Leaves of this node (unary primitive count in the top 3 bits of their meta byte).
            let mut leaves = hits & !imask;
            while leaves != 0 {
                let slot = leaves.trailing_zeros() as usize;
                leaves &= leaves - 1;
                let meta = node.child_meta[slot] as u32;
                let count = POPCOUNT8[(meta >> 5) as usize] as u32;
                if count != 0 {
                    tmax = leaf(node.primitive_base_idx + (meta & 0x1f), count);
                    if tmax == f32::NEG_INFINITY {
                        return;
                    }
                }
            }
            // Inner children: pushed in increasing priority, so the highest comes out first.
            let inner = hits & imask;
            if inner != 0 {
                let mut by_priority = PERMUTE_XOR[oct_inv as usize][inner as usize] as u32;
                while by_priority != 0 {
                    let slot = (by_priority.trailing_zeros() ^ oct_inv) as usize;
                    by_priority &= by_priority - 1;
                    let below = POPCOUNT8[(imask & ((1u32 << slot) - 1)) as usize] as u32;
                    stack.push(node.child_base_idx + below, near[slot]);
                }
            }
            loop {
                let Some((n, t)) = stack.pop() else {
                    return;
                };
                if t <= tmax {
                    cur = n;
                    break;
                }
            }
        }
    }

    /// Closest hit with `tmin < t < tmax` along `origin + t·dir` (`dir` unit length); among hits
    /// at the same `t`, the one with the smallest triangle index.
    #[inline]
    pub fn closest(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        if !valid_ray(dir, tmin, tmax) || self.tris.is_empty() {
            return None;
        }
        let (prim, th) = self.closest_bvh(origin.into(), dir.into(), tmin, tmax)?;
        Some(self.make_hit(prim, th, dir))
    }

    /// Upper limit for the triangle test while `best` holds the closest hit so far at `best_t`:
    /// `tmax` before the first hit, then just above `best_t`, so that a tie is seen.
    #[inline(always)]
    pub(crate) fn limit(best: &Option<(u32, TriHit)>, best_t: f32, tmax: f32) -> f32 {
        if best.is_some() {
            best_t.next_up()
        } else {
            tmax
        }
    }

    /// Whether a hit at `t` on `prim` replaces the best so far (closer, or a tie with a smaller
    /// triangle index). Only called with `t ≤ best_t`.
    #[inline(always)]
    pub(crate) fn improves(
        &self,
        t: f32,
        prim: u32,
        best: &Option<(u32, TriHit)>,
        best_t: f32,
    ) -> bool {
        t < best_t
            || best.is_some_and(|(b, _)| self.prim_tri[prim as usize] < self.prim_tri[b as usize])
    }

    fn closest_bvh(&self, o: Vec3A, d: Vec3A, tmin: f32, tmax: f32) -> Option<(u32, TriHit)> {
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        let mut best_t = tmax;
        let mut best: Option<(u32, TriHit)> = None;
        self.bvh_traverse(&br, d, tmax, |first, count| {
            for prim in first..first + count {
                let [v0, v1, v2] = self.tris[prim as usize].map(Vec3A::from);
                let lim = Self::limit(&best, best_t, tmax);
                if let Some(th) = wr.intersect_hit(v0, v1, v2, tmin, lim)
                    && self.improves(th.t, prim, &best, best_t)
                {
                    best_t = th.t;
                    best = Some((prim, th));
                }
            }
            best_t
        });
        best
    }

    /// The first hit in each direction from two open ranges of the line `x + s·dir` (`dir` unit
    /// length), found in ONE traversal: `.0` is the hit with the smallest `s` in `ahead` (what
    /// [`closest`](Self::closest) returns for the ray from `x + ahead.0·dir` along `dir` with
    /// `t_max = ahead.1 − ahead.0`), `.1` the hit with the largest `s` in `behind` (the ray from
    /// `x + behind.1·dir` along `−dir`). Ties at equal `s` go to the smaller triangle index, and
    /// [`Hit::t`] is `s`. The traversal stops at `max(s_ahead, behind.1)`: nothing beyond can
    /// change either answer. Used by the two-sided projection of the learned BSSRDF, where it
    /// replaces two root-to-leaf descents by one.
    pub fn first_hits_both_ways(
        &self,
        x: Vec3,
        dir: Vec3,
        ahead: (f32, f32),
        behind: (f32, f32),
    ) -> (Option<Hit>, Option<Hit>) {
        let (fwd, back) = self.both_ways_raw(x, dir, ahead, behind);
        (self.line_hit(fwd, dir), self.line_hit(back, dir))
    }

    /// Of the two answers of [`first_hits_both_ways`](Self::first_hits_both_ways), the one
    /// nearer to `x` (smaller |s|; the one ahead on a tie), with only that one's [`Hit`] built.
    pub fn nearest_hit_both_ways(
        &self,
        x: Vec3,
        dir: Vec3,
        ahead: (f32, f32),
        behind: (f32, f32),
    ) -> Option<Hit> {
        let (fwd, back) = self.both_ways_raw(x, dir, ahead, behind);
        let pick = match (fwd, back) {
            (Some(a), Some(b)) => Some(if a.2.abs() <= b.2.abs() { a } else { b }),
            (a, b) => a.or(b),
        };
        self.line_hit(pick, dir)
    }

    /// A raw line hit (primitive, triangle hit, line parameter s) as a [`Hit`] with `t = s`.
    #[inline]
    fn line_hit(&self, h: Option<(u32, TriHit, f32)>, dir: Vec3) -> Option<Hit> {
        h.map(|(prim, th, s)| Hit {
            t: s,
            ..self.make_hit(prim, th, dir)
        })
    }

    /// The traversal of [`first_hits_both_ways`](Self::first_hits_both_ways), without building
    /// the hits.
    #[allow(clippy::type_complexity)]
    fn both_ways_raw(
        &self,
        x: Vec3,
        dir: Vec3,
        ahead: (f32, f32),
        behind: (f32, f32),
    ) -> (Option<(u32, TriHit, f32)>, Option<(u32, TriHit, f32)>) {
        let s_lo = ahead.0.min(behind.0);
        let s_hi = ahead.1.max(behind.1);
        let len = s_hi - s_lo;
        if !valid_ray(dir, 0.0, len) || self.tris.is_empty() {
            return (None, None);
        }
        let (o, d) = (Vec3A::from(x + s_lo * dir), Vec3A::from(dir));
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, 0.0);
        let mut fwd: Option<(u32, TriHit, f32)> = None;
        let mut back: Option<(u32, TriHit, f32)> = None;
        let tri_of = |prim: u32| self.prim_tri[prim as usize];
        let cutoff = |fwd: &Option<(u32, TriHit, f32)>| {
            let a = fwd.map_or(ahead.1, |(_, _, s)| s);
            (a.max(behind.1) - s_lo).min(len)
        };
        self.bvh_traverse(&br, d, len, |first, count| {
            for prim in first..first + count {
                let [v0, v1, v2] = self.tris[prim as usize].map(Vec3A::from);
                let Some(th) = wr.intersect_hit(v0, v1, v2, 0.0, cutoff(&fwd).next_up()) else {
                    continue;
                };
                let s = th.t + s_lo;
                if s > ahead.0
                    && s < ahead.1
                    && fwd.is_none_or(|(p, _, b)| s < b || (s == b && tri_of(prim) < tri_of(p)))
                {
                    fwd = Some((prim, th, s));
                }
                if s > behind.0
                    && s < behind.1
                    && back.is_none_or(|(p, _, b)| s > b || (s == b && tri_of(prim) < tri_of(p)))
                {
                    back = Some((prim, th, s));
                }
            }
            cutoff(&fwd)
        });
        (fwd, back)
    }

    /// True when anything is hit with `tmin < t < tmax`.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if !valid_ray(dir, tmin, tmax) || self.tris.is_empty() {
            return false;
        }
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let mut hit = false;
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        self.bvh_traverse(&br, d, tmax, |first, count| {
            hit = (first..first + count).any(|prim| {
                let [v0, v1, v2] = self.tris[prim as usize].map(Vec3A::from);
                wr.intersect(v0, v1, v2, tmin, tmax).is_some()
            });
            if hit { f32::NEG_INFINITY } else { tmax }
        });
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
        self.bvh_traverse(&br, d, tmax, |first, count| {
            for prim in first..first + count {
                let [v0, v1, v2] = self.tris[prim as usize].map(Vec3A::from);
                if let Some(th) = wr.intersect_hit(v0, v1, v2, tmin, tmax) {
                    f(prim, th);
                }
            }
            tmax
        });
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
    /// back-face hit means inside; at equal `t` a back-face hit counts as first). Every crossing
    /// on the segment then toggles.
    ///
    /// Computed as `s(a)·L + Σ δᵢ·(L − tᵢ)` over the crossings `tᵢ < L` (δ = +1 entering, −1
    /// leaving), summed in f64 in the order of increasing `(tᵢ, facing)` (so the result does not
    /// depend on the structure that found the crossings), clamped to [0, L], so two crossings
    /// whose order is decided by rounding (a ray grazing a vertex) cost at most their distance.
    /// Allocation-free up to 16 crossings.
    pub fn inside_length(&self, a: Vec3, b: Vec3) -> f32 {
        let seg = b - a;
        let len = seg.length();
        if !(len > 0.0 && len.is_finite()) {
            return 0.0;
        }
        let dir = seg / len;
        let mut xs = StackVec::<(f32, bool), 16>::new();
        self.for_each_hit(a, dir, 0.0, f32::INFINITY, |_, th| {
            xs.push((th.t, th.front));
        });
        let xs = xs.as_mut_slice();
        // Insertion sort by (t, front): a handful of crossings.
        for i in 1..xs.len() {
            let mut j = i;
            while j > 0 && crossing_before(xs[j], xs[j - 1]) {
                xs.swap(j, j - 1);
                j -= 1;
            }
        }
        let lenf = len as f64;
        let mut winding = 0i32; // leaving − entering on (0, ∞)
        let mut sum = 0.0f64; // Σ δᵢ (L − tᵢ) over tᵢ < L
        for &(t, front) in xs.iter() {
            winding += if front { -1 } else { 1 };
            if t < len {
                let delta = if front { 1.0 } else { -1.0 };
                sum += delta * (lenf - t as f64);
            }
        }
        let inside_a = match winding {
            0 => 0.0,
            1 => 1.0,
            _ => xs.first().is_some_and(|&(_, front)| !front) as u8 as f64,
        };
        (inside_a * lenf + sum).clamp(0.0, lenf) as f32
    }

    /// True when `p` is inside the closed mesh: leaving minus entering hits along a fixed direction
    /// is 1 (exact for closed meshes, see [`inside_length`](Self::inside_length)); falls back to
    /// the facing of the first hit along that direction when the count is neither 0 nor 1.
    pub fn contains(&self, p: Vec3) -> bool {
        let dir = CONTAINS_DIR.normalize();
        let mut winding = 0i32;
        let mut first = (f32::INFINITY, true);
        self.for_each_hit(p, dir, 0.0, f32::INFINITY, |_, th| {
            winding += if th.front { -1 } else { 1 };
            if crossing_before((th.t, th.front), first) {
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

/// Bit counts of bytes.
const POPCOUNT8: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = (i as u32).count_ones() as u8;
        i += 1;
    }
    t
};

/// `PERMUTE_XOR[x][m]`: the byte whose bit `i ^ x` is bit `i` of `m` (slot mask → priority
/// mask for the octant `x`).
const PERMUTE_XOR: [[u8; 256]; 8] = {
    let mut t = [[0u8; 256]; 8];
    let mut x = 0;
    while x < 8 {
        let mut m = 0;
        while m < 256 {
            let mut out = 0u32;
            let mut i = 0;
            while i < 8 {
                if m & (1 << i) != 0 {
                    out |= 1 << (i ^ x);
                }
                i += 1;
            }
            t[x][m] = out as u8;
            m += 1;
        }
        x += 1;
    }
    t
};

/// Traversal stack of (node, entry distance): fixed capacity, not initialised (no per-query
/// memset), spilling to the heap only for pathologically deep trees.
struct NodeStack {
    len: usize,
    buf: [MaybeUninit<(u32, f32)>; 128],
    spill: Vec<(u32, f32)>,
}

impl NodeStack {
    #[inline(always)]
    fn new() -> Self {
        NodeStack {
            len: 0,
            buf: [MaybeUninit::uninit(); 128],
            spill: Vec::new(),
        }
    }

    #[inline(always)]
    fn push(&mut self, node: u32, t: f32) {
        if self.len < self.buf.len() {
            self.buf[self.len] = MaybeUninit::new((node, t));
            self.len += 1;
        } else {
            self.spill.push((node, t));
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if let Some(e) = self.spill.pop() {
            return Some(e);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: slots below `len` were written by `push`.
        Some(unsafe { self.buf[self.len].assume_init() })
    }
}

/// Order of crossings `(t, front)`: by `t`, a back-face hit first at equal `t`.
#[inline(always)]
fn crossing_before(a: (f32, bool), b: (f32, bool)) -> bool {
    a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).is_lt()
}

/// Stack buffer of up to `N` elements that moves to the heap beyond (allocation-free in the
/// common case; not initialised).
struct StackVec<T: Copy, const N: usize> {
    len: usize,
    buf: [MaybeUninit<T>; N],
    spill: Vec<T>,
}

impl<T: Copy, const N: usize> StackVec<T, N> {
    #[inline(always)]
    fn new() -> Self {
        StackVec {
            len: 0,
            buf: [MaybeUninit::uninit(); N],
            spill: Vec::new(),
        }
    }

    #[inline(always)]
    fn push(&mut self, v: T) {
        if self.len < N {
            self.buf[self.len] = MaybeUninit::new(v);
            self.len += 1;
        } else {
            self.spill_push(v);
        }
    }

    #[cold]
    fn spill_push(&mut self, v: T) {
        if self.spill.is_empty() {
            let mut all = Vec::with_capacity(2 * N);
            all.extend_from_slice(self.as_slice());
            self.spill = all;
        }
        self.spill.push(v);
    }

    #[inline(always)]
    fn as_slice(&self) -> &[T] {
        if self.spill.is_empty() {
            // SAFETY: the first `len` slots were written by `push`; `MaybeUninit<T>` has the
            // layout of `T`.
            unsafe { std::slice::from_raw_parts(self.buf.as_ptr().cast::<T>(), self.len) }
        } else {
            &self.spill
        }
    }

    #[inline(always)]
    fn as_mut_slice(&mut self) -> &mut [T] {
        if self.spill.is_empty() {
            // SAFETY: as in `as_slice`.
            unsafe { std::slice::from_raw_parts_mut(self.buf.as_mut_ptr().cast::<T>(), self.len) }
        } else {
            &mut self.spill
        }
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
