//! The clearance grid of [`Accel`]: a lower bound on the distance from a point to the mesh,
//! read from one byte, so that a short query that cannot reach the surface skips the BVH.
//!
//! Inside a dense medium most queries are short: a free flight of mean length 1/σ_t, or the first
//! leg of a tracked shadow ray limited to its optical budget. Deep in the medium such a segment
//! ends before it can meet the surface and the BVH answers "no hit" after descending to every
//! box the segment touches. The grid answers it from the point alone.
//!
//! Construction. A uniform grid of cubic cells of side `h` covers the mesh's bounding box
//! ([`CELLS_PER_AXIS`] cells along its longest axis). A cell is a *surface cell* when a triangle
//! may touch it: each triangle is split into four at its edge midpoints until the bounding box of
//! every piece spans at most two cells per axis; of the cells the (slightly widened) box of a
//! piece overlaps, those whose centre lies within half a cell diagonal of the triangle (exact
//! point–triangle distance in f64, Ericson 2005 §5.1.5) are marked. The pieces cover the
//! triangle and a cell holding a point of it has its centre that close, so every point of every
//! triangle lies in a marked cell, and no marked cell reaches farther than √3 cells from one. A two-pass chamfer sweep over the 26-neighbourhood then stores per cell `k`,
//! the Chebyshev distance in cells to the nearest surface cell (saturated at 255).
//!
//! The bound. For a point `o` in a cell at Chebyshev distance `k ≥ 1` from every surface cell,
//! and any triangle point `y` (which lies in some surface cell), the two cells differ by at least
//! `k` along some axis, so `|o − y| ≥ (k − 1)·h`. [`Clearance::reach`] returns that bound less
//! the rounding of the cell lookup and of the triangle test's reported `t` (a relative 2⁻¹⁶ and
//! an absolute 2⁻¹⁶ of the box's size: both far above the f32 errors and far below `h`). A query
//! from `o` whose whole segment is shorter than the bound cannot hit: the answer "no hit" is the
//! BVH's. (The one exception is the BVH's own known limitation, a triangle seen exactly edge-on,
//! whose reported `t` may be any of its corners' depths; there the grid returns the true answer,
//! no crossing within reach.)
//!
//! The absolute tolerance grows with the distance of the mesh from the origin, like the f32
//! rounding it covers: a mesh whose cells are smaller than 2⁻¹⁶ of its coordinates' magnitude
//! (a 1 cm object 100 m from the origin) gets no skips, only the BVH.
//!
//! Cost: `CELLS_PER_AXIS³` bytes at most (256 KiB), built in a few milliseconds; a query reads
//! one byte. Measured in docs/notes/tracer-speed.md ("A clearance grid for short queries").

use glam::{DVec3, Vec3, Vec3A};

/// Cells along the longest axis of the mesh's bounding box.
pub const CELLS_PER_AXIS: u32 = 64;

/// Half the diagonal of a cell in cells, plus 1/1000 cell: the marking radius (module docs).
const HALF_DIAGONAL: f64 = 0.866_025_403_784_438_6 + 1e-3;

/// Relative and box-relative tolerance of [`Clearance::reach`] (module docs).
const TOLERANCE: f32 = 1.0 / 65536.0;

/// Per-cell Chebyshev distance to the surface cells (module docs).
#[derive(Clone, Debug, Default)]
pub(crate) struct Clearance {
    lo: Vec3A,
    inv_h: f32,
    /// Cell side, reduced by [`TOLERANCE`].
    h: f32,
    /// Absolute tolerance: 2⁻¹⁶ of the largest coordinate magnitude of the box.
    slack: f32,
    dims: [u32; 3],
    /// `dims` as floats (the lookup's range check).
    dims_f: Vec3A,
    /// `k` per cell, x fastest. Empty when the grid could not be built (no skip then).
    k: Vec<u8>,
}

impl Clearance {
    /// The grid over triangles `tris` (module docs). Empty (never skips) for an empty or
    /// degenerate mesh or non-finite coordinates.
    pub(crate) fn build(tris: &[[Vec3; 3]]) -> Clearance {
        let (lo, hi) = tris.iter().flatten().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let extent = (hi - lo).max_element();
        if !(extent > 0.0 && extent.is_finite() && lo.is_finite()) {
            return Clearance::default();
        }
        let h = extent / CELLS_PER_AXIS as f32;
        let inv_h = 1.0 / h;
        let dims = ((hi - lo) * inv_h)
            .to_array()
            .map(|e| (e.floor() as u32 + 1).clamp(1, CELLS_PER_AXIS + 1));
        let mut grid = Clearance {
            lo: lo.into(),
            inv_h,
            h: h * (1.0 - TOLERANCE),
            slack: TOLERANCE * lo.abs().max(hi.abs()).max_element(),
            dims,
            dims_f: Vec3A::from_array(dims.map(|d| d as f32)),
            k: vec![u8::MAX; dims.iter().map(|&d| d as usize + 2).product()],
        };
        for tri in tris {
            let c = tri.map(|v| (v - lo) * inv_h);
            grid.mark(c.map(|v| v.as_dvec3()), c, 0);
        }
        grid.sweep();
        grid
    }

    /// Marks the cells that triangle `tri` (cell coordinates) may touch (module docs), among
    /// those of the piece `c` of it.
    fn mark(&mut self, tri: [DVec3; 3], c: [Vec3; 3], depth: u32) {
        // Widened by 1/1000 cell: far above the rounding of the cell coordinates.
        let lo = c[0].min(c[1]).min(c[2]) - 1e-3;
        let hi = c[0].max(c[1]).max(c[2]) + 1e-3;
        let max = Vec3::from_array(self.dims.map(|d| (d - 1) as f32));
        let (a, b) = (
            lo.floor().clamp(Vec3::ZERO, max),
            hi.floor().clamp(Vec3::ZERO, max),
        );
        if (b - a).max_element() > 1.0 && depth < 24 {
            let m = [
                (c[0] + c[1]) * 0.5,
                (c[1] + c[2]) * 0.5,
                (c[2] + c[0]) * 0.5,
            ];
            self.mark(tri, [c[0], m[0], m[2]], depth + 1);
            self.mark(tri, [m[0], c[1], m[1]], depth + 1);
            self.mark(tri, [m[2], m[1], c[2]], depth + 1);
            self.mark(tri, m, depth + 1);
            return;
        }
        let (a, b) = (a.as_uvec3(), b.as_uvec3());
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    // A cell holding a point of the triangle has its centre within half a
                    // diagonal of it (widened by 1/1000 cell).
                    let centre = DVec3::new(x as f64, y as f64, z as f64) + 0.5;
                    if point_triangle(centre, tri) <= HALF_DIAGONAL {
                        let i = self.index(x, y, z);
                        self.k[i] = 0;
                    }
                }
            }
        }
    }

    /// Position of cell (x, y, z) in `k`, which carries a border of one never-relaxed cell
    /// (value 255) on every side so that the sweep needs no bounds checks.
    #[inline(always)]
    fn index(&self, x: u32, y: u32, z: u32) -> usize {
        let [px, py, _] = self.dims.map(|d| d as usize + 2);
        (x as usize + 1) + px * (y as usize + 1 + py * (z as usize + 1))
    }

    /// Chebyshev distance transform from the surface cells (`k = 0`): the two-pass chamfer
    /// sweep with unit weights over the 26-neighbourhood, which is exact for the chessboard
    /// metric (Rosenfeld & Pfaltz 1966). The forward raster pass takes the 13 neighbours already
    /// visited, the backward pass the other 13. Per row, 12 of them lie in four finished rows
    /// (three of the previous plane, one of this plane), read as 3-cell windows; the 13th is the
    /// row's own previous cell, a running scan. Saturates at 255.
    fn sweep(&mut self) {
        let [nx, ny, nz] = self.dims.map(|d| d as usize);
        let [px, py, _] = self.dims.map(|d| d as usize + 2);
        // Start of the padded row (y, z) in cell coordinates offset by one (the border).
        let row = |y: usize, z: usize| px * (y + py * z);
        let mut m = vec![0u8; nx];
        for backward in [false, true] {
            for zz in 1..=nz {
                for yy in 1..=ny {
                    let (y, z) = if backward {
                        (ny + 1 - yy, nz + 1 - zz)
                    } else {
                        (yy, zz)
                    };
                    let (ys, zs) = if backward {
                        (y + 1, z + 1)
                    } else {
                        (y - 1, z - 1)
                    };
                    let done = [row(y - 1, zs), row(y, zs), row(y + 1, zs), row(ys, z)];
                    // Window minimum over the finished rows: cell x (padded x + 1) sees x..=x + 2.
                    m.fill(u8::MAX);
                    for &r in &done {
                        let w = &self.k[r..r + px];
                        for (x, mx) in m.iter_mut().enumerate() {
                            *mx = (*mx).min(w[x].min(w[x + 1]).min(w[x + 2]));
                        }
                    }
                    let cur = &mut self.k[row(y, z)..row(y, z) + px];
                    let mut run = u8::MAX;
                    let mut step = |x: usize| {
                        let v = cur[x + 1]
                            .min(m[x].saturating_add(1))
                            .min(run.saturating_add(1));
                        cur[x + 1] = v;
                        run = v;
                    };
                    if backward {
                        (0..nx).rev().for_each(&mut step);
                    } else {
                        (0..nx).for_each(&mut step);
                    }
                }
            }
        }
    }

    /// A distance within which no point of any triangle lies from `o` (module docs): a query
    /// from `o` with `t_max·|dir| ≤ reach(o)` has no hit. 0 outside the grid and near the surface.
    #[inline(always)]
    pub(crate) fn reach(&self, o: Vec3A) -> f32 {
        if self.k.is_empty() {
            return 0.0;
        }
        let f = (o - self.lo) * self.inv_h;
        // Also false for NaN.
        if !(f.cmpge(Vec3A::ZERO).all() && f.cmplt(self.dims_f).all()) {
            return 0.0;
        }
        let [x, y, z] = truncate(f);
        let k = self.k[self.index(x, y, z)];
        if k <= 1 {
            return 0.0;
        }
        (k - 1) as f32 * self.h - self.slack
    }
}

/// The integer parts of three non-negative coordinates below 2³¹ (one SSE2 conversion on
/// x86-64; `as u32` would add the saturating checks Rust defines).
#[inline(always)]
fn truncate(f: Vec3A) -> [u32; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_cvttps_epi32, _mm_storeu_si128};
        let mut out = [0u32; 4];
        // SAFETY: SSE2 is part of the x86-64 baseline; the store writes 16 bytes into `out`.
        unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), _mm_cvttps_epi32(__m128::from(f))) };
        [out[0], out[1], out[2]]
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        f.as_uvec3().to_array()
    }
}

/// Exact distance from `p` to triangle `t` (Ericson, Real-Time Collision Detection 5.1.5).
pub(crate) fn point_triangle(p: DVec3, t: [DVec3; 3]) -> f64 {
    let [a, b, c] = t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (p - a).length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (p - b).length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (p - c).length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).length()
}

#[cfg(test)]
mod tests {
    //! The grid against brute force: the sweep is the Chebyshev distance to the surface cells,
    //! every triangle point lies in a surface cell, the reach is below the exact distance to the
    //! mesh, and a query the grid skips is one the BVH answers with "no hit". Fixed seeds.

    use super::*;
    use crate::bvh::Accel;
    use crate::{Mesh, Shape};
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg32;

    /// A unit cube of 12 triangles: every triangle spans the whole grid, so marking recurses.
    fn cube() -> Mesh {
        let p = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32))
            .collect();
        let q = |a, b, c, d| [[a, b, c], [a, c, d]];
        let indices = [
            q(0, 2, 3, 1),
            q(4, 5, 7, 6),
            q(0, 1, 5, 4),
            q(2, 6, 7, 3),
            q(0, 4, 6, 2),
            q(1, 3, 7, 5),
        ]
        .concat();
        Mesh {
            positions: p,
            normals: None,
            indices,
        }
    }

    fn meshes() -> Vec<(&'static str, Mesh)> {
        let blob = Shape::Blob {
            radius: 0.5,
            amplitude: 0.15,
            bumps: 12,
            seed: 7,
            subdivisions: 3,
        };
        let torus = Shape::Torus {
            major: 0.35,
            minor: 0.15,
            segments: 32,
        };
        // Far from the origin (the tolerance is relative to the coordinates' magnitude), and
        // flat (a grid one cell thick along z: every cell is a surface cell).
        let mut far = blob.build().unwrap();
        far.positions
            .iter_mut()
            .for_each(|p| *p += Vec3::new(100.0, -50.0, 25.0));
        let mut flat = cube();
        flat.indices.truncate(2);
        vec![
            ("far", far),
            ("flat", flat),
            ("cube", cube()),
            ("blob", blob.build().unwrap()),
            ("torus", torus.build().unwrap()),
        ]
    }

    /// Every mesh but the flat quad (whose grid is one cell thick, so nothing is far from it)
    /// must exercise the property more than `min` times.
    fn exercised(name: &str, count: usize, min: usize, what: &str) {
        assert!(name == "flat" || count > min, "{name}: only {count} {what}");
    }

    /// A uniform random point of the grid's box.
    fn point_in_grid(g: &Clearance, rng: &mut Pcg32) -> Vec3 {
        let lo = Vec3::from(g.lo);
        let size = Vec3::from(g.dims_f) / g.inv_h;
        lo + Vec3::new(rng.random(), rng.random(), rng.random()) * size
    }

    fn grid(mesh: &Mesh) -> Clearance {
        let tris: Vec<[Vec3; 3]> = (0..mesh.triangle_count())
            .map(|i| mesh.triangle(i))
            .collect();
        Clearance::build(&tris)
    }

    #[test]
    fn sweep_is_the_chebyshev_distance_to_the_surface_cells() {
        for (name, mesh) in meshes() {
            let g = grid(&mesh);
            let [nx, ny, nz] = g.dims;
            let cells: Vec<[i64; 3]> = (0..nz)
                .flat_map(|z| (0..ny).flat_map(move |y| (0..nx).map(move |x| [x, y, z])))
                .map(|c| c.map(i64::from))
                .collect();
            let k = |c: [i64; 3]| g.k[g.index(c[0] as u32, c[1] as u32, c[2] as u32)];
            let surface: Vec<[i64; 3]> = cells.iter().copied().filter(|&c| k(c) == 0).collect();
            assert!(!surface.is_empty(), "{name}");
            let mut rng = Pcg32::seed_from_u64(11);
            let mut far = 0;
            for _ in 0..500 {
                let c = cells[rng.random_range(0..cells.len())];
                let brute = surface
                    .iter()
                    .map(|s| (0..3).map(|a| (s[a] - c[a]).abs()).max().unwrap())
                    .min()
                    .unwrap()
                    .min(255) as u8;
                assert_eq!(k(c), brute, "{name}: cell {c:?}");
                far += usize::from(brute > 2);
            }
            exercised(name, far, 50, "cells far from the surface");
        }
    }

    #[test]
    fn every_triangle_point_lies_in_a_surface_cell() {
        for (name, mesh) in meshes() {
            let g = grid(&mesh);
            let mut rng = Pcg32::seed_from_u64(12);
            for _ in 0..20_000 {
                let [a, b, c] = mesh.triangle(rng.random_range(0..mesh.triangle_count()));
                let (mut u, mut v) = (rng.random::<f32>(), rng.random::<f32>());
                if u + v > 1.0 {
                    (u, v) = (1.0 - u, 1.0 - v);
                }
                // The point and its cell in f64: an f32 point would carry the rounding of the
                // coordinates, which `reach` covers by its slack, not the marking.
                let [a, b, c] = [a, b, c].map(|v| v.as_dvec3());
                let p = a + (b - a) * u as f64 + (c - a) * v as f64;
                let f = (p - Vec3::from(g.lo).as_dvec3()) * g.inv_h as f64;
                let [x, y, z] = f.to_array().map(|e| e as u32);
                assert_eq!(g.k[g.index(x, y, z)], 0, "{name}: {p}");
            }
        }
    }

    #[test]
    fn reach_is_below_the_distance_to_the_mesh() {
        for (name, mesh) in meshes() {
            let g = grid(&mesh);
            let mut rng = Pcg32::seed_from_u64(13);
            let mut positive = 0;
            for _ in 0..2_000 {
                let p = point_in_grid(&g, &mut rng);
                let reach = g.reach(p.into());
                if reach <= 0.0 {
                    continue;
                }
                positive += 1;
                let exact = (0..mesh.triangle_count())
                    .map(|i| point_triangle(p.as_dvec3(), mesh.triangle(i).map(|v| v.as_dvec3())))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    reach as f64 <= exact,
                    "{name}: reach {reach} > distance {exact} at {p}"
                );
                // Marked cells reach at most √3 cells from the surface, the bound loses one more cell
                // and √3 across a diagonal: (k − 1)·h ≥ d/√3 − 3h.
                assert!(
                    reach as f64 >= exact / 3f64.sqrt() - 3.0 * g.h as f64,
                    "{name}: {p} reach {reach} exact {exact} h {}",
                    g.h
                );
            }
            exercised(name, positive, 200, "points with a positive reach");
        }
    }

    #[test]
    fn skipped_queries_are_misses_of_the_bvh() {
        for (name, mesh) in meshes() {
            let accel = Accel::new(mesh);
            let g = &accel.clearance;
            let mut rng = Pcg32::seed_from_u64(14);
            let mut skipped = 0;
            for _ in 0..20_000 {
                let o = point_in_grid(g, &mut rng);
                let z = 2.0 * rng.random::<f32>() - 1.0;
                let phi = std::f32::consts::TAU * rng.random::<f32>();
                let r = (1.0 - z * z).sqrt();
                let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                // Up to twice the reach: both sides of the threshold.
                let tmax = 2.0 * g.reach(o.into()) * rng.random::<f32>() + 1e-6;
                let bvh = accel
                    .closest_bvh(o.into(), d.into(), 0.0, tmax)
                    .map(|(p, _)| p);
                let hit = accel.closest(o, d, 0.0, tmax);
                assert_eq!(
                    hit.map(|h| h.tri),
                    bvh.map(|p| accel.prim_tri[p as usize]),
                    "{name}: {o} {d} {tmax}"
                );
                skipped += usize::from(accel.out_of_reach(o, d, tmax));
            }
            exercised(name, skipped, 2_000, "queries skipped");
        }
    }
}
