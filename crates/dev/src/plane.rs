//! `translucent-dev plane`: the learned models against directly simulated random walks on a
//! half-space (a distribution check on a plane).
//!
//! For each albedo (σ_t = 1 — the model is scale-invariant, docs/model.md §2; g and η as given,
//! by default 0 and 1) and
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
//! isolates how the networks respond to curvature from the fit and the mesh. Curved training
//! configurations are cylinder-like (the meshes are scaled per axis), so spheres probe the
//! networks outside their training distribution; `translucent-dev spread` compares them with their own
//! held-out data instead (docs/notes/decoder-training.md, "The decoder is the cause").
//!
//! On a sphere the exit distance is measured along the surface (the great-circle distance
//! R·θ from the entry point), for the walks' exits and for the model's proposals alike. The
//! proposals are first moved onto the sphere as the renderer's projection Π moves them: along
//! ∇p, which on a sphere is the radial line through its centre, with the renderer's default
//! reach of [`DEFAULT_MAX_DIST_SCALE`]·σ_n; a proposal farther from the surface is a miss
//! (reported, left out of the histogram). On the plane this is r = |(y₁, y₂)|. (The distance
//! from the normal axis, r = |(u_x, u_y)|, of unprojected proposals would not do on a sphere:
//! every exit on the far side of the ball would pile up at r ≤ R, and proposals beyond R would
//! be counted where no exit can lie.)

use std::path::PathBuf;

use anyhow::{Context, Result};
use bssrdf::medium::{ReducedMedium, sigma_n};
use bssrdf::nn::{INPUT_DIM, LATENT_DIM, POSITION_DIM, ShapeAdaptiveModel};
use bssrdf::polynomial::{Poly3, light_space_frame};
use bssrdf::projection::DEFAULT_MAX_DIST_SCALE;
use clap::Args;
use glam::{DVec3, Vec3};
use learn::walk::{WalkMedium, WalkOutcome, WalkSurface, random_walk};
use plot::{Figure, Panel, Series};
use rayon::prelude::*;
use volpath::rng::Sampler;

use cmdline::LearnedArgs;

#[derive(Args)]
#[command(mut_arg("out", cmdline::groups::default("out/bench-plane")))]
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
    /// Henyey–Greenstein anisotropy g of the medium.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub g: f64,
    /// Relative index of refraction η of the boundary (smooth; 1 = index-matched).
    #[arg(long, default_value_t = 1.0)]
    pub eta: f64,
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
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

const BINS: usize = 40;
const R_MAX: f64 = 8.0;

fn bin(r: f64) -> usize {
    ((r / R_MAX * BINS as f64) as usize).min(BINS - 1)
}

/// Mean exit distance (units of σ_n) of a normalised histogram, from its bin centres.
fn mean_distance(p: &[f64]) -> f64 {
    p.iter()
        .enumerate()
        .map(|(i, &q)| q * (i as f64 + 0.5) * R_MAX / BINS as f64)
        .sum()
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

/// Distance along the surface of `surface(κ)` from the entry point (the origin) to a point `q`
/// on it, in units of σ_n: R·θ on the sphere of radius R = 1/|κ| centred at (0, 0, −1/κ), where θ
/// is the angle at the centre; |(q_x, q_y)| on the plane.
fn surface_distance(kappa: f64, q: DVec3) -> f64 {
    if kappa == 0.0 {
        return (q.x * q.x + q.y * q.y).sqrt();
    }
    let c = DVec3::new(0.0, 0.0, -1.0 / kappa);
    let (a, b) = (-c, q - c);
    a.angle_between(b) / kappa.abs()
}

/// Π of the renderer on `surface(κ)`: moves the proposal `x` (units of σ_n) along the gradient of
/// p onto the surface. The gradient of p = u_z + κ/2·|u|² is ẑ + κu, parallel to u − c, so the
/// line is the radial one through the centre c and the nearest surface point is c + R·(x − c)/|x − c|
/// (x itself projected along ẑ on the plane). `None` when the surface is farther than `reach` (or x
/// sits at the centre).
fn project(kappa: f64, x: DVec3, reach: f64) -> Option<DVec3> {
    if kappa == 0.0 {
        return (x.z.abs() <= reach).then_some(DVec3::new(x.x, x.y, 0.0));
    }
    let c = DVec3::new(0.0, 0.0, -1.0 / kappa);
    let (r, d) = (1.0 / kappa.abs(), x - c);
    let len = d.length();
    (len > 0.0 && (len - r).abs() <= reach).then(|| c + d * (r / len))
}

/// Absorbed fraction and histogram of exit distances along the surface (units of σ_n) of random
/// walks below `poly` (the surface of curvature `kappa`).
fn simulate(
    poly: &Poly3,
    kappa: f64,
    (albedo, g, eta): (f64, f64, f64),
    angle: f64,
    walks: u64,
    seed: u64,
) -> (f64, Vec<u64>) {
    let sn = sigma_n(1.0, albedo, g);
    let surface = WalkSurface::new(poly, sn);
    let medium = WalkMedium {
        sigma_t: 1.0,
        albedo,
        g,
        eta,
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
                        h[bin(surface_distance(kappa, e.position / sn))] += 1;
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

/// A model's Absorb, the histogram of exit distances along the surface of its `n` decoded
/// samples after the renderer's projection ([`project`]), and the fraction of them that miss.
struct ModelCase {
    absorb: f64,
    hist: Vec<u64>,
    miss: f64,
}

/// [`ModelCase`] of `model` on `poly` = `surface(kappa)`.
fn model_case(
    model: &ShapeAdaptiveModel,
    poly: &Poly3,
    kappa: f64,
    (albedo, g, eta): (f64, f64, f64),
    angle: f64,
    n: usize,
    seed: u64,
) -> Result<ModelCase> {
    let d_in = Vec3::new(angle.sin() as f32, 0.0, -angle.cos() as f32);
    let ls = poly.to_light_space(d_in);
    let red = ReducedMedium::new(1.0, albedo, g);
    let x: [f32; INPUT_DIM] = model
        .normalisation()
        .normalise(ls.coeffs(), red.albedo_red, g, eta);
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
    let mut hist = vec![0u64; BINS];
    let mut misses = 0usize;
    for v in &y {
        let w = frame.to_world(Vec3::from_array(*v)).as_dvec3();
        match project(kappa, w, DEFAULT_MAX_DIST_SCALE as f64) {
            Some(q) => hist[bin(surface_distance(kappa, q))] += 1,
            None => misses += 1,
        }
    }
    Ok(ModelCase {
        absorb: absorb[0] as f64,
        hist,
        miss: misses as f64 / n.max(1) as f64,
    })
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
    let mut csv = String::from(
        "albedo,angle_deg,curvature,walk_absorbed,walk_mean_r,model,absorb,radial_l1,miss,mean_r\n",
    );
    print!(
        "{:>6} {:>5} {:>6} | {:>9} {:>6}",
        "α", "angle", "κ", "walks abs", "mean r"
    );
    for (name, _) in &models {
        print!(" | {name:>12}: Absorb  L1(r)  miss mean r");
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
            let (abs_walk, h_walk) =
                simulate(&poly, kappa, (albedo, a.g, a.eta), angle, a.walks, *a.seed);
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
            let r_walk = mean_distance(&p_walk);
            print!("{albedo:>6} {angle_deg:>5} {kappa:>6} | {abs_walk:>9.4} {r_walk:>6.3}");
            for (name, m) in &models {
                let ModelCase { absorb, hist, miss } = model_case(
                    m,
                    &poly,
                    kappa,
                    (albedo, a.g, a.eta),
                    angle,
                    a.samples,
                    *a.seed,
                )?;
                let p = normalised(&hist);
                let l1: f64 = p.iter().zip(&p_walk).map(|(x, y)| (x - y).abs()).sum();
                let r = mean_distance(&p);
                print!(
                    " | {:>12}  {absorb:>6.4} {l1:>6.3} {miss:>5.3} {r:>6.3}",
                    ""
                );
                csv.push_str(&format!(
                    "{albedo},{angle_deg},{kappa},{abs_walk},{r_walk},{name},{absorb},{l1},{miss},{r}\n"
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
                x_label: "exit distance along the surface / σ_n".into(),
                y_label: "fraction of exits".into(),
                log_y: false,
                series,
                reference_lines: vec![],
                bands: Vec::new(),
            });
        }
    }
    scene::fsutil::atomic_write(&a.out.join("plane.csv"), csv.as_bytes(), *a.overwrite)?;
    Figure::new(panels, a.albedo.len().min(3)).write_png(&a.out.join("plane.png"), *a.overwrite)?;
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

    /// Π moves proposals radially onto the sphere (the line of ∇p), with the reach as its limit,
    /// and the distance along the surface is R·θ: a quarter circle at the equator, half a circle
    /// at the far pole. On the plane both reduce to the distance from the normal axis.
    #[test]
    fn proposals_are_projected_radially_and_measured_along_the_surface() {
        let plane = project(0.0, DVec3::new(3.0, 4.0, -0.5), 8.0).unwrap();
        assert_eq!(plane, DVec3::new(3.0, 4.0, 0.0));
        assert_eq!(surface_distance(0.0, plane), 5.0);
        assert!(project(0.0, DVec3::new(0.0, 0.0, 9.0), 8.0).is_none());
        for kappa in [0.4, -0.25] {
            let r = 1.0 / f64::abs(kappa);
            let c = DVec3::new(0.0, 0.0, -1.0 / kappa);
            let poly = surface(kappa);
            for x in [
                DVec3::new(4.0, 1.0, 0.3),
                DVec3::new(-0.5, 0.2, -1.0),
                DVec3::new(0.1, -3.0, -6.0),
            ] {
                let q = project(kappa, x, 8.0).unwrap();
                assert!(poly.eval(q.as_vec3()).abs() < 1e-5, "κ {kappa}: q = {q}");
                // q lies on the line through x along ∇p(x).
                let g = poly.gradient(x.as_vec3()).as_dvec3().normalize();
                assert!((q - x).cross(g).length() < 1e-5 * (1.0 + (q - x).length()));
            }
            let equator = c + DVec3::X * r;
            let pole = c + c.normalize() * r;
            assert!(
                (surface_distance(kappa, equator) - r * std::f64::consts::FRAC_PI_2).abs() < 1e-9
            );
            assert!((surface_distance(kappa, pole) - r * std::f64::consts::PI).abs() < 1e-9);
            assert!(project(kappa, c + DVec3::Y * (r + 8.5), 8.0).is_none());
        }
    }
}
