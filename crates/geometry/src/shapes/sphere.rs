//! Sphere-like shapes over the unit icosphere: the icosphere itself (used by [`Shape::Sphere`]
//! and as the base of the blob) and the bumpy blob ([`Shape::Blob`]).
//!
//! [`Shape::Sphere`]: super::Shape::Sphere
//! [`Shape::Blob`]: super::Shape::Blob

use std::collections::HashMap;
use std::f64::consts::TAU;

use glam::DVec3;
use rand::{Rng, SeedableRng};

use crate::Mesh;

/// Unit icosphere: the regular icosahedron with every triangle split into four `subdivisions`
/// times, midpoints projected onto the unit sphere. Returns unit directions (which are also the
/// exact normals) and CCW-outward triangles: 10·4^s + 2 vertices, 20·4^s triangles.
pub(super) fn icosphere(subdivisions: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| DVec3::from_array(p).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::with_capacity(faces.len() * 3 / 2);
        let mut next = Vec::with_capacity(faces.len() * 4);
        let mut mid = |a: u32, b: u32, verts: &mut Vec<DVec3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *midpoints.entry(key).or_insert_with(|| {
                verts.push((verts[a as usize] + verts[b as usize]).normalize());
                (verts.len() - 1) as u32
            })
        };
        for &[a, b, c] in &faces {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    (verts, faces)
}

/// Uniform number in (0, 1) from the raw 32-bit output (independent of `rand`'s distributions,
/// so blobs stay identical across `rand` versions).
fn uniform(rng: &mut rand_pcg::Pcg32) -> f64 {
    (f64::from(rng.next_u32()) + 0.5) / 4_294_967_296.0
}

/// The bumpy blob: see [`Shape::Blob`](super::Shape::Blob).
pub(super) fn blob(radius: f64, amplitude: f64, bumps: u32, seed: u64, subdivisions: u32) -> Mesh {
    struct Bump {
        centre: DVec3,
        weight: f64,
        inv_w2: f64,
    }
    let mut rng = rand_pcg::Pcg32::seed_from_u64(seed);
    let bumps: Vec<Bump> = (0..bumps)
        .map(|_| {
            let z = 2.0 * uniform(&mut rng) - 1.0;
            let phi = TAU * uniform(&mut rng);
            let s = (1.0 - z * z).max(0.0).sqrt();
            let centre = DVec3::new(s * phi.cos(), z, s * phi.sin());
            let sign = if uniform(&mut rng) < 0.5 { -1.0 } else { 1.0 };
            let magnitude = 0.5 + 0.5 * uniform(&mut rng);
            let width = 0.2 + 0.3 * uniform(&mut rng);
            Bump {
                centre,
                weight: sign * magnitude,
                inv_w2: 1.0 / (width * width),
            }
        })
        .collect();
    let (dirs, indices) = icosphere(subdivisions);
    let positions = dirs
        .iter()
        .map(|&d| {
            let sum: f64 = bumps
                .iter()
                .map(|b| b.weight * (-(1.0 - d.dot(b.centre)) * b.inv_w2).exp())
                .sum();
            (d * radius * (amplitude * sum).exp()).as_vec3()
        })
        .collect();
    let mut mesh = Mesh {
        positions,
        normals: None,
        indices,
    };
    // The bumps make it asymmetric: centre the bounding box on the origin.
    let (lo, hi) = mesh.bounds();
    let centre = 0.5 * (lo + hi);
    for p in &mut mesh.positions {
        *p -= centre;
    }
    mesh.normals = Some(mesh.compute_vertex_normals());
    mesh
}
