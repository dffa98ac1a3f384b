//! `translucent-dev walks`: guided random walks ([`volpath::guided`]) against classical ones,
//! side by side in one run: per-pixel variance × time of the image, of its derivative images and
//! of the loss gradient.
//!
//! Cases: each shape (`--shapes`, about 1 unit across) × size in mean free paths (`--sizes`:
//! σ_t = size per unit, grey) × albedo (`--albedos`) × light (`--lights`: a flash beside the
//! camera, a fixed light, or a light behind the object), behind the boundary `--boundary` with HG `--g`; one view of the
//! house rig (`--res`², `--spp` per render).
//!
//! Per case and walk (classical, then guided at each `--shares`), `--reps` derivative renders
//! with their own seeds, timed together. Per pixel p and channel the sample variance over the
//! renders, summed over the pixels: V = Σ_p var_p, for the image and for ∂I/∂σ_t and ∂I/∂α. The
//! loss gradient is the optimiser's split-sample gradient of each pair of renders against the mean
//! of as many classical renders of other seeds (the truth's image), and V its variance over the
//! pairs. Each walk's renders start after one untimed render. The table
//! gives the efficiency against the classical walk, (V·t)_classical / (V·t)_guided, with t the
//! seconds per render: above 1 the guided walk is less noisy per second. Each figure is the mean
//! over the three channels (and over σ_t and α for the gradient).

use std::io::Write;
use std::time::Instant;

use anyhow::{Context, Result};
use bssrdf::diff::{DiffImages, Loss};
use clap::Args;
use geometry::Shape;
use glam::Vec3;
use scene::rig::{RigLight, house_rig};
use scene::{Image, Medium};
use volpath::{VolpathSettings, WalkSampling};

use inverse::forward::ModelSpec;
use inverse::views::build_accel;

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help("out/bench-walks", "Output folder (`walks.csv`)")
))]
#[command(mut_arg("res", cmdline::groups::default_and_help("64", "Image size")))]
#[command(mut_arg(
    "spp",
    cmdline::groups::default_and_help("16", "Samples per pixel of each render")
))]
pub struct WalksBenchArgs {
    /// Shapes (built-in names, about 1 unit across).
    #[arg(long, value_delimiter = ',', default_value = "blob")]
    pub shapes: Vec<String>,
    /// Sizes in mean free paths across the object (σ_t per unit, grey).
    #[arg(long, value_delimiter = ',', default_value = "5,15,50")]
    pub sizes: Vec<f32>,
    /// Single-scattering albedos (grey).
    #[arg(long, value_delimiter = ',', default_value = "0.8,0.95,0.99")]
    pub albedos: Vec<f32>,
    /// Lights: `flash` (beside the camera), `fixed` and/or `back` (behind the object).
    #[arg(long, value_delimiter = ',', default_value = "flash,fixed")]
    pub lights: Vec<String>,
    /// Guided shares P to compare with the classical walk.
    #[arg(long, value_delimiter = ',', default_value = "0.25,0.5,0.75")]
    pub shares: Vec<f32>,
    /// Henyey–Greenstein g of the medium.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub g: f32,
    /// The boundary: `null`, `ETA` (smooth dielectric) or `ETA/ALPHA` (rough, GGX α).
    #[arg(long, default_value = "null")]
    pub boundary: String,
    /// Renders per walk and case (pairs of them give the gradient's variance).
    #[arg(long, default_value_t = 16)]
    pub reps: u32,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
}

/// `--boundary` as (η, GGX α).
fn boundary(s: &str) -> Result<(f32, f32)> {
    if s == "null" {
        return Ok((1.0, 0.0));
    }
    let (eta, alpha) = s.split_once('/').unwrap_or((s, "0"));
    let eta: f32 = eta.parse().context("--boundary: η is not a number")?;
    let alpha: f32 = alpha.parse().context("--boundary: GGX α is not a number")?;
    anyhow::ensure!(
        eta >= 1.0 && alpha >= 0.0,
        "--boundary: need η ≥ 1 and α ≥ 0"
    );
    Ok((eta, alpha))
}

/// Σ_p var_p per channel over the renders `images` (sample variance per pixel and channel).
fn summed_variance(images: &[&Image]) -> [f64; 3] {
    let n = images.len() as f64;
    let mut out = [0.0f64; 3];
    for p in 0..images[0].data.len() {
        for (c, o) in out.iter_mut().enumerate() {
            let (mut s, mut s2) = (0.0f64, 0.0f64);
            for im in images {
                let v = im.data[p][c] as f64;
                s += v;
                s2 += v * v;
            }
            *o += (s2 - s * s / n).max(0.0) / (n - 1.0);
        }
    }
    out
}

/// The per-pixel mean of `images`.
fn mean(images: &[&Image]) -> Image {
    let mut m = images[0].clone();
    let n = images.len() as f32;
    for (p, px) in m.data.iter_mut().enumerate() {
        *px = std::array::from_fn(|c| images.iter().map(|im| im.data[p][c]).sum::<f32>() / n);
    }
    m
}

/// One walk's renders of a case, and their seconds per render.
struct Renders {
    images: Vec<DiffImages>,
    seconds: f64,
}

/// The variances (image, ∂σ_t, ∂α, gradient; each per channel or component) of `r` against
/// `target`.
fn variances(r: &Renders, target: &Image) -> [Vec<f64>; 4] {
    let pick = |f: fn(&DiffImages) -> &Image| -> Vec<f64> {
        summed_variance(&r.images.iter().map(f).collect::<Vec<_>>()).to_vec()
    };
    let mut grads: Vec<[f64; 6]> = Vec::new();
    for (i, a) in r.images.iter().enumerate() {
        for b in &r.images[i + 1..] {
            let g = inverse::optimize::split_sample_gradient(a, b, target, Loss::L2);
            grads.push(std::array::from_fn(|k| {
                if k < 3 {
                    g.d_sigma_t[k]
                } else {
                    g.d_albedo[k - 3]
                }
            }));
        }
    }
    let n = grads.len() as f64;
    let gvar = (0..6)
        .map(|k| {
            let m = grads.iter().map(|g| g[k]).sum::<f64>() / n;
            grads.iter().map(|g| (g[k] - m).powi(2)).sum::<f64>() / (n - 1.0)
        })
        .collect();
    [
        pick(|d| &d.value),
        pick(|d| &d.d_sigma_t),
        pick(|d| &d.d_albedo),
        gvar,
    ]
}

pub fn run(a: &WalksBenchArgs) -> Result<()> {
    anyhow::ensure!(a.reps >= 4, "--reps must be at least 4");
    anyhow::ensure!(
        a.shares.iter().all(|p| *p > 0.0 && *p <= 1.0),
        "--shares must lie in (0, 1]"
    );
    let (eta, roughness) = boundary(&a.boundary)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("{}: cannot create output folder", a.out.display()))?;
    let mut csv = std::fs::File::create(a.out.join("walks.csv"))?;
    writeln!(
        csv,
        "shape,size_mfp,albedo,light,walk,seconds,eff_image,eff_dsigma,eff_dalbedo,eff_gradient"
    )?;
    println!(
        "boundary {}, g {}, one view of {}² × {} spp, {} renders per walk; efficiency = (V·t) classical / (V·t) guided",
        a.boundary, a.g, *a.res, *a.spp, a.reps
    );
    println!(
        "{:<8} {:>5} {:>6} {:<6} {:<14} {:>8} {:>7} {:>7} {:>7} {:>9}",
        "shape", "mfp", "α", "light", "walk", "s/render", "image", "∂σ_t", "∂α", "gradient"
    );
    for shape in &a.shapes {
        let mesh = Shape::from_name(shape)?.build()?;
        let accel = build_accel(mesh, &[], shape);
        for light in &a.lights {
            let rig_light = match light.as_str() {
                "flash" => RigLight::Attached {
                    offset: Vec3::new(0.8, 0.8, 0.0),
                },
                "fixed" => RigLight::Fixed {
                    position: Vec3::new(1.2, 1.6, 0.8),
                },
                // Behind the object, 2 units past it along the view direction, a little off axis.
                "back" => RigLight::Attached {
                    offset: Vec3::new(0.4, 0.4, 4.0),
                },
                other => anyhow::bail!("--lights: unknown light '{other}' (flash, fixed or back)"),
            };
            let view = house_rig(1, *a.res, rig_light, (20.0, 20.0)).build()[0].clone();
            for &size in &a.sizes {
                for &albedo in &a.albedos {
                    let medium = Medium {
                        sigma_t: [size; 3],
                        albedo: [albedo; 3],
                        g: a.g.into(),
                        eta,
                        roughness,
                    };
                    let case = Case {
                        shape,
                        size,
                        albedo,
                        light,
                    };
                    measure(a, &case, &accel, &view, medium, &mut csv)?;
                }
            }
        }
    }
    println!("wrote {}", a.out.join("walks.csv").display());
    Ok(())
}

/// What names a case in the table.
struct Case<'a> {
    shape: &'a str,
    size: f32,
    albedo: f32,
    light: &'a str,
}

/// One case: the classical walk, then each guided share, against a reference of the truth's
/// image; prints and writes a row per walk.
fn measure(
    a: &WalksBenchArgs,
    case: &Case,
    accel: &geometry::Accel,
    view: &scene::ViewDesc,
    medium: Medium,
    csv: &mut std::fs::File,
) -> Result<()> {
    let render = |walks: WalkSampling, stream: u64| -> Result<Renders> {
        let settings = VolpathSettings {
            walks,
            ..VolpathSettings::default()
        };
        let model = ModelSpec::tracer(settings).build(accel);
        let at = model.at(medium)?;
        let tracer = at.view(&view.camera, &view.light);
        // One untimed render first: the timed ones start warm.
        let warm = volpath::RenderSettings {
            spp: 1,
            seed: *a.seed,
            view: 0,
        };
        tracer.derivatives(&warm, None)?;
        let t0 = Instant::now();
        let images = (0..a.reps as u64)
            .map(|k| {
                let seed = volpath::rng::hash_key(&[*a.seed, stream + k]);
                let rs = volpath::RenderSettings {
                    spp: *a.spp,
                    seed,
                    view: 0,
                };
                Ok(tracer.derivatives(&rs, None)?)
            })
            .collect::<Result<Vec<_>>>()?;
        let seconds = t0.elapsed().as_secs_f64() / a.reps as f64;
        Ok(Renders { images, seconds })
    };
    // The truth's image: classical renders of their own seeds.
    let reference = render(WalkSampling::Classical, 1 << 32)?;
    let target = mean(
        &reference
            .images
            .iter()
            .map(|d| &d.value)
            .collect::<Vec<_>>(),
    );
    let classical = render(WalkSampling::Classical, 0)?;
    let base = variances(&classical, &target);
    let mut walks = vec![("classical".to_string(), classical)];
    for &p in &a.shares {
        walks.push((
            format!("guided {p}"),
            render(WalkSampling::Guided { probability: p }, 0)?,
        ));
    }
    let t_c = walks[0].1.seconds;
    let Case {
        shape,
        size,
        albedo,
        light,
    } = case;
    for (name, r) in &walks {
        let v = variances(r, &target);
        let eff: Vec<f64> = (0..4)
            .map(|q| {
                let ratios: Vec<f64> = base[q]
                    .iter()
                    .zip(&v[q])
                    .filter(|(b, g)| **b > 0.0 && **g > 0.0)
                    .map(|(b, g)| (b * t_c) / (g * r.seconds))
                    .collect();
                ratios.iter().sum::<f64>() / ratios.len().max(1) as f64
            })
            .collect();
        println!(
            "{:<8} {:>5} {:>6} {:<6} {:<14} {:>8.3} {:>7.2} {:>7.2} {:>7.2} {:>9.2}",
            shape, size, albedo, light, name, r.seconds, eff[0], eff[1], eff[2], eff[3]
        );
        writeln!(
            csv,
            "{shape},{size},{albedo},{light},{name},{:.4},{:.4},{:.4},{:.4},{:.4}",
            r.seconds, eff[0], eff[1], eff[2], eff[3]
        )?;
    }
    Ok(())
}
