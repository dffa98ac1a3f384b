//! `translucent-dev learned-vs-volpath`: accuracy of the learned BSSRDF against the volumetric
//! path tracer.
//!
//! For every shape × σ_t × α × g × boundary (by default η = 1, g = 0; objects about 1 unit
//! across, camera rig at distance 2 with an attached light), render the views with volpath (≥ 1024 spp; cached as EXR under
//! `OUT/volpath/<case>/` and reused by later runs with the same settings) and with each model,
//! with real and with planar features. Per case: the relative error of the image mean
//! (mean over views of mean(learned)/mean(volpath) − 1, channels averaged: the medium is grey)
//! and the image relative RMSE (RMSE / mean of the volpath image, averaged over views). Writes
//! `OUT/learned_vs_volpath.csv` and prints the table.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use geometry::Shape;
use glam::Vec3;
use scene::rig::RigLight;
use scene::rig::house_rig;
use scene::{Image, Medium};
use volpath::VolpathSettings;

use cmdline::by_rows;
use inverse::forward::ModelSpec;
use inverse::views::build_accel;
use scene::image::pair_stats;

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help("out/bench-learned", "Output folder (volpath cache, CSV)")
))]
#[command(mut_arg("views", cmdline::groups::default_and_help("2", "Views per case")))]
#[command(mut_arg("res", cmdline::groups::default_and_help("64", "Image size")))]
#[command(mut_arg(
    "spp",
    cmdline::groups::default_and_help("64", "Samples per pixel of the learned renders")
))]
pub struct LearnedBenchArgs {
    /// Model files to evaluate (one or more, comma-separated; `shipped` = the built-in model),
    /// e.g. `shipped,son24.safetensors` (the imported reference model). With two or more, the
    /// first is compared case by case against each other one at the end.
    #[arg(long, value_delimiter = ',', default_value = "shipped")]
    pub model: Vec<PathBuf>,
    /// Shapes (built-in names).
    #[arg(long, value_delimiter = ',', default_value = "sphere,cone,torus,blob")]
    pub shapes: Vec<String>,
    /// Extinctions σ_t (1/unit).
    #[arg(long, value_delimiter = ',', default_value = "30,60,100")]
    pub sigma_t: Vec<f32>,
    /// Albedos α.
    #[arg(long, value_delimiter = ',', default_value = "0.8,0.9,0.98")]
    pub albedo: Vec<f32>,
    /// Henyey–Greenstein anisotropies g.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0",
        allow_hyphen_values = true
    )]
    pub g: Vec<f32>,
    /// Boundaries: `null` (index-matched), `ETA` (a smooth dielectric of relative index ETA) or
    /// `ETA/ALPHA` (a rough dielectric, GGX α = ALPHA), e.g. `null,1.5,1.33/0.1`.
    #[arg(long, value_delimiter = ',', default_value = "null", value_parser = parse_boundary)]
    pub boundary: Vec<(f32, f32)>,
    #[command(flatten)]
    pub views: cmdline::Views,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    /// Samples per pixel of the volumetric reference.
    #[arg(long, default_value_t = 1024)]
    pub volpath_spp: u32,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Light-side exit law of the learned renders.
    #[arg(long, value_enum, default_value_t)]
    pub exit_law: bssrdf::exit::ExitLaw,
    /// Projection rule of the learned renders.
    #[arg(long, value_enum, default_value_t)]
    pub projection: bssrdf::projection::ProjectionKind,
    /// Reach of the `son24` projection in units of σ_n (SON24: 2; default 8).
    #[arg(long, default_value_t = bssrdf::projection::DEFAULT_MAX_DIST_SCALE, value_parser = cmdline::parse_reach, allow_hyphen_values = true)]
    pub max_dist_scale: f32,
    /// Light-side incidence of the learned renders.
    #[arg(long, value_enum, default_value_t)]
    pub incidence: bssrdf::render::Incidence,
    /// Where the learned renders' entry points come from: the decoder or the walks it imitates.
    #[arg(long, value_enum, default_value_t)]
    pub entry_sampler: bssrdf::render::EntrySampler,
}

/// A boundary `null`, `ETA` or `ETA/ALPHA` as (η, GGX α).
fn parse_boundary(s: &str) -> Result<(f32, f32), String> {
    let bad =
        || format!("bad boundary {s:?}: expected `null`, `ETA` or `ETA/ALPHA`, e.g. `1.33/0.1`");
    if s.eq_ignore_ascii_case("null") {
        return Ok((1.0, 0.0));
    }
    let (eta, alpha) = match s.split_once('/') {
        Some((e, a)) => (e.parse().map_err(|_| bad())?, a.parse().map_err(|_| bad())?),
        None => (s.parse().map_err(|_| bad())?, 0.0),
    };
    Ok((eta, alpha))
}

/// A boundary's name in the table and the cache: `null`, `smooth1.5`, `rough1.33a0.1`.
fn boundary_name((eta, alpha): (f32, f32)) -> String {
    match (eta == 1.0, alpha == 0.0) {
        (true, _) => "null".into(),
        (false, true) => format!("smooth{eta}"),
        (false, false) => format!("rough{eta}a{alpha}"),
    }
}

/// Relative error of the mean and relative RMSE of `a` against reference `b`, over views.
fn errors(a: &[Image], b: &[Image]) -> Result<(f64, f64)> {
    let (mut me, mut rr) = (0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        let st = pair_stats(x, y)?;
        me += st.mean_ratio.iter().sum::<f64>() / 3.0 - 1.0;
        rr += st.rel_rmse.iter().sum::<f64>() / 3.0;
    }
    let n = a.len().max(1) as f64;
    Ok((me / n, rr / n))
}

/// The table's and the CSV's headers: a mean error and an rRMSE per model and feature mode.
fn headers(models: &[PathBuf], csv: &mut std::fs::File) -> Result<()> {
    write!(csv, "shape,sigma_t,albedo,g,boundary")?;
    for p in models {
        let name = p.file_stem().unwrap_or_default().to_string_lossy();
        write!(
            csv,
            ",{name}_mean_err,{name}_rel_rmse,{name}_planar_mean_err,{name}_planar_rel_rmse"
        )?;
    }
    writeln!(csv)?;
    print!(
        "{:<7} {:>5} {:>5} {:>4} {:>13}",
        "shape", "σ_t", "α", "g", "boundary"
    );
    for p in models {
        let name = p.file_stem().unwrap_or_default().to_string_lossy();
        print!(
            " | {:>22} {:>22}",
            format!("{name}: mean err, rRMSE"),
            "planar: mean err, rRMSE"
        );
    }
    println!();
    Ok(())
}

/// The volumetric tracer's images of a case at `spp`, written to `dir` (the cache a later run
/// reads).
fn tracer_reference(
    job: inverse::views::Job,
    spp: u32,
    dir: &std::path::Path,
    names: &[String],
) -> Result<Vec<Image>> {
    let rep = by_rows(job.views, "volpath", |pb| {
        inverse::views::render(
            ModelSpec::tracer(VolpathSettings::default()),
            &inverse::views::Job { spp, ..job },
            false,
            pb,
        )
    })?;
    cmdline::write_outputs(dir, names, &rep.images, true)?;
    Ok(rep.images)
}

pub fn run(a: &LearnedBenchArgs) -> Result<()> {
    let models: Vec<_> = a
        .model
        .iter()
        .map(|p| cmdline::load_model_arg(p).with_context(|| format!("model {}", p.display())))
        .collect::<Result<_>>()?;
    std::fs::create_dir_all(&a.out)?;
    let csv_path = a.out.join("learned_vs_volpath.csv");
    let mut csv = std::fs::File::create(&csv_path)?;
    headers(&a.model, &mut csv)?;
    let t0 = Instant::now();
    // Per model and feature mode: (|mean err|, rRMSE) of every case.
    let mut results: Vec<[Vec<(f64, f64)>; 2]> = vec![[Vec::new(), Vec::new()]; models.len()];
    for shape_name in &a.shapes {
        let shape = Shape::from_name(shape_name)?;
        let accel = build_accel(shape.build()?, &[], shape_name);
        let rig = house_rig(
            *a.views,
            *a.res,
            RigLight::Attached {
                offset: Vec3::new(0.8, 0.8, 0.0),
            },
            (-60.0, 60.0),
        );
        rig.validate("bench rig")?;
        let views = rig.build();
        let media = a.sigma_t.iter().flat_map(|&st| {
            a.albedo.iter().flat_map(move |&al| {
                a.g.iter()
                    .flat_map(move |&g| a.boundary.iter().map(move |&b| (st, al, g, b)))
            })
        });
        for (st, al, g, (eta, roughness)) in media {
            {
                let medium = Medium {
                    sigma_t: [st; 3],
                    albedo: [al; 3],
                    g: g.into(),
                    eta,
                    roughness,
                };
                medium.validate("bench medium")?;
                let bname = boundary_name((eta, roughness));
                // The index-matched isotropic cases keep their cache names.
                let case = if g == 0.0 && bname == "null" {
                    format!("{shape_name}_s{st}_a{al}")
                } else {
                    format!("{shape_name}_s{st}_a{al}_g{g}_{bname}")
                };
                let dir = a.out.join("volpath").join(format!(
                    "{case}_{}v_{}px_{}spp_seed{}",
                    *a.views, *a.res, a.volpath_spp, *a.seed
                ));
                let names: Vec<String> = (0..views.len()).map(|i| format!("view_{i:03}")).collect();
                let cached: Option<Vec<Image>> = names
                    .iter()
                    .map(|n| Image::read_exr(&dir.join(format!("{n}.exr"))).ok())
                    .collect();
                let job = inverse::views::Job {
                    accel: &accel,
                    medium: &medium,
                    views: &views,
                    spp: *a.spp,
                    seed: *a.seed,
                };
                let reference = match cached {
                    Some(v) => v,
                    None => tracer_reference(job, a.volpath_spp, &dir, &names)?,
                };
                print!("{shape_name:<7} {st:>5} {al:>5} {g:>4} {bname:>13}");
                write!(csv, "{shape_name},{st},{al},{g},{bname}")?;
                for (mi, model) in models.iter().enumerate() {
                    for planar in [false, true] {
                        let settings = bssrdf::render::LearnedSettings {
                            planar_features: planar,
                            projection: a.projection.rule(a.max_dist_scale),
                            exit: a.exit_law,
                            incidence: a.incidence,
                            entry: a.entry_sampler,
                            ..Default::default()
                        };
                        let rep = by_rows(&views, "learned", |pb| {
                            let spec = ModelSpec::learned(model, settings, job.seed);
                            inverse::views::render(spec, &job, false, pb)
                        })?;
                        let (me, rr) = errors(&rep.images, &reference)?;
                        print!(
                            "{}{:>+10.3} {:>10.3}",
                            if planar { "  " } else { " | " },
                            me,
                            rr
                        );
                        write!(csv, ",{me:.5},{rr:.5}")?;
                        results[mi][planar as usize].push((me.abs(), rr));
                    }
                }
                println!();
                writeln!(csv)?;
            }
        }
    }
    println!(
        "wrote {} ({:.0} s)",
        csv_path.display(),
        t0.elapsed().as_secs_f64()
    );
    summarise(&a.model, &results);
    Ok(())
}

/// Averages per model and mode, and how often the first model beats each other one.
fn summarise(names: &[PathBuf], results: &[[Vec<(f64, f64)>; 2]]) {
    let name = |p: &PathBuf| {
        p.file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    };
    let mean = |v: &[(f64, f64)], f: fn(&(f64, f64)) -> f64| {
        v.iter().map(f).sum::<f64>() / v.len().max(1) as f64
    };
    println!("\nsummary (averages over the cases):");
    for (p, r) in names.iter().zip(results) {
        for (mode, v) in ["real", "planar"].iter().zip(r) {
            println!(
                "  {:<24} {mode:<6} features: mean |mean err| {:.4}, mean rRMSE {:.4}",
                name(p),
                mean(v, |x| x.0),
                mean(v, |x| x.1)
            );
        }
    }
    for (p, r) in names.iter().zip(results).skip(1) {
        let (a, b) = (&results[0][0], &r[0]);
        let n = a.len().min(b.len());
        let wins_rr = (0..n).filter(|&i| a[i].1 <= b[i].1).count();
        let wins_me = (0..n).filter(|&i| a[i].0 <= b[i].0).count();
        println!(
            "  {} vs {} (real features): lower or equal rRMSE in {wins_rr}/{n} cases, lower or \
             equal |mean err| in {wins_me}/{n} cases",
            name(&names[0]),
            name(p)
        );
    }
}
