//! Tests of the cubic polynomial: evaluation, gradients, exact rotation, light-space frame and
//! incident-direction alignment (docs/model.md §3.1, §3.3, §3.5).

use bssrdf::polynomial::{
    N_COEFFS, POWERS, Poly3, align_direction, light_space_frame, monomial_gradients,
    monomial_gradients_f64, monomials, monomials_f64,
};
use glam::{DMat3, DVec3, Mat3, Quat, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use testkit::random_unit_vector;

fn random_poly(rng: &mut Pcg64) -> Poly3 {
    Poly3(std::array::from_fn(|_| 2.0 * rng.random::<f32>() - 1.0))
}

fn random_rotation(rng: &mut Pcg64) -> Mat3 {
    let axis = random_unit_vector(rng);
    let angle = std::f32::consts::TAU * rng.random::<f32>();
    Mat3::from_quat(Quat::from_axis_angle(axis, angle))
}

fn random_point(rng: &mut Pcg64, scale: f32) -> Vec3 {
    Vec3::new(
        scale * (2.0 * rng.random::<f32>() - 1.0),
        scale * (2.0 * rng.random::<f32>() - 1.0),
        scale * (2.0 * rng.random::<f32>() - 1.0),
    )
}

fn dv(v: Vec3) -> [f64; 3] {
    v.as_dvec3().to_array()
}

#[test]
fn eval_matches_explicit_monomials() {
    let mut rng = Pcg64::seed_from_u64(1);
    for _ in 0..100 {
        let p = random_poly(&mut rng);
        let u = random_point(&mut rng, 2.0);
        let (x, y, z) = (u.x as f64, u.y as f64, u.z as f64);
        let mut e = 0.0f64;
        for k in 0..N_COEFFS {
            let [a, b, c] = POWERS[k];
            e += p.0[k] as f64 * x.powi(a as i32) * y.powi(b as i32) * z.powi(c as i32);
        }
        assert!((p.eval_f64(dv(u)) - e).abs() < 1e-12 * (1.0 + e.abs()));
        assert!((p.eval(u) as f64 - e).abs() < 1e-5 * (1.0 + e.abs()));
        let m = monomials(u);
        let m64 = monomials_f64(dv(u));
        for k in 0..N_COEFFS {
            assert!((m[k] as f64 - m64[k]).abs() < 1e-5 * (1.0 + m64[k].abs()));
        }
    }
}

#[test]
fn gradient_matches_finite_differences() {
    let mut rng = Pcg64::seed_from_u64(2);
    let h = 1e-6;
    for _ in 0..100 {
        let p = random_poly(&mut rng);
        let u = dv(random_point(&mut rng, 2.0));
        let g = p.gradient_f64(u);
        let (_, g32) = p.eval_with_gradient(Vec3::new(u[0] as f32, u[1] as f32, u[2] as f32));
        let mg = monomial_gradients_f64(u);
        for axis in 0..3 {
            let mut up = u;
            let mut um = u;
            up[axis] += h;
            um[axis] -= h;
            let fd = (p.eval_f64(up) - p.eval_f64(um)) / (2.0 * h);
            assert!(
                (g[axis] - fd).abs() < 1e-6 * (1.0 + fd.abs()),
                "axis {axis}"
            );
            assert!((g32[axis] as f64 - fd).abs() < 1e-4 * (1.0 + fd.abs()));
            let mp = monomials_f64(up);
            let mm = monomials_f64(um);
            for k in 0..N_COEFFS {
                let fdk = (mp[k] - mm[k]) / (2.0 * h);
                assert!(
                    (mg[axis][k] - fdk).abs() < 1e-6 * (1.0 + fdk.abs()),
                    "{axis} {k}"
                );
            }
        }
        let mg32 = monomial_gradients(Vec3::new(u[0] as f32, u[1] as f32, u[2] as f32));
        for axis in 0..3 {
            for k in 0..N_COEFFS {
                assert!(
                    (mg32[axis][k] as f64 - mg[axis][k]).abs() < 1e-4 * (1.0 + mg[axis][k].abs())
                );
            }
        }
        assert_eq!(p.gradient(Vec3::ZERO), Vec3::new(p.0[1], p.0[2], p.0[3]));
    }
}

/// p'(u') = p(u'_1 e1 + u'_2 e2 + u'_3 e3) for random cubics, random rotations, random points.
#[test]
fn rotation_agrees_with_rotated_evaluation() {
    let mut rng = Pcg64::seed_from_u64(3);
    for _ in 0..200 {
        let p = random_poly(&mut rng);
        let r = random_rotation(&mut rng);
        let q = p.rotate(r.x_axis, r.y_axis, r.z_axis);
        assert_eq!(q.0[0], p.0[0], "degree 0 unchanged");
        let rd = DMat3::from_cols(
            r.x_axis.as_dvec3(),
            r.y_axis.as_dvec3(),
            r.z_axis.as_dvec3(),
        );
        for _ in 0..10 {
            let u = random_point(&mut rng, 2.0).as_dvec3();
            let lhs = q.eval_f64(u.to_array());
            let rhs = p.eval_f64((rd * u).to_array());
            assert!(
                (lhs - rhs).abs() < 2e-5 * (1.0 + rhs.abs()),
                "{lhs} vs {rhs}"
            );
        }
        // degree 1 = projections of (c1, c2, c3) onto the new axes
        let c = Vec3::new(p.0[1], p.0[2], p.0[3]);
        assert!((q.0[1] - c.dot(r.x_axis)).abs() < 1e-6);
        assert!((q.0[2] - c.dot(r.y_axis)).abs() < 1e-6);
        assert!((q.0[3] - c.dot(r.z_axis)).abs() < 1e-6);
        // rotating back with the transpose restores the polynomial
        let rt = r.transpose();
        let back = q.rotate(rt.x_axis, rt.y_axis, rt.z_axis);
        for k in 0..N_COEFFS {
            assert!((back.0[k] - p.0[k]).abs() < 1e-5, "k {k}");
        }
    }
}

/// The substitution is exact for any linear map, e.g. anisotropic scaling and shear.
#[test]
fn rotate_handles_general_linear_maps() {
    let mut rng = Pcg64::seed_from_u64(4);
    for _ in 0..50 {
        let p = random_poly(&mut rng);
        let cols = [
            random_point(&mut rng, 1.5),
            random_point(&mut rng, 1.5),
            random_point(&mut rng, 1.5),
        ];
        let q = p.rotate(cols[0], cols[1], cols[2]);
        let m = DMat3::from_cols(cols[0].as_dvec3(), cols[1].as_dvec3(), cols[2].as_dvec3());
        let u = random_point(&mut rng, 1.0).as_dvec3();
        let lhs = q.eval_f64(u.to_array());
        let rhs = p.eval_f64((m * u).to_array());
        assert!(
            (lhs - rhs).abs() < 1e-4 * (1.0 + rhs.abs()),
            "{lhs} vs {rhs}"
        );
    }
    // p(u) = x³ under x ↦ 2x gives 8x³
    let mut c = [0.0f32; 20];
    c[10] = 1.0;
    let q = Poly3(c).rotate(Vec3::X * 2.0, Vec3::Y, Vec3::Z);
    assert_eq!(q.0[10], 8.0);
}

/// The renderer's f32 tensor-contraction rotation is the reference substitution (f64) up to f32
/// rounding: for rotations and for general linear maps, every coefficient within 2e-6 of the
/// coefficient vector's scale (f32 ε ≈ 1.2e-7 times the ~27 terms summed per output).
#[test]
fn fast_rotation_equals_the_reference() {
    let mut rng = Pcg64::seed_from_u64(7);
    for i in 0..300 {
        let p = random_poly(&mut rng);
        let cols = if i % 2 == 0 {
            let r = random_rotation(&mut rng);
            [r.x_axis, r.y_axis, r.z_axis]
        } else {
            std::array::from_fn(|_| random_point(&mut rng, 1.5))
        };
        let a = p.rotate(cols[0], cols[1], cols[2]);
        let b = p.rotate_fast(cols[0], cols[1], cols[2]);
        let scale = 1.0 + a.0.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        for k in 0..N_COEFFS {
            assert!(
                (a.0[k] - b.0[k]).abs() <= 2e-6 * scale,
                "case {i}, k {k}: {} vs {}",
                a.0[k],
                b.0[k]
            );
        }
    }
    let mut c = [0.0f32; 20];
    c[10] = 1.0;
    assert_eq!(
        Poly3(c).rotate_fast(Vec3::X * 2.0, Vec3::Y, Vec3::Z).0[10],
        8.0
    );
}

/// Rotating by R1 then R2 equals rotating by R1·R2 (p2(u) = p1(R2 u) = p(R1 R2 u)).
#[test]
fn rotation_composes() {
    let mut rng = Pcg64::seed_from_u64(5);
    for _ in 0..100 {
        let p = random_poly(&mut rng);
        let r1 = random_rotation(&mut rng);
        let r2 = random_rotation(&mut rng);
        let a = p
            .rotate(r1.x_axis, r1.y_axis, r1.z_axis)
            .rotate(r2.x_axis, r2.y_axis, r2.z_axis);
        let r12 = r1 * r2;
        let b = p.rotate(r12.x_axis, r12.y_axis, r12.z_axis);
        for k in 0..N_COEFFS {
            assert!(
                (a.0[k] - b.0[k]).abs() < 2e-5,
                "k {k}: {} vs {}",
                a.0[k],
                b.0[k]
            );
        }
        // identity
        let id = p.rotate(Vec3::X, Vec3::Y, Vec3::Z);
        assert_eq!(id, p);
    }
}

#[test]
fn light_space_frame_and_plane() {
    let mut rng = Pcg64::seed_from_u64(6);
    for _ in 0..100 {
        let d_in = random_unit_vector(&mut rng);
        let f = light_space_frame(d_in);
        assert!((f.n + d_in).length() < 1e-6, "e3 = −d_in");
        assert!((f.s.length() - 1.0).abs() < 1e-5 && (f.t.length() - 1.0).abs() < 1e-5);
        assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(f.n).abs() < 1e-5);
        assert!((f.s.cross(f.t) - f.n).length() < 1e-5);
        let duff = geometry::Frame::from_normal(-d_in);
        assert!((duff.s - f.s).length() < 1e-6 && (duff.t - f.t).length() < 1e-6);
        // a plane with normal n seen along d_in = −n is p = u_z in light space
        let n = -d_in;
        let ls = Poly3::plane(n).to_light_space(d_in);
        let mut want = [0.0f32; 20];
        want[3] = 1.0;
        for k in 0..N_COEFFS {
            assert!((ls.0[k] - want[k]).abs() < 1e-6, "k {k}");
        }
        // evaluating the LS polynomial at LS coordinates = evaluating the world one
        let p = random_poly(&mut rng);
        let pls = p.to_light_space(d_in);
        let u = random_point(&mut rng, 1.0);
        let world = f.to_world(u);
        assert!((pls.eval(u) - p.eval(world)).abs() < 1e-4 * (1.0 + p.eval(world).abs()));
    }
    // degenerate direction falls back to a valid frame
    let f = light_space_frame(Vec3::ZERO);
    assert!(f.n.is_finite() && f.s.is_finite());
}

#[test]
fn poly_normal() {
    assert_eq!(Poly3::ZERO.normal(), None);
    let mut c = [0.0f32; 20];
    c[1] = 3.0;
    c[3] = 4.0;
    c[7] = 10.0;
    let n = Poly3(c).normal().unwrap();
    assert!((n - Vec3::new(0.6, 0.0, 0.8)).length() < 1e-6);
}

/// Alignment maps n_mesh onto n_poly and keeps the angle of d to the normal (docs/model.md §3.5).
#[test]
fn align_direction_rotates_mesh_normal_onto_poly_normal() {
    let mut rng = Pcg64::seed_from_u64(7);
    for _ in 0..200 {
        let n = random_unit_vector(&mut rng);
        // a nearby polynomial normal (as in practice) or an arbitrary one
        let np = if rng.random::<f32>() < 0.5 {
            (n + 0.3 * random_unit_vector(&mut rng)).normalize()
        } else {
            random_unit_vector(&mut rng)
        };
        if n.dot(np) < -0.999 {
            continue;
        }
        let d = random_unit_vector(&mut rng);
        let d2 = align_direction(d, n, np * 3.7); // unnormalised n_poly is fine
        assert!((d2.length() - 1.0).abs() < 1e-5);
        assert!(
            (d2.dot(np) - d.dot(n)).abs() < 1e-5,
            "angle to normal preserved"
        );
        let n2 = align_direction(n, n, np);
        assert!((n2 - np).length() < 1e-5, "n maps to n_p");
        // the rotation axis n × n_p is fixed
        let axis = n.cross(np).normalize();
        assert!((align_direction(axis, n, np) - axis).length() < 1e-5);
    }
    let d = Vec3::new(0.3, -0.4, 0.866).normalize();
    assert_eq!(align_direction(d, Vec3::Z, Vec3::Z), d);
    assert_eq!(
        align_direction(d, Vec3::Z, -Vec3::Z),
        d,
        "antiparallel: skipped"
    );
    assert_eq!(align_direction(d, Vec3::Z, Vec3::ZERO), d);
    // |n × n_p| just below 1e-8 is skipped, just above is applied
    let tiny = Vec3::new(0.0, 0.0, 1.0);
    let np = DVec3::new(5e-9, 0.0, 1.0).normalize().as_vec3();
    assert_eq!(align_direction(d, tiny, np), d);
}

#[test]
fn arithmetic_and_serde() {
    let mut rng = Pcg64::seed_from_u64(8);
    let a = random_poly(&mut rng);
    let b = random_poly(&mut rng);
    let s = a + b * 0.5;
    for k in 0..N_COEFFS {
        assert!((s.0[k] - (a.0[k] + 0.5 * b.0[k])).abs() < 1e-7);
    }
    let json = serde_json::to_string(&a).unwrap();
    let back: Poly3 = serde_json::from_str(&json).unwrap();
    assert_eq!(back, a);
}
