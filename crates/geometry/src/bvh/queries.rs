//! The ray queries of [`Accel`]: closest hit, first hits both ways along a line, occlusion, all
//! hits along a ray, the length of a segment inside the mesh and point containment.

use std::mem::MaybeUninit;

use glam::{Vec3, Vec3A};

#[cfg(target_arch = "x86_64")]
use super::traverse::{Avx2, avx2_available};
use super::traverse::{BoxKernel, BoxRay, Portable};
use super::{Accel, Hit, valid_ray};
use crate::triangle::{TriHit, WatertightRay};

/// Defines a query `$name` that runs its generic body `$body::<K>` with the AVX2 box kernel when
/// the CPU has it ([`avx2_available`]; the body is then compiled with AVX2 enabled, through the
/// wrapper `$avx2`) and with the portable kernel otherwise. Both give identical results.
macro_rules! dispatched {
    ($(#[$m:meta])* $vis:vis fn $name:ident $(<$($g:ident: $b:path),*>)?
        (&self $(, $a:ident: $t:ty)*) -> $r:ty => $avx2:ident, $body:ident) => {
        $(#[$m])*
        #[inline]
        $vis fn $name $(<$($g: $b),*>)? (&self $(, $a: $t)*) -> $r {
            #[cfg(target_arch = "x86_64")]
            if avx2_available() {
                // SAFETY: the CPU supports AVX2 (checked at run time).
                return unsafe { self.$avx2($($a),*) };
            }
            self.$body::<Portable $($(, $g)*)?>($($a),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
        unsafe fn $avx2 $(<$($g: $b),*>)? (&self $(, $a: $t)*) -> $r {
            self.$body::<Avx2 $($(, $g)*)?>($($a),*)
        }
    };
}

/// A raw hit on a line: BVH-order primitive, the triangle test's result, line parameter `s`.
type LineHit = (u32, TriHit, f32);

/// Fixed, irrational-looking direction used by [`Accel::contains`] (avoids axis-aligned edges).
const CONTAINS_DIR: Vec3 = Vec3::new(0.548_546_7, 0.627_302_6, 0.552_787_9);

impl Accel {
    /// Closest hit with `tmin < t < tmax` along `origin + t·dir` (`dir` unit length); among hits
    /// at the same `t`, the one with the smallest triangle index.
    #[inline]
    pub fn closest(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        if !valid_ray(dir, tmin, tmax)
            || self.tris.is_empty()
            || self.out_of_reach(origin, dir, tmax)
        {
            return None;
        }
        let (prim, th) = self.closest_bvh(origin.into(), dir.into(), tmin, tmax)?;
        Some(self.make_hit(prim, th, dir))
    }

    /// Whether the segment `origin + t·dir`, `t < tmax`, lies within the clearance of its origin
    /// (`clearance` module): no triangle can be hit, the BVH is not asked.
    #[inline(always)]
    pub(super) fn out_of_reach(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let reach = self.clearance.reach(origin.into());
        reach > 0.0 && tmax * dir.length() <= reach
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

    dispatched! {
        /// The closest hit as a BVH-order primitive and the triangle test's result.
        pub(super) fn closest_bvh(&self, o: Vec3A, d: Vec3A, tmin: f32, tmax: f32) -> Option<(u32, TriHit)>
            => closest_bvh_avx2, closest_bvh_k
    }

    #[inline(always)]
    fn closest_bvh_k<K: BoxKernel>(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmin: f32,
        tmax: f32,
    ) -> Option<(u32, TriHit)> {
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        let mut best_t = tmax;
        let mut best: Option<(u32, TriHit)> = None;
        self.bvh_traverse::<K>(&br, d, tmax, |first, count| {
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
    fn line_hit(&self, h: Option<LineHit>, dir: Vec3) -> Option<Hit> {
        h.map(|(prim, th, s)| Hit {
            t: s,
            ..self.make_hit(prim, th, dir)
        })
    }

    dispatched! {
        /// The traversal of [`first_hits_both_ways`](Self::first_hits_both_ways), without
        /// building the hits.
        fn both_ways_raw(&self, x: Vec3, dir: Vec3, ahead: (f32, f32), behind: (f32, f32))
            -> (Option<LineHit>, Option<LineHit>)
            => both_ways_raw_avx2, both_ways_raw_k
    }

    #[inline(always)]
    fn both_ways_raw_k<K: BoxKernel>(
        &self,
        x: Vec3,
        dir: Vec3,
        ahead: (f32, f32),
        behind: (f32, f32),
    ) -> (Option<LineHit>, Option<LineHit>) {
        let s_lo = ahead.0.min(behind.0);
        let s_hi = ahead.1.max(behind.1);
        let len = s_hi - s_lo;
        if !valid_ray(dir, 0.0, len) || self.tris.is_empty() {
            return (None, None);
        }
        let (o, d) = (Vec3A::from(x + s_lo * dir), Vec3A::from(dir));
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, 0.0);
        let mut fwd: Option<LineHit> = None;
        let mut back: Option<LineHit> = None;
        let tri_of = |prim: u32| self.prim_tri[prim as usize];
        let cutoff = |fwd: &Option<LineHit>| {
            let a = fwd.map_or(ahead.1, |(_, _, s)| s);
            (a.max(behind.1) - s_lo).min(len)
        };
        self.bvh_traverse::<K>(&br, d, len, |first, count| {
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
        if !valid_ray(dir, tmin, tmax)
            || self.tris.is_empty()
            || self.out_of_reach(origin, dir, tmax)
        {
            return false;
        }
        self.occluded_bvh(origin, dir, tmin, tmax)
    }

    dispatched! {
        fn occluded_bvh(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool
            => occluded_avx2, occluded_k
    }

    #[inline(always)]
    fn occluded_k<K: BoxKernel>(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let mut hit = false;
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        self.bvh_traverse::<K>(&br, d, tmax, |first, count| {
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
        f: impl FnMut(u32, TriHit),
    ) {
        if !valid_ray(dir, tmin, tmax) || self.tris.is_empty() {
            return;
        }
        self.for_each_hit_bvh(origin, dir, tmin, tmax, f);
    }

    dispatched! {
        fn for_each_hit_bvh<F: FnMut(u32, TriHit)>(
            &self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, f: F) -> ()
            => for_each_hit_avx2, for_each_hit_k
    }

    #[inline(always)]
    fn for_each_hit_k<K: BoxKernel, F: FnMut(u32, TriHit)>(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        mut f: F,
    ) {
        let (o, d) = (Vec3A::from(origin), Vec3A::from(dir));
        let wr = WatertightRay::new(o, d);
        let br = BoxRay::new(o, d, tmin);
        self.bvh_traverse::<K>(&br, d, tmax, |first, count| {
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
        self.inside_length_by(a, b, |dir, push| {
            self.for_each_hit(a, dir, 0.0, f32::INFINITY, |_, th| push(th));
        })
    }

    /// [`inside_length`](Self::inside_length) with the crossings along the ray from `a` in the
    /// direction `dir` of `b − a` (every hit with `0 < t < ∞`) reported by `hits(dir, push)`, which
    /// must call `push` once per hit of the watertight test (in any order). The result depends on
    /// the set of hits only, so any exact source of candidates (the BVH, per-direction triangle
    /// lists, all triangles) gives the same answer.
    #[inline]
    pub(crate) fn inside_length_by(
        &self,
        a: Vec3,
        b: Vec3,
        hits: impl FnOnce(Vec3, &mut dyn FnMut(TriHit)),
    ) -> f32 {
        let seg = b - a;
        let len = seg.length();
        if !(len > 0.0 && len.is_finite()) {
            return 0.0;
        }
        let dir = seg / len;
        let mut xs = StackVec::<(f32, bool), 16>::new();
        hits(dir, &mut |th: TriHit| xs.push((th.t, th.front)));
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
