//! The half-space walker of `bssrdf::exit` (depth and direction cosine only, a specialisation for
//! speed) against the library walk of the training data, `learn::walk::random_walk`, on the
//! plane p = u_z: the same exit-cosine histograms (two-sample chi-square) and escaped fractions.

use base::rng::Sampler;
use bssrdf::exit::{ExitTable, ExitTableSettings, MU_BINS};
use bssrdf::medium::sigma_n;
use bssrdf::polynomial::Poly3;
use glam::Vec3;
use learn::walk::{WalkMedium, WalkOutcome, WalkSurface, random_walk};
use rayon::prelude::*;

/// χ²(15) quantile at p = 0.999.
const CHI2_15_999: f64 = 37.70;

fn lambert_mass(j: usize) -> f64 {
    let (lo, hi) = (j as f64 / MU_BINS as f64, (j + 1) as f64 / MU_BINS as f64);
    hi * hi - lo * lo
}

/// Histogram over `bins` bins (`bin_of` of each exit) of `walks` library walks on the plane
/// (σ_t = 1), entering with outside cosine uniform in bin `i` of [`MU_BINS`] (refracted into the
/// medium), from the random streams of `seed`.
fn library_histogram(
    (albedo, g, eta): (f64, f64, f64),
    i: usize,
    (walks, seed): (u64, u64),
    bins: usize,
    bin_of: impl Fn(&learn::walk::Exit) -> usize + Sync,
) -> Vec<f64> {
    let sn = sigma_n(1.0, albedo, g);
    let surface = WalkSurface::new(&Poly3::plane(Vec3::Z), sn);
    let medium = WalkMedium {
        sigma_t: 1.0,
        albedo,
        g,
        eta,
    };
    (0..walks)
        .into_par_iter()
        .map(|k| {
            let mut rng = Sampler::new(seed, i as u64, k, 0);
            let mu_c = (i as f64 + rng.next_f32() as f64) / MU_BINS as f64;
            let mu_in = (1.0 - (1.0 - mu_c * mu_c) / (eta * eta)).max(1e-6).sqrt();
            let d_in = Vec3::new((1.0 - mu_in * mu_in).sqrt() as f32, 0.0, -mu_in as f32);
            let mut h = vec![0.0; bins];
            if let WalkOutcome::Exited(e) = random_walk(&surface, &medium, d_in, &mut rng) {
                h[bin_of(&e)] = 1.0;
            }
            h
        })
        .reduce(
            || vec![0.0; bins],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                a
            },
        )
}

/// Exit-cosine histogram and escaped count of `walks` library walks entering with outside
/// cosine uniform in bin `i` (refracted into the medium).
fn library_row(albedo: f64, g: f64, eta: f64, i: usize, walks: u64) -> (Vec<f64>, f64) {
    let h = library_histogram((albedo, g, eta), i, (walks, 5), MU_BINS, |e| {
        ((e.direction.z.max(0.0) * MU_BINS as f32) as usize).min(MU_BINS - 1)
    });
    let n = h.iter().sum();
    (h, n)
}

/// The media of both comparisons, (g, η, albedo index into ONE_MINUS_ALBEDO): the paper's and
/// an anisotropic one behind a dielectric boundary.
const MEDIA: [(f32, f32, usize); 2] = [(0.0, 1.0, 6), (0.5, 1.3, 4)];

/// Settings of the tables simulated for the comparisons.
fn table_settings(g: f32, eta: f32) -> ExitTableSettings {
    ExitTableSettings {
        g,
        eta,
        roughness: 0.0,
        walks: 40_000,
        seed: 1,
    }
}

#[test]
fn the_fast_walker_matches_the_training_walk() {
    for (g, eta, a) in MEDIA {
        let table = ExitTable::generate(table_settings(g, eta));
        let albedo = 1.0 - bssrdf::exit::ONE_MINUS_ALBEDO[a] as f64;
        for i in [1usize, 8, 15] {
            let r = a * MU_BINS + i;
            let n1 = table.escaped[r] as f64 * table.settings.walks as f64;
            let c1: Vec<f64> = (0..MU_BINS)
                .map(|j| table.f[r * MU_BINS + j] as f64 * lambert_mass(j) * n1)
                .collect();
            let walks = 20_000u64;
            let (c2, n2) = library_row(albedo, g as f64, eta as f64, i, walks);
            // Two-sample χ² over bins with counts (k1 = √(n2/n1), k2 = √(n1/n2)).
            let (k1, k2) = ((n2 / n1).sqrt(), (n1 / n2).sqrt());
            let chi2: f64 = (0..MU_BINS)
                .filter(|&j| c1[j] + c2[j] > 0.0)
                .map(|j| (k1 * c1[j] - k2 * c2[j]).powi(2) / (c1[j] + c2[j]))
                .sum();
            assert!(
                chi2 < CHI2_15_999,
                "g={g} η={eta} α={albedo} entry bin {i}: χ² = {chi2:.1}"
            );
            // Escaped fractions: binomial, 5 standard errors of the difference.
            let (e1, e2) = (table.escaped[r] as f64, n2 / walks as f64);
            let se = (e1 * (1.0 - e1) * (1.0 / walks as f64 + 1.0 / 40_000.0)).sqrt();
            assert!(
                (e1 - e2).abs() < 5.0 * se,
                "g={g} η={eta} α={albedo} entry bin {i}: escaped {e1} vs {e2}"
            );
        }
    }
}

/// χ² quantile at p = 0.999 for `k` degrees of freedom (Wilson–Hilferty).
fn chi2_999(k: f64) -> f64 {
    let z = 3.0902;
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

/// The three-dimensional walker of `bssrdf::incidence` against the library walk on the plane:
/// the same histograms of the exit point over (distance, angle from the light's forward
/// direction), by a two-sample χ² over the cells the table resolves, including g = 0.5, η = 1.3.
#[test]
fn the_incidence_walker_matches_the_training_walk() {
    use bssrdf::incidence::{IncidenceTable, MIN_CELL, PSI_BINS, RHO_0, RHO_BINS, RHO_MAX};
    for (g, eta, a) in MEDIA {
        let table = IncidenceTable::generate(table_settings(g, eta));
        let albedo = 1.0 - bssrdf::exit::ONE_MINUS_ALBEDO[a] as f64;
        let top = (1.0 + RHO_MAX / RHO_0).ln();
        for i in [2usize, 9] {
            let walk = (albedo, g as f64, eta as f64);
            let h = library_histogram(walk, i, (20_000, 6), RHO_BINS * PSI_BINS, |e| {
                let (x, y) = (e.position.x as f32, e.position.y as f32);
                let rho = x.hypot(y);
                let r =
                    (((1.0 + rho / RHO_0).ln() / top * RHO_BINS as f32) as usize).min(RHO_BINS - 1);
                let psi = y.abs().atan2(x);
                let q = ((psi / std::f32::consts::PI * PSI_BINS as f32) as usize).min(PSI_BINS - 1);
                r * PSI_BINS + q
            });
            // Cells the table resolves; its counts are A·n/PSI_BINS.
            let cell0 = (a * MU_BINS + i) * RHO_BINS;
            let mut c1 = Vec::new();
            let mut c2 = Vec::new();
            for r in 0..RHO_BINS {
                let n = table.cells[cell0 + r] as f64;
                if n < MIN_CELL as f64 {
                    continue;
                }
                for q in 0..PSI_BINS {
                    c1.push(table.a[(cell0 + r) * PSI_BINS + q] as f64 * n / PSI_BINS as f64);
                    c2.push(h[r * PSI_BINS + q]);
                }
            }
            let (n1, n2): (f64, f64) = (c1.iter().sum(), c2.iter().sum());
            let (k1, k2) = ((n2 / n1).sqrt(), (n1 / n2).sqrt());
            let used: Vec<usize> = (0..c1.len()).filter(|&j| c1[j] + c2[j] > 0.0).collect();
            let chi2: f64 = used
                .iter()
                .map(|&j| (k1 * c1[j] - k2 * c2[j]).powi(2) / (c1[j] + c2[j]))
                .sum();
            let dof = used.len() as f64 - 1.0;
            assert!(dof > 30.0, "only {} bins resolved", used.len());
            assert!(
                chi2 < chi2_999(dof),
                "g={g} η={eta} α={albedo} light bin {i}: χ² = {chi2:.1} over {dof} dof"
            );
        }
    }
}
