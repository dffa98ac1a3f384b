//! `translucent gradcheck` (Son et al. 2024 Fig. 3 and 5): derivative images ∂I/∂σ_t and ∂I/∂α
//! of one view by several estimators (`ours`, `ours-alpha-offsets`, `naive`, `fd`), written as
//! false-colour PNGs (red > 0, blue < 0, white 0; one symmetric range per parameter so the
//! methods are comparable) and EXRs, with a summary per method: the image-summed derivative per
//! channel, its relative error against `fd`, and the per-pixel correlation with `fd`.

use anyhow::{Context, Result, bail};
use bssrdf::diff::{Estimator, Primal};
use bssrdf::render::RenderSettings;
use clap::Args;
use inverse::forward::learned::LearnedSpec;
use scene::Dataset;
use std::path::PathBuf;

use inverse::gradcheck::{agreement, render_estimators};

use cmdline::{LearnedArgs, parse_rgb};
use inverse::views::build_accel;

#[derive(Args)]
#[command(mut_arg("out", cmdline::groups::default("out/gradcheck")))]
#[command(mut_arg("spp", cmdline::groups::default("64")))]
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
    /// Gradient estimators of the learned BSSRDF (comma-separated; `fd` is the reference and is
    /// always added).
    #[arg(
        long = "estimators",
        alias = "methods",
        value_delimiter = ',',
        default_value = "ours,naive"
    )]
    pub estimators: Vec<String>,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    /// Relative σ_t offset Δ/σ_t.
    #[arg(long, default_value_t = 0.02)]
    pub delta_rel: f32,
    /// Value image of `ours`: `offset-mean` (mean of the two σ_t offset samples) or `sample`.
    #[arg(long, default_value = "offset-mean")]
    pub primal: Primal,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
    #[command(flatten)]
    pub learned: LearnedArgs,
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
    let sigma_t = a
        .sigma_t
        .or(truth.map(|t| t.sigma_t))
        .context("the dataset has no truth medium: pass --sigma-t and --albedo")?;
    let albedo = a
        .albedo
        .or(truth.map(|t| t.albedo))
        .context("the dataset has no truth medium: pass --sigma-t and --albedo")?;
    // The boundary and phase function are what the dataset states, as for a recovery.
    let medium = ds
        .object
        .unwrap_or(scene::Object::INDEX_MATCHED_ISOTROPIC)
        .medium(sigma_t, albedo);
    medium.validate("gradcheck medium")?;
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &a.dataset.display().to_string());
    let model = a.learned.load_model()?;
    let rs = RenderSettings {
        spp: *a.spp,
        seed: *a.seed,
        view: a.view as u64,
    };
    let estimators: Vec<Estimator> = a
        .estimators
        .iter()
        .map(|m| m.parse())
        .collect::<Result<_, _>>()?;
    std::fs::create_dir_all(&a.out)?;
    let results = render_estimators(
        &accel,
        LearnedSpec::new(&model, a.learned.settings(), *a.seed),
        medium,
        &view.camera,
        &view.light,
        &rs,
        &rs,
        &estimators,
        a.delta_rel,
        a.primal,
    )?;
    inverse::gradcheck::write_estimators(&results, &a.out, *a.overwrite)?;
    println!(
        "view {} of {}, σ_t = {:?}, α = {:?}, {} spp",
        a.view,
        a.dataset.display(),
        medium.sigma_t,
        medium.albedo,
        *a.spp
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
    let fd = &results.last().expect("fd is always there").images;
    let mut csv = String::from("method,seconds,channel,sum_d_sigma_t,sum_d_albedo\n");
    for r in &results {
        let g = agreement(&r.images, fd);
        let (st, sa) = (g.sum_d_sigma_t, g.sum_d_albedo);
        println!(
            "{:<20} {:>8.2} | {:>+11.3e} {:>+11.3e} {:>+11.3e} {:>8.3} {:>6.3} | {:>+11.3e} {:>+11.3e} {:>+11.3e} {:>8.3} {:>6.3}",
            r.estimator.name(),
            r.seconds,
            st[0],
            st[1],
            st[2],
            g.relative_error[0],
            g.correlation[0],
            sa[0],
            sa[1],
            sa[2],
            g.relative_error[1],
            g.correlation[1]
        );
        for c in 0..3 {
            csv.push_str(&format!(
                "{},{},{c},{},{}\n",
                r.estimator.name(),
                r.seconds,
                st[c],
                sa[c]
            ));
        }
    }
    scene::fsutil::atomic_write(&a.out.join("gradcheck.csv"), csv.as_bytes(), *a.overwrite)?;
    println!("wrote {}", a.out.display());
    Ok(())
}
