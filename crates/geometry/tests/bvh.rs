//! BVH, watertight triangle test and area sampling: exact agreement with brute force, crossing
//! parity of full lines (random, through vertices, along edges), analytic chord lengths,
//! chi-square uniformity of the area sampler. Deterministic (fixed seeds, Pcg32).

use geometry::{Accel, AreaSampler, Mesh, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;

use crate::common;

/// Test support: meshes, random directions, brute force, chi-square.
mod support {
    use super::*;
    use std::collections::HashMap;

    /// Icosphere of unit radius with `level` midpoint subdivisions (20·4^level triangles),
    /// CCW outward: the library's `Shape::Sphere`, without normals.
    pub fn icosphere(level: u32) -> Mesh {
        let mut mesh = geometry::Shape::Sphere {
            radius: 1.0,
            subdivisions: level,
        }
        .build()
        .expect("valid sphere");
        mesh.normals = None;
        assert!(
            signed_volume(&mesh) > 0.0,
            "the tests assume CCW-outward triangles"
        );
        mesh
    }

    /// Icosphere with radial noise: smooth bumps of amplitude `smooth` plus per-vertex random
    /// jitter of amplitude `jitter` (relative to radius 1), with area-weighted vertex normals.
    pub fn noisy_icosphere(level: u32, smooth: f32, jitter: f32, seed: u64) -> Mesh {
        let mut mesh = icosphere(level);
        let mut rng = Pcg32::seed_from_u64(seed);
        for p in &mut mesh.positions {
            let d = *p;
            let bump = (5.0 * d.x + 1.0).sin() * (4.0 * d.y + 2.0).sin() * (6.0 * d.z + 0.5).sin();
            let r = 1.0 + smooth * bump + jitter * (2.0 * rng.random::<f32>() - 1.0);
            *p = d * r;
        }
        mesh.normals = Some(vertex_normals(&mesh));
        mesh
    }

    /// Closed cube [-1, 1]³ whose faces are `n`×`n` grids (welded lattice vertices, exact
    /// coordinates −1 + 2i/n for n a power of two), CCW outward.
    pub fn grid_cube(n: u32) -> Mesh {
        let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
        let mut positions = Vec::new();
        let mut id = |l: [u32; 3], positions: &mut Vec<Vec3>| -> u32 {
            *ids.entry(l).or_insert_with(|| {
                let c = |i: u32| -1.0 + 2.0 * i as f32 / n as f32;
                positions.push(Vec3::new(c(l[0]), c(l[1]), c(l[2])));
                (positions.len() - 1) as u32
            })
        };
        let mut indices = Vec::new();
        for a in 0..3 {
            let (u, v) = ((a + 1) % 3, (a + 2) % 3);
            for side in [0, n] {
                for i in 0..n {
                    for j in 0..n {
                        let mut q = [[0u32; 3]; 4];
                        for (k, (di, dj)) in
                            [(0, 0), (1, 0), (1, 1), (0, 1)].into_iter().enumerate()
                        {
                            q[k][a] = side;
                            q[k][u] = i + di;
                            q[k][v] = j + dj;
                        }
                        let q = q.map(|l| id(l, &mut positions));
                        // Alternate the diagonal so both kinds of shared edges occur.
                        let mut tris = if (i + j) % 2 == 0 {
                            [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
                        } else {
                            [[q[0], q[1], q[3]], [q[1], q[2], q[3]]]
                        };
                        if side == 0 {
                            for t in &mut tris {
                                t.swap(1, 2);
                            }
                        }
                        indices.extend_from_slice(&tris);
                    }
                }
            }
        }
        Mesh {
            positions,
            normals: None,
            indices,
        }
    }

    pub fn signed_volume(mesh: &Mesh) -> f64 {
        (0..mesh.triangle_count())
            .map(|i| {
                let [a, b, c] = mesh.triangle(i).map(|v| v.as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    pub fn vertex_normals(mesh: &Mesh) -> Vec<Vec3> {
        let mut n = vec![Vec3::ZERO; mesh.positions.len()];
        for (i, t) in mesh.indices.iter().enumerate() {
            let f = mesh.face_normal_raw(i);
            for &v in t {
                n[v as usize] += f;
            }
        }
        n.iter().map(|v| v.normalize()).collect()
    }

    /// Every undirected edge used by two triangles with opposite orientation (closed, manifold).
    pub fn assert_closed(mesh: &Mesh) {
        let mut count: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &mesh.indices {
            for k in 0..3 {
                *count.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &c) in &count {
            assert_eq!(c, 1, "directed edge {a}->{b} used {c} times");
            assert_eq!(
                count.get(&(b, a)),
                Some(&1),
                "edge {a}->{b} has no opposite"
            );
        }
    }

    pub fn unit_vector(rng: &mut Pcg32) -> Vec3 {
        let z = 2.0 * rng.random::<f32>() - 1.0;
        let phi = std::f32::consts::TAU * rng.random::<f32>();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    pub fn in_ball(rng: &mut Pcg32, radius: f32) -> Vec3 {
        unit_vector(rng) * radius * rng.random::<f32>().cbrt()
    }

    /// Random point on a random triangle and its unit geometric normal.
    pub fn surface_point(rng: &mut Pcg32, mesh: &Mesh) -> (Vec3, Vec3) {
        let i = rng.random_range(0..mesh.triangle_count());
        let [a, b, c] = mesh.triangle(i);
        let (mut u, mut v) = (rng.random::<f32>(), rng.random::<f32>());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        (
            a + (b - a) * u + (c - a) * v,
            mesh.face_normal_raw(i).normalize(),
        )
    }

    pub use super::common::brute_all;

    /// Pearson chi-square statistic and its p-value (survival function, `bins − 1 − constraints`
    /// degrees of freedom) for observed counts against expected probabilities.
    pub fn chi_square(observed: &[u64], probs: &[f64]) -> (f64, f64) {
        let n: u64 = observed.iter().sum();
        let obs: Vec<f64> = observed.iter().map(|&o| o as f64).collect();
        let exp: Vec<f64> = probs.iter().map(|&p| p * n as f64).collect();
        assert!(
            exp.iter().all(|&e| e >= 5.0),
            "expected counts too small for chi-square"
        );
        let r = testkit::chi2_test(&obs, &exp, 5.0);
        (r.statistic, r.p_value)
    }
}

use support::*;

/// Compare every query with brute force on one ray.
fn check_ray(
    accel: &Accel,
    mesh: &Mesh,
    o: Vec3,
    d: Vec3,
    tmin: f32,
    tmax: f32,
    buf: &mut Vec<geometry::Hit>,
) {
    let brute = brute_all(mesh, o, d, tmin, tmax);
    // closest: same t bit for bit; the reported triangle is one with that t (ties are legal).
    let closest = accel.closest(o, d, tmin, tmax);
    match (closest, brute.first()) {
        (None, None) => {}
        (Some(h), Some(&(t, _))) => {
            // `==`: a tie between +0 and -0 (origin exactly on a vertex) may pick either.
            assert!(h.t == t, "closest t differs: o {o} d {d}: {} vs {t}", h.t);
            assert!(
                brute.iter().any(|&(bt, tri)| bt == t && tri == h.tri),
                "closest tri {} not at t {t}",
                h.tri
            );
            let p_ray = o + d * h.t;
            assert!(
                (h.p - p_ray).length() <= 1e-5 * (1.0 + o.length() + h.t.abs()),
                "p {} vs ray {p_ray}",
                h.p
            );
            // The facing agrees with the geometric normal.
            assert_eq!(h.entering(d), d.dot(h.ng) < 0.0);
            assert!((h.ng.length() - 1.0).abs() < 1e-5 && (h.ns.length() - 1.0).abs() < 1e-5);
            assert!(h.ns.dot(h.ng) >= 0.0);
            let raw = mesh.face_normal_raw(h.tri as usize).normalize();
            assert!((raw - h.ng).length() < 1e-5);
            assert!(h.bary.x >= 0.0 && h.bary.y >= 0.0 && h.bary.x + h.bary.y <= 1.0 + 1e-6);
        }
        (c, b) => {
            panic!("closest mismatch: bvh {c:?} brute {b:?} (o {o} d {d} tmin {tmin} tmax {tmax})")
        }
    }
    assert_eq!(
        accel.occluded(o, d, tmin, tmax),
        !brute.is_empty(),
        "occluded mismatch: o {o} d {d}"
    );
    accel.all_hits(o, d, tmin, tmax, buf);
    let got: Vec<(f32, u32)> = buf.iter().map(|h| (h.t, h.tri)).collect();
    assert_eq!(got.len(), brute.len(), "all_hits count: o {o} d {d}");
    for (g, b) in got.iter().zip(&brute) {
        assert_eq!(
            (g.0.to_bits(), g.1),
            (b.0.to_bits(), b.1),
            "all_hits differ: o {o} d {d}"
        );
    }
}

/// ~24k rays of every kind against brute force on a bumpy sphere and on a flat-faced grid cube.
#[test]
fn queries_match_brute_force() {
    let meshes = [noisy_icosphere(3, 0.1, 0.04, 7), grid_cube(8)];
    let mut buf = Vec::new();
    for (m, mesh) in meshes.iter().enumerate() {
        let accel = Accel::new(mesh.clone());
        let mut rng = Pcg32::seed_from_u64(1000 + m as u64);
        let mut n = 0;
        // outside → in
        for _ in 0..6000 {
            let o = unit_vector(&mut rng) * 3.0;
            let d = (in_ball(&mut rng, 1.2) - o).normalize();
            check_ray(&accel, mesh, o, d, 0.0, f32::INFINITY, &mut buf);
            n += 1;
        }
        // inside → out
        for _ in 0..6000 {
            check_ray(
                &accel,
                mesh,
                in_ball(&mut rng, 0.8),
                unit_vector(&mut rng),
                0.0,
                f32::INFINITY,
                &mut buf,
            );
            n += 1;
        }
        // segments with random tmax (and a few with tmin > 0)
        for k in 0..6000 {
            let o = in_ball(&mut rng, 1.5);
            let tmin = if k % 4 == 0 {
                rng.random::<f32>() * 0.5
            } else {
                0.0
            };
            let tmax = tmin + rng.random::<f32>() * 2.5;
            check_ray(&accel, mesh, o, unit_vector(&mut rng), tmin, tmax, &mut buf);
            n += 1;
        }
        // origins 1e-7 .. 1e-4 off the surface, either side, random directions (the obvhs box test
        // skips boxes left before t = 1e-4; ours must not)
        for k in 0..4000 {
            let (p, ng) = surface_point(&mut rng, mesh);
            let off = [1e-7f32, 1e-6, 1e-5, 5e-5][k % 4] * if k % 8 < 4 { 1.0 } else { -1.0 };
            check_ray(
                &accel,
                mesh,
                p + ng * off,
                unit_vector(&mut rng),
                0.0,
                f32::INFINITY,
                &mut buf,
            );
            // and straight through the surface
            check_ray(
                &accel,
                mesh,
                p + ng * off,
                -ng * off.signum(),
                0.0,
                f32::INFINITY,
                &mut buf,
            );
            n += 2;
        }
        // axis-aligned directions (exact zeros in the direction)
        for k in 0..1200 {
            let mut d = Vec3::ZERO;
            d[k % 3] = if k % 2 == 0 { 1.0 } else { -1.0 };
            let o = if k % 3 == 0 {
                in_ball(&mut rng, 0.9)
            } else {
                in_ball(&mut rng, 1.1) - d * 3.0
            };
            check_ray(&accel, mesh, o, d, 0.0, f32::INFINITY, &mut buf);
            n += 1;
        }
        // aimed exactly at vertices
        for _ in 0..1000 {
            let v = mesh.positions[rng.random_range(0..mesh.positions.len())];
            let o = unit_vector(&mut rng) * 3.0;
            check_ray(
                &accel,
                mesh,
                o,
                (v - o).normalize(),
                0.0,
                f32::INFINITY,
                &mut buf,
            );
            check_ray(
                &accel,
                mesh,
                v,
                unit_vector(&mut rng),
                f32::NEG_INFINITY,
                f32::INFINITY,
                &mut buf,
            );
            n += 2;
        }
        assert!(n >= 20_000);
    }
}

/// Check that hits along a full line alternate entering/leaving, starting entering, ending
/// leaving. Hits whose `t` differ by rounding only (≤ 1e-6 relative: a line grazing a vertex, or
/// exactly equal `t` at a silhouette edge) may come in any order: such a group is accepted when
/// some order of it alternates.
fn line_is_consistent(hits: &[geometry::Hit], d: Vec3) -> bool {
    let entering = hits.iter().filter(|h| h.entering(d)).count();
    if 2 * entering != hits.len() {
        return false;
    }
    let mut inside = 0i32;
    let mut i = 0;
    while i < hits.len() {
        let mut j = i + 1;
        while j < hits.len() && hits[j].t - hits[j - 1].t <= 1e-6 * (1.0 + hits[j].t.abs()) {
            j += 1;
        }
        let enter = hits[i..j].iter().filter(|h| h.entering(d)).count() as i32;
        let leave = (j - i) as i32 - enter;
        // Alternating from state `inside`: outside needs enter − leave ∈ {0, 1}, inside {−1, 0}.
        let net = enter - leave;
        let ok = if inside == 0 {
            net == 0 || net == 1
        } else {
            net == 0 || net == -1
        };
        if !ok {
            return false;
        }
        inside += net;
        i = j;
    }
    inside == 0
}

#[test]
fn full_lines_have_consistent_crossings() {
    let mut buf = Vec::new();
    let mut total_lines = 0usize;
    let mut total_hits = 0usize;
    let mut check = |accel: &Accel, o: Vec3, d: Vec3, what: &str, buf: &mut Vec<geometry::Hit>| {
        accel.all_hits(o, d, f32::NEG_INFINITY, f32::INFINITY, buf);
        assert!(
            line_is_consistent(buf, d),
            "{what}: inconsistent crossings o {o} d {d}: {:?}",
            buf.iter()
                .map(|h| (h.t, h.tri, h.entering(d)))
                .collect::<Vec<_>>()
        );
        total_lines += 1;
        total_hits += buf.len();
    };

    // Bumpy spheres: smooth bumps, and rough per-vertex jitter (strongly non-convex locally).
    for (level, smooth, jitter, seed) in [(5, 0.1, 0.05, 11u64), (3, 0.0, 0.15, 12)] {
        let mesh = noisy_icosphere(level, smooth, jitter, seed);
        assert_closed(&mesh);
        let accel = Accel::new(mesh.clone());
        let mut rng = Pcg32::seed_from_u64(seed);
        for _ in 0..50_000 {
            let o = unit_vector(&mut rng) * 3.0;
            let d = (in_ball(&mut rng, 1.0) - o).normalize();
            check(&accel, o, d, "random line", &mut buf);
        }
        for _ in 0..5_000 {
            // aimed at a vertex from outside
            let v = mesh.positions[rng.random_range(0..mesh.positions.len())];
            let o = unit_vector(&mut rng) * 3.0;
            check(&accel, o, (v - o).normalize(), "aimed at vertex", &mut buf);
            // exactly through a vertex (origin on it), random and axis directions
            check(&accel, v, unit_vector(&mut rng), "through vertex", &mut buf);
            let mut a = Vec3::ZERO;
            a[rng.random_range(0..3)] = 1.0;
            check(&accel, v, a, "through vertex, axis direction", &mut buf);
            // exactly through a vertex along one of its edges
            let t = mesh.indices[rng.random_range(0..mesh.indices.len())];
            let k = rng.random_range(0..3);
            let (p, q) = (
                mesh.positions[t[k] as usize],
                mesh.positions[t[(k + 1) % 3] as usize],
            );
            check(&accel, p, (q - p).normalize(), "along edge", &mut buf);
            // exactly through a vertex, in the plane of one of its triangles (through the
            // opposite edge): that triangle is seen edge-on and its far edge passes within
            // rounding of the line
            let r = (mesh.positions[t[(k + 1) % 3] as usize]
                + mesh.positions[t[(k + 2) % 3] as usize])
                * 0.5;
            check(
                &accel,
                p,
                (r - p).normalize(),
                "through vertex, edge-on triangle",
                &mut buf,
            );
            // through an edge's midpoint from outside
            let m = (p + q) * 0.5;
            let o = unit_vector(&mut rng) * 3.0;
            check(&accel, o, (m - o).normalize(), "aimed at edge", &mut buf);
        }
    }

    // Grid cube with exactly representable lattice: axis-parallel lines exactly through lattice
    // vertices, along cube edges, inside face planes, through the triangles' diagonals.
    let n = 8u32;
    let mesh = grid_cube(n);
    assert_closed(&mesh);
    let accel = Accel::new(mesh.clone());
    let h = 1.0 / n as f32; // half a cell
    for a in 0..3usize {
        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
        for i in 0..=2 * n {
            for j in 0..=2 * n {
                for sign in [1.0f32, -1.0] {
                    // lattice points and cell midpoints: i, j even → lattice, odd → midpoints
                    let mut o = Vec3::ZERO;
                    o[u] = -1.0 + i as f32 * h;
                    o[v] = -1.0 + j as f32 * h;
                    o[a] = -3.0 * sign;
                    let mut d = Vec3::ZERO;
                    d[a] = sign;
                    check(&accel, o, d, "cube axis line", &mut buf);
                }
            }
        }
    }
    // Lines exactly through every lattice vertex in random directions, and through face
    // diagonals in diagonal directions.
    let mut rng = Pcg32::seed_from_u64(99);
    for p in mesh.positions.clone() {
        for _ in 0..8 {
            check(&accel, p, unit_vector(&mut rng), "cube vertex", &mut buf);
        }
        for d in [
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::ONE,
        ] {
            check(&accel, p, d.normalize(), "cube vertex diagonal", &mut buf);
        }
    }
    assert!(total_lines > 100_000, "{total_lines}");
    assert!(total_hits > 100_000, "{total_hits}");
}

/// The same lines through vertices break a non-watertight test (sensitivity of the test above):
/// Möller–Trumbore with inclusive bounds double counts, exclusive bounds miss.
#[test]
fn vertex_lines_break_moller_trumbore() {
    let mesh = noisy_icosphere(3, 0.1, 0.05, 11);
    let mut rng = Pcg32::seed_from_u64(5);
    let mut odd = 0;
    for _ in 0..300 {
        let o = mesh.positions[rng.random_range(0..mesh.positions.len())];
        let d = unit_vector(&mut rng);
        let mut count = 0;
        for i in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.triangle(i);
            let (e1, e2) = (b - a, c - a);
            let pv = d.cross(e2);
            let det = e1.dot(pv);
            if det == 0.0 {
                continue;
            }
            let inv = 1.0 / det;
            let tv = o - a;
            let u = tv.dot(pv) * inv;
            let qv = tv.cross(e1);
            let v = d.dot(qv) * inv;
            if u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
                count += 1;
            }
        }
        odd += count % 2;
    }
    assert!(odd > 0, "the vertex lines do not exercise watertightness");
}

/// Exact length of the part of segment a→b inside the ball of radius r at the origin.
fn ball_chord(a: Vec3, b: Vec3, r: f64) -> f64 {
    let (a, b) = (a.as_dvec3(), b.as_dvec3());
    let d = b - a;
    let len = d.length();
    let u = d / len;
    let pb = a.dot(u);
    let disc = pb * pb - (a.length_squared() - r * r);
    if disc <= 0.0 {
        return 0.0;
    }
    let (t0, t1) = (-pb - disc.sqrt(), -pb + disc.sqrt());
    (t1.min(len) - t0.max(0.0)).max(0.0)
}

#[test]
fn inside_length_and_contains_match_the_sphere() {
    let mut rng = Pcg32::seed_from_u64(3);
    for radius in [1.0f32, 0.25] {
        let mut mesh = icosphere(5);
        for p in &mut mesh.positions {
            *p *= radius;
        }
        mesh.normals = Some(mesh.positions.iter().map(|p| p.normalize()).collect());
        // The tessellation lies between the inscribed ball (distance from the centre to the
        // nearest face plane: the faces are nearly equilateral and contain their plane's closest
        // point to the centre) and the circumscribed one (all vertices at `radius`).
        let r_in = (0..mesh.triangle_count())
            .map(|i| {
                let [a, ..] = mesh.triangle(i).map(|v| v.as_dvec3());
                let n = mesh.face_normal_raw(i).as_dvec3().normalize();
                a.dot(n)
            })
            .fold(f64::INFINITY, f64::min);
        let r_out = radius as f64;
        assert!(r_out - r_in < 6e-4 * r_out && r_in > 0.0, "{r_in}");
        let accel = Accel::new(mesh);
        let tol = 2e-6 * radius as f64;
        for k in 0..20_000 {
            let (a, b) = match k % 4 {
                // both outside, crossing
                0 => {
                    let a = unit_vector(&mut rng) * 2.0 * radius;
                    (a, a + (in_ball(&mut rng, radius) - a) * 3.0)
                }
                // inside → outside
                1 => (
                    in_ball(&mut rng, 0.95 * radius),
                    unit_vector(&mut rng) * 1.5 * radius,
                ),
                // both inside
                2 => (
                    in_ball(&mut rng, 0.95 * radius),
                    in_ball(&mut rng, 0.95 * radius),
                ),
                // anywhere
                _ => (
                    in_ball(&mut rng, 2.0 * radius),
                    in_ball(&mut rng, 2.0 * radius),
                ),
            };
            let got = accel.inside_length(a, b) as f64;
            let lo = ball_chord(a, b, r_in);
            let hi = ball_chord(a, b, r_out);
            assert!(
                got >= lo - tol && got <= hi + tol,
                "a {a} b {b}: {got} not in [{lo}, {hi}]"
            );
            // Reversing the segment gives the same length up to rounding, which grazing rays
            // amplify (t error ~ ε/sin θ), so only check lines well inside the sphere.
            let dist_line = (a.as_dvec3().cross((b - a).as_dvec3().normalize())).length();
            if dist_line < 0.99 * r_in {
                let back = accel.inside_length(b, a) as f64;
                let tol_sym = 1e-5 * radius as f64 * (1.0 + (b - a).length() as f64);
                assert!((got - back).abs() <= tol_sym, "asymmetric: {got} vs {back}");
            }
            // contains(): exact away from the tessellation band
            let p = in_ball(&mut rng, 1.5 * radius);
            let r = p.length() as f64;
            if r < r_in - tol {
                assert!(accel.contains(p), "{p} should be inside");
            } else if r > r_out + tol {
                assert!(!accel.contains(p), "{p} should be outside");
            }
        }
        // Degenerate segments.
        assert_eq!(accel.inside_length(Vec3::ZERO, Vec3::ZERO), 0.0);
        let full = accel.inside_length(
            Vec3::new(0.0, 0.0, -2.0 * radius),
            Vec3::new(0.0, 0.0, 2.0 * radius),
        );
        assert!((full as f64 - 2.0 * r_out).abs() < 2.0 * (r_out - r_in) + tol);
    }
}

/// contains() agrees with the parity of brute-force crossings along another direction on a
/// bumpy mesh, and inside_length() with the sum of brute-force inside intervals.
#[test]
fn contains_and_inside_length_match_brute_force_on_bumpy_mesh() {
    let mesh = noisy_icosphere(3, 0.12, 0.05, 21);
    let accel = Accel::new(mesh.clone());
    let mut rng = Pcg32::seed_from_u64(22);
    let probe = Vec3::new(-0.31, 0.77, 0.55).normalize();
    for _ in 0..3000 {
        let p = in_ball(&mut rng, 1.3);
        let crossings = brute_all(&mesh, p, probe, 0.0, f32::INFINITY).len();
        assert_eq!(accel.contains(p), crossings % 2 == 1, "{p}");
        let q = in_ball(&mut rng, 1.3);
        let d = (q - p).normalize();
        let len = (q - p).length();
        // Brute force: inside at p by parity, then toggle at each crossing on the segment.
        let mut inside = crossings % 2 == 1;
        let mut last = 0.0f32;
        let mut total = 0.0f32;
        for (t, _) in brute_all(&mesh, p, d, 0.0, len) {
            if inside {
                total += t - last;
            }
            inside = !inside;
            last = t;
        }
        if inside {
            total += len - last;
        }
        let got = accel.inside_length(p, q);
        assert!(
            (got - total).abs() <= 1e-5 * (1.0 + len),
            "p {p} q {q}: {got} vs {total}"
        );
    }
}

/// Mesh of triangles whose areas span three decades (not closed: the sampler does not care).
fn mixed_size_triangles(rng: &mut Pcg32, count: usize) -> Mesh {
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for k in 0..count {
        let scale = 10f32.powf(-1.5 * k as f32 / (count - 1) as f32); // area ∝ scale²: 1 … 1e-3
        let c = in_ball(rng, 5.0);
        let (e1, e2) = (unit_vector(rng), unit_vector(rng));
        let base = positions.len() as u32;
        positions.extend_from_slice(&[c, c + e1 * scale, c + (e2 + e1 * 0.3) * scale]);
        indices.push([base, base + 1, base + 2]);
    }
    Mesh {
        positions,
        normals: None,
        indices,
    }
}

#[test]
fn area_sampler_is_uniform_by_area() {
    let mut rng = Pcg32::seed_from_u64(31);
    let mut mesh = mixed_size_triangles(&mut rng, 40);
    mesh.normals = Some(vertex_normals(&mesh));
    let sampler = AreaSampler::new(&mesh);
    let areas: Vec<f64> = (0..mesh.triangle_count())
        .map(|i| {
            let [a, b, c] = mesh.triangle(i).map(|v| v.as_dvec3());
            (b - a).cross(c - a).length() * 0.5
        })
        .collect();
    let total: f64 = areas.iter().sum();
    assert!((sampler.total_area() - total).abs() < 1e-9 * total);
    let probs: Vec<f64> = areas.iter().map(|a| a / total).collect();
    assert!(
        probs.iter().cloned().fold(f64::INFINITY, f64::min)
            < 1e-3 * probs.iter().cloned().fold(0.0, f64::max) * 1.01
    );

    let n = 2_000_000u64;
    let mut counts = vec![0u64; mesh.triangle_count()];
    for _ in 0..n {
        let s = sampler.sample(&mesh, [rng.random(), rng.random(), rng.random()]);
        counts[s.tri as usize] += 1;
    }
    let (stat, p) = chi_square(&counts, &probs);
    assert!(
        p > 1e-3,
        "triangle choice not area-proportional: chi2 {stat}, p {p}"
    );

    // Every field of a sample.
    for _ in 0..1000 {
        let s = sampler.sample(&mesh, [rng.random(), rng.random(), rng.random()]);
        let [a, b, c] = mesh.triangle(s.tri as usize);
        let ng = mesh.face_normal_raw(s.tri as usize).normalize();
        assert!((s.ng - ng).length() < 1e-5);
        assert!(s.ns.dot(s.ng) >= 0.0 && (s.ns.length() - 1.0).abs() < 1e-5);
        assert!((s.pdf as f64 - 1.0 / total).abs() < 1e-6 / total);
        assert!((s.p - a).dot(ng).abs() < 1e-5, "off the plane");
        let bary = barycentrics(s.p, a, b, c);
        assert!(bary.iter().all(|&x| x > -1e-5));
    }
}

/// Barycentrics (b0, b1, b2) of p in triangle abc (f64 least squares).
fn barycentrics(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> [f64; 3] {
    let (p, a, b, c) = (p.as_dvec3(), a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let (e1, e2, r) = (b - a, c - a, p - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (r.dot(e1), r.dot(e2));
    let det = d11 * d22 - d12 * d12;
    let b1 = (d22 * r1 - d12 * r2) / det;
    let b2 = (d11 * r2 - d12 * r1) / det;
    [1.0 - b1 - b2, b1, b2]
}

#[test]
fn area_sampler_is_uniform_within_triangles() {
    // One fat and one sliver triangle; bin the samples into the k² congruent sub-triangles of the
    // k-fold subdivision (cell (i, j) of the (b1, b2) grid, lower or upper half).
    let mesh = Mesh {
        positions: vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.1, 0.0),
            Vec3::new(0.3, 1.7, 0.4),
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(9.0, 0.02, 0.0),
            Vec3::new(5.5, 0.05, 0.01),
        ],
        normals: None,
        indices: vec![[0, 1, 2], [3, 4, 5]],
    };
    let sampler = AreaSampler::new(&mesh);
    let k = 8usize;
    let mut rng = Pcg32::seed_from_u64(41);
    let mut counts = vec![vec![0u64; k * k]; 2];
    for _ in 0..1_000_000 {
        let s = sampler.sample(&mesh, [rng.random(), rng.random(), rng.random()]);
        let [a, b, c] = mesh.triangle(s.tri as usize);
        let [_, b1, b2] = barycentrics(s.p, a, b, c);
        let (x, y) = (
            (b1 * k as f64).clamp(0.0, k as f64 - 1e-9),
            (b2 * k as f64).clamp(0.0, k as f64 - 1e-9),
        );
        let (i, mut j) = (x.floor() as usize, y.floor() as usize);
        j = j.min(k - 1 - i); // rounding at the hypotenuse
        let upper = (x - i as f64) + (y - j as f64) >= 1.0 && i + j < k - 1;
        // Index the k² sub-triangles: lower ones (i + j ≤ k − 1), then upper ones (i + j ≤ k − 2).
        let lower_count = k * (k + 1) / 2;
        let idx = if upper {
            lower_count + tri_index(i, j, k - 1)
        } else {
            tri_index(i, j, k)
        };
        counts[s.tri as usize][idx] += 1;
    }
    for c in &counts {
        let probs = vec![1.0 / (k * k) as f64; k * k];
        let (stat, p) = chi_square(c, &probs);
        assert!(
            p > 1e-3,
            "not uniform inside the triangle: chi2 {stat}, p {p}"
        );
    }
}

/// Index of cell (i, j), i + j < m, in a triangular array with m − i cells in row i.
fn tri_index(i: usize, j: usize, m: usize) -> usize {
    assert!(i + j < m);
    i * m - i * i.saturating_sub(1) / 2 + j
}

/// Build/queries from several threads at once (the Accel is Send + Sync).
#[test]
fn accel_is_shareable_across_threads() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<Accel>();
    assert_send_sync::<AreaSampler>();
    let accel = Accel::new(noisy_icosphere(4, 0.1, 0.02, 51));
    let results: Vec<usize> = std::thread::scope(|s| {
        let hs: Vec<_> = (0..2)
            .map(|k| {
                let accel = &accel;
                s.spawn(move || {
                    let mut rng = Pcg32::seed_from_u64(60 + k);
                    (0..2000)
                        .filter(|_| {
                            let o = unit_vector(&mut rng) * 3.0;
                            accel
                                .closest(o, -o.normalize(), 0.0, f32::INFINITY)
                                .is_some()
                        })
                        .count()
                })
            })
            .collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(results, vec![2000, 2000]);
}

/// Full-line crossing consistency and brute-force agreement on every built-in shape (torus: non
/// convex with a hole; rounded box: large flat faces), at unit size and scaled to 0.25.
#[test]
fn builtin_shapes_are_watertight() {
    let mut buf = Vec::new();
    for name in geometry::Shape::NAMES {
        for scale in [1.0f32, 0.25] {
            let shape = geometry::Shape::from_name(name).unwrap().scaled(scale);
            let mesh = shape.build().unwrap();
            let accel = Accel::new(mesh.clone());
            let (lo, hi) = mesh.bounds();
            let (center, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
            let mut rng = Pcg32::seed_from_u64(71);
            for k in 0..4000 {
                let (o, d) = match k % 3 {
                    0 => {
                        let o = center + unit_vector(&mut rng) * 2.0 * radius;
                        (o, (center + in_ball(&mut rng, radius) - o).normalize())
                    }
                    1 => {
                        let v = mesh.positions[rng.random_range(0..mesh.positions.len())];
                        (v, unit_vector(&mut rng))
                    }
                    _ => {
                        let mut d = Vec3::ZERO;
                        d[k % 3] = 1.0;
                        let v = mesh.positions[rng.random_range(0..mesh.positions.len())];
                        (v, d)
                    }
                };
                accel.all_hits(o, d, f32::NEG_INFINITY, f32::INFINITY, &mut buf);
                assert!(line_is_consistent(&buf, d), "{name} x{scale}: o {o} d {d}");
                if k % 8 == 0 {
                    check_ray(&accel, &mesh, o, d, 0.0, f32::INFINITY, &mut buf);
                }
            }
        }
    }
}

/// `first_hits_both_ways` (one traversal) against its definition: two `closest` rays, one from
/// `x + a₀·d` along `d` and one from `x + b₁·d` along `−d`, on a bumpy sphere with points near
/// the surface (the learned BSSRDF's projection queries).
#[test]
fn first_hits_both_ways_match_two_closest_rays() {
    let mesh = noisy_icosphere(4, 0.12, 0.05, 31);
    let accel = Accel::new(mesh.clone());
    let mut rng = Pcg32::seed_from_u64(32);
    let same =
        |got: Option<geometry::Hit>, want: Option<geometry::Hit>, s_want: f32, what: &str| {
            match (got, want) {
                (None, None) => {}
                (Some(g), Some(w)) => {
                    // Rounding may pick the neighbour at a shared edge; the point must agree.
                    assert!(
                        (g.t - s_want).abs() <= 1e-5 && (g.p - w.p).length() <= 1e-5,
                        "{what}: s {} vs {s_want}, p {} vs {}",
                        g.t,
                        g.p,
                        w.p
                    );
                    if g.tri != w.tri {
                        assert!((g.t - s_want).abs() <= 1e-6, "{what}: another triangle");
                    }
                }
                (g, w) => panic!("{what}: {g:?} vs {w:?}"),
            }
        };
    let (mut found_ahead, mut found_behind) = (0, 0);
    for _ in 0..4000 {
        let (p, n) = surface_point(&mut rng, &mesh);
        let x = p + n * rng.random_range(-0.08f32..0.08) + unit_vector(&mut rng) * 0.02;
        let d = unit_vector(&mut rng);
        let o = rng.random_range(0.0f32..0.02);
        let tmax = o + rng.random_range(0.001f32..0.3);
        let (ahead, behind) = accel.first_hits_both_ways(x, d, (-o, tmax - o), (o - tmax, o));
        let a = accel.closest(x - o * d, d, 0.0, tmax);
        let b = accel.closest(x + o * d, -d, 0.0, tmax);
        same(ahead, a, a.map_or(0.0, |h| h.t - o), "ahead");
        same(behind, b, b.map_or(0.0, |h| o - h.t), "behind");
        // The nearest of the two, built alone, is the one of the pair with the smaller |s|.
        let nearest = accel.nearest_hit_both_ways(x, d, (-o, tmax - o), (o - tmax, o));
        let want = match (ahead, behind) {
            (Some(f), Some(b)) => Some(if f.t.abs() <= b.t.abs() { f } else { b }),
            (f, b) => f.or(b),
        };
        assert_eq!(nearest, want, "nearest_hit_both_ways");
        found_ahead += a.is_some() as u32;
        found_behind += b.is_some() as u32;
    }
    // Both sides were exercised with hits and misses.
    assert!((500..3500).contains(&found_ahead), "{found_ahead}");
    assert!((500..3500).contains(&found_behind), "{found_behind}");
}
