//! Property tests (proptest) of the dielectric interface: Fresnel reflectance is an energy
//! fraction, reciprocal between the two sides, and refraction obeys Snell's law and reverses.

use glam::Vec3;
use proptest::prelude::*;
use volpath::fresnel::{fresnel_dielectric, reflect, refract};

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 512,
        failure_persistence: None,
        // A fixed seed: the same inputs on every run (the tests are deterministic).
        rng_seed: proptest::test_runner::RngSeed::Fixed(3),
        ..ProptestConfig::default()
    }
}

fn unit() -> impl Strategy<Value = Vec3> {
    (-1.0f32..1.0, -1.0f32..1.0, -1.0f32..1.0)
        .prop_map(|(x, y, z)| Vec3::new(x, y, z))
        .prop_filter("not near zero", |v| v.length() > 0.05)
        .prop_map(|v| v.normalize())
}

proptest! {
    #![proptest_config(config())]

    /// 0 ≤ R ≤ 1; R = 1 exactly past the critical angle; at normal incidence R is
    /// ((η − 1)/(η + 1))².
    #[test]
    fn reflectance_is_an_energy_fraction(cos_i in 0.0f32..=1.0, eta in 0.2f32..5.0) {
        let r = fresnel_dielectric(cos_i, eta);
        prop_assert!((0.0..=1.0).contains(&r), "R = {r}");
        let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        if sin2_t >= 1.0 {
            prop_assert_eq!(r, 1.0);
        }
        let r0 = fresnel_dielectric(1.0, eta);
        let want = ((eta - 1.0) / (eta + 1.0)).powi(2);
        prop_assert!((r0 - want).abs() < 1e-6, "{r0} vs {want}");
    }

    /// Reciprocity: light crossing from side 1 at cos θ_i and light crossing back from side 2 at
    /// the refracted cos θ_t are reflected alike, R(cos θ_i, η) = R(cos θ_t, 1/η). Both sides
    /// stay 3° away from grazing (cos > 0.05): there ∂R/∂cos θ grows like η/cos θ, and the f32
    /// rounding of the computed cos θ_t (relative 6·10⁻⁸, amplified by 1/cos² through the
    /// square root near the critical angle) moves R by more than the 2·10⁻⁴ allowed here.
    #[test]
    fn reflectance_is_reciprocal(cos_i in 0.0f32..=1.0, eta in 0.2f32..5.0) {
        let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        prop_assume!(cos_i > 0.05 && sin2_t < 1.0 - 0.05 * 0.05);
        let cos_t = (1.0 - sin2_t).sqrt();
        let a = fresnel_dielectric(cos_i, eta);
        let b = fresnel_dielectric(cos_t, 1.0 / eta);
        prop_assert!((a - b).abs() < 2e-4, "R({cos_i}, {eta}) = {a}, R({cos_t}, {}) = {b}", 1.0 / eta);
    }

    /// Refraction: a unit direction in the plane of d and n, on the far side, with
    /// sin θ_t = sin θ_i / η; refracting it back with 1/η gives d. Reflection keeps the angle
    /// and the tangential part.
    #[test]
    fn refraction_obeys_snell_and_reverses(d in unit(), n in unit(), eta in 0.3f32..3.0) {
        let cos_i = d.dot(n).abs();
        prop_assume!(cos_i > 0.02);
        let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
        match refract(d, n, eta) {
            None => prop_assert!(sin_i / eta >= 0.999, "TIR reported at sin θ_t = {}", sin_i / eta),
            Some(t) => {
                prop_assert!((t.length() - 1.0).abs() < 1e-4);
                prop_assert!(t.dot(n).signum() == d.dot(n).signum(), "not transmitted");
                let sin_t = t.cross(n).length();
                prop_assert!((sin_t * eta - sin_i).abs() < 2e-3, "Snell: {} vs {sin_i}", sin_t * eta);
                prop_assert!(t.dot(d.cross(n)).abs() < 1e-3, "out of the plane of incidence");
                let back = refract(-t, n, 1.0 / eta).expect("the reverse path exists");
                prop_assert!((back + d).length() < 2e-3, "{back} vs {}", -d);
            }
        }
        let r = reflect(d, n);
        prop_assert!((r.dot(n) + d.dot(n)).abs() < 1e-5);
        prop_assert!(((r - n * r.dot(n)) - (d - n * d.dot(n))).length() < 1e-5);
    }
}
