//! `translucent-dev noise`: per-pixel variance and loss-gradient variance of the learned
//! renderer against the volumetric path tracer, at equal time, on coloured media.
//!
//! Scenes: the built-in blob at two sizes (`--scales`, in scene units; the medium fixes the size in
//! mean free paths) under a light attached to each camera and under one fixed light, in a
//! coloured medium (`--sigma-t`, `--albedo`), plus the same small flash scene in a grey medium
//! (σ_t and α of the green channel) to see what the sampling scheme does where no channel
//! choice is needed.
//!
//! Per scene and renderer (volpath at `--volpath-spp`; the learned renderer at `--spp` with each
//! `--schemes` pixel sampling), two renders with different seeds: the per-pixel variance of one
//! render is Var ≈ (a − b)²/2, and per channel the relative variance is
//!
//!   v = mean_p (a_p − b_p)²/2 / mean_p m_p²,  m = (a + b)/2,
//!
//! over the pixels where the volpath mean is positive. At equal time the efficiency is
//! 1/(v·t) with t the render time of one render; the table gives volpath's v·t over each
//! learned scheme's (> 1: the learned renderer is less noisy per second).
//!
//! On a coloured medium a third row bounds what any channel-sharing scheme can reach (a
//! proposal per channel with multiple importance sampling, a density ratio, …): per channel c,
//! the learned renderer on the grey medium of channel c (σ_t,c and α_c in every channel), where
//! every sample serves channel c from c's own proposal at the cost of one sample, against the
//! tracer on the coloured medium. A scheme that lets each sample serve all three channels gains at
//! most this ratio unless it also lowers the variance of a single sample.
//!
//! Gradient variance: the loss gradient of an `optimize` iteration with its default settings
//! (`ours`, two renders, `--grad-spp` samples per pixel) on view 0 against the volpath render, at
//! the truth, over `--grad-seeds` iterations (each its own random numbers); per parameter the
//! variance over iterations times the time of one evaluation, relative to the first scheme. The
//! last gradient row is the volumetric path tracer's: the same split-sample loss gradient from
//! two of its derivative renders (`volpath::render_derivatives`, each path differentiated
//! analytically) at half of `--grad-spp` each, i.e. the iteration of a volumetric
//! differentiable recovery.

use std::io::Write;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use geometry::Shape;
use scene::rig::RigLight;
use scene::{Image, Medium};
use volpath::VolpathSettings;

use bssrdf::nn::ShapeAdaptiveModel;
use cmdline::{by_rows, parse_rgb};
use inverse::forward::ModelSpec;
use inverse::views::{RenderReport, build_accel};
use scene::rig::house_rig;

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(
        "out/bench-noise",
        "Output folder (`noise.csv`, `gradient-noise.csv`)"
    )
))]
#[command(mut_arg("seed", cmdline::groups::help("Seed (renders use seed and seed + 1)")))]
#[command(mut_arg("views", cmdline::groups::default_and_help("4", "Views per scene")))]
#[command(mut_arg("res", cmdline::groups::default_and_help("128", "Image size")))]
#[command(mut_arg(
    "spp",
    cmdline::groups::default_and_help("64", "Samples per pixel of the learned renders")
))]
pub struct NoiseBenchArgs {
    /// Blob sizes (uniform scale of the unit blob, about 1 unit across at scale 1).
    #[arg(long, value_delimiter = ',', default_value = "0.4,1")]
    pub scales: Vec<f32>,
    /// Extinction σ_t per channel (1/unit).
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true, default_value = "45,65,85")]
    pub sigma_t: [f32; 3],
    /// Albedo per channel.
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true, default_value = "0.85,0.92,0.96")]
    pub albedo: [f32; 3],
    #[command(flatten)]
    pub views: cmdline::Views,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    /// Samples per pixel of the volumetric renders.
    #[arg(long, default_value_t = 128)]
    pub volpath_spp: u32,
    /// Pixel sampling schemes of the learned renderer to compare (`stratified`, `one-hot`).
    #[arg(long, value_delimiter = ',', default_value = "one-hot,stratified")]
    pub schemes: Vec<String>,
    /// Loss-gradient evaluations per scheme and scene (0: skip the gradients).
    #[arg(long, default_value_t = 8)]
    pub grad_seeds: u32,
    /// Samples per pixel of the gradient evaluations (the default of `optimize`).
    #[arg(long, default_value_t = 32)]
    pub grad_spp: u32,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
}

struct Case {
    name: String,
    scale: f32,
    light: RigLight,
    medium: Medium,
}

fn cases(a: &NoiseBenchArgs) -> Vec<Case> {
    let coloured = Medium {
        sigma_t: a.sigma_t,
        albedo: a.albedo,
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let grey = Medium {
        sigma_t: [a.sigma_t[1]; 3],
        albedo: [a.albedo[1]; 3],
        ..coloured
    };
    let flash = RigLight::Attached {
        offset: glam::Vec3::new(0.8, 0.8, 0.0),
    };
    let fixed = RigLight::Fixed {
        position: glam::Vec3::new(1.2, 1.6, 0.8),
    };
    let mut out = Vec::new();
    for &scale in &a.scales {
        for (lname, light) in [("flash", flash), ("fixed", fixed)] {
            out.push(Case {
                name: format!("blob{scale}-{lname}"),
                scale,
                light,
                medium: coloured,
            });
        }
    }
    if let Some(&scale) = a.scales.first() {
        out.push(Case {
            name: format!("blob{scale}-flash-grey"),
            scale,
            light: flash,
            medium: grey,
        });
    }
    out
}

/// Relative variance per channel of one render from two seeds `a`, `b` over the pixels where
/// `mask` is positive in that channel (module docs).
fn relative_variance(a: &[Image], b: &[Image], mask: &[Image]) -> [f64; 3] {
    let mut num = [0.0f64; 3];
    let mut den = [0.0f64; 3];
    for ((a, b), m) in a.iter().zip(b).zip(mask) {
        for ((pa, pb), pm) in a.data.iter().zip(&b.data).zip(&m.data) {
            for c in 0..3 {
                if pm[c] > 0.0 {
                    let (x, y) = (pa[c] as f64, pb[c] as f64);
                    num[c] += 0.5 * (x - y) * (x - y);
                    den[c] += (0.5 * (x + y)).powi(2);
                }
            }
        }
    }
    std::array::from_fn(|c| if den[c] > 0.0 { num[c] / den[c] } else { 0.0 })
}

fn mean_image(a: &[Image], b: &[Image]) -> Vec<Image> {
    a.iter()
        .zip(b)
        .map(|(a, b)| {
            let mut m = a.clone();
            for (p, q) in m.data.iter_mut().zip(&b.data) {
                *p = std::array::from_fn(|c| 0.5 * (p[c] + q[c]));
            }
            m
        })
        .collect()
}

pub fn run(a: &NoiseBenchArgs) -> Result<()> {
    anyhow::ensure!(
        *a.views > 0 && *a.spp > 0 && a.volpath_spp > 0 && *a.res > 0,
        "--views, --res, --spp and --volpath-spp must be at least 1"
    );
    let schemes: Vec<bssrdf::render::PixelSampling> = a
        .schemes
        .iter()
        .map(|s| {
            bssrdf::render::PixelSampling::from_name(s).with_context(|| {
                format!("--schemes: unknown scheme '{s}' (expected stratified or one-hot)")
            })
        })
        .collect::<Result<_>>()?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("{}: cannot create output folder", a.out.display()))?;
    let model = cmdline::LearnedArgs::shipped_model()?;
    let vs = VolpathSettings::default();
    let mut csv = std::fs::File::create(a.out.join("noise.csv"))?;
    writeln!(
        csv,
        "case,renderer,spp,seconds,relvar_r,relvar_g,relvar_b,volpath_vt_over_vt_r,volpath_vt_over_vt_g,volpath_vt_over_vt_b"
    )?;
    let mut gcsv = std::fs::File::create(a.out.join("gradient-noise.csv"))?;
    writeln!(
        gcsv,
        "case,scheme,seconds,var_dsigma_r,var_dsigma_g,var_dsigma_b,var_dalbedo_r,var_dalbedo_g,var_dalbedo_b"
    )?;
    println!(
        "{} views of {}², learned {} spp, volpath {} spp; v = relative variance of one render per pixel, t = seconds per render",
        *a.views, *a.res, *a.spp, a.volpath_spp
    );
    println!(
        "{:<22} {:<18} {:>7} {:>26} {:>24}",
        "case", "renderer", "t (s)", "v (R, G, B)", "volpath v·t / v·t"
    );
    for case in cases(a) {
        let mesh = Shape::from_name("blob")?.scaled(case.scale).build()?;
        let accel = build_accel(mesh, &[], "blob");
        let rig = house_rig(*a.views, *a.res, case.light, (-90.0, 90.0));
        let views = rig.build();
        let timed = |f: &dyn Fn(u64) -> Result<RenderReport>| twice(*a.seed, f);
        let job = inverse::views::Job {
            accel: &accel,
            medium: &case.medium,
            views: &views,
            spp: *a.spp,
            seed: *a.seed,
        };
        let (v0, v1, vt) = timed(&|seed| {
            Ok(by_rows(&views, "volpath", |pb| {
                inverse::views::render(
                    ModelSpec::tracer(vs),
                    &inverse::views::Job {
                        spp: a.volpath_spp,
                        seed,
                        ..job
                    },
                    false,
                    pb,
                )
            })?)
        })?;
        let mask = mean_image(&v0, &v1);
        let vrel = relative_variance(&v0, &v1, &mask);
        let vol_vt: [f64; 3] = vrel.map(|v| v * vt);
        let row = |name: &str, spp: u32, ts: [f64; 3], v: [f64; 3], csv: &mut std::fs::File| {
            write_row(csv, &case.name, name, spp, ts, v, vol_vt)
        };
        row("volpath", a.volpath_spp, [vt; 3], vrel, &mut csv)?;
        for &scheme in &schemes {
            let settings = bssrdf::render::LearnedSettings {
                sampling: scheme,
                ..Default::default()
            };
            let (l0, l1, lt) = timed(&|seed| {
                Ok(by_rows(&views, "learned", |pb| {
                    inverse::views::render(
                        ModelSpec::learned(&model, settings, seed),
                        &inverse::views::Job { seed, ..job },
                        false,
                        pb,
                    )
                })?)
            })?;
            let lrel = relative_variance(&l0, &l1, &mask);
            row(
                &format!("learned {}", scheme_name(scheme)),
                *a.spp,
                [lt; 3],
                lrel,
                &mut csv,
            )?;
        }
        if case
            .medium
            .sigma_t
            .iter()
            .any(|&s| s != case.medium.sigma_t[0])
            || case
                .medium
                .albedo
                .iter()
                .any(|&x| x != case.medium.albedo[0])
        {
            let (v, ts) = ceiling(*a.seed, &model, job, &mask)?;
            row("ceiling (grey)", *a.spp, ts, v, &mut csv)?;
        }
        if a.grad_seeds > 0 {
            gradient_noise(
                a, &case, &accel, &views[0], &mask[0], &model, &schemes, &mut gcsv,
            )?;
        }
    }
    println!("wrote {}", a.out.join("noise.csv").display());
    Ok(())
}

/// Renders twice (seeds `seed` and `seed + 1`): both renders' images and the mean seconds per
/// render.
fn twice(
    seed: u64,
    f: &dyn Fn(u64) -> Result<RenderReport>,
) -> Result<(Vec<Image>, Vec<Image>, f64)> {
    let r0 = f(seed)?;
    let r1 = f(seed + 1)?;
    let t: f64 = r0
        .seconds_per_view
        .iter()
        .chain(&r1.seconds_per_view)
        .sum::<f64>()
        / 2.0;
    Ok((r0.images, r1.images, t))
}

/// One row of the table and of `noise.csv`: a renderer's relative variance `v` per channel,
/// with `ts` the seconds per render behind each channel's variance (one render for all three,
/// except the ceiling's one render per channel; the table shows their mean), and the
/// volumetric tracer's variance × time `vol_vt` over this renderer's.
fn write_row(
    csv: &mut std::fs::File,
    case: &str,
    name: &str,
    spp: u32,
    ts: [f64; 3],
    v: [f64; 3],
    vol_vt: [f64; 3],
) -> Result<()> {
    let ratio: [f64; 3] = std::array::from_fn(|c| vol_vt[c] / (v[c] * ts[c]));
    let t = ts.iter().sum::<f64>() / 3.0;
    println!(
        "{:<22} {:<18} {:>7.2} {:>8.5} {:>8.5} {:>8.5} {:>7.2} {:>7.2} {:>7.2}",
        case, name, t, v[0], v[1], v[2], ratio[0], ratio[1], ratio[2]
    );
    writeln!(
        csv,
        "{case},{name},{spp},{t:.4},{:.6e},{:.6e},{:.6e},{:.4},{:.4},{:.4}",
        v[0], v[1], v[2], ratio[0], ratio[1], ratio[2]
    )?;
    Ok(())
}

/// The ceiling of channel sharing (module docs): channel c of the learned renderer on the grey
/// medium of channel c, where every sample serves c from c's own proposal. Per channel: the
/// relative variance and the seconds per render.
fn ceiling(
    seed: u64,
    model: &ShapeAdaptiveModel,
    job: inverse::views::Job,
    mask: &[Image],
) -> Result<([f64; 3], [f64; 3])> {
    let mut v = [0.0; 3];
    let mut ts = [0.0; 3];
    for c in 0..3 {
        let grey = Medium {
            sigma_t: [job.medium.sigma_t[c]; 3],
            albedo: [job.medium.albedo[c]; 3],
            ..*job.medium
        };
        let (l0, l1, lt) = twice(seed, &|seed| {
            Ok(by_rows(job.views, "learned", |pb| {
                inverse::views::render(
                    ModelSpec::learned(model, bssrdf::render::LearnedSettings::default(), seed),
                    &inverse::views::Job {
                        seed,
                        medium: &grey,
                        ..job
                    },
                    false,
                    pb,
                )
            })?)
        })?;
        v[c] = relative_variance(&l0, &l1, mask)[c];
        ts[c] = lt;
    }
    Ok((v, ts))
}

fn scheme_name(s: bssrdf::render::PixelSampling) -> &'static str {
    match s {
        bssrdf::render::PixelSampling::Stratified => "stratified",
        bssrdf::render::PixelSampling::OneHot => "one-hot",
    }
}

/// Variance over iterations of the loss gradient of one view (module docs).
#[allow(clippy::too_many_arguments)]
fn gradient_noise(
    a: &NoiseBenchArgs,
    case: &Case,
    accel: &geometry::Accel,
    view: &scene::ViewDesc,
    target: &Image,
    model: &bssrdf::nn::ShapeAdaptiveModel,
    schemes: &[bssrdf::render::PixelSampling],
    csv: &mut std::fs::File,
) -> Result<()> {
    use inverse::optimize::{OptimizeConfig, Optimizer, TargetView};
    let truth = inverse::params::Params::of(&case.medium);
    let mut first: Option<([f64; 6], f64)> = None;
    for &scheme in schemes {
        let mut config = OptimizeConfig::new(truth);
        config.spp = a.grad_spp;
        config.seed = *a.seed;
        config.learned.sampling = scheme;
        let targets = vec![TargetView {
            camera: &view.camera,
            light: &view.light,
            image: target,
        }];
        let opt = Optimizer::new(config, accel, Some(model), case.medium, targets)?;
        let mut g: Vec<[f64; 6]> = Vec::new();
        let t0 = Instant::now();
        for k in 0..a.grad_seeds {
            let r = opt.gradient(k, &truth)?;
            g.push(six(r.d_sigma_t, r.d_albedo));
        }
        let t = t0.elapsed().as_secs_f64() / a.grad_seeds as f64;
        let var = variances(&g);
        gradient_row(case, scheme_name(scheme), var, t, first, csv)?;
        if first.is_none() {
            first = Some((var, t));
        }
    }
    let (var, t) = volpath_gradient_variance(a, case, accel, view, target)?;
    gradient_row(case, "volpath", var, t, first, csv)
}

/// σ_t R G B, α R G B in one array.
fn six(d_sigma_t: [f64; 3], d_albedo: [f64; 3]) -> [f64; 6] {
    std::array::from_fn(|i| if i < 3 { d_sigma_t[i] } else { d_albedo[i - 3] })
}

/// Per component, the variance of the gradients `g` over iterations.
fn variances(g: &[[f64; 6]]) -> [f64; 6] {
    let n = g.len() as f64;
    std::array::from_fn(|i| {
        let m = g.iter().map(|v| v[i]).sum::<f64>() / n;
        g.iter().map(|v| (v[i] - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)
    })
}

/// Prints and writes one gradient row: variance·time of `first` over this one's.
fn gradient_row(
    case: &Case,
    name: &str,
    var: [f64; 6],
    t: f64,
    first: Option<([f64; 6], f64)>,
    csv: &mut std::fs::File,
) -> Result<()> {
    let vt: Vec<String> = match first {
        None => vec!["1.00".into(); 6],
        Some((v0, t0)) => (0..6)
            .map(|i| format!("{:.2}", v0[i] * t0 / (var[i] * t)))
            .collect(),
    };
    println!(
        "{:<22} {:<18} {:>7.2}   gradient variance·time, first scheme over this (σ_t R G B, α R G B): {}",
        case.name,
        format!("∇ {name}"),
        t,
        vt.join(" ")
    );
    writeln!(
        csv,
        "{},{name},{t:.4},{}",
        case.name,
        var.map(|v| format!("{v:.6e}")).join(",")
    )?;
    Ok(())
}

/// The variance over `--grad-seeds` iterations of the volumetric path tracer's split-sample
/// loss gradient on one view at the truth (σ_t R G B, α R G B), and the seconds of one
/// evaluation.
fn volpath_gradient_variance(
    a: &NoiseBenchArgs,
    case: &Case,
    accel: &geometry::Accel,
    view: &scene::ViewDesc,
    target: &Image,
) -> Result<([f64; 6], f64)> {
    use bssrdf::diff::{DiffImages, Loss};
    use volpath::rng::hash_key;
    let model = ModelSpec::tracer(VolpathSettings::default()).build(accel);
    let at = model.at(case.medium)?;
    let tracer = at.view(&view.camera, &view.light);
    let render = |spp: u32, seed: u64| -> Result<DiffImages> {
        let rs = volpath::RenderSettings { spp, seed, view: 0 };
        Ok(tracer.derivatives(&rs, None)?)
    };
    let half = (a.grad_spp / 2).max(1);
    let mut g: Vec<[f64; 6]> = Vec::new();
    let t0 = Instant::now();
    for k in 0..a.grad_seeds as u64 {
        let da = render(half, hash_key(&[*a.seed, k]))?;
        let db = render(
            a.grad_spp.saturating_sub(half).max(1),
            hash_key(&[*a.seed, k, 0xB]),
        )?;
        let r = inverse::optimize::split_sample_gradient(&da, &db, target, Loss::L2);
        g.push(six(r.d_sigma_t, r.d_albedo));
    }
    let t = t0.elapsed().as_secs_f64() / a.grad_seeds.max(1) as f64;
    Ok((variances(&g), t))
}
