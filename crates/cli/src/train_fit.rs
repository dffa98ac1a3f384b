//! `translucent train fit`: train the learned BSSRDF on generated data (docs/model.md §6) and
//! write the model, its loss curves and history; `--resume` continues a run bit-identically.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use bssrdf::nn::ShapeAdaptiveModel;
use learn::cvae::Widths;
use learn::samplefile::{SampleFileHeader, read_samples};
use learn::train::{Objective, Prepared, TrainConfig, Trainer, normalisation_of, prepare};

use crate::train_cmd::FitArgs;
use cmdline::progress;

/// Parses `son24`, `vkj19` or `F=..;A=..;D=..;E=..`.
pub fn parse_widths(s: &str) -> Result<Widths> {
    match s {
        "son24" => return Ok(Widths::son24()),
        "vkj19" => return Ok(Widths::vkj19()),
        _ => {}
    }
    let mut w = Widths::son24();
    for part in s.split(';').filter(|p| !p.trim().is_empty()) {
        let (k, v) = part
            .split_once('=')
            .with_context(|| format!("--widths: '{part}' is not KEY=w1,w2,…"))?;
        let list: Vec<usize> = v
            .split(',')
            .map(|x| x.trim().parse::<usize>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("--widths: '{v}' is not a list of integers"))?;
        anyhow::ensure!(list.iter().all(|&x| x > 0), "--widths: widths must be ≥ 1");
        match k.trim() {
            "F" => w.feature = list,
            "A" => w.absorption_hidden = list,
            "D" => w.decoder_hidden = list,
            "E" => w.encoder_hidden = list,
            other => bail!("--widths: unknown block '{other}' (use F, A, D, E)"),
        }
    }
    anyhow::ensure!(
        !w.feature.is_empty(),
        "--widths: F needs at least one layer"
    );
    Ok(w)
}

fn load_set(path: &Path) -> Result<(SampleFileHeader, Vec<learn::sample::Sample>)> {
    if !path.exists() {
        bail!(
            "{} does not exist; create the data with `translucent train data --out {}`",
            path.display(),
            path.parent().unwrap_or(Path::new(".")).display()
        );
    }
    Ok(read_samples(path)?)
}

/// The training configuration `a` asks for (without `--resume`).
pub fn train_config(a: &FitArgs) -> Result<TrainConfig> {
    Ok(TrainConfig {
        widths: parse_widths(&a.widths)?,
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
        seed: a.seed,
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

pub fn run_fit(a: &FitArgs) -> Result<()> {
    let (train_header, train) = load_set(&a.data.join("train.tlsamples"))?;
    let val_path = a.data.join("val.tlsamples");
    let val = if val_path.exists() {
        read_samples(&val_path)?.1
    } else {
        tracing::warn!(
            "{} is missing: validating on the training set",
            val_path.display()
        );
        Vec::new()
    };
    // One run per output folder; released when this function returns (or the process dies).
    let _lock = scene::fsutil::lock_folder(&a.out)?;
    let ckpt = a.out.join("checkpoint.bin");
    let model_path = a.out.join("model.safetensors");
    let init = a
        .init
        .as_ref()
        .map(|p| ShapeAdaptiveModel::load(p).with_context(|| format!("--init {}", p.display())))
        .transpose()?;
    let norm = match &init {
        Some(m) => m.normalisation().clone(),
        None => normalisation_of(&train)?,
    };
    let train_p: Prepared = prepare(&train, &norm)?;
    let val_p: Prepared = prepare(&val, &norm)?;
    drop(val);
    let quirk = train_header
        .config
        .get("quirk_c19")
        .and_then(|v| v.as_bool())
        .with_context(|| {
            format!(
                "{}: the header has no boolean config.quirk_c19; regenerate the data",
                a.data.join("train.tlsamples").display()
            )
        })?;
    let mut trainer = if a.resume {
        if !ckpt.exists() {
            bail!("--resume: {} does not exist", ckpt.display());
        }
        Trainer::resume(&ckpt, Some(a.steps), train_p, val_p)?
    } else {
        if (ckpt.exists() || model_path.exists()) && !a.overwrite {
            bail!(
                "{} already holds a training run; pass --resume to continue it or --overwrite to \
                 start again",
                a.out.display()
            );
        }
        let config = train_config(a)?;
        let info = bssrdf::model::ModelInfo {
            c19_quirk: quirk,
            frame_convention: bssrdf::model::FrameConvention::Vkj19,
            provenance: serde_json::Value::Null,
        };
        anyhow::ensure!(
            a.position_weight.is_finite() && a.position_weight > 0.0,
            "--position-weight must be a positive number, got {}",
            a.position_weight
        );
        match init {
            Some(model) => {
                let path = a.init.as_ref().expect("init is loaded from --init");
                anyhow::ensure!(
                    model.info().c19_quirk == quirk,
                    "--init {}: the model was fitted {} VKJ19's c_19 = 0 quirk and the data in {} \
                     {} it; fine-tune on data made with the same setting (`train data \
                     --no-c19-quirk`)",
                    path.display(),
                    if model.info().c19_quirk {
                        "with"
                    } else {
                        "without"
                    },
                    a.data.display(),
                    if quirk { "with" } else { "without" },
                );
                Trainer::from_model(config, model, train_p, val_p)?
            }
            None => Trainer::new(config, norm, info, train_p, val_p)?,
        }
    };
    let total = trainer.config().steps;
    let pb = progress(total, "train");
    pb.set_position(trainer.step());
    let start_step = trainer.step();
    let t0 = Instant::now();
    trainer.run(Some(&ckpt), |s| {
        if s.step % 100 == 0 {
            pb.set_position(s.step);
            if let Some(v) = s.last_val {
                pb.set_message(format!("loss {:.3} val {:.3}", s.loss, v));
            }
        }
    })?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let last = trainer.history().last().cloned();
    let provenance = serde_json::json!({
        "source": "translucent train fit",
        "data": {
            "train_file": a.data.join("train.tlsamples").display().to_string(),
            "train_samples": train_header.sample_count,
            "generator": train_header.generator,
            "seed": train_header.seed,
            "config": train_header.config,
        },
        "training": trainer.config(),
        "init": a.init.as_ref().map(|p| p.display().to_string()),
        "steps": trainer.step(),
        "training_seconds": trainer.seconds(),
        "validation": last.as_ref().map(|r| &r.val),
    });
    trainer.model_info_mut().provenance = provenance.clone();
    trainer.model().save(&model_path)?;
    learn::plot::write_history(trainer.history(), &a.out, true)?;
    scene::fsutil::atomic_write(
        &a.out.join("train.json"),
        serde_json::to_string_pretty(&provenance)?.as_bytes(),
        true,
    )?;
    println!(
        "trained {} steps ({} this run) in {secs:.1} s ({:.0} samples/s); validation: {}",
        trainer.step(),
        trainer.step() - start_step,
        (trainer.step() - start_step) as f64 * trainer.config().batch_size as f64 / secs.max(1e-9),
        last.map(|r| format!("{:?}", r.val)).unwrap_or_default()
    );
    println!("model -> {}", model_path.display());
    Ok(())
}
