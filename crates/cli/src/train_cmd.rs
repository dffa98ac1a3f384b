//! `translucent train …`: make training data with our random walks and train the learned BSSRDF
//! (docs/model.md §5–§6).
//!
//! * `train data --out DIR`: `DIR/train.tlsamples` and `DIR/val.tlsamples` (validation from other
//!   meshes than training).
//! * `train fit --data DIR --out DIR`: trains, writes `checkpoint.bin` (atomic, every N steps),
//!   `model.safetensors`, `history.csv`, `loss.png` and `train.json`; `--resume` continues a run
//!   bit-identically.
//! * `train all --out DIR`: data, the CVAE (`DIR/cvae/`), then the energy-score fine-tuning of
//!   the decoder ([`learn::energy`]) into `DIR/model/`: the recipe of the shipped model.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use learn::datagen::{DataConfig, generate};
use learn::samplefile::{SampleFileHeader, write_samples};
use learn::train::{Objective, TrainConfig};

use cmdline::{arg_defaults, progress};

#[derive(Subcommand)]
pub enum TrainCommand {
    /// Generate training data: random walks inside the polynomial fitted at random entry points
    /// of random procedural shapes (and given meshes), with random media (docs/model.md §5).
    Data(DataArgs),
    /// Train the conditional VAE and the absorption network on generated data (docs/model.md §6).
    Fit(FitArgs),
    /// Generate data and train with the recipe of the shipped model (`models/`): the CVAE with
    /// the defaults of `train fit`, then the energy-score fine-tuning of its decoder.
    All(AllArgs),
}

#[derive(Args, Clone)]
#[command(mut_arg(
    "out",
    cmdline::groups::help("Output folder (train.tlsamples, val.tlsamples)")
))]
#[command(mut_arg("overwrite", cmdline::groups::help("Replace existing files")))]
pub struct DataArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Random training meshes.
    #[arg(long, default_value_t = 160)]
    pub meshes: usize,
    /// Random validation meshes (disjoint from the training meshes).
    #[arg(long, default_value_t = 16)]
    pub val_meshes: usize,
    /// Incident configurations per mesh (each with its own medium and entry point).
    #[arg(long, default_value_t = 1250)]
    pub configs_per_mesh: usize,
    /// Exit samples kept per configuration.
    #[arg(long, default_value_t = 16)]
    pub samples_per_config: usize,
    /// Random walks per configuration for its absorption probability.
    #[arg(long, default_value_t = 1024)]
    pub path_attempts: usize,
    /// Also draw base shapes from these meshes (OBJ/PLY), besides the procedural families.
    #[arg(long = "mesh")]
    pub meshes_in: Vec<PathBuf>,
    /// Fit without VKJ19's c_19 = 0 quirk (docs/model.md §3.2; the renderer follows the model).
    #[arg(long)]
    pub no_c19_quirk: bool,
    /// Uniform mesh scale after normalisation to extent 1 (docs/model.md §5: 20). Smaller values
    /// give more strongly curved surfaces in units of the kernel σ_n.
    #[arg(long, default_value_t = 20.0)]
    pub mesh_scale: f32,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

#[derive(Args, Clone)]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed (initialisation, batch order, VAE noise)")
))]
#[command(mut_arg(
    "overwrite",
    cmdline::groups::help("Replace the outputs of an existing run in --out (without --resume)")
))]
pub struct FitArgs {
    /// Folder written by `train data`.
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Optimisation steps.
    #[arg(long, default_value_t = 400_000)]
    pub steps: u64,
    /// Samples per step.
    #[arg(long, default_value_t = 256)]
    pub batch: usize,
    /// Initial learning rate (Adam).
    #[arg(long, default_value_t = 1e-3)]
    pub lr: f32,
    /// Learning-rate decay factor (staircase).
    #[arg(long, default_value_t = 0.5)]
    pub lr_decay: f32,
    /// Steps between decays.
    #[arg(long, default_value_t = 60_000)]
    pub lr_decay_every: u64,
    /// Floor of the learning rate as a fraction of --lr.
    #[arg(long, default_value_t = 0.05)]
    pub lr_floor: f32,
    /// Global-norm gradient clipping threshold.
    #[arg(long, default_value_t = 100.0)]
    pub clip: f32,
    /// Weight of the mean squared position error in the loss (docs/model.md §6: 100). Read as a
    /// Gaussian decoder, weight w means an output noise of σ² = 3/(2w) per dimension (units of
    /// σ_n²), the finest detail of the exit distribution the VAE is asked to resolve.
    #[arg(long, default_value_t = 100.0)]
    pub position_weight: f32,
    /// Network widths: `son24` (Son et al.'s light model), `vkj19` (VKJ19's), or
    /// `F=32,32;A=16;D=32,32;E=32,32` (feature, absorption hidden, decoder hidden, encoder hidden).
    #[arg(long, default_value = "son24")]
    pub widths: String,
    /// Validation every N steps.
    #[arg(long, default_value_t = 2000)]
    pub eval_every: u64,
    /// Checkpoint every N steps.
    #[arg(long, default_value_t = 5000)]
    pub checkpoint_every: u64,
    /// Objective: `cvae` (docs/model.md §6) or `energy` (the energy score of the decoder's
    /// proposals against the walks' exits, plus the absorption term: fits the exit distribution
    /// directly; `learn::energy`). `energy` is meant as a fine-tuning stage after `cvae`
    /// (`--init`).
    #[arg(long, value_enum, default_value_t)]
    pub objective: learn::train::ObjectiveKind,
    /// Latent draws per training row of the energy objective.
    #[arg(long, default_value_t = 8)]
    pub draws: usize,
    /// Weight of the energy score (units of σ_n) against the absorption term (weight 5000).
    #[arg(long, default_value_t = 100.0)]
    pub energy_weight: f32,
    /// Start from this model (a file written by `train fit`) instead of a fresh
    /// initialisation: its widths and input normalisation are kept (fine-tuning).
    #[arg(long)]
    pub init: Option<PathBuf>,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Continue the run in --out from its checkpoint (--steps may extend it).
    #[arg(long)]
    pub resume: bool,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

#[derive(Args, Clone)]
#[command(mut_arg(
    "out",
    cmdline::groups::help("Output folder (data/ and model/ inside)")
))]
pub struct AllArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

pub fn run(cmd: &TrainCommand) -> Result<()> {
    match cmd {
        TrainCommand::Data(a) => run_data(a),
        TrainCommand::Fit(a) => run_fit(a),
        TrainCommand::All(a) => {
            let data: DataArgs = arg_defaults(&["--out", "o"]);
            run_data(&DataArgs {
                out: a.out.join("data").into(),
                seed: a.seed,
                overwrite: a.overwrite,
                ..data
            })?;
            let fit: FitArgs = arg_defaults(&["--data", "d", "--out", "o"]);
            let cvae = FitArgs {
                data: a.out.join("data"),
                out: a.out.join("cvae").into(),
                seed: a.seed,
                overwrite: a.overwrite,
                ..fit
            };
            run_fit(&cvae)?;
            run_fit(&energy_stage(&cvae, a.out.join("model")))
        }
    }
}

/// The fine-tuning stage of the shipped recipe: the energy objective from the CVAE's model in
/// `cvae.out`, on the same data and seed (settings measured in docs/notes/decoder-training.md,
/// "The energy score: the decoder fitted as a distribution").
pub fn energy_stage(cvae: &FitArgs, out: PathBuf) -> FitArgs {
    FitArgs {
        out: out.into(),
        init: Some(cvae.out.join("model.safetensors")),
        objective: learn::train::ObjectiveKind::Energy,
        draws: ENERGY_DRAWS,
        energy_weight: ENERGY_WEIGHT,
        steps: ENERGY_STEPS,
        lr: ENERGY_LR,
        lr_decay: 0.5,
        lr_decay_every: ENERGY_STEPS / 5,
        lr_floor: 0.1,
        ..cvae.clone()
    }
}

/// Latent draws per row of the shipped fine-tuning.
pub const ENERGY_DRAWS: usize = 8;
/// Weight of the energy score against the absorption term (5000) in the shipped fine-tuning.
pub const ENERGY_WEIGHT: f32 = 100.0;
/// Steps of the shipped fine-tuning.
pub const ENERGY_STEPS: u64 = 300_000;
/// Initial learning rate of the shipped fine-tuning (halved every fifth of the steps, floored
/// at a tenth).
pub const ENERGY_LR: f32 = 2e-4;

fn run_data(a: &DataArgs) -> Result<()> {
    anyhow::ensure!(a.meshes > 0, "--meshes must be at least 1");
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let mut base_meshes = Vec::new();
    let mut base_mesh_names = Vec::new();
    for p in &a.meshes_in {
        let (mesh, warnings) = geometry::io::load_mesh(p)?;
        for w in warnings {
            tracing::warn!("{}: {w}", p.display());
        }
        base_meshes.push(mesh);
        base_mesh_names.push(p.display().to_string());
    }
    let base = DataConfig {
        configs_per_mesh: a.configs_per_mesh,
        samples_per_config: a.samples_per_config,
        path_attempts: a.path_attempts,
        seed: *a.seed,
        quirk_c19: !a.no_c19_quirk,
        base_meshes,
        base_mesh_names,
        ranges: learn::datagen::ParamRanges {
            mesh_scale: a.mesh_scale,
            ..Default::default()
        },
        ..DataConfig::default()
    };
    let sets = [
        ("train", 0u64, a.meshes),
        ("val", a.meshes as u64, a.val_meshes),
    ];
    for (name, first_mesh, meshes) in sets {
        let path = a.out.join(format!("{name}.tlsamples"));
        if meshes == 0 {
            continue;
        }
        if path.exists() && !*a.overwrite {
            bail!(
                "{} exists; pass --overwrite to replace it or choose another --out",
                path.display()
            );
        }
        let cfg = DataConfig {
            meshes,
            first_mesh,
            ..base.clone()
        };
        let t0 = Instant::now();
        let pb = progress((meshes * a.configs_per_mesh) as u64, name);
        let (samples, summary) = generate(&cfg, Some(&pb))?;
        pb.finish_and_clear();
        let secs = t0.elapsed().as_secs_f64();
        let header = SampleFileHeader::new(&cfg, Some(&summary));
        write_samples(&path, &header, &samples, *a.overwrite)?;
        println!(
            "{name}: {} samples from {} meshes ({} configurations, {} skipped; {} paths, {:.1} % \
             absorbed) in {secs:.1} s ({:.0} samples/s) -> {}",
            samples.len(),
            meshes,
            summary.configs,
            summary.configs_skipped,
            summary.paths,
            100.0 * summary.absorbed as f64 / summary.paths.max(1) as f64,
            samples.len() as f64 / secs,
            path.display()
        );
    }
    Ok(())
}

/// The training configuration `a` asks for (without `--resume`).
pub fn train_config(a: &FitArgs) -> Result<TrainConfig> {
    Ok(TrainConfig {
        widths: a.widths.parse().map_err(anyhow::Error::msg)?,
        batch_size: a.batch,
        steps: a.steps,
        adam: learn::optim::AdamConfig {
            lr: a.lr,
            decay: a.lr_decay,
            decay_every: a.lr_decay_every,
            floor_fraction: a.lr_floor,
            clip_norm: a.clip,
            ..Default::default()
        },
        weights: learn::cvae::LossWeights {
            position: a.position_weight,
            ..Default::default()
        },
        seed: *a.seed,
        eval_every: a.eval_every.max(1),
        checkpoint_every: a.checkpoint_every.max(1),
        objective: match a.objective {
            learn::train::ObjectiveKind::Energy => Objective::EnergyScore {
                draws: a.draws,
                weight: a.energy_weight,
            },
            learn::train::ObjectiveKind::Cvae => Objective::Cvae,
        },
    })
}

/// `train fit`: the run `a` asks for ([`learn::fit::run`]), with a progress bar and a summary.
pub fn run_fit(a: &FitArgs) -> Result<()> {
    let run = learn::fit::FitRun {
        data: a.data.clone(),
        out: a.out.to_path_buf(),
        init: a.init.clone(),
        resume: a.resume,
        overwrite: *a.overwrite,
        config: train_config(a)?,
    };
    let done = learn::fit::run(&run, &cmdline::progress(0, "train"))?;
    println!(
        "trained {} steps ({} this run) in {:.1} s ({:.0} samples/s); validation: {}",
        done.steps,
        done.steps_this_run,
        done.seconds,
        done.samples_per_second,
        done.validation.unwrap_or_default()
    );
    println!("model -> {}", done.model.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cmdline::arg_defaults;

    #[test]
    fn train_all_uses_the_shipped_models_defaults() {
        let d: DataArgs = arg_defaults(&["--out", "o"]);
        assert_eq!(
            (d.meshes, d.val_meshes, d.configs_per_mesh),
            (160, 16, 1250)
        );
        assert_eq!(
            (d.samples_per_config, d.path_attempts, *d.seed),
            (16, 1024, 0)
        );
        assert!(!d.no_c19_quirk);
        let f: FitArgs = arg_defaults(&["--data", "d", "--out", "o"]);
        assert_eq!((f.steps, f.batch, f.lr_decay_every), (400_000, 256, 60_000));
        assert_eq!(
            (f.lr, f.lr_decay, f.lr_floor, f.clip),
            (1e-3, 0.5, 0.05, 100.0)
        );
        assert_eq!(f.widths, "son24");
        assert_eq!(
            f.position_weight,
            learn::cvae::LossWeights::default().position
        );
    }

    /// `train all`'s second stage is the configuration stored in the shipped model's
    /// provenance, started from the first stage's model.
    #[test]
    fn train_all_fine_tunes_as_the_shipped_model_was() {
        let cvae = FitArgs {
            out: PathBuf::from("o/cvae").into(),
            ..arg_defaults(&["--data", "d", "--out", "o"])
        };
        let stage = energy_stage(&cvae, "o/model".into());
        assert_eq!(stage.init, Some(PathBuf::from("o/cvae/model.safetensors")));
        let want = train_config(&stage).unwrap();
        let shipped = cmdline::LearnedArgs::shipped_model().unwrap();
        let prov = &shipped.info().provenance;
        let got: learn::train::TrainConfig =
            serde_json::from_value(prov["training"].clone()).unwrap();
        assert_eq!(got, want, "the shipped model was trained otherwise");
        assert!(
            prov["init"]
                .as_str()
                .is_some_and(|p| p.ends_with("cvae/model.safetensors")),
            "{}",
            prov["init"]
        );
    }
}
