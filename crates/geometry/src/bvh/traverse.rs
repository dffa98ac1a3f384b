//! The CWBVH traversal kernel of [`Accel`]: the conservative child-box test (eight quantised
//! child boxes against one ray, widened to f32 with SSE2) and the depth-first traversal with its
//! fixed node stack and octant-order tables. See the [`bvh`](super) module doc for why the box
//! test is our own.

use std::mem::MaybeUninit;

use glam::{Vec3A, Vec4};
use obvhs::cwbvh::node::CwBvhNode;

use super::Accel;

/// Per-ray data of the conservative child-box test.
#[derive(Clone, Copy)]
pub(super) struct BoxRay {
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
    pub(super) fn new(org: Vec3A, dir: Vec3A, tmin: f32) -> Self {
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

    /// The per-node constants of the slab test shared by both kernels: the quantisation scale
    /// `e/d`, and the slab offsets `(p − o)/d` minus and plus the slack of the module doc.
    #[inline(always)]
    fn node_frame(&self, node: &CwBvhNode) -> (Vec3A, Vec3A, Vec3A) {
        let e = node.compute_extent();
        let po = Vec3A::from(node.p) - self.org;
        let scale = e * self.inv;
        let off = po * self.inv;
        let slack = (e * 255.0 + po.abs()) * self.inv.abs() * BOX_SLACK;
        (scale, off - slack, off + slack)
    }

    /// Per axis, the eight children's quantised planes the ray meets first and last (min and
    /// max swapped where the direction is negative), widened by `widen`.
    #[inline(always)]
    fn near_far<T>(&self, node: &CwBvhNode, widen: impl Fn(&[u8; 8]) -> T) -> [(T, T); 3] {
        let pick = |neg: bool, lo: &[u8; 8], hi: &[u8; 8]| {
            let (l, h) = (widen(lo), widen(hi));
            if neg { (h, l) } else { (l, h) }
        };
        [
            pick(self.neg[0], &node.child_min_x, &node.child_max_x),
            pick(self.neg[1], &node.child_min_y, &node.child_max_y),
            pick(self.neg[2], &node.child_min_z, &node.child_max_z),
        ]
    }
}

/// The child-box test of the traversal: the children of `node` whose (grown, see the module doc)
/// box the ray meets for some `t` in `[tmin, tmax]` (bit `i` for child slot `i`; empty slots may
/// be set), and their entry distances. Both kernels compute the same IEEE operations in the same
/// order (no FMA), so they return identical bits (`kernels_agree_bit_for_bit`).
pub(super) trait BoxKernel {
    fn intersect8(br: &BoxRay, node: &CwBvhNode, tmax: f32) -> (u32, [f32; 8]);
}

/// SSE2, two lanes of four children: the x86-64 baseline (and plain `Vec4` elsewhere).
pub(super) struct Portable;

impl BoxKernel for Portable {
    #[inline(always)]
    fn intersect8(br: &BoxRay, node: &CwBvhNode, tmax: f32) -> (u32, [f32; 8]) {
        let (scale, lo, hi) = br.node_frame(node);
        let [(nx, fx), (ny, fy), (nz, fz)] = br.near_far(node, bytes_to_f32);
        let mut mask = 0u32;
        let mut near = [0.0f32; 8];
        for h in 0..2 {
            let t0 = (nx[h] * scale.x + Vec4::splat(lo.x))
                .max(ny[h] * scale.y + Vec4::splat(lo.y))
                .max(nz[h] * scale.z + Vec4::splat(lo.z))
                .max(Vec4::splat(br.tmin));
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

/// AVX2, all eight children in one 256-bit lane. Only reachable through the `*_avx2` query
/// entry points, which run when [`avx2_available`] says so.
#[cfg(target_arch = "x86_64")]
pub(super) struct Avx2;

#[cfg(target_arch = "x86_64")]
impl BoxKernel for Avx2 {
    #[inline(always)]
    fn intersect8(br: &BoxRay, node: &CwBvhNode, tmax: f32) -> (u32, [f32; 8]) {
        // SAFETY: `Avx2` is only used inside functions compiled with AVX2 enabled, which are only
        // called after `avx2_available()` confirmed the CPU has it.
        unsafe { intersect8_avx2(br, node, tmax) }
    }
}

/// [`Portable::intersect8`] with 8-wide vectors: the same operations, operands and order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn intersect8_avx2(br: &BoxRay, node: &CwBvhNode, tmax: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::*;
    let (scale, lo, hi) = br.node_frame(node);
    let widen = |v: &[u8; 8]| {
        let b = _mm_cvtsi64_si128(i64::from_le_bytes(*v));
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(b))
    };
    let [(nx, fx), (ny, fy), (nz, fz)] = br.near_far(node, widen);
    let plane = |q: __m256, s: f32, o: f32| {
        _mm256_add_ps(_mm256_mul_ps(q, _mm256_set1_ps(s)), _mm256_set1_ps(o))
    };
    let t0 = _mm256_max_ps(
        _mm256_max_ps(
            _mm256_max_ps(plane(nx, scale.x, lo.x), plane(ny, scale.y, lo.y)),
            plane(nz, scale.z, lo.z),
        ),
        _mm256_set1_ps(br.tmin),
    );
    let t1 = _mm256_min_ps(
        _mm256_min_ps(
            _mm256_min_ps(plane(fx, scale.x, hi.x), plane(fy, scale.y, hi.y)),
            plane(fz, scale.z, hi.z),
        ),
        _mm256_set1_ps(tmax),
    );
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32;
    let mut near = [0.0f32; 8];
    // SAFETY: `near` holds eight f32; unaligned store.
    unsafe { _mm256_storeu_ps(near.as_mut_ptr(), t0) };
    (mask, near)
}

/// Whether this CPU runs the AVX2 kernel: detected once; `TRANSLUCENT_ISA=portable` in the
/// environment forces the portable kernel (for measurements; results are identical).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(super) fn avx2_available() -> bool {
    use std::sync::OnceLock;
    static AVX2: OnceLock<bool> = OnceLock::new();
    *AVX2.get_or_init(|| {
        std::env::var("TRANSLUCENT_ISA").map_or(true, |v| v != "portable")
            && std::arch::is_x86_feature_detected!("avx2")
    })
}

impl Accel {
    /// Depth-first traversal of the CWBVH: `leaf(first, count)` is called for every leaf whose
    /// box the ray meets within `[tmin, tmax]` (primitives `first..first + count` of `tris`) and
    /// returns the new `tmax` (−∞ ends the traversal). Inner children are visited in the octant
    /// order of the build (front to back for the ray's direction octant), and a child popped from
    /// the stack is skipped when its entry distance exceeds the current `tmax`.
    #[inline(always)]
    pub(super) fn bvh_traverse<K: BoxKernel>(
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
            let (hits, near) = K::intersect8(br, node, tmax);
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

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg32;

    use super::*;
    use crate::Shape;

    /// The AVX2 kernel returns the portable kernel's bits (mask and entry distances) at every
    /// node of a real tree, for rays from inside, outside and far away, with axis-parallel and
    /// nearly axis-parallel directions (the `1/d` clamp) and `tmin`/`tmax` cutting the range.
    #[test]
    fn kernels_agree_bit_for_bit() {
        #[cfg(target_arch = "x86_64")]
        {
            if !std::arch::is_x86_feature_detected!("avx2") {
                eprintln!("no AVX2 on this CPU: only the portable kernel runs, nothing to compare");
                return;
            }
            let mesh = Shape::from_name("blob")
                .expect("built-in shape")
                .build()
                .expect("valid blob");
            let accel = Accel::new(mesh);
            let mut rng = Pcg32::seed_from_u64(17);
            let (mut rays, mut hits) = (0, 0);
            for i in 0..4000 {
                let o = Vec3::new(
                    rng.random_range(-1.5..1.5f32),
                    rng.random_range(-1.5..1.5f32),
                    rng.random_range(-1.5..1.5f32),
                ) * if i % 4 == 0 { 40.0 } else { 1.0 };
                let mut d = Vec3::new(
                    rng.random_range(-1.0..1.0f32),
                    rng.random_range(-1.0..1.0f32),
                    rng.random_range(-1.0..1.0f32),
                );
                if i % 2 == 1 {
                    // Aimed at the object (random directions from far away mostly miss it).
                    d = d * 0.4 - o;
                }
                match i % 5 {
                    0 => d.x = 0.0,
                    1 => d.y = 1e-20 * d.y.signum(),
                    2 => (d.x, d.z) = (0.0, -0.0),
                    _ => {}
                }
                let Some(d) = d.try_normalize() else { continue };
                let tmin = if i % 3 == 0 {
                    rng.random_range(0.0..0.5f32)
                } else {
                    0.0
                };
                let tmax = if i % 2 == 0 {
                    rng.random_range(0.1..2.0f32)
                } else {
                    f32::INFINITY
                };
                let br = BoxRay::new(o.into(), d.into(), tmin);
                for node in &accel.bvh.nodes {
                    let (m0, n0) = Portable::intersect8(&br, node, tmax);
                    // SAFETY: AVX2 was detected above.
                    let (m1, n1) = unsafe { intersect8_avx2(&br, node, tmax) };
                    assert_eq!(m0, m1, "ray {o} {d} [{tmin}, {tmax}]");
                    assert_eq!(n0.map(f32::to_bits), n1.map(f32::to_bits), "ray {o} {d}");
                    hits += m0.count_ones();
                }
                rays += 1;
            }
            assert!(
                rays > 3000 && accel.bvh.nodes.len() > 100 && hits > 5 * rays,
                "{rays} {hits}"
            );
        }
    }
}
