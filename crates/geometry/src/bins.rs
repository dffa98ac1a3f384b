//! Closest hits of a pinhole camera's primary rays by per-pixel candidate lists (screen-space
//! binning), an exact replacement for [`Accel::closest`] on those rays.
//!
//! A ray from the camera origin through a film point inside pixel (x, y) can only hit a triangle
//! whose perspective projection contains that film point, so only triangles whose projected
//! bounding box (widened by [`MARGIN`] pixels for the rounding of the ray generation) overlaps
//! the pixel are candidates. [`PixelBins::build`] projects every triangle once per view and
//! stores, per pixel, its candidates sorted by a lower bound `lb` of any `t` the watertight test
//! can report for them; [`PixelBins::closest`] tests them in that order with exactly the
//! arithmetic and tie-break of [`Accel::closest`] (smallest `t`, then smallest original triangle
//! index) and stops at the first candidate with `lb > t_best`. The answer is the minimum of
//! (t, triangle index) over a superset of the triangles the ray can hit, so it does not depend on
//! the order of the tests and equals the BVH's answer.
//!
//! The lower bound. The watertight test (Woop et al. 2013) reports `t` as a convex combination of
//! the corners' `q_i = (v_i − o)[k]/d[k]` (`k` the dominant axis of the unit direction `d`).
//! Write `v_i − o = s_i·d + w_i` with `w_i ⊥ d`. Then `|w_i[k]/d[k]| ≤ √2·|w_i|` (as
//! `|d[k]| ≥ 1/√3`), so `q_i ≥ s_i − √2·|w_i|`; with `f` the unit optical axis and
//! `z_i = (v_i − o)·f`, `z_i ≤ s_i + |w_i|` when `s_i ≥ 0`. A ray that meets the triangle passes
//! within its diameter `D` (longest edge) of every corner, so `|w_i| ≤ D` and, when
//! `min z_i > 2.5·D` (every corner then lies ahead along `d`), `t ≥ min_i z_i − (1 + √2)·D`. We use
//! `lb = min_i z_i − 2.5·D − 10⁻⁴·min_i z_i` (the last term covers the f32 rounding of both
//! sides). This holds for ill-conditioned (edge-on) hits too, whose `t` may lie anywhere between
//! the corners' `q_i`.
//!
//! When a corner lies on or behind the camera plane, when the projection is not finite, or when
//! the lists would exceed [`MAX_ENTRIES_PER_PIXEL`] entries per pixel on average (huge
//! overlapping triangles), [`PixelBins::build`] returns `None` and the caller keeps the BVH.
//!
//! Continued rays. A ray that crosses an index-matched boundary goes on along the camera ray's
//! line from an origin a few ulps off it; [`PixelBins::closest_next`] answers its closest-hit
//! queries from the same list (the argument is in its docs), and a [`FilmCursor`] carries one
//! camera ray's scan from query to query so that the edge tests are not repeated.
//!
//! Cost: one pass over the triangles per view (a few ms for 80 k triangles) and 8
//! bytes per (triangle, pixel) overlap; a camera ray then costs a few triangle tests instead of
//! a BVH descent.

use glam::{Vec3, Vec3A};

use crate::bvh::{Accel, Hit};
use crate::triangle::{TriHit, WatertightRay};

/// Widening of every projected bounding box, in pixels. The film position of a generated ray and
/// the projection of a point on it agree to about 10⁻⁴ pixel at 4k resolution.
pub const MARGIN: f32 = 1.0 / 16.0;

/// How far (in pixels) the origin of a continued camera ray may project from the camera ray's
/// film point for [`PixelBins::closest_next`] to answer it (a small part of [`MARGIN`]; the
/// offsets after a boundary crossing are about 10⁻⁵ of the distance).
pub const CONTINUATION_OFFSET: f32 = 1.0 / 20.0;

/// How many candidates a [`FilmCursor`] remembers.
pub const CURSOR_CAPACITY: usize = 24;

/// One camera ray's walk through its pixel's candidate list ([`PixelBins::cursor`]): how far
/// the list has been scanned for the film point `(fx, fy)` and which of the scanned candidates
/// passed the edge test there (the others cannot be met by the camera ray or by a ray
/// continuing it, [`PixelBins::closest_next`]).
#[derive(Clone, Debug)]
pub struct FilmCursor<'a> {
    list: &'a [(f32, u32)],
    fx: f32,
    fy: f32,
    scanned: usize,
    passed: [u32; CURSOR_CAPACITY],
    /// Candidates that passed; beyond [`CURSOR_CAPACITY`] the cursor forgets them all.
    n_passed: usize,
}

/// Beyond this mean number of candidates per pixel the bins are not built.
pub const MAX_ENTRIES_PER_PIXEL: u64 = 256;

/// Per-pixel candidate lists of triangles for rays through one centre of projection (module
/// docs): `entries[offsets[p]..offsets[p + 1]]` are pixel `p`'s (lb, triangle in BVH order),
/// sorted by (lb, triangle).
#[derive(Clone, Debug)]
pub(crate) struct Lists {
    pub(crate) width: u32,
    pub(crate) height: u32,
    offsets: Vec<u32>,
    entries: Vec<(f32, u32)>,
}

impl Lists {
    /// `project(p) = (px, py, z)`: film position in pixels and depth along the unit optical axis
    /// (module docs); `None` or a non-finite or non-positive depth for any corner: no lists.
    /// `sorted`: each list in the order of (lb, triangle) (for closest-hit queries that stop
    /// early); otherwise in the order of the triangles.
    pub(crate) fn build(
        accel: &Accel,
        width: u32,
        height: u32,
        sorted: bool,
        project: impl Fn(Vec3) -> Option<(f32, f32, f32)>,
    ) -> Option<Lists> {
        let tris = accel.bvh_triangles();
        let pixels = width as usize * height as usize;
        if pixels == 0 || tris.is_empty() || tris.len() >= u32::MAX as usize {
            return None;
        }
        // Per triangle: pixel box (x0, x1, y0, y1), inclusive (x0 > x1: empty), and lb.
        let mut boxes: Vec<([u32; 4], f32)> = Vec::with_capacity(tris.len());
        let mut total: u64 = 0;
        let range = |lo: f32, hi: f32, n: u32| -> Option<(u32, u32)> {
            let (l, h) = ((lo - MARGIN).floor(), (hi + MARGIN).floor());
            if h < 0.0 || l > (n - 1) as f32 {
                return None;
            }
            Some((l.max(0.0) as u32, h.min((n - 1) as f32) as u32))
        };
        for corners in tris {
            let mut lo = [f32::INFINITY; 2];
            let mut hi = [f32::NEG_INFINITY; 2];
            let mut z_min = f32::INFINITY;
            for &v in corners {
                let (px, py, z) = project(v)?;
                if !(px.is_finite() && py.is_finite() && z.is_finite() && z > 0.0) {
                    return None;
                }
                lo = [lo[0].min(px), lo[1].min(py)];
                hi = [hi[0].max(px), hi[1].max(py)];
                z_min = z_min.min(z);
            }
            let [a, b, c] = *corners;
            let diameter = (b - a).length().max((c - b).length()).max((a - c).length());
            let lb = z_min - 2.5 * diameter - 1e-4 * z_min;
            match (range(lo[0], hi[0], width), range(lo[1], hi[1], height)) {
                (Some((x0, x1)), Some((y0, y1))) => {
                    total += (x1 - x0 + 1) as u64 * (y1 - y0 + 1) as u64;
                    boxes.push(([x0, x1, y0, y1], lb));
                }
                _ => boxes.push(([1, 0, 1, 0], lb)),
            }
        }
        if total > MAX_ENTRIES_PER_PIXEL * pixels as u64 || total >= u32::MAX as u64 {
            return None;
        }
        let each = |b: &[u32; 4], f: &mut dyn FnMut(usize)| {
            for y in b[2]..=b[3] {
                for x in b[0]..=b[1] {
                    f(y as usize * width as usize + x as usize);
                }
            }
        };
        let mut offsets = vec![0u32; pixels + 1];
        for (b, _) in &boxes {
            if b[0] <= b[1] {
                each(b, &mut |p| offsets[p + 1] += 1);
            }
        }
        for p in 0..pixels {
            offsets[p + 1] += offsets[p];
        }
        let mut fill = offsets.clone();
        let mut entries = vec![(0.0f32, 0u32); total as usize];
        for (prim, (b, lb)) in boxes.iter().enumerate() {
            if b[0] <= b[1] {
                each(b, &mut |p| {
                    entries[fill[p] as usize] = (*lb, prim as u32);
                    fill[p] += 1;
                });
            }
        }
        if sorted {
            for p in 0..pixels {
                entries[offsets[p] as usize..offsets[p + 1] as usize]
                    .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            }
        }
        Some(Lists {
            width,
            height,
            offsets,
            entries,
        })
    }

    /// The candidates of pixel (x, y), which must lie inside the film.
    #[inline]
    pub(crate) fn at(&self, x: u32, y: u32) -> &[(f32, u32)] {
        let p = y as usize * self.width as usize + x as usize;
        &self.entries[self.offsets[p] as usize..self.offsets[p + 1] as usize]
    }

    pub(crate) fn mean_candidates(&self) -> f64 {
        self.entries.len() as f64 / (self.width as f64 * self.height as f64)
    }
}

/// The three edge lines of a triangle's projection onto a film (pixels or bins), `[a₀, b₀, c₀, a₁, …]` with
/// `aᵢ·x + bᵢ·y + cᵢ ≥ 0` on the inner side of edge `i`, each moved outward by [`EDGE_MARGIN`]
/// bins. A film point outside any of them cannot be the projection of a point of the triangle
/// (module docs), so the exact test is skipped there. Projections too thin to orient get
/// `(0, 0, 1)` edges (always pass).
pub(crate) type Edges = [f32; 9];

/// Outward shift of the edge lines, in bins: the query's projection error (≤ 0.0014 bin, module
/// docs) plus the rounding of the edge coefficients (about 10⁻⁷·N bins), with a wide margin.
pub const EDGE_MARGIN: f32 = 1.0 / 8.0;

/// The edges ([`Edges`]) of the triangle whose corners project to `p` (film bins).
pub(crate) fn edges(p: [(f32, f32); 3]) -> Edges {
    const PASS: Edges = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0];
    let mut e = [0.0f32; 9];
    for i in 0..3 {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let (xj, yj) = (p[j].0 as f64, p[j].1 as f64);
        let (xk, yk) = (p[k].0 as f64, p[k].1 as f64);
        let (a, b) = (yk - yj, xj - xk);
        let c = -(a * xj + b * yj);
        let len = a.hypot(b);
        let side = a * p[i].0 as f64 + b * p[i].1 as f64 + c;
        // Twice the projected area over the edge's length: the opposite corner's distance.
        if !(len > 0.0 && side.abs() > 1e-3 * len && side.is_finite()) {
            return PASS;
        }
        let sign = side.signum();
        e[3 * i] = (sign * a) as f32;
        e[3 * i + 1] = (sign * b) as f32;
        e[3 * i + 2] = (sign * c + EDGE_MARGIN as f64 * len) as f32;
    }
    e
}

/// Whether the film point (x, y) lies inside all three (widened) edges.
#[inline(always)]
pub(crate) fn inside_edges(e: &Edges, x: f32, y: f32) -> bool {
    (e[0] * x + e[1] * y + e[2] >= 0.0)
        & (e[3] * x + e[4] * y + e[5] >= 0.0)
        & (e[6] * x + e[7] * y + e[8] >= 0.0)
}

/// Per-pixel candidate lists of one pinhole camera view (module docs).
#[derive(Clone, Debug)]
pub struct PixelBins {
    lists: Lists,
    /// Per triangle (BVH order): its projection's edge lines in pixels, widened by
    /// [`EDGE_MARGIN`] pixels ([`Edges`]; [`closest_film`](Self::closest_film)).
    edges: Vec<Edges>,
    /// Camera origin the bins were built for.
    origin: Vec3,
}

impl PixelBins {
    /// Bin the triangles of `accel` for a `width × height` pinhole view from `origin`.
    ///
    /// `project(p)` maps a world point to `(px, py, z)`: its film position in this view's pixels
    /// (a ray from `origin` through film point (px, py) passes through `p`) and its depth
    /// `z = (p − origin)·f` along the unit optical axis `f`. It returns `None` (or a non-finite
    /// value) when it cannot project `p`; the bins are then not built.
    pub fn build(
        accel: &Accel,
        width: u32,
        height: u32,
        origin: Vec3,
        project: impl Fn(Vec3) -> Option<(f32, f32, f32)>,
    ) -> Option<PixelBins> {
        let lists = Lists::build(accel, width, height, true, &project)?;
        let edges = accel
            .bvh_triangles()
            .iter()
            .map(|c| edges(c.map(|v| project(v).map_or((0.0, 0.0), |(x, y, _)| (x, y)))))
            .collect();
        Some(PixelBins {
            lists,
            edges,
            origin,
        })
    }

    /// Image size the bins were built for.
    pub fn size(&self) -> (u32, u32) {
        (self.lists.width, self.lists.height)
    }

    /// Mean number of candidates per pixel (for statistics).
    pub fn mean_candidates(&self) -> f64 {
        self.lists.mean_candidates()
    }

    /// [`Accel::closest`]`(origin, dir, tmin, tmax)` for a ray from the build's camera origin
    /// through a film point in pixel (x, y) (module docs), bit for bit. `accel` must be the one
    /// the bins were built over; `x`, `y` outside the image give `None`.
    #[inline]
    pub fn closest(
        &self,
        accel: &Accel,
        x: u32,
        y: u32,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<Hit> {
        let (w, h) = self.size();
        if x >= w || y >= h {
            return None;
        }
        let list = self.lists.at(x, y);
        self.closest_in(accel, list, self.origin, dir, tmin, tmax, |t| t, |_| true)
    }

    /// [`closest`](Self::closest) for the ray from the camera origin through the film point
    /// `(fx, fy)` (pixels; `dir` generated from it), bit for bit, skipping candidates whose
    /// projection's edge lines ([`Edges`], widened by [`EDGE_MARGIN`] = 1/8 pixel) exclude the
    /// film point before the triangle test. Every point of the generated ray projects within
    /// about 10⁻⁴ pixel of `(fx, fy)` (the [`MARGIN`] argument), so a triangle the ray meets
    /// contains a point within that distance of its projection and is never skipped.
    #[inline]
    pub fn closest_film(
        &self,
        accel: &Accel,
        fx: f32,
        fy: f32,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<Hit> {
        let mut cursor = self.cursor(fx, fy);
        self.closest_first(accel, &mut cursor, dir, tmin, tmax)
    }

    /// A [`FilmCursor`] for the camera ray through the film point `(fx, fy)`.
    #[inline]
    pub fn cursor(&self, fx: f32, fy: f32) -> FilmCursor<'_> {
        let (w, h) = self.size();
        // x + jitter may round up to the pixel's right edge (= w for the last column): that film
        // point still lies in the pixel's (closed) bin, so the bin index is clamped.
        let inside = fx >= 0.0 && fy >= 0.0 && fx <= w as f32 && fy <= h as f32;
        let list = match inside {
            true => self
                .lists
                .at((fx as u32).min(w - 1), (fy as u32).min(h - 1)),
            false => &[],
        };
        FilmCursor {
            list,
            fx,
            fy,
            scanned: 0,
            passed: [0; CURSOR_CAPACITY],
            n_passed: 0,
        }
    }

    /// [`closest_film`](Self::closest_film) through a cursor: the same answer, and the
    /// candidates it scanned are remembered for [`closest_next`](Self::closest_next).
    #[inline]
    pub fn closest_first(
        &self,
        accel: &Accel,
        cursor: &mut FilmCursor,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<Hit> {
        self.closest_cursor(accel, cursor, self.origin, dir, tmin, tmax, |t| t)
    }

    /// [`Accel::closest`]`(origin, dir, tmin, tmax)`, bit for bit, for a ray that continues the
    /// camera ray through the film point `(fx, fy)` (`dir` generated from it, as for
    /// [`closest_film`](Self::closest_film)) from a point `origin` near that ray: the ray that
    /// crossed an index-matched boundary and goes on in the same direction (the first free
    /// flight inside the medium, the search for a re-entry behind it). `origin_film` is the
    /// projection `(px, py, z)` of `origin` by the projector the bins were built with.
    ///
    /// `None` (ask the BVH) when `origin` does not project within [`CONTINUATION_OFFSET`] pixels
    /// of `(fx, fy)`. Why the lists suffice otherwise: the ray is parallel to the camera ray, so
    /// its projection is a segment from the projection of `origin` towards the vanishing point of
    /// `dir`, which is `(fx, fy)` (to the 10⁻⁴ pixel of the ray generation). Every point of the
    /// ray therefore projects within the offset of `(fx, fy)`, well inside [`MARGIN`] and
    /// [`EDGE_MARGIN`], and a triangle it meets is among the pixel's candidates and passes the
    /// edge test. The early stop moves with the origin's depth `z₀`: with `v_i − origin =
    /// s_i·dir + w_i` (`|w_i| ≤ D` for a triangle the ray meets), `z_i ≤ s_i + D + z₀` when every
    /// `s_i ≥ 0`, so `t ≥ min z_i − (1 + √2)·D − z₀ > lb − z₀`; a corner with `s_i < 0` has
    /// `z_i ≤ D + z₀`, hence `lb < z₀`. So no candidate with `lb > z₀ + t_best` can improve on
    /// `t_best` (we add 10⁻⁴ of `z₀ + t_best` for the rounding of `z₀`).
    ///
    /// `cursor` is the camera ray's ([`cursor`](Self::cursor) of `(fx, fy)`). The edge test
    /// depends only on the film point, so the candidates that the cursor's earlier queries
    /// scanned and that passed it are tested again from the new origin without a second pass
    /// over the list; the scan then goes on where it stopped.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn closest_next(
        &self,
        accel: &Accel,
        cursor: &mut FilmCursor,
        origin: Vec3,
        origin_film: (f32, f32, f32),
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<Option<Hit>> {
        let (px, py, z0) = origin_film;
        let (dx, dy) = (px - cursor.fx, py - cursor.fy);
        let near = dx * dx + dy * dy <= CONTINUATION_OFFSET * CONTINUATION_OFFSET;
        if !(near && z0 > 0.0 && z0.is_finite()) {
            return None;
        }
        let bound = |t: f32| (z0 + t) * (1.0 + 1e-4);
        Some(self.closest_cursor(accel, cursor, origin, dir, tmin, tmax, bound))
    }

    /// The closest hit of `(origin, dir)` among the cursor's candidates: those it has passed
    /// already, then the rest of its list until `lb > bound(t_best)`. A cursor that has passed
    /// more than [`CURSOR_CAPACITY`] candidates scans its list from the start every time.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn closest_cursor(
        &self,
        accel: &Accel,
        cursor: &mut FilmCursor,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        bound: impl Fn(f32) -> f32,
    ) -> Option<Hit> {
        let (fx, fy) = (cursor.fx, cursor.fy);
        let keep = |prim: u32| inside_edges(&self.edges[prim as usize], fx, fy);
        if cursor.n_passed > CURSOR_CAPACITY {
            return self.closest_in(accel, cursor.list, origin, dir, tmin, tmax, bound, keep);
        }
        if cursor.list.is_empty() || !crate::bvh::valid_ray(dir, tmin, tmax) {
            return None;
        }
        let tris = accel.bvh_triangles();
        let wr = WatertightRay::new(Vec3A::from(origin), Vec3A::from(dir));
        let mut best_t = tmax;
        let mut best: Option<(u32, TriHit)> = None;
        let test = |prim: u32, best_t: &mut f32, best: &mut Option<(u32, TriHit)>| {
            let [v0, v1, v2] = tris[prim as usize].map(Vec3A::from);
            let lim = Accel::limit(best, *best_t, tmax);
            if let Some(th) = wr.intersect_hit(v0, v1, v2, tmin, lim)
                && accel.improves(th.t, prim, best, *best_t)
            {
                *best_t = th.t;
                *best = Some((prim, th));
            }
        };
        for &prim in &cursor.passed[..cursor.n_passed] {
            test(prim, &mut best_t, &mut best);
        }
        while let Some(&(lb, prim)) = cursor.list.get(cursor.scanned) {
            if lb > bound(best_t) {
                break;
            }
            cursor.scanned += 1;
            if !keep(prim) {
                continue;
            }
            if cursor.n_passed < CURSOR_CAPACITY {
                cursor.passed[cursor.n_passed] = prim;
            }
            cursor.n_passed += 1;
            test(prim, &mut best_t, &mut best);
        }
        best.map(|(prim, th)| accel.make_hit(prim, th, dir))
    }

    /// The closest hit of the ray `(origin, dir)` among the candidates of `list` that pass
    /// `keep` (the loop of [`Accel::closest`] over a list sorted by lower bound: stops at the
    /// first `lb > bound(t_best)`).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn closest_in(
        &self,
        accel: &Accel,
        list: &[(f32, u32)],
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        bound: impl Fn(f32) -> f32,
        keep: impl Fn(u32) -> bool,
    ) -> Option<Hit> {
        if list.is_empty() || !crate::bvh::valid_ray(dir, tmin, tmax) {
            return None;
        }
        let tris = accel.bvh_triangles();
        let wr = WatertightRay::new(Vec3A::from(origin), Vec3A::from(dir));
        let mut best_t = tmax;
        let mut best: Option<(u32, TriHit)> = None;
        for &(lb, prim) in list {
            if lb > bound(best_t) {
                break;
            }
            if !keep(prim) {
                continue;
            }
            let [v0, v1, v2] = tris[prim as usize].map(Vec3A::from);
            let lim = Accel::limit(&best, best_t, tmax);
            if let Some(th) = wr.intersect_hit(v0, v1, v2, tmin, lim)
                && accel.improves(th.t, prim, &best, best_t)
            {
                best_t = th.t;
                best = Some((prim, th));
            }
        }
        best.map(|(prim, th)| accel.make_hit(prim, th, dir))
    }
}
