//! The exit table's walks behind a rough boundary (`tables::exit` with a GGX roughness) against
//! walks written out in three dimensions with the same physics.

use base::microfacet::RoughDielectric;
use base::phase::HenyeyGreenstein;
use base::rng::Sampler;
use glam::Vec3;
use tables::exit::{ExitTable, ExitTableSettings, MU_BINS, ONE_MINUS_ALBEDO};

/// Per walk: the energy that entered and the energy that escaped, with its outside exit cosine.
struct Walks {
    entered: Vec<f64>,
    escaped: Vec<(f64, f32)>,
}

/// Walks in the half-space z < 0 in three dimensions (directions as vectors, the HG phase
/// function's own sampler, the rough boundary's sampler at every crossing), entering at outside
/// cosines uniform in entry bin `i`: the physics that `ExitTable::simulate_row` reduces to the
/// direction's z component.
fn walks_3d(b: &RoughDielectric, g: f32, albedo: f32, i: usize, n: usize) -> Walks {
    let phase = HenyeyGreenstein { g };
    let mut rng = Sampler::new(7, 3, i as u64, 0);
    let mut out = Walks {
        entered: Vec::with_capacity(n),
        escaped: Vec::with_capacity(n),
    };
    'walk: for _ in 0..n {
        let mu_c = (i as f32 + rng.next_f32()) / MU_BINS as f32;
        let phi = std::f32::consts::TAU * rng.next_f32();
        let s = (1.0 - mu_c * mu_c).max(0.0).sqrt();
        let wi = Vec3::new(s * phi.cos(), s * phi.sin(), mu_c.max(1e-4));
        let mut entry = None;
        for _ in 0..64 {
            let x = b.sample(wi, rng.next_f32(), rng.next_f32(), rng.next_f32());
            if let Some(x) = x.filter(|x| x.transmitted) {
                entry = Some((x.wo, x.weight * b.eta * b.eta));
                break;
            }
        }
        let Some((mut d, w_in)) = entry else {
            continue;
        };
        out.entered.push(w_in as f64);
        let mut z = -(-rng.next_f32()).ln_1p() * d.z;
        let mut w = w_in;
        for _ in 0..10_000 {
            if rng.next_f32() >= albedo {
                continue 'walk;
            }
            d = phase.sample(d, rng.next_f32(), rng.next_f32());
            loop {
                let t = -(-rng.next_f32()).ln_1p();
                if z + t * d.z < 0.0 {
                    z += t * d.z;
                    break;
                }
                let Some(x) = b.sample(-d, rng.next_f32(), rng.next_f32(), rng.next_f32()) else {
                    continue 'walk;
                };
                if x.transmitted {
                    out.escaped
                        .push(((w * x.weight / (b.eta * b.eta)) as f64, x.wo.z));
                    continue 'walk;
                }
                w *= x.weight;
                d = x.wo;
                z = 0.0;
            }
        }
    }
    out
}

/// Per entry bin, the table's escaped share of the entered energy and its mean exit cosine
/// (over bin centres) agree with the three-dimensional walks within 4.5 standard errors of
/// the difference (a ratio estimator's, from the 3-D walks' spread).
#[test]
fn rough_walks_reduce_to_the_directions_z_component() {
    let (g, eta, alpha, a) = (0.3f32, 1.5f32, 0.3f32, 6usize);
    let albedo = 1.0 - ONE_MINUS_ALBEDO[a];
    let settings = ExitTableSettings {
        g,
        eta,
        roughness: alpha,
        walks: 200_000,
        seed: 5,
    };
    let b = RoughDielectric::new(eta, alpha);
    let centre = |j: usize| (j as f64 + 0.5) / MU_BINS as f64;
    let lambert = |j: usize| {
        let (lo, hi) = (j as f64 / MU_BINS as f64, (j + 1) as f64 / MU_BINS as f64);
        hi * hi - lo * lo
    };
    for i in [2usize, 9, 15] {
        let (f, escaped) = ExitTable::simulate_row(&settings, a * MU_BINS + i);
        let w = walks_3d(&b, g, albedo, i, 200_000);
        let entered: f64 = w.entered.iter().sum();
        let out: f64 = w.escaped.iter().map(|e| e.0).sum();
        let ratio = out / entered;
        // The ratio estimator's variance: Σ(e_k − R n_k)² / (Σ n_k)² over all walks.
        let mut var = w.escaped.iter().map(|e| e.0 * e.0).sum::<f64>();
        var += -2.0 * ratio * out + ratio * ratio * w.entered.iter().map(|x| x * x).sum::<f64>();
        let se = var.max(0.0).sqrt() / entered;
        let tol = 4.5 * se * 2f64.sqrt();
        assert!(
            (escaped as f64 - ratio).abs() < tol,
            "entry bin {i}: table {escaped} against 3-D {ratio} (tolerance {tol})"
        );
        let mean_table: f64 = (0..MU_BINS)
            .map(|j| f[j] as f64 * lambert(j) * centre(j))
            .sum();
        let bin = |mu: f32| ((mu * MU_BINS as f32) as usize).min(MU_BINS - 1);
        let mean_3d = w
            .escaped
            .iter()
            .map(|e| e.0 * centre(bin(e.1)))
            .sum::<f64>()
            / out;
        let sd = (w
            .escaped
            .iter()
            .map(|e| e.0 * (centre(bin(e.1)) - mean_3d).powi(2))
            .sum::<f64>()
            / out)
            .sqrt();
        let n_eff = out * out / w.escaped.iter().map(|e| e.0 * e.0).sum::<f64>();
        let tol = 4.5 * sd * (2.0 / n_eff).sqrt();
        assert!(
            (mean_table - mean_3d).abs() < tol,
            "entry bin {i}: mean exit cosine {mean_table} against 3-D {mean_3d} (tolerance {tol})"
        );
    }
}
