//! `translucent optimize`: recover σ_t and α from a dataset's images by differentiable rendering
//! with the learned BSSRDF (Son et al. 2024 §5; the loop is in the `inverse` crate).
//!
//! Writes `OUT/iterations.csv` (every iteration), `OUT/checkpoint.json` (atomic, every
//! `--checkpoint-every` iterations; `--resume` continues bit-identically), and at the end
//! `OUT/result.json`, `OUT/convergence.png` and re-renders beside the targets with false-colour
//! error images in `OUT/final/`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use bssrdf::diff::{DiffMethod, Loss, Primal};
use bssrdf::render::RenderSettings;
use clap::Args;
use inverse::forward::ModelKind;
use inverse::optimize::{Checkpoint, OptimizeConfig, Optimizer, TargetView};
use inverse::params::{ParamSpec, Parameterisation, Params};
use inverse::report;
use scene::{Dataset, Image, Medium};

use crate::common::{LearnedArgs, build_accel, parse_rgb, progress};

mod bias_correction;
pub(crate) mod multi_start;
pub(crate) mod reuse;

pub use bias_correction::BiasCorrectionArgs;
pub use reuse::run_or_reuse;

#[derive(Args, Clone)]
pub struct OptimizeArgs {
    /// Dataset folder: ours (dataset.json) or a Mitsuba reference folder (scene.json); its
    /// truth medium, when present, is only used to report errors.
    #[arg(long)]
    pub dataset: PathBuf,
    /// Output folder.
    #[arg(long, default_value = "out/optimize")]
    pub out: PathBuf,
    /// Gradient estimator of the model (`--model`). The learned BSSRDF takes ours (default),
    /// ours-alpha-offsets, naive and fd; `volpath` and `dipole` take ad (default) and fd.
    #[arg(
        long = "estimator",
        alias = "method",
        value_enum,
        value_name = "ESTIMATOR"
    )]
    pub method: Option<DiffMethod>,
    /// Maximum depth of the volumetric path tracer when it is the model (Mitsuba `volpath`
    /// semantics; default: the dataset's own, else 32).
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub max_depth: Option<u32>,
    /// The volumetric refinement: the last N of --iterations use the volumetric path tracer
    /// (estimator `ad`, depth --max-depth) from where the learned model's fit has got to, in
    /// place of the bias correction (docs/notes/default-model.md). Default: half of
    /// --iterations with the learned model, none with the others; 0: the learned model alone.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, value_name = "N")]
    pub refine: Option<u32>,
    #[command(flatten)]
    pub budget: IterationArgs,
    /// Image loss.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, value_enum, default_value_t)]
    pub loss: Loss,
    /// The single-render gradient 2(I − T)·∂I/∂θ (the paper's; biased by the covariance of I and
    /// ∂I/∂θ) instead of the default: ∂ℓ/∂I from one render and ∂I/∂θ from an independent one.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub single_render: bool,
    /// (The default; accepted for older scripts.)
    #[arg(long, hide = true, conflicts_with = "single_render")]
    pub two_renders: bool,
    /// The two renders of the gradient as a full value render and a full derivative render at
    /// --spp each, instead of two derivative renders at half of --spp each (the default: as
    /// unbiased, at the cost of one render).
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, conflicts_with = "single_render")]
    pub full_renders: bool,
    /// Normalise each view's loss, per channel, by the loss of a black image against its target,
    /// so that dim views (light that crossed the object) count as much as bright ones.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub normalize_views: bool,
    /// With --normalize-views: no view weighs more than 1/FLOOR times an average view.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = 0.01, value_name = "FLOOR")]
    pub view_weight_floor: f64,
    /// Initial σ_t (1/unit; one value or R,G,B).
    #[arg(long, default_value = "50", value_parser = parse_rgb, allow_negative_numbers = true)]
    pub init_sigma_t: [f32; 3],
    /// Initial albedo (one value or R,G,B).
    #[arg(long, default_value = "0.5", value_parser = parse_rgb, allow_negative_numbers = true)]
    pub init_albedo: [f32; 3],
    /// Learning rate on ln σ_t (or on σ_t/100 with --scaled-sigma-t).
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().lr_sigma_t)]
    pub lr_sigma_t: f32,
    /// Learning rate on α.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().lr_albedo)]
    pub lr_albedo: f32,
    /// Learning-rate decay factor.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().decay)]
    pub decay: f32,
    /// Iterations between decays.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().decay_every)]
    pub decay_every: u32,
    /// Optimise σ_t/100 (the paper's parameterisation) instead of ln σ_t.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub scaled_sigma_t: bool,
    /// (The default; accepted for older scripts.)
    #[arg(long, hide = true, conflicts_with = "scaled_sigma_t")]
    pub log_sigma_t: bool,
    /// Albedo first: keep σ_t at its initial value for this many initial iterations (at most a
    /// third of the run) while α converges.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().albedo_warmup)]
    pub albedo_warmup: u32,
    /// One σ_t and one α for all channels.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub monochrome: bool,
    /// Keep σ_t at its initial value.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub fix_sigma_t: bool,
    /// Keep α at its initial value.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub fix_albedo: bool,
    /// Refit the polynomial features every K iterations (0: once, at the initial parameters).
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = 0)]
    pub refit_every: u32,
    /// Also fit the polynomial's σ_n-derivative at every fit, so that the descriptor at another
    /// σ_n (in the value and in the σ_t offsets) follows a refit, not only the rescaling. Three
    /// fits instead of one; use with --refit-every.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long)]
    pub fit_derivative: bool,
    /// Relative offset Δ/σ_t of the correlated offset samples.
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().delta_rel)]
    pub delta_rel: f32,
    /// Value image of `ours`: `offset-mean` (mean of the two σ_t offset samples, O(Δ²) bias,
    /// a third less work) or `sample` (an unperturbed sample of its own).
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value = "offset-mean")]
    pub primal: Primal,
    /// Fit only these views of the dataset (indices, e.g. `0,3,5`; default: all). The
    /// re-renders and the bias correction use the same views; `--resume` keeps the run's own.
    #[arg(help_heading = crate::common::CHECK_OPTIONS, long, value_delimiter = ',', value_name = "I,J,…")]
    pub view_subset: Option<Vec<usize>>,
    /// Checkpoint every N iterations.
    #[arg(help_heading = crate::common::CHECK_OPTIONS, long, default_value_t = 10)]
    pub checkpoint_every: u32,
    /// Samples per pixel of the final re-renders.
    #[arg(help_heading = crate::common::CHECK_OPTIONS, long, default_value_t = 64)]
    pub final_spp: u32,
    /// Views for the 95 % intervals at the end (two derivative renders each, spread evenly
    /// over the dataset; 0: no intervals).
    #[arg(help_heading = crate::common::CHECK_OPTIONS, long, default_value_t = inverse::uncertainty::UncertaintySettings::default().views)]
    pub uncertainty_views: usize,
    /// Samples per pixel of the interval renders.
    #[arg(help_heading = crate::common::CHECK_OPTIONS, long, default_value_t = inverse::uncertainty::UncertaintySettings::default().spp)]
    pub uncertainty_spp: u32,
    /// Views re-rendered at the estimate by the volumetric path tracer (twice, at the dataset's
    /// samples per pixel) to check that the estimate reproduces the images without the learned
    /// model (0: no check).
    #[arg(help_heading = crate::common::CHECK_OPTIONS, long, default_value_t = 4)]
    pub consistency_views: usize,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Several initialisations first: N shorter runs (a third of --iterations each) from σ_t
    /// between a third and three times --init-sigma-t; the one with the lowest loss starts the
    /// run. For images that may leave σ_t open; costs N/3 more runs. Listed in
    /// OUT/starts/starts.json and result.json.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub starts: u32,
    /// Continue the run in --out from its checkpoint (--iterations may extend it).
    #[arg(long)]
    pub resume: bool,
    /// Replace an existing run in --out.
    #[arg(long)]
    pub overwrite: bool,
    #[command(flatten)]
    pub bc: BiasCorrectionArgs,
    #[command(flatten)]
    pub learned: LearnedArgs,
}

/// The work of an optimisation run (shared by `optimize` and `experiment`).
#[derive(Args, Clone, Copy, Debug)]
pub struct IterationArgs {
    /// Iterations (per run).
    #[arg(long, default_value_t = OptimizeConfig::default().iterations)]
    pub iterations: u32,
    /// Samples per pixel per iteration.
    #[arg(long, default_value_t = OptimizeConfig::default().spp)]
    pub spp: u32,
    /// Views rendered per iteration (drawn at random).
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, default_value_t = OptimizeConfig::default().views_per_iter)]
    pub views_per_iter: usize,
    /// Render a random N×N crop of each chosen view per iteration instead of the whole image
    /// (the paper's released optimiser; clamped to the image size).
    #[arg(help_heading = crate::common::RESEARCH_OPTIONS, long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub crop: Option<u32>,
}

impl OptimizeArgs {
    /// The command's defaults for `--dataset dataset --out out`.
    pub fn with_defaults(dataset: PathBuf, out: PathBuf) -> Self {
        Self {
            dataset,
            out,
            ..crate::common::arg_defaults(&["--dataset", "d"])
        }
    }
}

impl OptimizeArgs {
    /// The estimator's name: `--estimator`, or the model's default.
    pub fn estimator(&self) -> String {
        self.method
            .unwrap_or(self.learned.kind().estimators()[0])
            .name()
            .to_string()
    }
}

pub(crate) fn config_of(a: &OptimizeArgs) -> Result<OptimizeConfig> {
    config_for(a, || Ok(Dataset::load(&a.dataset)?.render.max_depth))
}

/// [`config_of`] with the dataset's own tracer depth from `dataset_depth`, asked only when the
/// tracer is used and `--max-depth` is not given.
fn config_for(
    a: &OptimizeArgs,
    dataset_depth: impl FnOnce() -> Result<Option<u32>>,
) -> Result<OptimizeConfig> {
    let model = a.learned.kind();
    let method = a.method.unwrap_or(model.estimators()[0]);
    let mut c = OptimizeConfig::new(Params {
        sigma_t: a.init_sigma_t.map(|v| v as f64),
        albedo: a.init_albedo.map(|v| v as f64),
    });
    c.model = model;
    c.method = method;
    c.iterations = a.budget.iterations;
    c.refine_iterations = match a.refine {
        Some(r) if r > 0 && a.bc.bias_correction => bail!(
            "--bias-correction with --refine {r}: the correction is for the learned model alone; \
             fix: drop one of the two (the refinement replaces the correction)"
        ),
        Some(r) => r,
        // `--bias-correction` asks for the learned model alone with the correction.
        None if a.bc.bias_correction => 0,
        None => OptimizeConfig::default_refinement(model, a.budget.iterations),
    };
    if model == ModelKind::Volpath || c.refine_iterations > 0 {
        c.volpath_max_depth = match a.max_depth {
            Some(d) => Some(d),
            None => dataset_depth()?,
        };
    }
    c.spp = a.budget.spp;
    c.views_per_iter = a.budget.views_per_iter;
    c.view_subset = a.view_subset.clone();
    c.loss = a.loss;
    c.two_renders = !a.single_render;
    c.split_samples = !a.full_renders;
    anyhow::ensure!(
        a.view_weight_floor > 0.0 && a.view_weight_floor <= 1.0,
        "--view-weight-floor must be in (0, 1], got {}",
        a.view_weight_floor
    );
    c.normalize_views = a.normalize_views;
    c.view_weight_floor = a.view_weight_floor;
    c.crop = a.budget.crop;
    c.lr_sigma_t = a.lr_sigma_t;
    c.lr_albedo = a.lr_albedo;
    c.decay = a.decay;
    c.decay_every = a.decay_every;
    c.refit_every = a.refit_every;
    c.fit_derivative = a.fit_derivative;
    c.delta_rel = a.delta_rel;
    c.primal = a.primal;
    c.learned = a.learned.settings();
    c.seed = a.seed;
    c.albedo_warmup = a.albedo_warmup;
    c.params = ParamSpec {
        parameterisation: if a.scaled_sigma_t {
            Parameterisation::Scaled
        } else {
            Parameterisation::Log
        },
        monochrome: a.monochrome,
        fix_sigma_t: a.fix_sigma_t,
        fix_albedo: a.fix_albedo,
    };
    Ok(c)
}

/// A resumed run continues with the settings it started with: every setting given now must
/// equal the checkpoint's ([`reuse::differing_settings`]), except the number of iterations (a
/// run may be extended) and the view subset (a resumed run may leave it out). The error names
/// each differing setting with both values.
/// The (iterations, refinement) a resumed run goes on with: `--iterations`, and `--refine` when
/// given; without it, a run already in its refinement keeps refining from where it began (a
/// longer run refines longer), and one that has not reached it takes the default of its new
/// length, begun no earlier than the iterations done.
fn resume_budget(a: &OptimizeArgs, c: &Checkpoint) -> Result<(u32, u32)> {
    let n = a.budget.iterations;
    let saved = &c.config;
    let done = c.history.len() as u32;
    let start = saved.iterations - saved.refine_iterations;
    let refining = saved.refine_iterations > 0 && done > start;
    let r = match a.refine {
        None if refining => n.saturating_sub(start),
        None => config_of(a)?.refine_iterations.min(n.saturating_sub(done)),
        Some(_) => config_of(a)?.refine_iterations,
    };
    Ok((n, r))
}

fn check_resume_settings(now: &OptimizeConfig, saved: &OptimizeConfig, ckpt: &Path) -> Result<()> {
    // The length and its refinement may change together (`Optimizer::resume` checks them).
    let json = |c: &OptimizeConfig| {
        let mut c = c.clone();
        c.view_subset = None;
        c.refine_iterations = 0;
        serde_json::to_value(&c)
    };
    let diffs: Vec<String> = reuse::differing_settings(&json(now)?, &json(saved)?)
        .into_iter()
        .map(|d| {
            format!(
                "{}: the run has {}, this command gives {}",
                d.key, d.recorded, d.expected
            )
        })
        .collect();
    if !diffs.is_empty() {
        bail!(
            "--resume: the settings differ from those of the run in {} ({}); repeat the run's \
             own options (only --iterations may change), or start a new run with --overwrite",
            ckpt.display(),
            diffs.join("; ")
        );
    }
    Ok(())
}

/// The views of `ds` named by `subset` (indices into the dataset), in that order: a clear error
/// for an empty list, an index past the last view or an index given twice.
pub(crate) fn select_views(ds: &mut Dataset, subset: &[usize], what: &Path) -> Result<()> {
    let n = ds.views.len();
    anyhow::ensure!(
        !subset.is_empty(),
        "--view-subset: give at least one view index"
    );
    for (k, &i) in subset.iter().enumerate() {
        anyhow::ensure!(
            i < n,
            "--view-subset: {} has {n} views (0 … {}); there is no view {i}",
            what.display(),
            n.saturating_sub(1)
        );
        anyhow::ensure!(
            !subset[..k].contains(&i),
            "--view-subset: view {i} is named twice"
        );
    }
    ds.views = subset.iter().map(|&i| ds.views[i].clone()).collect();
    Ok(())
}

pub fn run(a: &OptimizeArgs) -> Result<()> {
    if a.starts > 1 {
        Dataset::load(&a.dataset)?;
        let (starts, best) = {
            let _lock = scene::fsutil::lock_folder(&a.out)?;
            multi_start::run_starts(a)?
        };
        let mut b = a.clone();
        b.starts = 1;
        b.init_sigma_t = starts[best].estimate.sigma_t.map(|v| v as f32);
        b.init_albedo = starts[best].estimate.albedo.map(|v| v as f32);
        run(&b)?;
        // The starts go into the run's record.
        let mut result = reuse::read_json(&a.out.join("result.json"))?;
        result["starts"] = serde_json::json!({ "starts": starts, "chosen": best });
        return write_result(&a.out, &result);
    }
    let mut ds = Dataset::load(&a.dataset)?;
    // One run per output folder; released when this function returns (or the process dies).
    let _lock = scene::fsutil::lock_folder(&a.out)?;
    let ckpt = a.out.join("checkpoint.json");
    let checkpoint = if a.resume {
        let c = Checkpoint::read(&ckpt)?;
        check_resume_settings(&config_of(a)?, &c.config, &ckpt)?;
        Some(c)
    } else {
        None
    };
    // A resumed run fits the views it started with.
    let subset = match &checkpoint {
        Some(c) => {
            if a.view_subset.is_some() && a.view_subset != c.config.view_subset {
                bail!(
                    "--view-subset {:?} differs from the views of the run in {} ({:?}); resume \
                     without --view-subset or start a new run",
                    a.view_subset.as_deref().unwrap_or_default(),
                    a.out.display(),
                    c.config
                        .view_subset
                        .as_deref()
                        .map_or("all".into(), |v| format!("{v:?}"))
                );
            }
            c.config.view_subset.clone()
        }
        None => a.view_subset.clone(),
    };
    if let Some(s) = &subset {
        select_views(&mut ds, s, &a.dataset)?;
    }
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &a.dataset.display().to_string());
    // Every iteration's light term asks for them; decide them once, in parallel, before the
    // first iteration rather than lazily in the first iterations.
    let t0 = std::time::Instant::now();
    let supporting = accel.decide_all_supporting();
    tracing::debug!(
        "supporting planes: {supporting} of {} triangles in {:.0} ms",
        accel.mesh().triangle_count(),
        t0.elapsed().as_secs_f64() * 1e3
    );
    // The volumetric and dipole models have no networks; the optimiser's interface still
    // takes the learned model's, unused.
    let model = match a.learned.kind() {
        ModelKind::Dipole => crate::common::LearnedArgs::shipped_model()?,
        ModelKind::Volpath => {
            let depth = a.max_depth.unwrap_or(32);
            if let Some(d) = ds
                .render
                .max_depth
                .filter(|d| a.max_depth.is_some() && *d != depth)
            {
                tracing::warn!(
                    "the dataset was rendered with maximum depth {d}, the model traces to \
                     --max-depth {depth}"
                );
            }
            crate::common::LearnedArgs::shipped_model()?
        }
        ModelKind::Learned => a.learned.load_model()?,
    };
    let targets = TargetView::of_dataset(&ds, &a.dataset.display().to_string())?;
    let images: Vec<&Image> = targets.iter().map(|t| t.image).collect();
    let base = ds.truth.unwrap_or(Medium {
        sigma_t: [50.0; 3],
        albedo: [0.5; 3],
        g: 0.0,
        eta: 1.0,
    });
    let truth = ds.truth.as_ref().map(Params::of);
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut opt = if let Some(c) = checkpoint {
        let budget = resume_budget(a, &c)?;
        Optimizer::resume(c, Some(budget), &accel, &model, base, targets)?
    } else {
        if ckpt.exists() && !a.overwrite {
            bail!(
                "{} already holds an optimisation run; pass --resume to continue it or \
                 --overwrite to start again",
                a.out.display()
            );
        }
        // The bootstrap folders belong to the run being replaced.
        let boot = a.out.join("bootstrap");
        if a.overwrite && boot.is_dir() {
            std::fs::remove_dir_all(&boot)
                .with_context(|| format!("cannot remove {}", boot.display()))?;
        }
        Optimizer::new(config_of(a)?, &accel, &model, base, targets)?
    };
    let t0 = Instant::now();
    let pb = progress(opt.config().iterations as u64, "optimize");
    pb.set_position(opt.iteration() as u64);
    let csv = a.out.join("iterations.csv");
    let ran = opt.run(Some((&ckpt, a.checkpoint_every)), |r, p| {
        pb.set_position(r.iteration as u64 + 1);
        pb.set_message(format!(
            "loss {:.3e} σ_t ({:.1}, {:.1}, {:.1}) α ({:.3}, {:.3}, {:.3})",
            r.loss, p.sigma_t[0], p.sigma_t[1], p.sigma_t[2], p.albedo[0], p.albedo[1], p.albedo[2]
        ));
    });
    pb.finish_and_clear();
    if let Err(e) = ran {
        if !matches!(e, inverse::optimize::InverseError::NonFinite { .. }) {
            // A failed write (disk full, permissions) or render: the outputs on disk stay as
            // they were (the last checkpoint included, written atomically); say what failed.
            return Err(e).context(format!(
                "the optimisation stopped in iteration {}; {} holds the last checkpoint written \
                 before (resume from it with --resume)",
                opt.history().len(),
                ckpt.display()
            ));
        }
        // A run that broke down numerically still leaves its record: the history so far and a
        // failed status (the last good checkpoint stays as it was).
        report::write_csv(opt.history(), &csv)?;
        let failed = serde_json::json!({
            "status": "failed",
            "problems": [inverse::health::Problem::NonFinite { detail: e.to_string() }],
            "iterations": opt.history().len(),
            "config": opt.config(),
        });
        write_result(&a.out, &failed)?;
        return Err(e).context(format!(
            "the optimisation failed after {} iterations (status in {})",
            opt.history().len(),
            a.out.join("result.json").display()
        ));
    }
    let seconds_total = t0.elapsed().as_secs_f64();
    report::write_csv(opt.history(), &csv)?;
    let estimate = opt.params();
    let uncertainty = if a.uncertainty_views > 0 {
        let settings = inverse::uncertainty::UncertaintySettings {
            views: a.uncertainty_views,
            spp: a.uncertainty_spp,
            ..Default::default()
        };
        let pb = progress(0, "95 % intervals");
        let u = opt.uncertainty(&settings)?;
        pb.finish_and_clear();
        Some(u)
    } else {
        None
    };
    let mut result = report::result_json(
        opt.config(),
        opt.history(),
        &estimate,
        truth.as_ref(),
        seconds_total,
    );
    report::add_assessment(&mut result, &[], uncertainty.as_ref());
    // Not final until the correction and the checks below are in: an interrupted command is
    // resumed rather than reused (`run_or_reuse`).
    result["complete"] = serde_json::json!(false);
    write_result(&a.out, &result)?;
    report::write_plots(
        opt.history(),
        &estimate,
        truth.as_ref(),
        uncertainty.as_ref(),
        &a.out.join("convergence.png"),
    )?;
    rerender(a, &opt, &ds, &estimate)?;
    let spi = result["seconds_per_iteration"].as_f64().unwrap_or(f64::NAN);
    print_summary(&estimate, truth.as_ref(), opt.history().len(), spi);
    let (mut shown, mut shown_u) = (estimate, uncertainty.clone());
    // The volumetric model is the simulator the correction would use: it has no bias of its own
    // to measure, and a correction would only add a second recovery's noise. The same holds
    // after a volumetric refinement.
    if a.bc.enabled() && opt.config().final_model() == ModelKind::Learned {
        // The model's own fit stays in convergence.png and final/; result.json reports the
        // corrected medium.
        let c = bias_correction::correct(a, &ds, &estimate, &base)?;
        result =
            bias_correction::corrected_result(result, &c, truth.as_ref(), uncertainty.as_ref());
        if let Some(last) = c.steps.last() {
            println!(
                "bias-corrected ({} step{}, simulations at {} spp):",
                c.steps.len(),
                if c.steps.len() == 1 { "" } else { "s" },
                c.spp
            );
            print_estimate(&last.corrected, truth.as_ref());
            shown = last.corrected;
            shown_u = uncertainty.as_ref().map(|u| u.corrected(&estimate, &shown));
        }
    }
    // The reported medium, rendered by the volumetric path tracer, against the targets; and
    // the tracer's own sensitivity along the σ_t valley on the same views.
    let n = ds.views.len();
    let k = a.consistency_views.min(n);
    let check_views: Vec<(usize, inverse::consistency::CheckView)> = (0..k)
        .map(|i| i * n / k)
        .map(|v| {
            let view = inverse::consistency::CheckView {
                camera: &ds.views[v].camera,
                light: &ds.views[v].light,
                target: images[v],
                index: opt.config().view_subset.as_ref().map_or(v, |s| s[v]),
            };
            (v, view)
        })
        .collect();
    let check_spp = ds.render.spp.unwrap_or(64);
    // The tracer renders the checks at the targets' own path depth.
    let check_depth = ds.render.max_depth.unwrap_or(32);
    let consistency = (k > 0).then(|| {
        let views: Vec<_> = check_views.iter().map(|(_, v)| *v).collect();
        let pb = progress(0, "consistency (volumetric path tracer)");
        let c = inverse::consistency::check(
            &accel,
            &shown.medium(&base),
            &views,
            check_spp,
            check_depth,
            a.seed ^ 0xC0_5157,
        );
        pb.finish_and_clear();
        c
    });
    // The tracer's own curvature against the learned model's: nothing to check when the
    // tracer is the model.
    let learned_model = opt.config().final_model() == ModelKind::Learned;
    let sensitivity = uncertainty
        .as_ref()
        .filter(|_| learned_model)
        .and_then(|u| {
            // The checked views whose learned bread the intervals measured.
            let (views, breads): (Vec<_>, Vec<_>) = check_views
                .iter()
                .filter_map(|(v, view)| {
                    let bread = u.view_bread.iter().find(|(i, _)| i == v)?.1;
                    Some((*view, bread))
                })
                .unzip();
            if views.is_empty() {
                return None;
            }
            let pb = progress(
                0,
                "sensitivity along the σ_t valley (volumetric path tracer)",
            );
            let s = inverse::sensitivity::measure(
                &accel,
                &shown.medium(&base),
                &views,
                &breads,
                inverse::sensitivity::valley_slope(&u.bread()),
                check_spp,
                check_depth,
                a.seed ^ 0x5E_4517,
            );
            pb.finish_and_clear();
            Some(s)
        });
    if let (Some(u), Some(s)) = (&shown_u, &sensitivity) {
        let widened = u.with_sensitivity(&shown, s);
        if let serde_json::Value::Object(m) = widened.to_json() {
            result
                .as_object_mut()
                .expect("result.json is an object")
                .extend(m);
        }
        result["sensitivity"] = serde_json::to_value(s)?;
        shown_u = Some(widened);
    }
    let mut problems = inverse::health::assess(
        opt.history(),
        &shown,
        &opt.config().params,
        base.g as f64,
        consistency.as_ref(),
    );
    if !learned_model {
        // The training range is the learned model's; the tracer has none.
        problems.retain(|p| !matches!(p, inverse::health::Problem::OutsideTrainingRange { .. }));
    }
    report::add_assessment(&mut result, &problems, None);
    if let Some(c) = &consistency {
        result["consistency"] = serde_json::to_value(c)?;
    }
    result["complete"] = serde_json::json!(true);
    write_result(&a.out, &result)?;
    if let Some(u) = &shown_u {
        for line in report::interval_lines(&shown, u) {
            println!("  {line}");
        }
    }
    if let Some(s) = &sensitivity {
        let rel = |c: usize| {
            format!(
                "{:.2} ± {:.2}",
                s.volpath[c] / s.learned[c],
                (2.0 * s.volpath_se[c] / s.learned[c]).abs()
            )
        };
        println!(
            "  sensitivity to σ_t along the σ_t–α valley (volumetric path tracer, {} views): the \
             images curve ({}, {}, {})× as much as the learned model says (± two standard \
             errors); the intervals widen by up to √ρ = ({:.2}, {:.2}, {:.2}) from the lower \
             end, to at most a factor 10 either way",
            s.views.len(),
            rel(0),
            rel(1),
            rel(2),
            s.ratio[0].sqrt(),
            s.ratio[1].sqrt(),
            s.ratio[2].sqrt()
        );
    }
    if let Some(c) = &consistency {
        println!(
            "  consistency (the estimate rendered by the volumetric path tracer, {} views): \
             brightness ratio ({:.3}, {:.3}, {:.3}), L2 ({:.2}, {:.2}, {:.2})× the noise floor \
             (the targets' own pixel variance {:.1}, {:.1}, {:.1}× our renders')",
            c.views.len(),
            c.mean_ratio[0],
            c.mean_ratio[1],
            c.mean_ratio[2],
            c.l2_over_noise[0],
            c.l2_over_noise[1],
            c.l2_over_noise[2],
            c.target_noise_ratio[0],
            c.target_noise_ratio[1],
            c.target_noise_ratio[2]
        );
    }
    if problems.is_empty() {
        println!("  status: ok");
    }
    for p in &problems {
        println!("  FAILED: {}", p.message());
    }
    println!(
        "wrote {} (result.json, convergence.png/.svg, final/contact-sheet.png: every target \
         beside its re-render and difference)",
        a.out.display()
    );
    Ok(())
}

/// `OUT/result.json`, replaced atomically.
fn write_result(out: &Path, result: &serde_json::Value) -> Result<()> {
    scene::fsutil::atomic_write(
        &out.join("result.json"),
        serde_json::to_string_pretty(result)?.as_bytes(),
        true,
    )?;
    Ok(())
}

fn print_summary(est: &Params, truth: Option<&Params>, iters: usize, spi: f64) {
    println!("after {iters} iterations ({spi:.2} s/iteration):");
    print_estimate(est, truth);
}

/// The estimate, and the truth and the errors when known.
fn print_estimate(est: &Params, truth: Option<&Params>) {
    let f3 = |v: [f64; 3], p: usize| format!("({:.p$}, {:.p$}, {:.p$})", v[0], v[1], v[2], p = p);
    println!(
        "  estimate  σ_t = {}  α = {}",
        f3(est.sigma_t, 2),
        f3(est.albedo, 4)
    );
    if let Some(t) = truth {
        println!(
            "  truth     σ_t = {}  α = {}",
            f3(t.sigma_t, 2),
            f3(t.albedo, 4)
        );
        let rel: [f64; 3] = std::array::from_fn(|c| 100.0 * (est.sigma_t[c] / t.sigma_t[c] - 1.0));
        let abs: [f64; 3] = std::array::from_fn(|c| est.albedo[c] - t.albedo[c]);
        println!("  error     σ_t {} %  α {}", f3(rel, 1), f3(abs, 4));
    }
}

/// Views re-rendered at the end of a run, at most: evenly spread over larger datasets.
const RERENDER_VIEWS: usize = 48;

/// Re-renders the views at the estimate next to their targets, with error images, and the
/// contact sheet of them all (`final/contact-sheet.png`).
fn rerender(a: &OptimizeArgs, opt: &Optimizer, ds: &Dataset, est: &Params) -> Result<()> {
    let dir = a.out.join("final");
    std::fs::create_dir_all(&dir)?;
    let n = ds.views.len();
    let k = n.min(RERENDER_VIEWS);
    let chosen: Vec<usize> = (0..k).map(|i| i * n / k).collect();
    let pb = progress(k as u64, "re-renders");
    let mut imgs = Vec::new();
    for &i in &chosen {
        let v = &ds.views[i];
        let rs = RenderSettings {
            spp: a.final_spp,
            seed: a.seed ^ 0xF1AA_1000,
            view: i as u64,
        };
        imgs.push(opt.render(est, &v.camera, &v.light, &rs)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let targets: Vec<&Image> = chosen
        .iter()
        .filter_map(|&i| ds.views[i].image.as_ref())
        .collect();
    let exposure = scene::image::auto_exposure(
        &targets
            .iter()
            .take(8)
            .map(|&t| t.clone())
            .collect::<Vec<_>>(),
    );
    for ((img, t), &i) in imgs.iter().zip(&targets).zip(&chosen) {
        // Named by the view's index in the dataset (the same as i without --view-subset).
        let index = opt.config().view_subset.as_ref().map_or(i, |s| s[i]);
        write_view(&dir, &format!("view_{index:03}"), img, t, exposure)?;
    }
    // The first four views at a glance: targets above, re-renders below.
    let m = imgs.len().min(targets.len()).min(4);
    let overview = Image::grid(&[targets[..m].to_vec(), imgs[..m].iter().collect()], 2);
    overview.write_png(&dir.join("overview.png"), exposure, true)?;
    let renders: Vec<&Image> = imgs.iter().collect();
    report::contact_sheet(&targets, &renders, exposure)?.write_png(
        &dir.join("contact-sheet.png"),
        1.0,
        true,
    )?;
    Ok(())
}

fn write_view(dir: &Path, name: &str, img: &Image, target: &Image, exposure: f32) -> Result<()> {
    img.write_exr(&dir.join(format!("{name}.exr")), true)?;
    img.write_png(&dir.join(format!("{name}.png")), exposure, true)?;
    target.write_png(&dir.join(format!("{name}_target.png")), exposure, true)?;
    Image::false_colour_diff(img, target)?.write_png(
        &dir.join(format!("{name}_diff.png")),
        1.0,
        true,
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `optimize --dataset D` runs the library's defaults ([`OptimizeConfig::default`]), and so
    /// do `demo` and `experiment accuracy`: every number they publish comes from the settings a
    /// user gets.
    #[test]
    fn optimize_demo_and_experiment_share_the_library_defaults() {
        let d = PathBuf::from("d");
        let o = OptimizeArgs::with_defaults(d.clone(), PathBuf::from("o"));
        let no_depth = || Ok(None);
        assert_eq!(config_for(&o, no_depth).unwrap(), OptimizeConfig::default());
        let demo =
            crate::demo::recovery_args(&crate::common::arg_defaults::<crate::demo::DemoArgs>(&[]));
        let expected = OptimizeConfig {
            seed: demo.seed,
            ..OptimizeConfig::default().with_iterations(demo.budget.iterations)
        };
        assert_eq!(config_for(&demo, no_depth).unwrap(), expected);
        let exp = crate::common::arg_defaults::<crate::experiment::AccuracyArgs>(&[]);
        let init = Params {
            sigma_t: [50.0; 3],
            albedo: [0.5; 3],
        };
        // The estimator comparison runs the learned model alone (`--refine 0`), the rest as
        // the defaults.
        let run = crate::experiment::run_args(&exp, &d, &d, "ours", init);
        let expected = OptimizeConfig {
            seed: exp.seed,
            refine_iterations: 0,
            ..OptimizeConfig::default()
        };
        assert_eq!(config_for(&run, no_depth).unwrap(), expected);
        // The robustness suite, which measures the defaults, runs them unchanged.
        let suite =
            crate::common::arg_defaults::<crate::experiment::robustness::RobustnessArgs>(&[]);
        let run = crate::experiment::robustness::run_args(&suite, &d, &d, 0);
        let expected = OptimizeConfig {
            seed: suite.seed,
            ..OptimizeConfig::default()
        };
        assert_eq!(config_for(&run, no_depth).unwrap(), expected);
    }
}
