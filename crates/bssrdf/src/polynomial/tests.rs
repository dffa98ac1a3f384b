//! Unit tests of the polynomial module: term ordering (docs/model.md §3.1), monomials, rescaling.

use super::*;

#[test]
fn ordering_matches_spec_table() {
    let expected: [[u8; 3]; 20] = [
        [0, 0, 0],
        [1, 0, 0],
        [0, 1, 0],
        [0, 0, 1],
        [2, 0, 0],
        [1, 1, 0],
        [1, 0, 1],
        [0, 2, 0],
        [0, 1, 1],
        [0, 0, 2],
        [3, 0, 0],
        [2, 1, 0],
        [2, 0, 1],
        [1, 2, 0],
        [1, 1, 1],
        [1, 0, 2],
        [0, 3, 0],
        [0, 2, 1],
        [0, 1, 2],
        [0, 0, 3],
    ];
    assert_eq!(POWERS, expected);
    for (k, p) in expected.iter().enumerate() {
        assert_eq!(
            power_to_index(p[0] as usize, p[1] as usize, p[2] as usize),
            k
        );
    }
}

#[test]
fn monomials_match_powers() {
    let u = [0.3f64, -1.7, 2.1];
    let m = monomials_f64(u);
    for k in 0..20 {
        let p = POWERS[k];
        let e = u[0].powi(p[0] as i32) * u[1].powi(p[1] as i32) * u[2].powi(p[2] as i32);
        assert!((m[k] - e).abs() < 1e-12, "k {k}");
    }
}

#[test]
fn rescaled_is_the_same_surface_at_another_scale() {
    let c: [f32; N_COEFFS] = std::array::from_fn(|i| ((i * 37 % 11) as f32 - 5.0) * 0.1);
    let p = Poly3(c);
    for k in [0.5f32, 1.0, 1.7] {
        let q = p.rescaled(k);
        for u in [Vec3::new(0.3, -0.2, 0.5), Vec3::new(-1.1, 0.4, 0.9)] {
            // q(u) = p(k·u)/k and ∇q(u) = ∇p(k·u).
            let (a, b) = (q.eval(u), p.eval(k * u) / k);
            assert!((a - b).abs() < 1e-5 * (1.0 + b.abs()), "k {k}: {a} vs {b}");
            let (ga, gb) = (q.gradient(u), p.gradient(k * u));
            assert!((ga - gb).length() < 1e-5 * (1.0 + gb.length()), "k {k}");
        }
    }
    assert_eq!(p.rescaled(1.0), p);
}
