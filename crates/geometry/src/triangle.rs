//! Watertight ray/triangle intersection: Woop, Benthin, Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013. No back-face culling (rays leave closed meshes from inside).
//!
//! # The math
//!
//! Let `d` be the ray direction and `k_z = argmax |d_k|`, `k_x = (k_z + 1) mod 3`,
//! `k_y = (k_x + 1) mod 3` (`k_x` and `k_y` swapped when `d[k_z] < 0`, which keeps the winding of
//! the projected triangles). With the shear constants
//!
//! ```text
//! S_x = d[k_x] / d[k_z],   S_y = d[k_y] / d[k_z],   S_z = 1 / d[k_z]
//! ```
//!
//! every vertex `v` is translated to the ray origin and sheared so that the ray becomes the
//! positive z axis through (0, 0):
//!
//! ```text
//! A = v − o,   A'_x = A[k_x] − S_x·A[k_z],   A'_y = A[k_y] − S_y·A[k_z],   A'_z = S_z·A[k_z]
//! ```
//!
//! The 2-D edge functions of the projected triangle (A, B, C) = (v0, v1, v2) at the origin are
//!
//! ```text
//! U = C_x·B_y − C_y·B_x   (edge B→C, weight of v0)
//! V = A_x·C_y − A_y·C_x   (edge C→A, weight of v1)
//! W = B_x·A_y − B_y·A_x   (edge A→B, weight of v2)
//! ```
//!
//! The ray hits iff U, V, W do not have opposite signs (either orientation: no culling) and
//! `det = U + V + W ≠ 0`; then `t = (U·A'_z + V·B'_z + W·C'_z) / det`, `b1 = V / det`,
//! `b2 = W / det`. Each edge function depends only on the two (transformed) end points of its edge,
//! and the transformed coordinates of a vertex depend only on the vertex, so two triangles sharing
//! an edge compute bit-identical edge functions of opposite sign: no ray slips between them.
//! The paper recomputes the three edge functions in f64 from the same f32 inputs when one of them
//! is exactly 0 in f32 (products of two f32 are exact in f64, so the sign is exact). Here the
//! fallback is taken whenever an f32 edge function is within its rounding bound of 0
//! (`|E| ≤ 2^-23·(|p| + |q|)` for `E = fl(p − q)`): that decision depends on the edge alone, so the
//! two triangles of an edge always agree, and every sign used is the exact sign for the computed
//! 2-D coordinates. (With the paper's rule, one triangle could use the f64 sign and its neighbour
//! a wrong f32 sign of the same edge when the ray passes within rounding of it.)
//!
//! # Tie-break (one report per crossing)
//!
//! The paper's test accepts U = 0, so a ray through a shared edge (or a vertex) is reported by every
//! triangle that touches it, which double counts crossings. Here a remaining exact zero is resolved
//! by symbolic perturbation of the ray to (ε, ε²) in the sheared plane: for the edge P→Q,
//! `E(P, Q)(δ) = E + δ_x (Q_y − P_y) + δ_y (P_x − Q_x)`, so the sign of a zero edge function is
//! `sign(Q_y − P_y)`, or `sign(P_x − Q_x)` when that is 0. This is antisymmetric under edge reversal,
//! so exactly one of two same-facing neighbours claims an edge hit, and at a vertex exactly one
//! triangle of the fan claims it. As all signs are exact, the reported triangles are exactly those
//! containing the perturbed point in the (computed) 2-D projection, so along any full line through
//! a closed, consistently oriented mesh the numbers of front (`det > 0`) and back hits are equal
//! (a silhouette edge reports both or neither). Barycentrics and `t` still use the unperturbed
//! values.

use glam::{Mat3A, Vec3A};

/// Precomputed per-ray data of the watertight test (shear constants and axis permutation).
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    pub org: Vec3A,
    pub kx: usize,
    pub ky: usize,
    pub kz: usize,
    pub sx: f32,
    pub sy: f32,
    pub sz: f32,
    /// The translation-free part of the transform as a matrix:
    /// `shear * (v − org) = (A[kx] − sx·A[kz], A[ky] − sy·A[kz], sz·A[kz])`. Its columns are unit
    /// vectors except column `kz`, so every output is one product plus exact zeros: bit-identical
    /// to the scalar formulas of the paper.
    pub shear: Mat3A,
}

impl WatertightRay {
    /// Precompute the shear for a ray. `dir` need not be unit length (t is then in units of
    /// `dir`); a zero or non-finite `dir` gives a ray that hits nothing.
    #[inline]
    pub fn new(org: Vec3A, dir: Vec3A) -> Self {
        let ad = dir.abs();
        let kz = if ad.x >= ad.y && ad.x >= ad.z {
            0
        } else if ad.y >= ad.z {
            1
        } else {
            2
        };
        // (k_x, k_y) = (k_z + 1, k_z + 2) mod 3, swapped when d[k_z] < 0.
        let neg = dir[kz] < 0.0;
        let (kx, ky) = match (kz, neg) {
            (0, false) => (1, 2),
            (0, true) => (2, 1),
            (1, false) => (2, 0),
            (1, true) => (0, 2),
            (_, false) => (0, 1),
            (_, true) => (1, 0),
        };
        let sz = 1.0 / dir[kz];
        let sx = dir[kx] * sz;
        let sy = dir[ky] * sz;
        // Column j of the shear is d(output)/d(v_j): unit x for k_x, unit y for k_y.
        let k = Vec3A::new(-sx, -sy, sz);
        let (x, y) = (Vec3A::X, Vec3A::Y);
        let shear = match (kz, neg) {
            (0, false) => Mat3A::from_cols(k, x, y),
            (0, true) => Mat3A::from_cols(k, y, x),
            (1, false) => Mat3A::from_cols(y, k, x),
            (1, true) => Mat3A::from_cols(x, k, y),
            (_, false) => Mat3A::from_cols(x, y, k),
            (_, true) => Mat3A::from_cols(y, x, k),
        };
        WatertightRay {
            org,
            kx,
            ky,
            kz,
            sx,
            sy,
            sz,
            shear,
        }
    }

    /// Returns `(t, b1, b2)` (hit point = (1 − b1 − b2)·v0 + b1·v1 + b2·v2) when the ray hits the
    /// triangle with `tmin < t < tmax`.
    #[inline]
    pub fn intersect(
        &self,
        v0: Vec3A,
        v1: Vec3A,
        v2: Vec3A,
        tmin: f32,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        self.intersect_hit(v0, v1, v2, tmin, tmax)
            .map(|h| (h.t, h.b1, h.b2))
    }

    /// Like [`intersect`](Self::intersect), also reporting which face was hit as decided by the
    /// test itself (`front = det > 0`: the ray arrives from the side the CCW normal
    /// `cross(v1 − v0, v2 − v0)` points to). Use this facing, not `dir · n`, when counting
    /// crossings: for a triangle seen exactly edge-on the sign of `dir · n` is rounding noise,
    /// while `front` is exactly consistent with which triangles were reported.
    #[inline]
    pub fn intersect_hit(
        &self,
        v0: Vec3A,
        v1: Vec3A,
        v2: Vec3A,
        tmin: f32,
        tmax: f32,
    ) -> Option<TriHit> {
        let a = self.shear * (v0 - self.org);
        let b = self.shear * (v1 - self.org);
        let c = self.shear * (v2 - self.org);
        let (pu, qu) = (c.x * b.y, c.y * b.x);
        let (pv, qv) = (a.x * c.y, a.y * c.x);
        let (pw, qw) = (b.x * a.y, b.y * a.x);
        let (u, v, w) = (pu - qu, pv - qv, pw - qw);
        if uncertain(u, pu, qu) || uncertain(v, pv, qv) || uncertain(w, pw, qw) {
            return intersect_exact(a, b, c, tmin, tmax);
        }
        // All three signs are exact and non-zero here.
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        let t_scaled = u * a.z + v * b.z + w * c.z;
        let rcp = 1.0 / det;
        let t = t_scaled * rcp;
        if t > tmin && t < tmax {
            Some(TriHit {
                t,
                b1: v * rcp,
                b2: w * rcp,
                front: det > 0.0,
            })
        } else {
            None
        }
    }
}

/// Result of [`WatertightRay::intersect_hit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
    /// The ray arrives from the side the CCW normal points to (`det > 0`; entering a closed
    /// CCW-outward mesh).
    pub front: bool,
}

/// True when the f32 edge function `e = fl(p − q)` (with `p`, `q` the rounded products) might
/// not have the sign of the exact value: `|e| ≤ 2^-23 (|p| + |q|)` (twice the rounding bound), or
/// it is in the subnormal range. Depends on the edge only, so both triangles sharing an edge decide
/// alike.
#[inline(always)]
fn uncertain(e: f32, p: f32, q: f32) -> bool {
    e.abs() <= (p.abs() + q.abs()) * f32::EPSILON + f32::MIN_POSITIVE
}

/// Slow path: the three edge functions in f64 from the same f32 inputs (products of two f32 are
/// exact in f64, so the sign of each is exact; the paper does this when one is exactly 0), exact
/// zeros resolved by the tie-break, then `t` and the barycentrics in f64.
#[cold]
#[inline(never)]
fn intersect_exact(a: Vec3A, b: Vec3A, c: Vec3A, tmin: f32, tmax: f32) -> Option<TriHit> {
    let (ax, ay) = (a.x as f64, a.y as f64);
    let (bx, by) = (b.x as f64, b.y as f64);
    let (cx, cy) = (c.x as f64, c.y as f64);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let su = if u == 0.0 { tie(b, c) } else { u };
    let sv = if v == 0.0 { tie(c, a) } else { v };
    let sw = if w == 0.0 { tie(a, b) } else { w };
    if (su < 0.0 || sv < 0.0 || sw < 0.0) && (su > 0.0 || sv > 0.0 || sw > 0.0) {
        return None;
    }
    // Same signs (or zeros): the sum has the exact sign, and is 0 only for a triangle degenerate
    // in projection.
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let t_scaled = u * a.z as f64 + v * b.z as f64 + w * c.z as f64;
    let t = (t_scaled / det) as f32;
    if t > tmin && t < tmax {
        Some(TriHit {
            t,
            b1: (v / det) as f32,
            b2: (w / det) as f32,
            front: det > 0.0,
        })
    } else {
        None
    }
}

/// Sign (as a value) of the edge function of the edge `p → q` (`E = q_x·p_y − q_y·p_x`) when the
/// ray is perturbed to (ε, ε²): `q_y − p_y`, or `p_x − q_x` when that is 0. Exact (the sign of a
/// floating-point difference is exact); antisymmetric in `(p, q)`.
#[inline]
fn tie(p: Vec3A, q: Vec3A) -> f64 {
    let dy = q.y - p.y;
    (if dy != 0.0 { dy } else { p.x - q.x }) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::vec3a;

    #[test]
    fn hits_both_faces_with_barycentrics() {
        let (v0, v1, v2) = (
            vec3a(0.0, 0.0, 0.0),
            vec3a(1.0, 0.0, 0.0),
            vec3a(0.0, 1.0, 0.0),
        );
        let down = WatertightRay::new(vec3a(0.25, 0.5, 2.0), vec3a(0.0, 0.0, -1.0));
        let (t, b1, b2) = down.intersect(v0, v1, v2, 0.0, f32::INFINITY).unwrap();
        assert_eq!((t, b1, b2), (2.0, 0.25, 0.5));
        let up = WatertightRay::new(vec3a(0.25, 0.5, -3.0), vec3a(0.0, 0.0, 1.0));
        assert_eq!(
            up.intersect(v0, v1, v2, 0.0, f32::INFINITY),
            Some((3.0, 0.25, 0.5))
        );
        // Interval is open on both ends.
        assert!(down.intersect(v0, v1, v2, 2.0, 10.0).is_none());
        assert!(down.intersect(v0, v1, v2, 0.0, 2.0).is_none());
        // Misses outside and behind.
        let out = WatertightRay::new(vec3a(0.75, 0.5, 2.0), vec3a(0.0, 0.0, -1.0));
        assert!(out.intersect(v0, v1, v2, 0.0, f32::INFINITY).is_none());
        let away = WatertightRay::new(vec3a(0.25, 0.25, 2.0), vec3a(0.0, 0.0, 1.0));
        assert!(away.intersect(v0, v1, v2, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn shared_edge_and_vertex_reported_once() {
        // A square split along its diagonal, and a fan of 6 triangles around the origin.
        let sq = [
            vec3a(0.0, 0.0, 0.0),
            vec3a(1.0, 0.0, 0.0),
            vec3a(1.0, 1.0, 0.0),
            vec3a(0.0, 1.0, 0.0),
        ];
        let tris = [[sq[0], sq[1], sq[2]], [sq[0], sq[2], sq[3]]];
        for o in [
            vec3a(0.5, 0.5, 1.0),
            vec3a(0.0, 0.0, 1.0),
            vec3a(0.0, 0.5, 1.0),
            vec3a(0.3, 0.3, 1.0),
        ] {
            for dz in [-1.0f32, 1.0] {
                let r = WatertightRay::new(o * vec3a(1.0, 1.0, -dz), vec3a(0.0, 0.0, dz));
                let n = tris
                    .iter()
                    .filter(|t| {
                        r.intersect(t[0], t[1], t[2], f32::NEG_INFINITY, f32::INFINITY)
                            .is_some()
                    })
                    .count();
                assert_eq!(n, 1, "origin {o} dz {dz}");
            }
        }
        let ring: Vec<Vec3A> = (0..6)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / 6.0;
                vec3a(a.cos(), a.sin(), 0.1 * (i % 2) as f32)
            })
            .collect();
        for dz in [-1.0f32, 1.0] {
            let r = WatertightRay::new(vec3a(0.0, 0.0, -dz), vec3a(0.0, 0.0, dz));
            let n = (0..6)
                .filter(|&i| {
                    r.intersect(
                        Vec3A::ZERO,
                        ring[i],
                        ring[(i + 1) % 6],
                        f32::NEG_INFINITY,
                        f32::INFINITY,
                    )
                    .is_some()
                })
                .count();
            assert_eq!(n, 1);
        }
    }

    #[test]
    fn degenerate_ray_hits_nothing() {
        let r = WatertightRay::new(vec3a(0.2, 0.2, 1.0), Vec3A::ZERO);
        let hit = r.intersect(
            vec3a(0.0, 0.0, 0.0),
            vec3a(1.0, 0.0, 0.0),
            vec3a(0.0, 1.0, 0.0),
            0.0,
            f32::INFINITY,
        );
        assert!(hit.is_none());
    }
}
