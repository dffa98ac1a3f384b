//! `translucent bench plane`: the learned models against directly simulated random walks on a
//! half-space (issue #4 acceptance 2, "distribution check on a plane").
//!
//! For each albedo (g = 0, η = 1, σ_t = 1 — the model is scale-invariant, model-spec §2) and
//! incidence angle, random walks in the half-space below the plane p = u_z
//! (`learn::walk::random_walk`, the exact physics of the training data) give the absorbed fraction
//! and the radial distribution of exit points r/σ_n around the entry point. Each model gets the
//! plane's light-space coefficients, decodes `z ~ N(0, I₄)` samples, projects them onto the plane
//! (along its normal: r = |(y₁, y₂)| in units of σ_n after undoing the light-space rotation) and
//! reports Absorb. Table: absorbed fraction vs Absorb, and the L1 distance between the normalised
//! radial histograms (0 = identical, 2 = disjoint). Writes `OUT/plane.csv` and `OUT/plane.png`.
//!
//! `--curvature κ` replaces the plane by a sphere of radius σ_n/|κ| touching the entry point,
//! p(u) = u_z + κ/2·|u|² in units of σ_n (κ > 0: the medium is the ball, convex; κ < 0: the medium
//! surrounds a spherical cavity, concave). The quadric is exact in the cubic descriptor, so this
//! isolates how the networks respond to curvature from the fit, the mesh and the projection.

use std::path::PathBuf;

use anyhow::{Context, Result};
use bssrdf::medium::{ReducedMedium, sigma_n};
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, POSITION_DIM, ShapeAdaptiveModel};
use bssrdf::polynomial::{Poly3, light_space_frame};
use clap::Args;
use glam::{DVec3, Vec3};
use learn::walk::{WalkMedium, WalkOutcome, WalkSurface, random_walk};
use plot::{Figure, Panel, Series};
use rayon::prelude::*;
use volpath::rng::Sampler;

use crate::common::LearnedArgs;

#[derive(Args)]
pub struct PlaneBenchArgs {
    /// Model files to compare (comma-separated; default: the shipped model).
    #[arg(long, value_delimiter = ',')]
    pub model: Vec<PathBuf>,
    /// Albedos.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0.3,0.8,0.9,0.95,0.98,0.995"
    )]
    pub albedo: Vec<f64>,
    /// Incidence angles in degrees from the normal.
    #[arg(long, value_delimiter = ',', default_value = "0,60")]
    pub angle: Vec<f64>,
    /// Curvatures κ = σ_n/radius of a sphere through the entry point (0: the plane; > 0 convex,
    /// < 0 concave). Walks and models see p(u) = u_z + κ/2·|u|².
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0",
        allow_hyphen_values = true
    )]
    pub curvature: Vec<f64>,
    /// Random walks per case.
    #[arg(long, default_value_t = 200_000)]
    pub walks: u64,
    /// Decoder samples per case and model.
    #[arg(long, default_value_t = 200_000)]
    pub samples: usize,
    /// Output folder.
    #[arg(long, default_value = "out/bench-plane")]
    pub out: PathBuf,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Replace existing outputs.
    #[arg(long)]
    pub overwrite: bool,
}

const BINS: usize = 40;
const R_MAX: f64 = 8.0;

fn bin(r: f64) -> usize {
    ((r / R_MAX * BINS as f64) as usize).min(BINS - 1)
}

fn normalised(h: &[u64]) -> Vec<f64> {
    let n: u64 = h.iter().sum();
    h.iter().map(|&c| c as f64 / n.max(1) as f64).collect()
}

/// The surface through the origin with outward normal +z and curvature κ (units of 1/σ_n):
/// p(u) = u_z + κ/2·(u_x² + u_y² + u_z²), a sphere of radius 1/|κ| (the plane when κ = 0).
fn surface(kappa: f64) -> Poly3 {
    let mut p = Poly3::plane(Vec3::Z);
    for (a, b, c) in [(2, 0, 0), (0, 2, 0), (0, 0, 2)] {
        p.0[bssrdf::polynomial::power_to_index(a, b, c)] = (0.5 * kappa) as f32;
    }
    p
}

/// Absorbed fraction and radial histogram (r/σ_n) of random walks below `poly`.
fn simulate(poly: &Poly3, albedo: f64, angle: f64, walks: u64, seed: u64) -> (f64, Vec<u64>) {
    let sn = sigma_n(1.0, albedo, 0.0);
    let surface = WalkSurface::new(poly, sn);
    let medium = WalkMedium {
        sigma_t: 1.0,
        albedo,
        g: 0.0,
        eta: 1.0,
    };
    let d_in = Vec3::new(angle.sin() as f32, 0.0, -angle.cos() as f32);
    let (absorbed, hist) = (0..walks)
        .into_par_iter()
        .fold(
            || (0u64, vec![0u64; BINS]),
            |(mut a, mut h), i| {
                let mut rng = Sampler::new(seed, 0xB1A4E, i, 0);
                match random_walk(&surface, &medium, d_in, &mut rng) {
                    WalkOutcome::Exited(e) => {
                        let p: DVec3 = e.position;
                        h[bin((p.x * p.x + p.y * p.y).sqrt() / sn)] += 1;
                    }
                    WalkOutcome::Absorbed { .. } => a += 1,
                    WalkOutcome::Invalid(_) => {}
                }
                (a, h)
            },
        )
        .reduce(
            || (0, vec![0; BINS]),
            |(a, mut h), (b, g)| {
                h.iter_mut().zip(&g).for_each(|(x, y)| *x += y);
                (a + b, h)
            },
        );
    (absorbed as f64 / walks as f64, hist)
}

/// Absorb and the radial histogram of `n` decoded samples of `model` on `poly`.
fn model_case(
    model: &ShapeAdaptiveModel,
    poly: &Poly3,
    albedo: f64,
    angle: f64,
    n: usize,
    seed: u64,
) -> Result<(f64, Vec<u64>)> {
    let d_in = Vec3::new(angle.sin() as f32, 0.0, -angle.cos() as f32);
    let ls = poly.to_light_space(d_in);
    let red = ReducedMedium::new(1.0, albedo, 0.0);
    let x: [f32; INPUT_DIM] =
        model
            .normalisation()
            .normalise(ls.coeffs(), red.albedo_red, 0.0, 1.0);
    let mut f = vec![0.0f32; model.feature_dim()];
    model.features(&[x], &mut f)?;
    let mut absorb = [0.0f32];
    model.absorb(&f, &mut absorb)?;
    let z: Vec<[f32; LATENT_DIM]> = (0..n)
        .map(|i| {
            let mut s = Sampler::new(seed, 0xDEC0, i as u64, 0);
            std::array::from_fn(|_| bssrdf::gaussian::probit(s.next_f32() as f64) as f32)
        })
        .collect();
    let mut y = vec![[0.0f32; POSITION_DIM]; n];
    model.decode(&f, &z, &vec![0u32; n], &mut y)?;
    let frame = light_space_frame(d_in);
    let mut h = vec![0u64; BINS];
    for v in &y {
        let w = frame.to_world(Vec3::from_array(*v));
        h[bin(((w.x * w.x + w.y * w.y) as f64).sqrt())] += 1;
    }
    Ok((absorb[0] as f64, h))
}

pub fn run(a: &PlaneBenchArgs) -> Result<()> {
    let models: Vec<(String, ShapeAdaptiveModel)> = if a.model.is_empty() {
        vec![("shipped".into(), LearnedArgs::shipped_model()?)]
    } else {
        a.model
            .iter()
            .map(|p| {
                let name = p.file_stem().map(|s| s.to_string_lossy().into_owned());
                Ok((name.unwrap_or_default(), bssrdf::model::load(p)?))
            })
            .collect::<Result<_>>()?
    };
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut csv = String::from("albedo,angle_deg,curvature,walk_absorbed,model,absorb,radial_l1\n");
    print!("{:>6} {:>5} {:>6} | {:>9}", "α", "angle", "κ", "walks abs");
    for (name, _) in &models {
        print!(" | {name:>12}: Absorb  L1(r)");
    }
    println!();
    let mut panels = Vec::new();
    for &kappa in &a.curvature {
        anyhow::ensure!(
            kappa.is_finite() && kappa.abs() <= 2.0,
            "--curvature values must be finite and within [-2, 2] (σ_n/radius), got {kappa}"
        );
    }
    for (&angle_deg, &kappa) in a
        .angle
        .iter()
        .flat_map(|g| a.curvature.iter().map(move |k| (g, k)))
    {
        let poly = surface(kappa);
        for &albedo in &a.albedo {
            anyhow::ensure!(
                albedo > 0.0 && albedo < 1.0,
                "--albedo values must be in (0, 1)"
            );
            let angle = angle_deg.to_radians();
            let (abs_walk, h_walk) = simulate(&poly, albedo, angle, a.walks, a.seed);
            let p_walk = normalised(&h_walk);
            let centre = |i: usize| (i as f64 + 0.5) * R_MAX / BINS as f64;
            let mut series = vec![Series::new(
                "random walks",
                p_walk
                    .iter()
                    .enumerate()
                    .map(|(i, &p)| (centre(i), p))
                    .collect(),
            )];
            print!("{albedo:>6} {angle_deg:>5} {kappa:>6} | {abs_walk:>9.4}");
            for (name, m) in &models {
                let (absorb, h) = model_case(m, &poly, albedo, angle, a.samples, a.seed)?;
                let p = normalised(&h);
                let l1: f64 = p.iter().zip(&p_walk).map(|(x, y)| (x - y).abs()).sum();
                print!(" | {:>12}  {absorb:>6.4} {l1:>6.3}", "");
                csv.push_str(&format!(
                    "{albedo},{angle_deg},{kappa},{abs_walk},{name},{absorb},{l1}\n"
                ));
                series.push(Series::new(
                    name.clone(),
                    p.iter().enumerate().map(|(i, &q)| (centre(i), q)).collect(),
                ));
            }
            println!();
            panels.push(Panel {
                title: if kappa == 0.0 {
                    format!("α = {albedo}, {angle_deg}° incidence")
                } else {
                    format!("α = {albedo}, {angle_deg}° incidence, κ = {kappa}")
                },
                x_label: "exit distance r / σ_n".into(),
                y_label: "fraction of exits".into(),
                log_y: false,
                series,
                reference_lines: vec![],
            });
        }
    }
    scene::fsutil::atomic_write(&a.out.join("plane.csv"), csv.as_bytes(), a.overwrite)?;
    Figure::new(panels, a.albedo.len().min(3)).write_png(&a.out.join("plane.png"), a.overwrite)?;
    println!("wrote {}", a.out.join("plane.csv").display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The curved surface is the sphere of radius 1/|κ| through the origin with normal +z.
    #[test]
    fn curvature_surface_is_the_sphere_through_the_entry_point() {
        assert_eq!(surface(0.0).0, Poly3::plane(Vec3::Z).0);
        for kappa in [0.4f32, -0.25] {
            let p = surface(kappa as f64);
            let r = 1.0 / kappa;
            let centre = Vec3::new(0.0, 0.0, -r);
            for d in [
                Vec3::X,
                Vec3::Y,
                Vec3::new(0.3, -0.5, 0.8).normalize(),
                -Vec3::Z,
            ] {
                let on = centre + d * r.abs();
                assert!(p.eval(on).abs() < 1e-4, "κ {kappa}: p = {}", p.eval(on));
            }
            assert_eq!(p.eval(Vec3::ZERO), 0.0);
            assert!((p.gradient(Vec3::ZERO) - Vec3::Z).length() < 1e-6);
            // The medium (p < 0) is the ball when convex, the outside of the cavity when concave.
            assert_eq!(p.eval(centre) < 0.0, kappa > 0.0);
        }
    }
}
