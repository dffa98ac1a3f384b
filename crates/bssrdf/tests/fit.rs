//! Tests of the constraint cloud and the weighted least-squares cubic fit
//! (docs/model.md §3.2, §3.4).
//!
//! Analytic surfaces whose exact implicit function is a quadratic (sphere, cylinder, plane) must
//! be recovered: the fitted zero set passes through held-out surface points and its gradient is
//! the true normal there. A brute-force reference (dense rows, spec weights) checks the assembly.

use std::time::Instant;
use testkit::random_unit_vector;

use bssrdf::fit::{ConstraintCloud, fit_mesh_vertices, interpolate};
use bssrdf::medium;
use bssrdf::polynomial::{N_COEFFS, Poly3, monomial_gradients_f64, monomials_f64};
use geometry::shapes::Shape;
use geometry::{Mat4, Mesh, Vec3};
use glam::{DVec3, Quat};
use nalgebra::{DMatrix, DVector};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// `n` points uniform on the sphere (centre `c`, radius `r`) with outward normals.
fn sphere_cloud(rng: &mut Pcg64, n: usize, c: Vec3, r: f32) -> (Vec<Vec3>, Vec<Vec3>) {
    (0..n)
        .map(|_| {
            let d = random_unit_vector(rng);
            (c + r * d, d)
        })
        .unzip()
}

/// `n` points uniform on the lateral surface of a cylinder (axis `a` through `c`, radius `r`,
/// length `len`) with outward normals.
fn cylinder_cloud(
    rng: &mut Pcg64,
    n: usize,
    c: Vec3,
    a: Vec3,
    r: f32,
    len: f32,
) -> (Vec<Vec3>, Vec<Vec3>) {
    let f = geometry::Frame::from_normal(a);
    (0..n)
        .map(|_| {
            let phi = std::f32::consts::TAU * rng.random::<f32>();
            let t = len * (rng.random::<f32>() - 0.5);
            let d = f.s * phi.cos() + f.t * phi.sin();
            (c + a * t + r * d, d)
        })
        .unzip()
}

struct ZeroSetError {
    /// max |p(u)| / |∇p(u)| in units of σ_n over the held-out points
    distance: f64,
    /// max angle (rad) between ∇p and the true normal
    angle: f64,
}

/// Check the fit against held-out surface points (q, n_q) within `max_r` σ_n of `p`.
fn zero_set_error(
    poly: &Poly3,
    p: Vec3,
    sigma_n: f64,
    held_out: &[(Vec3, Vec3)],
    max_r: f64,
) -> ZeroSetError {
    let mut out = ZeroSetError {
        distance: 0.0,
        angle: 0.0,
    };
    let mut count = 0;
    for &(q, nq) in held_out {
        let u = (q.as_dvec3() - p.as_dvec3()) / sigma_n;
        if u.length() > max_r {
            continue;
        }
        count += 1;
        let v = poly.eval_f64(u.to_array());
        let g = DVec3::from(poly.gradient_f64(u.to_array()));
        out.distance = out.distance.max(v.abs() / g.length());
        let cos = (g.normalize().dot(nq.as_dvec3())).clamp(-1.0, 1.0);
        out.angle = out.angle.max(cos.acos());
    }
    assert!(count >= 10, "too few held-out points ({count})");
    out
}

/// Dense reference: rows and weights exactly as written in docs/model.md §3.2.
fn reference_fit(cloud: &ConstraintCloud, p: Vec3, eps: f64) -> [f64; N_COEFFS] {
    let sigma_n = eps.sqrt();
    let pd = p.as_dvec3();
    let mut rows: Vec<(f64, DVec3, DVec3)> = Vec::new(); // (w, r, n)
    let mut local = Vec::new();
    for (q, n) in cloud.points().iter().zip(cloud.normals()) {
        let d2 = (q.as_dvec3() - pd).length_squared();
        if d2 < 9.0 * eps {
            local.push((d2, *q, *n));
        }
    }
    let n_tot = local.len() + 32;
    for (d2, q, n) in local {
        let w = (-d2 / (2.0 * eps)).exp().sqrt() / (n_tot as f64).sqrt();
        rows.push((w, (q.as_dvec3() - pd) / sigma_n, n.as_dvec3()));
    }
    for (q, n) in cloud.points()[..32].iter().zip(cloud.normals()) {
        rows.push((
            0.01 * (1.0f64 / 32.0).sqrt(),
            (q.as_dvec3() - pd) / sigma_n,
            n.as_dvec3(),
        ));
    }
    let m = rows.len();
    let mut a = DMatrix::<f64>::zeros(4 * m, 19);
    let mut b = DVector::<f64>::zeros(4 * m);
    for (i, (w, r, n)) in rows.iter().enumerate() {
        let mono = monomials_f64(r.to_array());
        let grad = monomial_gradients_f64(r.to_array());
        for k in 1..20 {
            a[(4 * i, k - 1)] = w * mono[k];
            for axis in 0..3 {
                a[(4 * i + 1 + axis, k - 1)] = w * grad[axis][k];
            }
        }
        for axis in 0..3 {
            b[4 * i + 1 + axis] = w * n[axis];
        }
    }
    let mut ata = a.transpose() * &a;
    for k in 3..19 {
        ata[(k, k)] += 1e-4;
    }
    let atb = a.transpose() * b;
    let x = ata.lu().solve(&atb).unwrap();
    let mut c = [0.0; N_COEFFS];
    for k in 1..20 {
        c[k] = x[k - 1];
    }
    c
}

#[test]
fn assembly_matches_dense_reference() {
    let mut rng = Pcg64::seed_from_u64(11);
    let (pts, nrm) = sphere_cloud(&mut rng, 3000, Vec3::new(0.1, -0.2, 0.3), 1.0);
    let cloud = ConstraintCloud::from_points(pts.clone(), nrm).unwrap();
    for (i, sigma_n) in [(100usize, 0.25f64), (200, 0.1), (300, 0.4)] {
        let eps = sigma_n * sigma_n;
        let p = pts[i];
        let fit = cloud.fit_at(p, eps, false).unwrap();
        let reference = reference_fit(&cloud, p, eps);
        for k in 0..N_COEFFS {
            assert!(
                (fit.0[k] as f64 - reference[k]).abs() < 1e-5 * (1.0 + reference[k].abs()),
                "σ_n {sigma_n} k {k}: {} vs {}",
                fit.0[k],
                reference[k]
            );
        }
        assert!(cloud.local_count(p, eps) > 20);
        // the quirk drops the solved z³ value and keeps everything else
        let quirk = cloud.fit_at(p, eps, true).unwrap();
        assert_eq!(quirk.0[19], 0.0);
        assert_eq!(&quirk.0[..19], &fit.0[..19]);
    }
}

/// Sphere of radius R, σ_n = R/4 (ρ = R/σ_n = 4): exact implicit function n·u + |u|²/(2ρ).
#[test]
fn sphere_is_recovered() {
    let mut rng = Pcg64::seed_from_u64(12);
    let r = 0.8f32;
    let c = Vec3::new(0.3, 0.1, -0.2);
    let (pts, nrm) = sphere_cloud(&mut rng, 4000, c, r);
    let cloud = ConstraintCloud::from_points(pts.clone(), nrm).unwrap();
    let (ho_p, ho_n) = sphere_cloud(&mut rng, 20_000, c, r);
    let held_out: Vec<(Vec3, Vec3)> = ho_p.into_iter().zip(ho_n).collect();
    let sigma_n = r as f64 / 4.0;
    let rho = r as f64 / sigma_n;
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for quirk in [false, true] {
        for i in (40..4000).step_by(397) {
            let p = pts[i];
            let n = (p - c).normalize();
            let poly = cloud.fit_at(p, sigma_n * sigma_n, quirk).unwrap();
            let e = zero_set_error(&poly, p, sigma_n, &held_out, 2.0);
            let mut exact = [0.0f64; 20];
            exact[1..4].copy_from_slice(&n.as_dvec3().to_array());
            exact[4] = 0.5 / rho;
            exact[7] = 0.5 / rho;
            exact[9] = 0.5 / rho;
            let coeff_err = (0..20)
                .map(|k| (poly.0[k] as f64 - exact[k]).abs())
                .fold(0.0, f64::max);
            worst = (
                worst.0.max(e.distance),
                worst.1.max(e.angle),
                worst.2.max(coeff_err),
            );
        }
    }
    println!(
        "sphere: max |p|/|∇p| = {:.2e} σ_n, max normal angle = {:.2e} rad, max coeff err = {:.2e}",
        worst.0, worst.1, worst.2
    );
    assert!(worst.0 < 2e-3, "zero set off the sphere by {} σ_n", worst.0);
    assert!(worst.1 < 5e-3, "normal angle {}", worst.1);
    assert!(
        worst.2 < 5e-3,
        "coefficients differ from the exact implicit by {}",
        worst.2
    );
}

/// Cylinder of radius R along an oblique axis: exact implicit n·u + |u_⊥|²/(2ρ).
#[test]
fn cylinder_is_recovered() {
    let mut rng = Pcg64::seed_from_u64(13);
    let r = 0.5f32;
    let axis = Vec3::new(0.3, 0.8, -0.5).normalize();
    let c = Vec3::new(-0.1, 0.2, 0.05);
    let len = 6.0;
    let (pts, nrm) = cylinder_cloud(&mut rng, 12_000, c, axis, r, len);
    let cloud = ConstraintCloud::from_points(pts.clone(), nrm).unwrap();
    let (ho_p, ho_n) = cylinder_cloud(&mut rng, 50_000, c, axis, r, len);
    let held_out: Vec<(Vec3, Vec3)> = ho_p.into_iter().zip(ho_n).collect();
    let sigma_n = r as f64 / 4.0;
    let rho = r as f64 / sigma_n;
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    let mut fitted = 0;
    for (i, &p) in pts.iter().enumerate().skip(32) {
        // stay away from the open ends
        if ((p - c).dot(axis)).abs() > 0.3 * len || i % 97 != 0 {
            continue;
        }
        fitted += 1;
        let poly = cloud.fit_at(p, sigma_n * sigma_n, true).unwrap();
        let e = zero_set_error(&poly, p, sigma_n, &held_out, 2.0);
        let n = ((p - c) - axis * (p - c).dot(axis)).normalize().as_dvec3();
        let a = axis.as_dvec3();
        let mut worst_val = 0.0f64;
        for _ in 0..20 {
            let u = random_unit_vector(&mut rng).as_dvec3() * 1.5;
            let u_perp = u - a * u.dot(a);
            let exact = n.dot(u) + u_perp.length_squared() / (2.0 * rho);
            worst_val = worst_val.max((poly.eval_f64(u.to_array()) - exact).abs());
        }
        worst = (
            worst.0.max(e.distance),
            worst.1.max(e.angle),
            worst.2.max(worst_val),
        );
    }
    assert!(fitted >= 20);
    println!(
        "cylinder: max |p|/|∇p| = {:.2e} σ_n, max normal angle = {:.2e} rad, max |p − p_exact| \
         (|u| ≤ 1.5) = {:.2e}",
        worst.0, worst.1, worst.2
    );
    assert!(
        worst.0 < 2e-3,
        "zero set off the cylinder by {} σ_n",
        worst.0
    );
    assert!(worst.1 < 5e-3, "normal angle {}", worst.1);
    // Off the surface the fit is pinned only through the gradient constraints (and the ridge),
    // so the implicit values agree less tightly than the zero set.
    assert!(
        worst.2 < 3e-2,
        "implicit differs from the exact one by {}",
        worst.2
    );
}

fn square(half: f32) -> Mesh {
    Mesh {
        positions: vec![
            Vec3::new(-half, -half, 0.0),
            Vec3::new(half, -half, 0.0),
            Vec3::new(half, half, 0.0),
            Vec3::new(-half, half, 0.0),
        ],
        normals: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// For a plane the fit is exactly u·n (the mesh path, with the medium's ε).
#[test]
fn plane_fit_is_exact() {
    let eps = medium::kernel_epsilon(10.0, 0.9, 0.0, 1.0); // σ_n ≈ 0.1
    let mesh = square(1.0);
    let cloud = ConstraintCloud::from_mesh(&mesh, eps, 5).unwrap();
    assert_eq!(cloud.len(), ((2.0 * 4.0 / eps) as usize).max(1024));
    let polys = cloud.fit_vertices(&mesh, eps, true).unwrap();
    let inner = cloud
        .fit_points(&[Vec3::new(0.1, -0.3, 0.0), Vec3::ZERO], eps, true)
        .unwrap();
    for poly in polys.iter().chain(&inner) {
        let mut want = [0.0f32; 20];
        want[3] = 1.0;
        for k in 0..N_COEFFS {
            assert!((poly.0[k] - want[k]).abs() < 1e-6, "k {k}: {}", poly.0[k]);
        }
    }
    // tilted plane (f32 rounding of the rotated positions ⇒ slightly looser)
    let rot = Quat::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.9);
    let mut tilted = mesh.clone();
    tilted.transform(Mat4::from_quat(rot));
    let n = rot * Vec3::Z;
    let polys = fit_mesh_vertices(&tilted, eps, 5, false).unwrap();
    for poly in &polys {
        let want = Poly3::plane(n);
        for k in 0..N_COEFFS {
            assert!((poly.0[k] - want.0[k]).abs() < 2e-5, "k {k}: {}", poly.0[k]);
        }
    }
}

/// Icosphere mesh through the mesh path: vertex fits match the analytic sphere.
#[test]
fn icosphere_mesh_fits_match_sphere() {
    let r = 0.5f32;
    let mesh = Shape::Sphere {
        radius: r,
        subdivisions: 5,
    }
    .build()
    .unwrap();
    let sigma_n = 0.125f64;
    let eps = sigma_n * sigma_n;
    let cloud = ConstraintCloud::from_mesh(&mesh, eps, 1).unwrap();
    let verts: Vec<Vec3> = mesh.positions.iter().step_by(211).copied().collect();
    let polys = cloud.fit_points(&verts, eps, true).unwrap();
    let mut rng = Pcg64::seed_from_u64(14);
    let (ho_p, ho_n) = sphere_cloud(&mut rng, 20_000, Vec3::ZERO, r);
    let held_out: Vec<(Vec3, Vec3)> = ho_p.into_iter().zip(ho_n).collect();
    let mut worst = (0.0f64, 0.0f64);
    for (p, poly) in verts.iter().zip(&polys) {
        let e = zero_set_error(poly, *p, sigma_n, &held_out, 2.0);
        worst = (worst.0.max(e.distance), worst.1.max(e.angle));
        let n = poly.normal().unwrap();
        assert!(n.dot(p.normalize()) > 0.9999);
    }
    println!(
        "icosphere (5 subdiv.): max |p|/|∇p| = {:.2e} σ_n, max normal angle = {:.2e} rad",
        worst.0, worst.1
    );
    // tessellation: sagitta of a ~0.017-unit edge on R = 0.5 is ~1e-4 units ≈ 1e-3 σ_n
    assert!(worst.0 < 1e-2);
    assert!(worst.1 < 2e-2);
}

fn blob() -> Mesh {
    Shape::Blob {
        radius: 0.5,
        amplitude: 0.2,
        bumps: 12,
        seed: 3,
        subdivisions: 4,
    }
    .build()
    .unwrap()
}

/// Rotating the mesh rigidly and rotating the fitted world polynomials back gives the same
/// polynomials (without the c_19 quirk, which is tied to the world z axis).
#[test]
fn rigid_rotation_invariance() {
    let mesh = blob();
    let eps = medium::kernel_epsilon(40.0, 0.9, 0.0, 1.0);
    let rot = Quat::from_axis_angle(Vec3::new(-0.4, 0.7, 0.2).normalize(), 2.1);
    let mut rotated = mesh.clone();
    rotated.transform(Mat4::from_quat(rot));
    let a = fit_mesh_vertices(&mesh, eps, 9, false).unwrap();
    let b = fit_mesh_vertices(&rotated, eps, 9, false).unwrap();
    let m = geometry::Mat3::from_quat(rot);
    let mut worst = 0.0f32;
    for (pa, pb) in a.iter().zip(&b) {
        // p_b(u') = p_a(Rᵀ u') ⇒ p_a(u) = p_b(R u): rotate p_b by the columns of R
        let back = pb.rotate(m.x_axis, m.y_axis, m.z_axis);
        let scale = pa.0.iter().fold(0.0f32, |s, c| s.max(c.abs()));
        for k in 0..N_COEFFS {
            worst = worst.max((back.0[k] - pa.0[k]).abs() / scale);
        }
    }
    println!("rigid rotation: max relative coefficient difference {worst:.2e}");
    assert!(worst < 1e-3, "{worst}");
}

#[test]
fn deterministic_and_thread_independent() {
    let mesh = blob();
    let eps = medium::kernel_epsilon(40.0, 0.9, 0.0, 1.0);
    let c1 = ConstraintCloud::from_mesh(&mesh, eps, 42).unwrap();
    let c2 = ConstraintCloud::from_mesh(&mesh, eps, 42).unwrap();
    assert_eq!(c1.points(), c2.points());
    assert_eq!(c1.normals(), c2.normals());
    let c3 = ConstraintCloud::from_mesh(&mesh, eps, 43).unwrap();
    assert_ne!(c1.points(), c3.points());
    assert_eq!(c1.global_points().len(), 32);
    assert_eq!(c1.global_points(), &c1.points()[..32]);

    let a = c1.fit_vertices(&mesh, eps, true).unwrap();
    let b = c2.fit_vertices(&mesh, eps, true).unwrap();
    assert_eq!(a, b);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let single = pool.install(|| {
        let c = ConstraintCloud::from_mesh(&mesh, eps, 42).unwrap();
        assert_eq!(c.points(), c1.points());
        c.fit_vertices(&mesh, eps, true).unwrap()
    });
    assert_eq!(a, single);
    let sequential: Vec<Poly3> = mesh
        .positions
        .iter()
        .map(|&p| c1.fit_at(p, eps, true).unwrap())
        .collect();
    assert_eq!(a, sequential);
}

#[test]
fn interpolation_is_barycentric() {
    let mesh = blob();
    let eps = medium::kernel_epsilon(40.0, 0.9, 0.0, 1.0);
    let polys = fit_mesh_vertices(&mesh, eps, 1, true).unwrap();
    let [i0, i1, i2] = mesh.indices[17].map(|i| i as usize);
    let tri = [&polys[i0], &polys[i1], &polys[i2]];
    assert_eq!(interpolate(tri, [1.0, 0.0, 0.0]), polys[i0]);
    assert_eq!(interpolate(tri, [0.0, 0.0, 1.0]), polys[i2]);
    let b = [0.2, 0.5, 0.3];
    let p = interpolate(tri, b);
    for k in 0..N_COEFFS {
        let want = b[0] * tri[0].0[k] + b[1] * tri[1].0[k] + b[2] * tri[2].0[k];
        assert!((p.0[k] - want).abs() < 1e-6);
    }
    assert_eq!(p.0[0], 0.0);
    // the interpolated normal is close to the vertex normals on a fine mesh
    let n = p.normal().unwrap();
    assert!(n.dot(tri[0].normal().unwrap()) > 0.9);
}

/// A fit far from the surface has only the global constraints and still returns a finite cubic.
#[test]
fn fit_far_from_surface_is_finite() {
    let mesh = blob();
    let eps = medium::kernel_epsilon(40.0, 0.9, 0.0, 1.0);
    let cloud = ConstraintCloud::from_mesh(&mesh, eps, 3).unwrap();
    let p = Vec3::new(5.0, 5.0, 5.0);
    assert_eq!(cloud.local_count(p, eps), 0);
    let poly = cloud.fit_at(p, eps, true).unwrap();
    assert!(poly.0.iter().all(|c| c.is_finite()));
}

/// Timing (printed with `--nocapture`, not asserted).
#[test]
fn fit_timing() {
    let mesh = Shape::Blob {
        radius: 0.5,
        amplitude: 0.15,
        bumps: 12,
        seed: 7,
        subdivisions: 6,
    }
    .build()
    .unwrap();
    for (sigma_t, albedo) in [(30.0, 0.98), (50.0, 0.9), (100.0, 0.8)] {
        let eps = medium::kernel_epsilon(sigma_t, albedo, 0.0, 1.0);
        let t0 = Instant::now();
        let cloud = ConstraintCloud::from_mesh(&mesh, eps, 0).unwrap();
        let t_cloud = t0.elapsed();
        let verts = &mesh.positions;
        let n_seq = verts.len().min(5000);
        let t1 = Instant::now();
        let mut acc = 0.0f32;
        for &p in &verts[..n_seq] {
            acc += cloud.fit_at(p, eps, true).unwrap().0[3];
        }
        let t_seq = t1.elapsed();
        let t2 = Instant::now();
        let all = cloud.fit_vertices(&mesh, eps, true).unwrap();
        let t_par = t2.elapsed();
        let t3 = Instant::now();
        let mean_local = verts[..n_seq]
            .iter()
            .map(|&p| cloud.local_count(p, eps))
            .sum::<usize>() as f64
            / n_seq as f64;
        let t_query = t3.elapsed();
        println!(
            "σ_t {sigma_t}, α {albedo}: σ_n {:.4}, cloud {} pts in {:.1} ms, {:.1} local pts/fit, \
             {:.2} µs/fit (1 thread; k-d query alone {:.2} µs), {} vertices in {:.1} ms \
             ({} threads) [{acc:.1}]",
            eps.sqrt(),
            cloud.len(),
            t_cloud.as_secs_f64() * 1e3,
            mean_local,
            t_seq.as_secs_f64() * 1e6 / n_seq as f64,
            t_query.as_secs_f64() * 1e6 / n_seq as f64,
            all.len(),
            t_par.as_secs_f64() * 1e3,
            rayon::current_num_threads(),
        );
    }
}

/// `VertexFeatures::fit_with_derivative`: its fits are those of `fit` (same cloud and seed), and
/// its first-order prediction of a refit at σ_n·e^{±0.05} on the bumpy blob (where the fit
/// depends on the kernel beyond the rescaling) is much closer to the refit on the same cloud
/// than the rescaling alone: the remaining error is second order, ~(0.05/0.1)² of the
/// derivative's own truncation, while the rescaling misses the whole first-order term.
#[test]
fn fit_derivative_predicts_a_refit() {
    use bssrdf::render::{DFIT_STEP, VertexFeatures};
    let mesh = blob();
    let accel = geometry::Accel::new(mesh.clone());
    let m = scene::Medium {
        sigma_t: [40.0; 3],
        albedo: [0.9; 3],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let plain = VertexFeatures::fit(&accel, &m, true, 5).unwrap();
    let with = VertexFeatures::fit_with_derivative(&accel, &m, true, 5).unwrap();
    assert_eq!(plain.polys, with.polys);
    let dfit = with.dfit.as_ref().unwrap();
    let sn = with.sigma_n[0] as f64;
    let cloud = ConstraintCloud::from_mesh(&mesh, sn * sn, 5).unwrap();
    for l in [0.05f32, -0.05] {
        let refit = cloud
            .fit_vertices(&mesh, sn * sn * (2.0 * l as f64).exp(), true)
            .unwrap();
        let (mut err_rescale, mut err_linear, mut scale) = (0.0f64, 0.0f64, 0.0f64);
        for ((g, d), r) in with.polys[0].iter().zip(&dfit[0]).zip(&refit) {
            let resc = g.rescaled(l.exp());
            for k in 0..N_COEFFS {
                let lin = resc.0[k] + l * d.0[k];
                err_rescale += ((resc.0[k] - r.0[k]) as f64).powi(2);
                err_linear += ((lin - r.0[k]) as f64).powi(2);
                scale += (r.0[k] as f64).powi(2);
            }
        }
        let (er, el) = ((err_rescale / scale).sqrt(), (err_linear / scale).sqrt());
        println!("ln k = {l}: rescaling misses {er:.3e}, with dfit {el:.3e} (step {DFIT_STEP})");
        assert!(
            er > 1e-4,
            "the refit should differ from the rescaling ({er:.2e})"
        );
        assert!(
            el < 0.3 * er,
            "dfit should remove most of it: {el:.2e} vs {er:.2e}"
        );
    }
}
