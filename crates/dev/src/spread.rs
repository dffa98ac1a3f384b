//! `translucent-dev spread`: the learned models against their own held-out training data,
//! configuration by configuration, binned by the surface's mean curvature.
//!
//! `translucent-dev plane --curvature` compares a model with random walks on exact spheres. This bench asks
//! the question behind it on the data the model was trained on: for every configuration of a
//! samples file (`train data` writes `val.tlsamples` from meshes the training never saw), the
//! walks' exits `x_LS` (units of σ_n, light space) against `K` proposals `x̂ = Decoder(z, f)` with
//! `z ~ N(0, I₄)` for the same network inputs, and the configuration's absorption probability
//! against Absorb.
//!
//! **Distance.** The chord |x| from the entry point, for exits and proposals alike. Proposals lie
//! slightly off the surface (the renderer projects them, `translucent-dev plane` does too); the chord of
//! an exit is its distance in space, so this compares the two distributions in the same measure
//! without a projection.
//!
//! **Curvature.** The mean curvature of the fitted implicit cubic at the entry point (units of
//! 1/σ_n; > 0 where the medium is convex), from the gradient g = (c₁, c₂, c₃) and the Hessian H:
//! κ = (|g|²·tr H − gᵀHg) / (2|g|³). It equals κ for `translucent-dev plane`'s sphere
//! p = u_z + κ/2·|u|², and is invariant under the light-space rotation.
//!
//! Per bin of (α', κ): configurations, the mean and the 25th/50th/90th/99th percentiles of the
//! exits' distances and of the proposals' (with the relative difference of the means), and the
//! mean absorption probability against Absorb. Writes `OUT/spread.csv` (one row per
//! configuration: κ, α', g, η, the cosine of the incidence, the absorption probability and the
//! exits' mean distance, then Absorb and the proposals' mean distance per model).

use std::path::PathBuf;

use anyhow::{Context, Result};
use bssrdf::medium::ReducedMedium;
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, N_POLY, POSITION_DIM, ShapeAdaptiveModel};
use bssrdf::polynomial::Poly3;
use clap::Args;
use learn::sample::Sample;
use rayon::prelude::*;
use volpath::rng::Sampler;

use cmdline::LearnedArgs;

#[derive(Args)]
#[command(mut_arg("out", cmdline::groups::default("out/bench-spread")))]
#[command(mut_arg("seed", cmdline::groups::help("Seed of the latent samples")))]
pub struct SpreadBenchArgs {
    /// Samples file (default: the validation set of `train data --out out/train/data`).
    #[arg(long, default_value = "out/train/data/val.tlsamples")]
    pub data: PathBuf,
    /// Model files to compare (comma-separated; default: the shipped model).
    #[arg(long, value_delimiter = ',')]
    pub model: Vec<PathBuf>,
    /// Decoder proposals per configuration.
    #[arg(long, default_value_t = 64)]
    pub proposals: usize,
    /// Upper edges of the curvature bins (units of 1/σ_n; a last bin takes the rest).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "-0.3,-0.1,0.1,0.3,0.6,1.0",
        allow_hyphen_values = true
    )]
    pub bins: Vec<f64>,
    /// Upper edges of the reduced-albedo bins (α'; a last bin takes the rest). Each table row
    /// is one (α', κ) bin.
    #[arg(long, value_delimiter = ',', default_value = "0.7,0.9,0.97")]
    pub albedo_bins: Vec<f64>,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

/// Mean curvature at the origin of the implicit cubic with coefficients `c` (module doc;
/// [`Poly3::mean_curvature`]).
pub fn mean_curvature(c: &[f32; N_POLY]) -> f64 {
    Poly3(*c).mean_curvature()
}

/// One configuration of a samples file: its first sample's inputs and all its exits.
struct Config {
    id: u32,
    kappa: f64,
    albedo_red: f64,
    sample: Sample,
    exits: Vec<f64>,
}

/// Groups consecutive samples of the same configuration.
fn configs(samples: &[Sample]) -> Vec<Config> {
    let mut out: Vec<Config> = Vec::new();
    for s in samples {
        let d = s
            .out_ls
            .iter()
            .map(|&v| (v as f64).powi(2))
            .sum::<f64>()
            .sqrt();
        match out.last_mut() {
            Some(c) if c.id == s.config => c.exits.push(d),
            _ => out.push(Config {
                id: s.config,
                kappa: mean_curvature(&s.poly_ls),
                albedo_red: ReducedMedium::new(s.sigma_t as f64, s.albedo as f64, s.g as f64)
                    .albedo_red,
                sample: *s,
                exits: vec![d],
            }),
        }
    }
    out
}

/// Absorb and the distances |x̂| of `k` proposals for one configuration.
fn proposals(m: &ShapeAdaptiveModel, c: &Config, k: usize, seed: u64) -> Result<(f64, Vec<f64>)> {
    let s = &c.sample;
    let x: [f32; INPUT_DIM] =
        m.normalisation()
            .normalise(&s.poly_ls, c.albedo_red, s.g as f64, s.eta as f64);
    let mut f = vec![0.0f32; m.feature_dim()];
    m.features(&[x], &mut f)?;
    let mut absorb = [0.0f32];
    m.absorb(&f, &mut absorb)?;
    let z: Vec<[f32; LATENT_DIM]> = (0..k)
        .map(|i| {
            let mut r = Sampler::new(seed, c.id as u64, i as u64, 0x5D);
            std::array::from_fn(|_| bssrdf::gaussian::probit(r.next_f32() as f64) as f32)
        })
        .collect();
    let mut y = vec![[0.0f32; POSITION_DIM]; k];
    m.decode(&f, &z, &vec![0u32; k], &mut y)?;
    let d = y
        .iter()
        .map(|v| v.iter().map(|&t| (t as f64).powi(2)).sum::<f64>().sqrt())
        .collect();
    Ok((absorb[0] as f64, d))
}

/// The `q`-quantile of `v` (sorted in place; nearest rank).
fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((q * v.len() as f64) as usize).min(v.len() - 1)]
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// Distances and absorption of one bin.
#[derive(Default)]
struct Bin {
    configs: usize,
    exits: Vec<f64>,
    absorption: Vec<f64>,
    proposals: Vec<Vec<f64>>,
    absorb: Vec<Vec<f64>>,
}

/// The table by (albedo, curvature) bin: the training data's exit distances and absorption,
/// and each model's (`names`) proposals beside them.
fn print_bins(a: &SpreadBenchArgs, bins: &mut [Bin], names: &[&str]) {
    let nk = a.bins.len() + 1;
    for (mi, name) in names.iter().enumerate() {
        println!("model {mi}: {name}");
    }
    println!(
        "{:>13} {:>13} {:>6} | {:>34} {:>6} | per model: {:>34} {:>6}",
        "α'",
        "κ·σ_n",
        "configs",
        "exits |x|: mean p25 p50 p90 p99",
        "P(abs)",
        "|x̂|: mean p25 p50 p90 p99",
        "Absorb"
    );
    let range = |v: &[f64], i: usize| {
        let lo = if i == 0 { f64::NEG_INFINITY } else { v[i - 1] };
        format!(
            "[{lo:>5},{:>5})",
            v.get(i).copied().unwrap_or(f64::INFINITY)
        )
    };
    for (i, b) in bins.iter_mut().enumerate() {
        if b.configs == 0 {
            continue;
        }
        let stats = |v: &mut Vec<f64>| {
            let m = mean(v);
            let q = [0.25, 0.5, 0.9, 0.99].map(|f| quantile(v, f));
            (m, q)
        };
        let (m, [p25, p50, p90, p99]) = stats(&mut b.exits);
        print!(
            "{} {} {:>6} | {m:>6.3} {p25:>6.3} {p50:>6.3} {p90:>6.3} {p99:>6.3} {:>6.4}",
            range(&a.albedo_bins, i / nk),
            range(&a.bins, i % nk),
            b.configs,
            mean(&b.absorption)
        );
        for mi in 0..names.len() {
            let (pm, [q25, q50, q90, q99]) = stats(&mut b.proposals[mi]);
            print!(
                " | {mi}: {pm:>6.3} {q25:>6.3} {q50:>6.3} {q90:>6.3} {q99:>6.3} {:>6.4} ({:+.1} %)",
                mean(&b.absorb[mi]),
                100.0 * (pm / m - 1.0)
            );
        }
        println!();
    }
}

pub fn run(a: &SpreadBenchArgs) -> Result<()> {
    let models: Vec<(String, ShapeAdaptiveModel)> = if a.model.is_empty() {
        vec![("shipped".into(), LearnedArgs::shipped_model()?)]
    } else {
        a.model
            .iter()
            .map(|p| {
                let name = p.display().to_string();
                Ok((name, bssrdf::model::load(p)?))
            })
            .collect::<Result<_>>()?
    };
    anyhow::ensure!(a.proposals > 0, "--proposals must be at least 1");
    for (edges, flag) in [(&a.bins, "--bins"), (&a.albedo_bins, "--albedo-bins")] {
        anyhow::ensure!(
            edges.iter().all(|b| b.is_finite()) && edges.windows(2).all(|w| w[0] < w[1]),
            "{flag} must be finite and increasing"
        );
    }
    let (_, samples) = learn::samplefile::read_samples(&a.data)
        .with_context(|| format!("reading {}", a.data.display()))?;
    let configs = configs(&samples);
    anyhow::ensure!(!configs.is_empty(), "{} holds no samples", a.data.display());
    let edge = |v: &[f64], x: f64| v.iter().position(|&e| x < e).unwrap_or(v.len());
    let nk = a.bins.len() + 1;
    let bin_of = |c: &Config| edge(&a.albedo_bins, c.albedo_red) * nk + edge(&a.bins, c.kappa);
    let mut bins: Vec<Bin> = (0..nk * (a.albedo_bins.len() + 1))
        .map(|_| Bin {
            proposals: vec![Vec::new(); models.len()],
            absorb: vec![Vec::new(); models.len()],
            ..Bin::default()
        })
        .collect();
    let mut csv = String::from("config,kappa,albedo_red,g,eta,cos_in,absorption_prob,exit_mean");
    for i in 0..models.len() {
        csv.push_str(&format!(",absorb_{i},proposal_mean_{i}"));
    }
    csv.push('\n');
    let per_model: Vec<Vec<(f64, Vec<f64>)>> = models
        .iter()
        .map(|(_, m)| {
            configs
                .par_iter()
                .map(|c| proposals(m, c, a.proposals, *a.seed))
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<_>>()?;
    for (ci, c) in configs.iter().enumerate() {
        let b = &mut bins[bin_of(c)];
        b.configs += 1;
        b.exits.extend_from_slice(&c.exits);
        b.absorption.push(c.sample.absorption_prob as f64);
        let p = &c.sample.poly_ls;
        let cos_in = p[3] / (p[1] * p[1] + p[2] * p[2] + p[3] * p[3]).sqrt();
        csv.push_str(&format!(
            "{},{},{},{},{},{cos_in},{},{}",
            c.id,
            c.kappa,
            c.albedo_red,
            c.sample.g,
            c.sample.eta,
            c.sample.absorption_prob,
            mean(&c.exits)
        ));
        for (mi, pm) in per_model.iter().enumerate() {
            let (absorb, d) = &pm[ci];
            b.proposals[mi].extend_from_slice(d);
            b.absorb[mi].push(*absorb);
            csv.push_str(&format!(",{absorb},{}", mean(d)));
        }
        csv.push('\n');
    }
    let names: Vec<&str> = models.iter().map(|(n, _)| n.as_str()).collect();
    print_bins(a, &mut bins, &names);
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    scene::fsutil::atomic_write(&a.out.join("spread.csv"), csv.as_bytes(), *a.overwrite)?;
    println!("wrote {}", a.out.join("spread.csv").display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use bssrdf::polynomial::{Poly3, power_to_index};
    use glam::Vec3;

    /// The mean curvature is κ on the sphere p = u_z + κ/2·|u|² (`translucent-dev plane`'s surface), in any
    /// orientation and at any scale of the polynomial, and 0 on a plane.
    #[test]
    fn mean_curvature_of_a_sphere_is_its_curvature() {
        assert_eq!(mean_curvature(&Poly3::plane(Vec3::Z).0), 0.0);
        for kappa in [0.4f32, -0.25] {
            let mut p = Poly3::plane(Vec3::Z);
            for (a, b, c) in [(2, 0, 0), (0, 2, 0), (0, 0, 2)] {
                p.0[power_to_index(a, b, c)] = 0.5 * kappa;
            }
            assert!((mean_curvature(&p.0) - kappa as f64).abs() < 1e-6);
            let d = Vec3::new(0.3, -0.4, -0.8).normalize();
            let r = p.to_light_space(d);
            assert!((mean_curvature(&r.0) - kappa as f64).abs() < 1e-5);
            let s = Poly3(p.0.map(|v| 2.5 * v));
            assert!((mean_curvature(&s.0) - kappa as f64).abs() < 1e-5);
        }
        // A cylinder of radius 2 about the y axis: mean curvature ½·(1/2).
        let mut cyl = Poly3::plane(Vec3::Z);
        cyl.0[power_to_index(2, 0, 0)] = 0.25;
        cyl.0[power_to_index(0, 0, 2)] = 0.25;
        assert!((mean_curvature(&cyl.0) - 0.25).abs() < 1e-6);
    }
}
