//! Property tests (proptest) of the geometry crate: the BVH's queries against brute force on
//! random triangle soups and closed meshes, and write → read round trips of OBJ and PLY.
//!
//! Each property runs 256 cases from a fixed seed (the same inputs on every run); a failure
//! prints its minimal input.

use geometry::{Accel, Mesh, MeshWarning, Vec3};

use crate::common;
use common::brute_all;
use proptest::prelude::*;

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 256,
        failure_persistence: None,
        // A fixed seed: the same inputs on every run (the tests are deterministic).
        rng_seed: proptest::test_runner::RngSeed::Fixed(1),
        ..ProptestConfig::default()
    }
}

fn vec3(r: f32) -> impl Strategy<Value = Vec3> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn unit() -> impl Strategy<Value = Vec3> {
    vec3(1.0)
        .prop_filter("not near zero", |v| v.length() > 0.05)
        .prop_map(|v| v.normalize())
}

/// A soup of 1–60 triangles over 3–40 random points in [−1, 1]³ (no repeated corner).
fn soup() -> impl Strategy<Value = Mesh> {
    (3u32..40)
        .prop_flat_map(|nv| {
            (
                prop::collection::vec(vec3(1.0), nv as usize),
                prop::collection::vec((0..nv, 0..nv, 0..nv), 1..60),
            )
        })
        .prop_map(|(positions, tris)| Mesh {
            positions,
            normals: None,
            indices: tris
                .into_iter()
                .filter(|(a, b, c)| a != b && b != c && a != c)
                .map(|(a, b, c)| [a, b, c])
                .collect(),
        })
        .prop_filter("at least one triangle", |m| !m.indices.is_empty())
}

/// A closed star-shaped mesh: the library's unit icosphere subdivided once, each vertex at its
/// own random radius in [0.3, 1] about a random centre.
fn closed() -> impl Strategy<Value = Mesh> {
    let base = geometry::Shape::Sphere {
        radius: 1.0,
        subdivisions: 1,
    }
    .build()
    .expect("the unit icosphere");
    let n = base.positions.len();
    (prop::collection::vec(0.3f32..1.0, n), vec3(0.5)).prop_map(move |(radii, centre)| Mesh {
        positions: base
            .positions
            .iter()
            .zip(&radii)
            .map(|(p, r)| centre + *p * *r)
            .collect(),
        normals: None,
        indices: base.indices.clone(),
    })
}

/// The triangles' corner positions in order: what a round trip must keep, whatever the vertex
/// numbering.
fn corners(m: &Mesh) -> Vec<[Vec3; 3]> {
    (0..m.triangle_count()).map(|i| m.triangle(i)).collect()
}

/// Whether `b` is `a` up to a cyclic rotation (the same triangle, the same orientation).
fn same_cycle(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    (0..3).any(|r| (0..3).all(|i| a[i] == b[(i + r) % 3]))
}

/// Whether `b` is `a` up to orientation.
fn same_triangle(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    same_cycle(a, b) || same_cycle(a, &[b[0], b[2], b[1]])
}

proptest! {
    #![proptest_config(config())]

    /// `closest`, `occluded` and `all_hits` agree with the brute-force watertight test on
    /// random soups, for rays from anywhere in any direction and random [tmin, tmax].
    #[test]
    fn queries_match_brute_force_on_soups(
        mesh in soup(),
        rays in prop::collection::vec((vec3(2.0), unit(), 0.0f32..0.5, 0.5f32..6.0), 16),
    ) {
        let accel = Accel::new(mesh.clone());
        let mut hits = Vec::new();
        for (o, d, tmin, tmax) in rays {
            let b = brute_all(&mesh, o, d, tmin, tmax);
            match (accel.closest(o, d, tmin, tmax), b.first()) {
                (None, None) => {}
                (Some(h), Some(&(t, _))) => {
                    prop_assert_eq!(h.t, t);
                    prop_assert!(b.iter().any(|&(bt, tri)| bt == h.t && tri == h.tri));
                }
                (got, want) => prop_assert!(false, "closest {got:?} brute {want:?}"),
            }
            prop_assert_eq!(accel.occluded(o, d, tmin, tmax), !b.is_empty());
            accel.all_hits(o, d, tmin, tmax, &mut hits);
            let got: Vec<(f32, u32)> = hits.iter().map(|h| (h.t, h.tri)).collect();
            prop_assert_eq!(got, b);
        }
    }

    /// On closed meshes the inside length of a segment is symmetric, additive over a split,
    /// within [0, |b − a|], and equal to the sum of the inside parts between the brute-force
    /// crossings of the whole line (odd crossings count from −∞).
    #[test]
    fn inside_length_is_consistent_on_closed_meshes(
        mesh in closed(),
        segs in prop::collection::vec((vec3(2.0), vec3(2.0), 0.05f32..0.95), 16),
    ) {
        let accel = Accel::new(mesh.clone());
        for (a, b, s) in segs {
            let len = (b - a).length();
            if len < 1e-3 {
                continue;
            }
            let ab = accel.inside_length(a, b);
            let tol = 1e-4 * (1.0 + len);
            prop_assert!((0.0..=len + tol).contains(&ab), "{ab} outside [0, {len}]");
            prop_assert!((ab - accel.inside_length(b, a)).abs() <= tol);
            let m = a + (b - a) * s;
            let split = accel.inside_length(a, m) + accel.inside_length(m, b);
            prop_assert!((ab - split).abs() <= 2.0 * tol, "{ab} vs {split}");
            // Brute force: crossings of the whole line, from far behind a.
            let d = (b - a) / len;
            let far = 10.0;
            let xs = brute_all(&mesh, a - d * far, d, 0.0, f32::INFINITY);
            let mut inside = false;
            let mut total = 0.0f64;
            let mut prev = 0.0f64;
            for &(t, _) in &xs {
                let t = (t as f64 - far as f64).clamp(0.0, len as f64);
                if inside {
                    total += t - prev;
                }
                prev = t;
                inside = !inside;
            }
            prop_assert!(!inside, "odd number of crossings of a closed mesh");
            prop_assert!((ab as f64 - total).abs() <= 1e-3 * (1.0 + len as f64), "{ab} vs brute {total}");
        }
    }

    /// OBJ and binary PLY: what `save_obj` / `save_ply` write, `load_mesh` reads back with the
    /// same triangles at bit-identical corners, with and without vertex normals.
    #[test]
    fn obj_and_ply_round_trip(mesh in soup(), with_normals in any::<bool>()) {
        let mut mesh = mesh;
        // Only the vertices the triangles use (the readers drop the others, with a warning).
        let mut used: Vec<u32> = mesh.indices.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        let remap: std::collections::HashMap<u32, u32> =
            used.iter().enumerate().map(|(i, &v)| (v, i as u32)).collect();
        mesh.positions = used.iter().map(|&v| mesh.positions[v as usize]).collect();
        mesh.indices = mesh.indices.iter().map(|t| t.map(|v| remap[&v])).collect();
        if with_normals {
            mesh.normals = Some(mesh.positions.iter().map(|p| p.normalize_or(Vec3::Z)).collect());
        }
        let dir = tempfile::tempdir().unwrap();
        for name in ["m.obj", "m.ply"] {
            let path = dir.path().join(name);
            match name {
                "m.obj" => geometry::io::save_obj(&mesh, &path).unwrap(),
                _ => geometry::io::save_ply(&mesh, &path).unwrap(),
            }
            let (back, warnings) = geometry::io::load_mesh(&path).unwrap();
            // The reader's validation may drop degenerate triangles and turn a mesh of negative
            // signed volume outward, each with its warning; nothing else changes.
            let flipped = warnings.iter().any(|w| matches!(w, MeshWarning::Flipped { .. }));
            let dropped = warnings
                .iter()
                .any(|w| matches!(w, MeshWarning::DroppedDegenerate { .. }));
            let got = corners(&back);
            let mut want = corners(&mesh);
            if dropped {
                want.retain(|[a, b, c]| got.iter().any(|g| same_triangle(g, &[*a, *b, *c])));
            }
            prop_assert_eq!(got.len(), want.len(), "{}", name);
            for (g, w) in got.iter().zip(&want) {
                let w = if flipped { [w[0], w[2], w[1]] } else { *w };
                prop_assert!(same_cycle(g, &w), "{}: {:?} vs {:?}", name, g, w);
            }
            if with_normals {
                let n = back.normals.as_ref().unwrap();
                prop_assert_eq!(n.len(), back.positions.len());
            }
        }
    }
}
