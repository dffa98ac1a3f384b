//! Supporting planes: the triangles whose plane has the whole mesh on its inner side.
//!
//! If every vertex of the mesh lies on or behind the plane of triangle `i` (behind = against its
//! outward normal), so does every triangle (the convex hull of its corners) and hence the whole
//! mesh. A ray that starts in front of that plane and moves away from it
//! (`d · n > 0`) stays in the open half-space in front, which contains no point of the mesh: it
//! can never meet the mesh again. That is the situation of every ray that leaves the medium
//! through triangle `i` (its origin offset off the surface to the outside), so the tracer can
//! skip the query that looks for a re-entry ([`Accel::exit_is_final`]). On a convex mesh every
//! triangle qualifies; on a concave one, those on the convex hull.
//!
//! Tolerance. A vertex counts as in front when `n · (v − v₀) > τ` with τ = 2⁻²² · max |v₀,₁,₂|∞
//! of the triangle's own corners (f64 arithmetic): about 4 units in the last place of its
//! coordinates, enough for neighbours that are coplanar up to the f32 rounding of their
//! coordinates (flat faces, straight generators), and more than ten times below how far an
//! origin leaving through the triangle sits in front of its plane (`bvh::offset_origin` moves the
//! coordinate of the dominant normal axis by ≥ 147 ulps: ≥ 2.9·10⁻⁶ · |p|; Mitsuba's offset
//! 10⁻⁴). Such an origin moving outward is in front of every point of the mesh. Neighbours bent
//! forward by more than τ (noise, a concave edge) clear the flag, which only forgoes the
//! shortcut there.
//!
//! The search for a vertex in front descends the BVH and prunes every child whose (quantised,
//! conservative, widened by one quantisation step) box lies behind the plane, so a hull triangle
//! costs a few dozen box tests. Each triangle is decided when a ray first leaves through it.

use glam::{DVec3, Vec3};

use std::sync::atomic::{AtomicU8, Ordering};

use super::Accel;

const UNKNOWN: u8 = 0;
const SUPPORTING: u8 = 1;
const NOT_SUPPORTING: u8 = 2;

/// The per-triangle flags of [`Accel::exit_is_final`], all undecided.
pub(super) fn undecided(triangles: usize) -> Vec<AtomicU8> {
    (0..triangles).map(|_| AtomicU8::new(UNKNOWN)).collect()
}

/// τ / max |corner coordinate| (module docs): 2⁻²².
pub const TOLERANCE: f64 = 1.0 / 4_194_304.0;

impl Accel {
    /// True when no point of the mesh lies in front of the plane of triangle `tri` (original
    /// index), i.e. a ray leaving the medium through it cannot meet the mesh again (module
    /// docs). Decided on the first call for each triangle (0.75–5 µs) and remembered; calls from
    /// several threads at once may decide it twice, with the same answer.
    #[inline]
    pub fn exit_is_final(&self, tri: u32) -> bool {
        let Some(flag) = self.supporting.get(tri as usize) else {
            return false;
        };
        match flag.load(Ordering::Relaxed) {
            SUPPORTING => true,
            NOT_SUPPORTING => false,
            _ => self.decide_supporting(tri as usize),
        }
    }

    /// Decide [`Accel::exit_is_final`] for every triangle now, in parallel (rayon), instead of
    /// on first use; returns how many are supporting. The flags are the same either way. For
    /// long runs that will meet most triangles anyway (an optimisation), this moves the
    /// decisions (about 10 µs per supporting triangle of a smooth mesh) out of the first
    /// iterations, where lazily they run on whichever thread meets the triangle first and may
    /// be made twice.
    pub fn decide_all_supporting(&self) -> usize {
        use rayon::prelude::*;
        (0..self.supporting.len() as u32)
            .into_par_iter()
            .with_min_len(256)
            .filter(|&t| self.exit_is_final(t))
            .count()
    }

    #[cold]
    fn decide_supporting(&self, tri: usize) -> bool {
        let yes = self.behind_plane(self.mesh.triangle(tri));
        let v = if yes { SUPPORTING } else { NOT_SUPPORTING };
        self.supporting[tri].store(v, Ordering::Relaxed);
        yes
    }

    /// Whether every vertex of the mesh satisfies `n · (v − v₀) ≤ τ` (module docs) for the plane
    /// of the triangle with corners `c` (outward normal by the CCW convention). Degenerate
    /// triangles (no normal): false.
    fn behind_plane(&self, c: [Vec3; 3]) -> bool {
        let tol = TOLERANCE * c.iter().fold(0.0f32, |m, v| m.max(v.abs().max_element())) as f64;
        let [v0, v1, v2] = c.map(|v| v.as_dvec3());
        let Some(n) = (v1 - v0).cross(v2 - v0).try_normalize() else {
            return false;
        };
        let h = n.dot(v0) + tol;
        let nodes = &self.bvh.nodes;
        if nodes.is_empty() {
            return true;
        }
        let in_front = |v: Vec3| n.dot(v.as_dvec3()) > h;
        // Depth first, the child reaching farthest in front of the plane first (a vertex in
        // front, if any, is most likely there). Fixed capacity: at most 7 siblings wait per
        // level.
        let mut stack = [0u32; 256];
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let cur = stack[len];
            let node = &nodes[cur as usize];
            // The reach of a child (the largest n·x over its box, one quantisation step wider
            // on every side) is n·p + Σ_k n_k·e_k·(q_k ± 1): per axis the quantised max + 1
            // where n_k ≥ 0, the min − 1 where n_k < 0 (e_k > 0).
            let e = node.compute_extent();
            let (p, e) = (
                node.p.as_dvec3(),
                DVec3::new(e.x as f64, e.y as f64, e.z as f64),
            );
            let base = n.dot(p);
            let s = n * e;
            let side = |k: usize| {
                let (lo, hi) = [
                    (&node.child_min_x, &node.child_max_x),
                    (&node.child_min_y, &node.child_max_y),
                    (&node.child_min_z, &node.child_max_z),
                ][k];
                if n[k] >= 0.0 { (hi, 1.0) } else { (lo, -1.0) }
            };
            let axes = [side(0), side(1), side(2)];
            let imask = node.imask as u32;
            let mut inner: [(f64, u32); 8] = [(0.0, 0); 8];
            let mut n_inner = 0;
            for slot in 0..8 {
                let meta = node.child_meta[slot] as u32;
                let is_inner = imask >> slot & 1 == 1;
                if !is_inner && meta == 0 {
                    continue; // empty slot
                }
                let reach: f64 = base
                    + (0..3)
                        .map(|k| s[k] * (axes[k].0[slot] as f64 + axes[k].1))
                        .sum::<f64>();
                if reach <= h {
                    continue;
                }
                if is_inner {
                    let below = (imask & ((1u32 << slot) - 1)).count_ones();
                    inner[n_inner] = (reach, node.child_base_idx + below);
                    n_inner += 1;
                } else {
                    let first = node.primitive_base_idx + (meta & 0x1f);
                    let count = (meta >> 5).count_ones();
                    let tris = &self.tris[first as usize..(first + count) as usize];
                    if tris.iter().flatten().any(|&v| in_front(v)) {
                        return false;
                    }
                }
            }
            let inner = &mut inner[..n_inner];
            inner.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
            for &(_, c) in inner.iter() {
                if len == stack.len() {
                    return false; // deeper than any sane tree: no claim
                }
                stack[len] = c;
                len += 1;
            }
        }
        true
    }
}
