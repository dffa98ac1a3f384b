//! `translucent experiment gradients` (Son et al. 2024, Fig. 3 and 5: naive differentiation
//! misses the boundary term, ours matches finite differences): derivative images ∂I/∂σ_t and
//! ∂I/∂α of one view of a cone and of a blob, lit from above and beside, by the learned
//! renderer's estimators `ours` and `naive` and by central differences of full renders with
//! independent random numbers and four times the samples ([`inverse::gradcheck`]). Per scene and estimator: the relative error of the image-summed
//! derivative against the differences and the per-pixel correlation with them, in a table
//! (`OUT/gradients.md`, `gradients.csv`), and the derivative images in false colour
//! (`OUT/<scene>/<estimator>_d_sigma_t.png` …, one colour range per parameter).
//!
//! A scene whose images are all there is not rendered again (an interrupted run continues with
//! the missing scenes); other settings need another `--out`.

use recovery::Observer;
use std::path::{Path, PathBuf};

use crate::bail;
use crate::error::{Context, Result};
use bssrdf::diff::{Estimator, Primal};
use bssrdf::render::RenderSettings;
use geometry::Shape;
use inverse::forward::learned::LearnedSpec;
use inverse::gradcheck::{Agreement, agreement, render_estimators};
use scene::rig::RigLight;
use scene::setting::Setting;
use scene::{Dataset, Image, Medium, MeshSource};

use inverse::gradcheck::write_estimators;
use inverse::views::{RenderOpts, make_dataset};
use scene::rig::house_rig;

/// The gradient experiment's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct GradientsConfig {
    /// The output folder.
    pub out: PathBuf,
    /// Image width and height.
    pub res: u32,
    /// Samples per pixel of the estimators' derivative renders (the differences: four times).
    pub spp: u32,
    /// Seed of the renders.
    pub seed: u64,
    /// A smoke test in seconds (32², 4 spp, coarse meshes): not a measurement.
    pub quick: bool,
    pub jobs: super::jobs::Jobs,
}

impl Default for GradientsConfig {
    fn default() -> Self {
        GradientsConfig {
            out: PathBuf::from("out/experiment-gradients"),
            res: 256,
            spp: 64,
            seed: 0,
            quick: false,
            jobs: super::jobs::Jobs::default(),
        }
    }
}

/// The estimators compared with the differences.
const METHODS: [Estimator; 2] = [Estimator::Ours, Estimator::Naive];

/// The scenes: a cone (the paper's Fig. 3) and a blob, with a medium of the paper's ranges; at a
/// smoke test's resolution ([`Shape::coarse`]) with `quick`.
fn scenes(quick: bool) -> Result<[(&'static str, Shape, Medium); 2]> {
    let medium = Medium {
        sigma_t: [60.0, 80.0, 100.0],
        albedo: [0.95, 0.9, 0.85],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    };
    let mesh = |name: &str| -> Result<Shape> {
        let shape = Shape::from_name(name)?;
        Ok(if quick { shape.coarse() } else { shape })
    };
    Ok([
        ("cone", mesh("cone")?, medium),
        ("blob", mesh("blob")?, medium),
    ])
}

/// Writes the run's `settings` into `out/settings.txt`, or checks them against those of the run
/// the folder holds (a run at other settings needs another folder).
fn stamp(out: &Path, settings: &str) -> Result<()> {
    let stamp = out.join("settings.txt");
    match std::fs::read_to_string(&stamp) {
        Ok(s) if s != settings => {
            bail!(
                "{} holds a run at {s}; use another {}",
                out.display(),
                Setting::Out
            )
        }
        _ => {
            std::fs::create_dir_all(out)?;
            std::fs::write(&stamp, settings)?;
        }
    }
    Ok(())
}

pub fn run(a: &GradientsConfig, obs: &dyn Observer) -> Result<()> {
    let (res, spp) = if a.quick { (32, 4) } else { (a.res, a.spp) };
    let scenes = scenes(a.quick)?;
    let cases: Vec<String> = scenes.iter().map(|(n, ..)| n.to_string()).collect();
    if a.jobs.listed(&cases, obs)? {
        return Ok(());
    }
    let _lock = a.jobs.lock(&a.out)?;
    let model = bssrdf::model::shipped()?;
    let settings = format!("{res}² × {spp} spp, seed {}", a.seed);
    stamp(&a.out, &settings)?;
    let mut rows: Vec<(String, Estimator, Agreement, f64)> = Vec::new();
    let mut missing = Vec::new();
    for (name, shape, medium) in scenes {
        let dir = a.out.join(name);
        let done = |m: Estimator| dir.join(format!("{}_d_albedo.exr", m.name())).exists();
        let finished = METHODS.iter().chain([&Estimator::Fd]).all(|m| done(*m));
        if !a.jobs.runs(name) {
            if !finished {
                missing.push(name.to_string());
                continue;
            }
            let results = reread(&dir)?;
            let fd = &results.last().expect("fd is last").1;
            for (m, img, secs) in &results {
                rows.push((name.to_string(), *m, agreement(img, fd), *secs));
            }
            continue;
        }
        let data = dir.join("data");
        let ds = if data.join("dataset.json").exists() {
            Dataset::load(&data)?
        } else {
            let rig = house_rig(
                1,
                res,
                RigLight::Fixed {
                    position: geometry::Vec3::new(1.6, 1.4, 0.4),
                },
                (20.0, 20.0),
            );
            make_dataset(
                &rig,
                MeshSource::Shape(shape),
                medium,
                RenderOpts {
                    spp: 4,
                    seed: a.seed,
                    max_depth: 32,
                    shadow: Default::default(),
                },
                &data,
                false,
                obs,
            )?
        };
        let view = ds.views.first().context("the scene has no view")?;
        let (mesh, warnings) = ds.load_mesh()?;
        let accel = inverse::views::build_accel(mesh, &warnings, name);
        let rs = RenderSettings {
            spp,
            seed: a.seed,
            view: 0,
        };
        // The differences: an independent render (another seed) at four times the samples.
        let reference = RenderSettings {
            spp: 4 * spp,
            seed: a.seed ^ 0xFD,
            view: 0,
        };
        let results = if finished {
            obs.say(&format!("{name}: reusing {}", dir.display()));
            reread(&dir)?
        } else {
            let pb = obs.progress(0, &format!("{name}: ours, naive, fd"));
            let r = render_estimators(
                &accel,
                LearnedSpec::new(&model, Default::default(), a.seed),
                medium,
                &view.camera,
                &view.light,
                &rs,
                &reference,
                &METHODS,
                0.02,
                Primal::default(),
            )?;
            pb.finish_and_clear();
            write_estimators(&r, &dir, true)?;
            r.into_iter()
                .map(|e| (e.estimator, e.images, e.seconds))
                .collect()
        };
        let fd = &results.last().expect("fd is last").1;
        for (m, img, secs) in &results {
            rows.push((name.to_string(), *m, agreement(img, fd), *secs));
        }
    }
    a.jobs.report_missing(&missing, obs);
    let (md, csv) = tables(&rows, &settings, a.quick);
    super::write_tables(
        &a.out,
        "gradients",
        &md,
        &csv,
        ", <scene>/<estimator>_d_*.png",
        obs,
    )
}

/// The derivative images of a finished scene, read back (the value image is not kept, and the
/// seconds are not known: NaN).
fn reread(dir: &std::path::Path) -> Result<Vec<(Estimator, bssrdf::diff::DiffImages, f64)>> {
    METHODS
        .iter()
        .chain([&Estimator::Fd])
        .map(|&m| {
            let read = |what: &str| Image::read_exr(&dir.join(format!("{}_{what}.exr", m.name())));
            let d_sigma_t = read("d_sigma_t")?;
            let images = bssrdf::diff::DiffImages {
                value: Image::new(d_sigma_t.width, d_sigma_t.height),
                d_albedo: read("d_albedo")?,
                d_sigma_t,
                d_g: None,
            };
            Ok((m, images, f64::NAN))
        })
        .collect()
}

/// The Markdown and CSV tables.
fn tables(
    rows: &[(String, Estimator, Agreement, f64)],
    settings: &str,
    quick: bool,
) -> (String, String) {
    let mut md = format!(
        "Derivative images against central differences, {settings}{}\n\n\
         | scene | estimator | Σ∂I/∂σ_t rel. error | ∂I/∂σ_t correlation | Σ∂I/∂α rel. error | ∂I/∂α correlation | seconds |\n\
         |---|---|---|---|---|---|---|\n",
        if quick {
            " — QUICK: a smoke test, not a measurement"
        } else {
            ""
        }
    );
    let mut csv = String::from(
        "scene,estimator,sigma_t_relative_error,sigma_t_correlation,albedo_relative_error,albedo_correlation,seconds\n",
    );
    for (scene, m, g, secs) in rows {
        md.push_str(&format!(
            "| {scene} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {secs:.1} |\n",
            m.name(),
            g.relative_error[0],
            g.correlation[0],
            g.relative_error[1],
            g.correlation[1]
        ));
        csv.push_str(&format!(
            "{scene},{},{},{},{},{},{secs}\n",
            m.name(),
            g.relative_error[0],
            g.correlation[0],
            g.relative_error[1],
            g.correlation[1]
        ));
    }
    (md, csv)
}
