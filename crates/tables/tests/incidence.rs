//! The light-side incidence factor (`tables::incidence`): the shipped table against its
//! generator, its normalisations, the α-interpolation with its derivative, and the physics it
//! encodes (light entering obliquely leaves ahead of its entry point).

use glam::Vec3;
use tables::exit::{MU_BINS, ONE_MINUS_ALBEDO};
use tables::incidence::{
    IncidenceSettings, IncidenceTable, MIN_CELL, PHI_BINS, PSI_BINS, RHO_BINS,
};

const CELLS: usize = 16 * MU_BINS * RHO_BINS;

/// Every (albedo, light cosine, distance) cell of A averages to 1 over the angle (it is a
/// density relative to uniform), in the shipped table (rounded to 4 digits: 12 values with a
/// relative rounding of at most 5·10⁻⁵ each) and in a table simulated for another medium, and so
/// does every slice between grid albedos (the spline is linear in the rows).
#[test]
fn a_is_an_angular_density_relative_to_uniform() {
    let shipped = IncidenceTable::index_matched_isotropic();
    let other = IncidenceTable::generate(IncidenceSettings {
        g: 0.4,
        eta: 1.3,
        roughness: 0.0,
        walks: 4_000,
        seed: 1,
    });
    for (t, tol) in [(&*shipped, 5e-4), (&other, 1e-5)] {
        assert_eq!(t.a.len(), CELLS * PSI_BINS);
        assert_eq!(t.cells.len(), CELLS);
        assert_eq!(t.norm.len(), 16 * MU_BINS * MU_BINS * PHI_BINS);
        for c in 0..CELLS {
            let mean: f64 = t.a[c * PSI_BINS..(c + 1) * PSI_BINS]
                .iter()
                .map(|&v| v as f64)
                .sum::<f64>()
                / PSI_BINS as f64;
            assert!((mean - 1.0).abs() < tol, "cell {c}: mean A = {mean}");
        }
    }
    // Between grid albedos, at bin centres (where the interpolation returns table values).
    let s = shipped.slice(0.87);
    for i in [1usize, 7, 14] {
        for r in [0usize, 4, 9] {
            let mu = (i as f32 + 0.5) / MU_BINS as f32;
            let top = (1.0 + tables::incidence::RHO_MAX / tables::incidence::RHO_0).ln();
            let rho =
                tables::incidence::RHO_0 * (((r as f32 + 0.5) / RHO_BINS as f32 * top).exp() - 1.0);
            let mean: f32 = (0..PSI_BINS)
                .map(|k| {
                    let psi = (k as f32 + 0.5) / PSI_BINS as f32 * std::f32::consts::PI;
                    s.eval(mu, rho, psi.cos()).0
                })
                .sum::<f32>()
                / PSI_BINS as f32;
            assert!(
                (mean - 1.0).abs() < 1e-3,
                "μ {mu}, ρ {rho}: mean A = {mean}"
            );
        }
    }
}

/// The shipped table is what `IncidenceTable::generate` makes with its recorded settings. A of
/// a fresh table from independent walks agrees bin by bin within 5 standard errors of the
/// difference of two multinomial frequencies (cells with enough walks in both), and N, recomputed
/// from the shipped A with independent walks, within 5 standard errors of that mean. N is a mean
/// of A ∈ [0, A_max] over n escaped walks, so its variance is at most m·(A_max − m)/n
/// (Bhatia–Davis, with m the shipped value); the shipped table's own error enters through the
/// walk ratio. (The sample variance is no bound: at low albedo and grazing angles N is carried by
/// rare walks.)
#[test]
fn the_shipped_table_is_the_generators_output() {
    let shipped = IncidenceTable::index_matched_isotropic();
    assert_eq!((shipped.settings.g, shipped.settings.eta), (0.0, 1.0));
    assert!(shipped.settings.walks >= 1_000_000);
    let fresh = IncidenceTable::generate(IncidenceSettings {
        walks: 20_000,
        seed: 99,
        ..shipped.settings
    });
    let mut worst: f64 = 0.0;
    let mut compared = 0;
    for c in 0..CELLS {
        let (n1, n2) = (shipped.cells[c] as f64, fresh.cells[c] as f64);
        if n1 < MIN_CELL as f64 || n2 < MIN_CELL as f64 {
            continue;
        }
        for k in 0..PSI_BINS {
            let i = c * PSI_BINS + k;
            let (p1, p2) = (
                shipped.a[i] as f64 / PSI_BINS as f64,
                fresh.a[i] as f64 / PSI_BINS as f64,
            );
            let p = (p1 * n1 + p2 * n2) / (n1 + n2);
            let se = (p * (1.0 - p) * (1.0 / n1 + 1.0 / n2)).sqrt();
            // The shipped values are rounded to 4 significant digits.
            let z = ((p1 - p2).abs() - 5e-5 * p1).max(0.0) / se.max(1e-12);
            worst = worst.max(z);
            assert!(
                z < 5.0,
                "cell {c}, angle bin {k}: {p1} vs {p2} (z = {z:.2})"
            );
            compared += 1;
        }
    }
    assert!(
        compared > CELLS * PSI_BINS / 2,
        "only {compared} bins compared"
    );
    let ratio = fresh.settings.walks as f64 / shipped.settings.walks as f64;
    let stats = IncidenceTable::normalisation(&fresh.settings, &shipped.a);
    let norm = &stats.mean;
    let block = RHO_BINS * PSI_BINS;
    let mut worst_n: f64 = 0.0;
    for i in 0..shipped.norm.len() {
        // i = ((alb·MU_BINS + i_c)·MU_BINS + j)·PHI_BINS + k.
        let row = i / (MU_BINS * PHI_BINS);
        let (alb, j) = (row / MU_BINS, (i / PHI_BINS) % MU_BINS);
        let a_block = &shipped.a[(alb * MU_BINS + j) * block..(alb * MU_BINS + j + 1) * block];
        let a_max = a_block.iter().fold(0.0f32, |m, &v| m.max(v)) as f64;
        let m = shipped.norm[i] as f64;
        let n = stats.escaped[row].max(1) as f64;
        let se = ((m * (a_max - m)).max(0.0) / n).sqrt() * (1.0 + ratio).sqrt();
        // Rounding of the shipped N and of the A it was computed from (before rounding).
        let d = (shipped.norm[i] as f64 - norm[i] as f64).abs() - 1e-4 * shipped.norm[i] as f64;
        let z = d.max(0.0) / se.max(1e-9);
        worst_n = worst_n.max(z);
        assert!(
            z < 5.0,
            "N entry {i}: {} vs {} (z = {z:.2})",
            shipped.norm[i],
            norm[i]
        );
    }
    eprintln!("largest |z|: A {worst:.2} over {compared} bins, N {worst_n:.2}");
}

/// The physics: light leaves ahead of its entry point more often than behind, the more so the
/// more oblique it enters (over ten times at a light cosine of 0.1); at exactly normal incidence
/// the factor is 1.
#[test]
fn oblique_light_leaves_ahead_of_its_entry_point() {
    let t = IncidenceTable::index_matched_isotropic();
    let s = t.slice(0.88);
    let ratio = |mu: f32| s.eval(mu, 1.0, 1.0).0 / s.eval(mu, 1.0, -1.0).0;
    let (grazing, oblique, normal) = (ratio(0.1), ratio(0.5), ratio(0.97));
    assert!(
        grazing > oblique && oblique > normal && normal > 1.0,
        "ahead/behind at μ_l 0.1, 0.5, 0.97: {grazing}, {oblique}, {normal}"
    );
    assert!(grazing > 10.0, "grazing light: ahead/behind {grazing}");
    // Normal incidence at x_i: no preferred azimuth, the factor is exactly 1.
    let (f, df) = s.at_points(
        (Vec3::ZERO, Vec3::Z, Vec3::Z, 1.0),
        (Vec3::new(0.02, 0.0, 0.0), 0.5, Vec3::X),
        50.0,
    );
    assert_eq!((f, df), (1.0, 0.0));
}

/// ∂(A/N)/∂α of `at_points` is the slope of the interpolated factor (central difference in α
/// between grid albedos), and the factor scales with σ_t only through ρ = |Δ|·σ_t.
#[test]
fn the_factor_has_its_albedo_derivative_and_scales_with_sigma_t() {
    let t = IncidenceTable::index_matched_isotropic();
    let w_l = Vec3::new(-0.8, 0.0, 0.6).normalize();
    let light_side = (Vec3::ZERO, Vec3::Z, w_l, w_l.z);
    let cam = (Vec3::new(0.015, 0.004, 0.0), 0.7, Vec3::new(0.0, 1.0, 0.0));
    for albedo in [0.83f32, 0.9, 0.955] {
        let h = 1e-3;
        let (f, df) = t.slice(albedo).at_points(light_side, cam, 60.0);
        let (fp, _) = t.slice(albedo + h).at_points(light_side, cam, 60.0);
        let (fm, _) = t.slice(albedo - h).at_points(light_side, cam, 60.0);
        let fd = (fp - fm) / (2.0 * h);
        assert!(f > 0.0 && f.is_finite());
        assert!(
            (df - fd).abs() <= 0.02 * fd.abs().max(0.05),
            "α {albedo}: ∂/∂α {df} vs central difference {fd}"
        );
    }
    // Doubling σ_t and halving the distance leaves the factor unchanged.
    let s = t.slice(0.9);
    let (a1, _) = s.at_points(light_side, cam, 60.0);
    let half = (cam.0 * 0.5, cam.1, cam.2);
    let (a2, _) = s.at_points(light_side, half, 120.0);
    assert!((a1 - a2).abs() < 1e-5 * a1, "{a1} vs {a2}");
}

/// Rows of the grid albedos are the table's own: a slice at a grid albedo returns the stored
/// values at bin centres.
#[test]
fn slices_at_grid_albedos_are_the_table_rows() {
    let t = IncidenceTable::index_matched_isotropic();
    let alb = 5;
    let s = t.slice(1.0 - ONE_MINUS_ALBEDO[alb]);
    let top = (1.0 + tables::incidence::RHO_MAX / tables::incidence::RHO_0).ln();
    for (i, r, k) in [(2usize, 3usize, 0usize), (9, 6, 5), (13, 1, 11)] {
        let mu = (i as f32 + 0.5) / MU_BINS as f32;
        let rho =
            tables::incidence::RHO_0 * (((r as f32 + 0.5) / RHO_BINS as f32 * top).exp() - 1.0);
        let psi = (k as f32 + 0.5) / PSI_BINS as f32 * std::f32::consts::PI;
        let (v, _) = s.eval(mu, rho, psi.cos());
        let stored = t.a[((alb * MU_BINS + i) * RHO_BINS + r) * PSI_BINS + k];
        assert!(
            (v - stored).abs() < 1e-3 * stored.max(1.0),
            "{v} vs {stored}"
        );
    }
}

/// The table coordinate's arccos stays within its stated error bound (7·10⁻⁵ rad) everywhere.
#[test]
fn fast_acos_is_within_its_bound() {
    let mut worst = 0.0f64;
    for k in 0..=200_000 {
        let x = -1.0 + 2.0 * k as f64 / 200_000.0;
        let e = (tables::incidence::fast_acos(x as f32) as f64 - x.acos()).abs();
        worst = worst.max(e);
    }
    assert!(worst < 7e-5, "largest error {worst}");
}
