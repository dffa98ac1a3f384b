//! The corpus files that come out of running the library: optimisation checkpoints, training
//! samples and checkpoints, and SON24's binary weights.

use bssrdf::diff::Loss;
use bssrdf::model::ModelInfo;
use bssrdf::nn::ShapeAdaptiveModel;
use fuzz::readers::{Reader, train_data};
use geometry::{Accel, Shape};
use glam::Vec3;
use inverse::optimize::{OptimizeConfig, Optimizer, TargetView};
use inverse::params::Params;
use scene::{Camera, Image, Medium, PointLight};
use std::path::Path;

use super::{Res, corpus, pattern, support};

/// What an optimisation checkpoint of the corpus was made on: a sphere of radius 0.5
/// (subdivided once), the shipped model, two 8 × 8 views and the medium that supplies g and η.
struct OptimizeSetup {
    /// The object.
    accel: Accel,
    /// The shipped model.
    model: ShapeAdaptiveModel,
    /// Cameras, lights and target images.
    views: Vec<(Camera, PointLight, Image)>,
    /// The base medium (g, η).
    base: Medium,
}

impl OptimizeSetup {
    /// The setup (the shipped model is read from `models/`).
    fn new() -> Result<Self, String> {
        let mesh = Shape::Sphere {
            radius: 0.5,
            subdivisions: 1,
        }
        .build()
        .map_err(|e| e.to_string())?;
        let model_path = fuzz::fuzz_dir().join("../models/translucent-v2.safetensors");
        let model = bssrdf::model::load(&model_path).map_err(|e| e.to_string())?;
        let views = [Vec3::new(0.0, 0.3, 2.0), Vec3::new(1.5, 0.5, -1.2)]
            .into_iter()
            .enumerate()
            .map(|(i, o)| {
                (
                    Camera::look_at(o, Vec3::ZERO, Vec3::Y, 30.0, 8, 8),
                    PointLight {
                        position: o + Vec3::new(0.8, 0.8, 0.0),
                        intensity: [10.0; 3],
                    },
                    pattern(8, 8, i as f32),
                )
            })
            .collect();
        Ok(OptimizeSetup {
            accel: Accel::new(mesh),
            model,
            views,
            base: Medium {
                sigma_t: [60.0; 3],
                albedo: [0.9; 3],
                g: scene::Anisotropy::uniform(0.0),
                eta: 1.0,
                roughness: 0.0,
            },
        })
    }

    /// The target views, in order.
    fn targets(&self) -> Vec<TargetView<'_>> {
        self.views
            .iter()
            .map(|(camera, light, image)| TargetView {
                camera,
                light,
                image,
            })
            .collect()
    }
}

pub(super) fn optimize_checkpoints(work: &Path) -> Res {
    let setup = OptimizeSetup::new()?;
    let init = Params {
        sigma_t: [50.0; 3],
        albedo: [0.5; 3],
        g: None,
        light_scale: None,
    };
    let mut plain = OptimizeConfig::new(init);
    plain.iterations = 2;
    plain.refine_iterations = 0;
    plain.spp = 1;
    plain.albedo_warmup = 1;
    let mut varied = plain.clone();
    varied.loss = Loss::L1;
    varied.crop = Some(4);
    varied.refit_every = 1;
    varied.normalize_views = true;
    varied.view_subset = Some(vec![0, 1]);
    varied.views_per_iter = 2;
    varied.two_renders = false;
    // The tracer with g and the lights' scale free: eight variables.
    let mut free = plain.clone();
    free.model = inverse::forward::ModelChoice::Volpath(inverse::forward::TracerEstimator::Ad);
    free.params.free_g = true;
    free.params.free_light_scale = true;
    free.init.g = Some(inverse::params::OneOrRgb::One(0.2));
    for (name, config) in [
        ("plain.json", plain),
        ("varied.json", varied),
        ("free.json", free),
    ] {
        let path = work.join(name);
        let mut run = Optimizer::new(
            config,
            &setup.accel,
            Some(&setup.model),
            setup.base,
            setup.targets(),
        )?;
        run.run(Some((&path, 1)), |_, _| {})?;
        std::fs::copy(&path, corpus(Reader::OptimizeCheckpoint, name))?;
    }
    Ok(())
}

pub(super) fn samples_and_train_checkpoints(work: &Path) -> Res {
    let cfg = learn::datagen::DataConfig {
        meshes: 1,
        configs_per_mesh: 3,
        samples_per_config: 8,
        path_attempts: 64,
        seed: 3,
        ..Default::default()
    };
    let (samples, summary) = learn::datagen::generate(&cfg, None)?;
    let mut header = learn::samplefile::SampleFileHeader::new(&cfg, Some(&summary));
    header.created_unix_s = 0;
    let all = support(Reader::TrainCheckpoint, "train.samples");
    learn::samplefile::write_samples(&all, &header, &samples, false)?;
    std::fs::copy(&all, corpus(Reader::Samples, "small.samples"))?;
    learn::samplefile::write_samples(
        &corpus(Reader::Samples, "three.samples"),
        &header,
        &samples[..3.min(samples.len())],
        false,
    )?;

    let (norm, train, val) = train_data(&samples)?;
    let widths = learn::cvae::Widths {
        feature: vec![4],
        absorption_hidden: vec![2],
        decoder_hidden: vec![3],
        encoder_hidden: vec![2],
    };
    let cvae = learn::train::TrainConfig {
        widths,
        batch_size: 4,
        steps: 2,
        eval_every: 1,
        checkpoint_every: 1,
        ..Default::default()
    };
    let energy = learn::train::TrainConfig {
        objective: learn::train::Objective::EnergyScore {
            draws: 2,
            weight: 1.0,
        },
        ..cvae.clone()
    };
    for (name, config) in [("cvae.bin", cvae), ("energy.bin", energy)] {
        let mut t = learn::train::Trainer::new(
            config,
            norm.clone(),
            ModelInfo::default(),
            train.clone(),
            val.clone(),
        )?;
        t.train_step()?;
        t.train_step()?;
        let path = work.join(name);
        t.save_checkpoint(&path)?;
        std::fs::copy(&path, corpus(Reader::TrainCheckpoint, name))?;
    }
    Ok(())
}

/// `.bin` tensors of the reference weights' layout: int32 ndim, the dims, f32 values.
pub(super) fn son24_bins() -> Res {
    let tensor = |dims: &[i32]| -> Vec<u8> {
        let mut b = (dims.len() as i32).to_le_bytes().to_vec();
        for d in dims {
            b.extend_from_slice(&d.to_le_bytes());
        }
        let n: i32 = dims.iter().product();
        for i in 0..n {
            b.extend_from_slice(&(0.1 * i as f32 - 0.3).to_le_bytes());
        }
        b
    };
    std::fs::write(corpus(Reader::Son24Bin, "weights-4x3.bin"), tensor(&[4, 3]))?;
    std::fs::write(corpus(Reader::Son24Bin, "biases-4.bin"), tensor(&[4]))?;
    std::fs::write(corpus(Reader::Son24Bin, "scalar.bin"), tensor(&[]))?;
    Ok(())
}
