//! The renderer's walk sampler (`bssrdf::render::walk_exit`, `EntrySampler::Walks`): the exit of
//! the first escaping walk of a sample's stream must follow the distribution of the exits of
//! plain walks, p(x | exit), which is what the decoder is trained on.
//!
//! Two-sample χ² test (`testkit::chi2_two_sample`) of the radial exit distance on a half-space
//! and on a convex sphere (κ = 0.3 in units of 1/σ_n), with and without internal reflection:
//! 40 000 sampler draws against the escaped ones of 400 000 independent plain walks, at a
//! p-value threshold of 10⁻³ per case.

use base::rng::Sampler;
use bssrdf::polynomial::{Poly3, power_to_index};
use bssrdf::render::{WALK_MAX_TRIES, walk_exit};
use bssrdf::walk::{WalkMedium, WalkOutcome, WalkSurface, random_walk};
use glam::Vec3;
use rayon::prelude::*;
use testkit::chi2_two_sample;

const BINS: usize = 40;
const R_MAX: f64 = 8.0;

fn bin(p: [f64; 3]) -> usize {
    let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    ((r / R_MAX * BINS as f64) as usize).min(BINS - 1)
}

/// The surface u_z + κ/2·|u|² (a sphere of radius 1/κ through the origin; the plane at κ = 0).
fn surface(kappa: f32) -> Poly3 {
    let mut p = Poly3::plane(Vec3::Z);
    for (a, b, c) in [(2, 0, 0), (0, 2, 0), (0, 0, 2)] {
        p.0[power_to_index(a, b, c)] = 0.5 * kappa;
    }
    p
}

fn medium(albedo: f64, eta: f64) -> WalkMedium {
    WalkMedium {
        sigma_t: 1.3,
        albedo,
        g: 0.0,
        eta,
    }
}

#[test]
fn walk_sampler_draws_exits_conditioned_on_escape() {
    for (kappa, albedo, eta) in [(0.0f32, 0.6, 1.0), (0.3, 0.9, 1.0), (0.0, 0.95, 1.4)] {
        let poly = surface(kappa);
        let m = medium(albedo, eta);
        let surf = WalkSurface::new(&poly, 1.0);
        let reference: Vec<u64> = (0..400_000u64)
            .into_par_iter()
            .fold(
                || vec![0u64; BINS],
                |mut h, i| {
                    let mut rng = Sampler::new(99, 1, i, 0);
                    if let WalkOutcome::Exited(e) = random_walk(&surf, &m, -Vec3::Z, &mut rng) {
                        h[bin(e.position.to_array())] += 1;
                    }
                    h
                },
            )
            .reduce(
                || vec![0; BINS],
                |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
            );
        let n = 40_000u64;
        let draws: Vec<[f32; 3]> = (0..n)
            .into_par_iter()
            .map(|k| walk_exit(&poly, &m, k))
            .collect();
        let mut observed = vec![0.0; BINS];
        for y in &draws {
            assert!(y.iter().all(|v| v.is_finite()), "every draw escapes here");
            let p = y.map(|v| v as f64);
            assert!(
                poly.eval(Vec3::from_array(*y)).abs() < 1e-4,
                "exit off the surface"
            );
            observed[bin(p)] += 1.0;
        }
        let reference: Vec<f64> = reference.iter().map(|&c| c as f64).collect();
        let r = chi2_two_sample(&observed, &reference, 10.0);
        eprintln!(
            "κ {kappa} α {albedo} η {eta}: χ² = {:.1} ({} dof), p = {:.4}",
            r.statistic, r.dof, r.p_value
        );
        assert!(
            r.p_value > 1e-3,
            "κ {kappa} α {albedo} η {eta}: p = {}",
            r.p_value
        );
    }
}

/// A medium that almost never lets a walk escape: after the maximal number of tries the draw is
/// NaN, which the renderer counts as an invalid sample.
#[test]
fn walk_sampler_gives_nan_when_nothing_escapes() {
    let y = walk_exit(&surface(0.0), &medium(1e-9, 1.0), 5);
    assert!(y.iter().all(|v| v.is_nan()), "{y:?}");
    const { assert!(WALK_MAX_TRIES >= 256) };
}
