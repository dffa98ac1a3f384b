//! `translucent experiment volumetric` (Son et al. 2024, Fig. 8: with α fixed at 0.9 and a grey
//! medium, ours converges at 32 spp where volumetric differentiable rendering diverges even at
//! 128 spp): σ_t alone recovered from one grey dataset (a blob, 40 views of 256², one fixed
//! light, σ_t = 80, α = 0.9, targets by our volumetric path tracer at 128 spp), from σ_t = 50
//! with α fixed at its true 0.9, by the learned model (`ours`, 32 spp) and by the volumetric
//! baseline (`optimize --model volpath`, 32 and 128 spp), each with `optimize`'s defaults
//! otherwise and without refinement or bias correction. Reports the σ_t error against iterations
//! and against seconds (`OUT/volumetric.png`, `.svg`), and a table of final errors, s/it and total
//! time (`OUT/volumetric.md`, `volumetric.csv`). Runs resume and are reused like `experiment
//! accuracy`'s.

use inverse::forward::ModelKind;
use recovery::Observer;
use std::path::PathBuf;

use crate::error::Result;
use plot::{Figure, Panel, Series};
use scene::Medium;

use super::report::read_steps;

use crate::run::Run;
use inverse::params::Params;

/// The volumetric-baseline experiment's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumetricConfig {
    /// The output folder (the dataset in `OUT/data`, runs in `OUT/runs`).
    pub out: PathBuf,
    /// Iterations per run.
    pub iterations: u32,
    /// Seed of the renders and the runs.
    pub seed: u64,
    /// A smoke test in seconds (4 views of 32², 6 iterations, 2 and 8 spp, coarse meshes): not a measurement.
    pub quick: bool,
    pub jobs: super::jobs::Jobs,
}

impl Default for VolumetricConfig {
    fn default() -> Self {
        VolumetricConfig {
            out: PathBuf::from("out/experiment-volumetric"),
            iterations: 300,
            seed: 0,
            quick: false,
            jobs: super::jobs::Jobs::default(),
        }
    }
}

/// The true medium: grey, the paper's fixed α.
const TRUTH: Medium = Medium {
    sigma_t: [80.0; 3],
    albedo: [0.9; 3],
    g: scene::Anisotropy::uniform(0.0),
    eta: 1.0,
    roughness: 0.0,
};

/// One run: its name, model (`None`: learned), samples per pixel over the base count.
struct Variant {
    name: &'static str,
    model: Option<ModelKind>,
    spp_factor: u32,
}

const VARIANTS: [Variant; 3] = [
    Variant {
        name: "ours",
        model: None,
        spp_factor: 1,
    },
    Variant {
        name: "volumetric",
        model: Some(ModelKind::Volpath),
        spp_factor: 1,
    },
    Variant {
        name: "volumetric",
        model: Some(ModelKind::Volpath),
        spp_factor: 4,
    },
];

pub fn run(a: &VolumetricConfig, obs: &dyn Observer) -> Result<()> {
    let (targets, iterations, spp) = super::workload(a.quick, a.iterations);
    let (views, res) = (targets.views, targets.res);
    let case = |v: &Variant| format!("{}-{}spp", v.name, spp * v.spp_factor);
    let cases: Vec<String> = VARIANTS.iter().map(case).collect();
    if a.jobs.listed(&cases, obs)? {
        return Ok(());
    }
    let _lock = a.jobs.lock(&a.out)?;
    let data = a.out.join("data");
    a.jobs.shared_input(&a.out, "data", || {
        super::blob_dataset(&data, targets, TRUTH, a.seed, obs)
    })?;
    let mut missing = Vec::new();
    let mut curves = Vec::new();
    let mut md = format!(
        "σ_t alone, α fixed at 0.9, grey medium (σ_t = 80), {views} views {res}², {iterations} \
         iterations from σ_t = 50{}\n\n| run | final σ_t | error % | s/it | seconds |\n|---|---|---|---|---|\n",
        if a.quick {
            " — QUICK: a smoke test, not a measurement"
        } else {
            ""
        }
    );
    let mut csv = String::from("model,spp,sigma_t,error,seconds_per_iteration,seconds\n");
    for v in &VARIANTS {
        let label = format!("{}, {} spp", v.name, spp * v.spp_factor);
        let dir = a.out.join("runs").join(case(v));
        let mut o = Run::defaults(&data, &dir);
        let s = &mut o.settings;
        s.model.kind = v.model.unwrap_or_default();
        (s.schedule.iterations, s.schedule.spp) = (iterations, spp * v.spp_factor);
        s.start.sigma_t_from_units = false;
        s.start.init = Params {
            sigma_t: [50.0; 3],
            albedo: TRUTH.albedo.map(f64::from),
            g: None,
            light_scale: None,
        };
        s.schedule.params.fix_albedo = true;
        s.schedule.params.monochrome = true;
        s.schedule.seed = a.seed;
        s.checks.final_spp = 16;
        s.bias_correction.correction.enabled = false;
        // The paper's method is the learned model alone: no volumetric refinement.
        s.tracer.refine = Some(0);
        let done = if a.jobs.runs(&case(v)) {
            o.run_or_reuse(obs, &label)?
        } else if let Some(done) = o.finished()? {
            done
        } else {
            missing.push(case(v));
            continue;
        };
        let t: Vec<(f64, f64, f64)> = read_steps(&dir.join("iterations.csv"))?
            .iter()
            .map(|p| (p.iteration, p.seconds, p.sigma_t[0]))
            .collect();
        let est = done.estimate.sigma_t[0];
        let err = 100.0 * (est / TRUTH.sigma_t[0] as f64 - 1.0);
        let total = t.last().map_or(0.0, |p| p.1);
        md.push_str(&format!(
            "| {label} | {est:.2} | {err:+.1} | {:.3} | {total:.0} |\n",
            done.seconds_per_iteration
        ));
        csv.push_str(&format!(
            "{},{},{est},{},{},{total}\n",
            v.name,
            spp * v.spp_factor,
            err / 100.0,
            done.seconds_per_iteration
        ));
        curves.push((label, t));
    }
    a.jobs.report_missing(&missing, obs);
    let err = |s: f64| 100.0 * (s / TRUTH.sigma_t[0] as f64 - 1.0).abs();
    let panel = |title: &str, x_label: &str, by_time: bool| Panel {
        title: title.into(),
        x_label: x_label.into(),
        y_label: "|σ_t error|, %".into(),
        log_y: true,
        series: curves
            .iter()
            .map(|(label, t)| {
                Series::new(
                    label.clone(),
                    t.iter()
                        .map(|&(it, secs, s)| (if by_time { secs } else { it }, err(s)))
                        .collect(),
                )
            })
            .collect(),
        reference_lines: Vec::new(),
        bands: Vec::new(),
    };
    let fig = Figure::new(
        vec![
            panel("σ_t error at equal iterations", "iteration", false),
            panel("σ_t error at equal time", "seconds", true),
        ],
        2,
    );
    fig.write_png(&a.out.join("volumetric.png"), true)?;
    fig.write_svg(&a.out.join("volumetric.svg"), true)?;
    super::write_tables(
        &a.out,
        "volumetric",
        &md,
        &csv,
        ", volumetric.png/.svg",
        obs,
    )
}
