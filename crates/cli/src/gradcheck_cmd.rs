//! `translucent gradcheck` (Son et al. 2024 Fig. 3 and 5): derivative images ∂I/∂σ_t and ∂I/∂α
//! of one view by several estimators (`ours`, `ours-alpha-offsets`, `naive`, `fd`), written as
//! false-colour PNGs (red > 0, blue < 0, white 0; one symmetric range per parameter so the
//! methods are comparable) and EXRs, with a summary per method: the image-summed derivative per
//! channel, its relative error against `fd`, and the per-pixel correlation with `fd`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use bssrdf::diff::{DiffImages, DiffMethod, DiffSettings, Primal, render_diff};
use bssrdf::render::{LearnedScene, RenderSettings, VertexFeatures};
use clap::Args;
use scene::{Dataset, Image, Medium};

use crate::common::{LearnedArgs, build_accel, parse_rgb};

#[derive(Args)]
pub struct GradcheckArgs {
    /// Dataset folder (ours or a Mitsuba reference folder): mesh, camera and light of --view.
    #[arg(long)]
    pub dataset: PathBuf,
    /// View index.
    #[arg(long, default_value_t = 0)]
    pub view: usize,
    /// σ_t at which to differentiate (default: the dataset's truth).
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true)]
    pub sigma_t: Option<[f32; 3]>,
    /// α at which to differentiate (default: the dataset's truth).
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true)]
    pub albedo: Option<[f32; 3]>,
    /// Methods (comma-separated; `fd` is the reference and is always added).
    #[arg(long, value_delimiter = ',', default_value = "ours,naive")]
    pub methods: Vec<String>,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Relative σ_t offset Δ/σ_t.
    #[arg(long, default_value_t = 0.02)]
    pub delta_rel: f32,
    /// Value image of `ours`: `offset-mean` (mean of the two σ_t offset samples) or `sample`.
    #[arg(long, default_value = "offset-mean")]
    pub primal: Primal,
    /// Output folder.
    #[arg(long, default_value = "out/gradcheck")]
    pub out: PathBuf,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Replace existing outputs.
    #[arg(long)]
    pub overwrite: bool,
    #[command(flatten)]
    pub learned: LearnedArgs,
}

fn sums(img: &Image) -> [f64; 3] {
    let mut s = [0.0; 3];
    for p in &img.data {
        for c in 0..3 {
            s[c] += p[c] as f64;
        }
    }
    s
}

/// Pearson correlation of the per-pixel values (all channels together).
fn correlation(a: &Image, b: &Image) -> f64 {
    let xs: Vec<(f64, f64)> = a
        .data
        .iter()
        .zip(&b.data)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] as f64, q[c] as f64)))
        .collect();
    let n = xs.len().max(1) as f64;
    let (ma, mb) = (
        xs.iter().map(|x| x.0).sum::<f64>() / n,
        xs.iter().map(|x| x.1).sum::<f64>() / n,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in &xs {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt().max(1e-300)
}

pub fn run(a: &GradcheckArgs) -> Result<()> {
    let ds = Dataset::load(&a.dataset)?;
    let Some(view) = ds.views.get(a.view) else {
        bail!(
            "{} has {} views; --view {} does not exist",
            a.dataset.display(),
            ds.views.len(),
            a.view
        );
    };
    let truth = ds.truth;
    let medium = Medium {
        sigma_t: a
            .sigma_t
            .or(truth.map(|t| t.sigma_t))
            .context("the dataset has no truth medium: pass --sigma-t and --albedo")?,
        albedo: a
            .albedo
            .or(truth.map(|t| t.albedo))
            .context("the dataset has no truth medium: pass --sigma-t and --albedo")?,
        g: truth.map(|t| t.g).unwrap_or(0.0),
        eta: truth.map(|t| t.eta).unwrap_or(1.0),
    };
    medium.validate("gradcheck medium")?;
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &a.dataset.display().to_string());
    let model = a.learned.load_model()?;
    let features = VertexFeatures::fit(&accel, &medium, model.info().c19_quirk, a.seed)?;
    let scene = LearnedScene::new(&accel, &model, &features, medium, a.learned.settings())?;
    let rs = RenderSettings {
        spp: a.spp,
        seed: a.seed,
        view: a.view as u64,
    };
    let mut methods: Vec<DiffMethod> = a
        .methods
        .iter()
        .map(|m| m.parse())
        .collect::<Result<_, _>>()?;
    methods.retain(|m| *m != DiffMethod::Fd);
    methods.push(DiffMethod::Fd);
    std::fs::create_dir_all(&a.out)?;
    let mut results: Vec<(DiffMethod, DiffImages, f64)> = Vec::new();
    for &m in &methods {
        let t0 = Instant::now();
        let ds = DiffSettings {
            method: m,
            delta_rel: a.delta_rel,
            primal: a.primal,
            ..DiffSettings::default()
        };
        let img = render_diff(&scene, &view.camera, &view.light, &rs, &ds, None)?;
        results.push((m, img, t0.elapsed().as_secs_f64()));
    }
    let fd = &results.last().expect("fd is always there").1;
    let zero = Image::new(fd.value.width, fd.value.height);
    // One colour range per parameter: the 99th percentile of |fd|.
    let (_, r_t) = Image::false_colour_diff_with_range(&fd.d_sigma_t, &zero, None)?;
    let (_, r_a) = Image::false_colour_diff_with_range(&fd.d_albedo, &zero, None)?;
    println!(
        "view {} of {}, σ_t = {:?}, α = {:?}, {} spp",
        a.view,
        a.dataset.display(),
        medium.sigma_t,
        medium.albedo,
        a.spp
    );
    println!(
        "{:<20} {:>8} | {:>36} {:>8} {:>6} | {:>36} {:>8} {:>6}",
        "method",
        "seconds",
        "Σ ∂I/∂σ_t (R, G, B)",
        "rel.err",
        "corr",
        "Σ ∂I/∂α (R, G, B)",
        "rel.err",
        "corr"
    );
    let (ft, fa) = (sums(&fd.d_sigma_t), sums(&fd.d_albedo));
    let rel = |s: [f64; 3], f: [f64; 3]| {
        let num: f64 = (0..3).map(|c| (s[c] - f[c]).powi(2)).sum::<f64>().sqrt();
        let den: f64 = (0..3).map(|c| f[c].powi(2)).sum::<f64>().sqrt();
        num / den.max(1e-300)
    };
    let mut csv = String::from("method,seconds,channel,sum_d_sigma_t,sum_d_albedo\n");
    for (m, img, secs) in &results {
        let (st, sa) = (sums(&img.d_sigma_t), sums(&img.d_albedo));
        println!(
            "{:<20} {:>8.2} | {:>+11.3e} {:>+11.3e} {:>+11.3e} {:>8.3} {:>6.3} | {:>+11.3e} {:>+11.3e} {:>+11.3e} {:>8.3} {:>6.3}",
            m.name(),
            secs,
            st[0],
            st[1],
            st[2],
            rel(st, ft),
            correlation(&img.d_sigma_t, &fd.d_sigma_t),
            sa[0],
            sa[1],
            sa[2],
            rel(sa, fa),
            correlation(&img.d_albedo, &fd.d_albedo)
        );
        for c in 0..3 {
            csv.push_str(&format!("{},{secs},{c},{},{}\n", m.name(), st[c], sa[c]));
        }
        for (what, d, r) in [
            ("d_sigma_t", &img.d_sigma_t, r_t),
            ("d_albedo", &img.d_albedo, r_a),
        ] {
            let stem = format!("{}_{what}", m.name());
            d.write_exr(&a.out.join(format!("{stem}.exr")), a.overwrite)?;
            let (fc, _) = Image::false_colour_diff_with_range(d, &zero, Some(r))?;
            fc.write_png(&a.out.join(format!("{stem}.png")), 1.0, a.overwrite)?;
        }
    }
    scene::fsutil::atomic_write(&a.out.join("gradcheck.csv"), csv.as_bytes(), a.overwrite)?;
    println!("wrote {}", a.out.display());
    Ok(())
}
