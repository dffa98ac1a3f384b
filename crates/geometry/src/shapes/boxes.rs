//! Boxes: the box with rounded edges ([`Shape::RoundedBox`]) and the sharp-edged test fixture
//! [`sharp_box`].
//!
//! [`Shape::RoundedBox`]: super::Shape::RoundedBox

use std::collections::HashMap;
use std::f64::consts::FRAC_PI_4;

use glam::{DVec3, Vec3};

use crate::Mesh;

/// Rounded box as the Minkowski sum of the inner box `[−h, h]` (h = size/2 − radius) and a ball of
/// `radius`: every point p of a subdivided cube of half-extent e = size/2 is mapped to
/// `q + radius·normalize(p − q)` with `q = clamp(p, −h, h)`, normal `normalize(p − q)`.
///
/// Per axis the grid coordinates are: in the band [h, e], `h + radius·tan(θ)` with θ uniform in
/// [0, π/4] (so the fillet arc is sampled uniformly in angle: each 45° half of a quarter-circle
/// lies on one cube face), and uniform steps of about the arc step on the flat part [−h, h].
/// Cube vertices are shared between faces through their integer lattice coordinates, so the
/// mesh is watertight.
pub(super) fn rounded_box(size: [f64; 3], radius: f64, segments: u32) -> Mesh {
    let k = (segments as usize).div_ceil(8).max(1);
    let arc_step = radius * FRAC_PI_4 / k as f64;
    let half = size.map(|s| 0.5 * s);
    let inner = half.map(|e| (e - radius).max(0.0));
    let grids: Vec<Vec<f64>> = (0..3)
        .map(|a| {
            let h = inner[a];
            let band = |m: usize| h + radius * (FRAC_PI_4 * m as f64 / k as f64).tan();
            let mut g: Vec<f64> = (0..=k).rev().map(|m| -band(m)).collect();
            // Flat part, skipped if the inner box is (numerically) flat along this axis.
            if h > 1e-9 * radius {
                let nflat = ((2.0 * h / arc_step).ceil() as usize).clamp(1, 4 * segments as usize);
                for m in 1..nflat {
                    g.push(-h + 2.0 * h * m as f64 / nflat as f64);
                }
                g.push(h);
            } else {
                // −h and +h coincide: share the point.
                if let Some(last) = g.last_mut() {
                    *last = 0.0;
                }
            }
            g.extend((1..=k).map(band));
            let e = half[a];
            if let Some(first) = g.first_mut() {
                *first = -e;
            }
            if let Some(last) = g.last_mut() {
                *last = e;
            }
            g
        })
        .collect();
    let n = [grids[0].len() - 1, grids[1].len() - 1, grids[2].len() - 1];

    let mut map: HashMap<[usize; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut vertex = |ijk: [usize; 3]| -> u32 {
        *map.entry(ijk).or_insert_with(|| {
            let p = DVec3::new(grids[0][ijk[0]], grids[1][ijk[1]], grids[2][ijk[2]]);
            let h = DVec3::from_array(inner);
            let q = p.clamp(-h, h);
            let d = (p - q).normalize();
            positions.push((q + radius * d).as_vec3());
            normals.push(d.as_vec3());
            (positions.len() - 1) as u32
        })
    };
    let mut indices = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for (fixed, outward) in [(0, false), (n[axis], true)] {
            for i in 0..n[u] {
                for j in 0..n[v] {
                    let at = |di: usize, dj: usize| {
                        let mut ijk = [0; 3];
                        ijk[axis] = fixed;
                        ijk[u] = i + di;
                        ijk[v] = j + dj;
                        ijk
                    };
                    let a = vertex(at(0, 0));
                    let b = vertex(at(1, 0));
                    let c = vertex(at(1, 1));
                    let d = vertex(at(0, 1));
                    // e_u × e_v = e_axis: (a, b, c) faces +axis.
                    if outward {
                        indices.push([a, b, c]);
                        indices.push([a, c, d]);
                    } else {
                        indices.push([a, c, b]);
                        indices.push([a, d, c]);
                    }
                }
            }
        }
    }
    Mesh {
        positions,
        normals: Some(normals),
        indices,
    }
}

/// The axis-aligned box `[min, max]` with sharp edges: 8 corners, 12 triangles, CCW-outward,
/// no vertex normals (flat faces). A fixture for tests with flat faces and sharp edges.
pub fn sharp_box(min: Vec3, max: Vec3) -> Mesh {
    let (a, b) = (min, max);
    let p = Vec3::new;
    let positions = vec![
        p(a.x, b.y, a.z),
        p(b.x, b.y, a.z),
        p(b.x, b.y, b.z),
        p(a.x, b.y, b.z),
        p(a.x, a.y, a.z),
        p(b.x, a.y, a.z),
        p(b.x, a.y, b.z),
        p(a.x, a.y, b.z),
    ];
    let indices = vec![
        [0, 2, 1],
        [0, 3, 2], // top (+y)
        [4, 5, 6],
        [4, 6, 7], // bottom (−y)
        [0, 1, 5],
        [0, 5, 4], // −z
        [3, 7, 6],
        [3, 6, 2], // +z
        [0, 4, 7],
        [0, 7, 3], // −x
        [1, 2, 6],
        [1, 6, 5], // +x
    ];
    Mesh {
        positions,
        normals: None,
        indices,
    }
}
