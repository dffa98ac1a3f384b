//! Shadow-ray queries toward one point light by per-direction candidate lists: an exact
//! replacement for [`Accel::inside_length`] (and [`Accel::occluded`]) on segments that end at the
//! light.
//!
//! Every shadow ray of next-event estimation to a point light at `c` lies on a line through `c`.
//! All points of such a line on one side of `c` have the same direction from `c`, so the only
//! triangles the segment `p → c` can cross are those whose central projection from `c` contains
//! the projection of `p`. [`LightBins::build`] projects every triangle once onto a square film
//! around the mesh's bounding sphere (a pinhole "camera" at the light looking at the sphere's
//! centre, `N × N` bins) and keeps per bin the triangles whose projected bounding box, widened by
//! [`MARGIN`] bins, overlaps it (the lists of [`crate::bins`]). A query projects `p`, reads its
//! bin and runs the same watertight test ([`crate::triangle`]) as the BVH on those candidates; the
//! crossings are reduced exactly as [`Accel::inside_length`] reduces them (in the order of
//! increasing `(t, facing)`), so the result equals the BVH's bit for bit whenever both see the same
//! set of hits — always, up to the edge-on hits the BVH may miss (the known limitation in the
//! [`bvh`](crate::bvh) docs), which the lists do not.
//!
//! Why the ray beyond the light does not matter. `inside_length` counts the crossings of the whole
//! ray from `p` through `c` to decide whether `p` is inside. Past `c` the ray runs away from the
//! mesh: the bins are only built when `c` lies outside the bounding sphere (by 5 % of its radius),
//! so every point of the mesh has a positive depth along the film's axis while points past `c`
//! have a negative one. Both sources therefore see the same hits.
//!
//! The margin. The shadow ray's direction `(c − p)/|c − p|` is rounded, so the ray passes `c` at
//! a distance of about 10⁻⁷·|c − p|; a triangle at distance `s ≥ d − R` from `c` (`d` the distance
//! of `c` from the sphere's centre, `R` the radius) then sees the ray up to 10⁻⁷·(d + R)/(d − R)
//! ≤ 4.1·10⁻⁶ rad off the projection of `p`, and the film has at most `N / (2 tan θ)` ≤ 330 bins
//! per radian at `N` = 2048 and the closest allowed light (`tan θ` ≤ 3.2): 0.0014 bin, far inside
//! the margin of 1/16 bin.
//!
//! Cost: one pass over the triangles per light position (a few ms for 80 k triangles) and 8 bytes
//! per (triangle, bin) overlap; a shadow query then costs a projection and a handful of triangle
//! tests instead of an all-hits BVH traversal over the whole segment.

use glam::{Vec3, Vec3A};

pub use crate::bins::{EDGE_MARGIN, MARGIN};
use crate::bins::{Edges, Lists, edges, inside_edges};
use crate::bvh::{Accel, valid_ray};
use crate::triangle::WatertightRay;

/// Smallest distance of the light from the bounding sphere's centre, in radii, for which the
/// bins are built (module docs: it bounds the projection error of a shadow ray).
pub const MIN_LIGHT_DISTANCE: f32 = 1.05;

/// Largest film resolution (bins per side).
pub const MAX_RESOLUTION: u32 = 2048;

/// Largest mesh for which [`LightBins::build`] builds lists. The lists pay off while they stay
/// in cache (measured, docs/notes/tracer-speed.md, "Shadow rays through the light's triangle
/// lists" and "Lists for the 82k-triangle blob"): 17–20 % faster volpath renders of the
/// 20k-triangle reference sphere, 14–29 % of the 82k-triangle blob (renders and `optimize
/// --model volpath` at 256²), and on a 327k-triangle mesh random shadow queries are 1.7×
/// SLOWER than the BVH's (68 MB of lists).
pub const MAX_TRIANGLES: usize = 131_072;

/// Per-direction triangle lists around one point light (module docs).
#[derive(Clone, Debug)]
pub struct LightBins {
    lists: Lists,
    film: Film,
    /// Per triangle (BVH order): its projection's three edge lines on the film, `a·x + b·y + c ≥ 0`
    /// inside, widened by [`EDGE_MARGIN`] bins ([`Edges`]).
    edges: Vec<Edges>,
    /// Distance from the light to the nearest point of the bounding sphere.
    near: f32,
}

/// The central projection from the light onto the bins' film.
#[derive(Clone, Copy, Debug)]
struct Film {
    light: Vec3,
    /// Film frame: `f` from the light to the sphere's centre, `u`, `v` spanning the film.
    f: Vec3,
    u: Vec3,
    v: Vec3,
    /// Bins per unit of film coordinate (`N / (2 tan θ)`, also bins per radian at the film's
    /// centre, the most anywhere) and the film's half size in bins.
    scale: f32,
    half: f32,
}

/// A film position (x, y) in bins and the (lb, triangle) list of its bin.
type Candidates<'a> = (f32, f32, &'a [(f32, u32)]);

impl Film {
    /// Film position (bins) and depth of `p` as seen from the light; `None` behind the light.
    #[inline(always)]
    fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let q = p - self.light;
        let z = q.dot(self.f);
        if z.is_nan() || z <= 0.0 {
            return None;
        }
        let inv = 1.0 / z;
        Some((
            q.dot(self.u) * inv * self.scale + self.half,
            q.dot(self.v) * inv * self.scale + self.half,
            z,
        ))
    }
}

impl LightBins {
    /// Bins for the light at `light` with the default resolution `N = ⌈2√T⌉` (T triangles),
    /// clamped to [32, [`MAX_RESOLUTION`]]. `None` when the mesh has more than
    /// [`MAX_TRIANGLES`] triangles, the light is not at least [`MIN_LIGHT_DISTANCE`] radii from
    /// the mesh's bounding sphere's centre, the mesh is empty, or the lists would be too long;
    /// the caller then keeps the BVH.
    pub fn build(accel: &Accel, light: Vec3) -> Option<LightBins> {
        let t = accel.bvh_triangles().len() as f32;
        if accel.bvh_triangles().len() > MAX_TRIANGLES {
            return None;
        }
        let n = ((2.0 * t.sqrt()).ceil() as u32).clamp(32, MAX_RESOLUTION);
        Self::build_with_resolution(accel, light, n)
    }

    /// [`build`](Self::build) with `n × n` bins (`n` in 1..=[`MAX_RESOLUTION`]).
    pub fn build_with_resolution(accel: &Accel, light: Vec3, n: u32) -> Option<LightBins> {
        if !(1..=MAX_RESOLUTION).contains(&n) || !light.is_finite() {
            return None;
        }
        let tris = accel.bvh_triangles();
        if tris.is_empty() {
            return None;
        }
        let (lo, hi) = tris.iter().flatten().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let centre = 0.5 * (lo + hi);
        let radius = tris
            .iter()
            .flatten()
            .map(|&p| (p - centre).length())
            .fold(0.0f32, f32::max)
            * (1.0 + 1e-4)
            + 1e-6 * centre.abs().max_element();
        let to_centre = centre - light;
        let dist = to_centre.length();
        if !(radius > 0.0 && dist.is_finite() && dist >= MIN_LIGHT_DISTANCE * radius) {
            return None;
        }
        let f = to_centre / dist;
        let (u, v) = f.any_orthonormal_pair();
        // tan of the sphere's half angle, widened slightly so every corner projects inside.
        let tan_half = radius / (dist * dist - radius * radius).sqrt() * 1.001;
        let half = n as f32 / 2.0;
        let film = Film {
            light,
            f,
            u,
            v,
            scale: half / tan_half,
            half,
        };
        let lists = Lists::build(accel, n, n, false, |p| film.project(p))?;
        let edges = tris
            .iter()
            .map(|c| {
                let p = c.map(|v| film.project(v).map_or((0.0, 0.0), |(x, y, _)| (x, y)));
                edges(p)
            })
            .collect();
        Some(LightBins {
            lists,
            film,
            edges,
            near: dist - radius,
        })
    }

    /// The film position of `p` and the candidate list of its bin; `None` outside the film.
    #[inline(always)]
    fn candidates(&self, p: Vec3) -> Option<Candidates<'_>> {
        let (x, y, _) = self.film.project(p)?;
        let n = self.lists.width as f32;
        if !(x >= 0.0 && x < n && y >= 0.0 && y < n) {
            return None;
        }
        Some((x, y, self.lists.at(x as u32, y as u32)))
    }

    /// The light position the bins were built for.
    pub fn light(&self) -> Vec3 {
        self.film.light
    }

    /// Bins per side of the film.
    pub fn resolution(&self) -> u32 {
        self.lists.width
    }

    /// Mean number of candidates per bin over the whole film (for statistics).
    pub fn mean_candidates(&self) -> f64 {
        self.lists.mean_candidates()
    }

    /// [`Accel::inside_length`]`(a, light)` — the length of the segment from `a` to the light
    /// inside the closed mesh — from the candidates of `a`'s bin (module docs). `accel` must be
    /// the one the bins were built over. Points outside the film are answered by the BVH.
    #[inline]
    pub fn inside_length(&self, accel: &Accel, a: Vec3) -> f32 {
        let Some((x, y, list)) = self.candidates(a) else {
            return accel.inside_length(a, self.film.light);
        };
        let tris = accel.bvh_triangles();
        accel.inside_length_by(a, self.film.light, |dir, push| {
            let wr = WatertightRay::new(Vec3A::from(a), Vec3A::from(dir));
            for &(_, prim) in list {
                if !inside_edges(&self.edges[prim as usize], x, y) {
                    continue;
                }
                let [v0, v1, v2] = tris[prim as usize].map(Vec3A::from);
                if let Some(th) = wr.intersect_hit(v0, v1, v2, 0.0, f32::INFINITY) {
                    push(th);
                }
            }
        })
    }

    /// [`Accel::occluded`]`(origin, dir, tmin, tmax)` for a ray that points at the light (its
    /// line passes the light within a small fraction of a bin; checked, otherwise the BVH
    /// answers) and ends at or before it.
    #[inline]
    pub fn occluded(&self, accel: &Accel, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if !valid_ray(dir, tmin, tmax) {
            return false;
        }
        // Angle under which the ray's line misses the light, seen from the nearest triangle.
        let miss = (self.film.light - origin).cross(dir).length() / self.near;
        let (x, y, list) = match self.candidates(origin) {
            Some(c) if miss * self.film.scale <= 0.5 * MARGIN => c,
            _ => return accel.occluded(origin, dir, tmin, tmax),
        };
        let tris = accel.bvh_triangles();
        let wr = WatertightRay::new(Vec3A::from(origin), Vec3A::from(dir));
        list.iter().any(|&(_, prim)| {
            if !inside_edges(&self.edges[prim as usize], x, y) {
                return false;
            }
            let [v0, v1, v2] = tris[prim as usize].map(Vec3A::from);
            wr.intersect(v0, v1, v2, tmin, tmax).is_some()
        })
    }
}
