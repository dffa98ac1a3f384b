//! `translucent render SCENE`: render every view of a scene file with the volumetric path tracer
//! into `OUT/view_XXX.exr` + `.png`.
//!
//! With `--derivatives` each view also gets `view_XXX_d_sigma_t` and `view_XXX_d_albedo` (EXR,
//! and a false-colour PNG: red > 0, blue < 0, one symmetric range per parameter over all views):
//! ∂I/∂σ_t and ∂I/∂α of channel c with respect to that channel's parameter; and from the
//! volumetric path tracer `view_XXX_d_g`, ∂I_c/∂g_c of channel c with respect to its own g (of
//! the one g all channels share, where they share one). The volumetric
//! path tracer differentiates each of its paths analytically (`volpath::derivative`), and its
//! image is the plain render, bit for bit; the learned BSSRDF uses the paper's estimator
//! (`ours`), whose image is the mean of its σ_t offset samples.
//!
//! With `--as-dataset` the output is a dataset folder instead (`dataset.json` beside the images,
//! the rendered medium as its truth, the renderer in its `render` block; DATASET.md). Rendering a
//! dataset's truth with `--model learned --as-dataset` gives targets that the learned model
//! explains exactly: an optimisation on them measures the estimator and the optimiser alone,
//! without the model's error against the volumetric path tracer (docs/notes/light-side.md, "The
//! light side on convex surfaces").

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use inverse::forward::learned::LearnedSpec;
use inverse::forward::{ModelKind, ModelSpec};
use scene::{Dataset, RenderInfo, SceneDesc};
use volpath::{ChannelSampling, VolpathSettings, WalkSampling};

use cmdline::{LearnedArgs, by_rows, check_output_free, write_outputs};
use inverse::views::build_accel;

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help("out/render", "Output folder (created if needed)")
))]
#[command(mut_arg(
    "overwrite",
    cmdline::groups::help("Replace existing images in the output folder")
))]
pub struct RenderArgs {
    /// Scene file (.toml, .json, or a Mitsuba 3 scene .xml; format in SCENE.md), or a dataset
    /// folder (dataset.json or a Mitsuba reference folder with scene.json: its truth medium is
    /// rendered).
    pub scene: PathBuf,
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Samples per pixel (default: the scene's [render].spp, else 64).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Seed of every random stream (default: the scene's [render].seed, else 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Maximum depth, Mitsuba volpath semantics (default: the scene's, else 32).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Russian roulette starts after this many scattering events.
    #[arg(long, default_value_t = 5)]
    pub rr_depth: u32,
    /// Replaced by `--model` (learned, volpath, dipole or a model file).
    #[arg(long, hide = true)]
    pub method: Option<String>,
    #[command(flatten)]
    pub learned: LearnedArgs,
    /// Sample free flights with one channel and ratio weights (Mitsuba's RGB scheme) instead of
    /// spectral MIS. For comparisons only: noisier.
    #[arg(long)]
    pub single_channel: bool,
    /// Shadow-ray transmittance estimator of the volumetric tracer.
    #[arg(long, value_enum, default_value_t)]
    pub shadow: volpath::ShadowTransmittance,
    /// Ray origins after boundary crossings.
    #[arg(long, value_enum, default_value_t)]
    pub spawn_offset: volpath::SpawnOffset,
    /// Guide this share of the tracer's walks towards the surface they entered by (Dwivedi
    /// sampling, weighed against the classical walk: the same expected image). 0 (default): the
    /// classical walk alone; the guided walks' variance × time measured 0.52–1.17× its own
    /// (docs/notes/guided-walks.md).
    #[arg(long, default_value_t = 0.0, value_name = "SHARE")]
    pub guided_walks: f32,
    /// Also write each view's derivatives with respect to σ_t and α (`view_XXX_d_sigma_t`,
    /// `view_XXX_d_albedo`: EXR and a false-colour PNG), and with the volumetric path tracer
    /// with respect to the phase function's g (`view_XXX_d_g`).
    #[arg(long)]
    pub derivatives: bool,
    /// Write a dataset folder (`dataset.json` + images; the rendered medium is its truth) that
    /// `optimize --dataset`, `compare` and `translucent-dev loss-scan` read.
    #[arg(long)]
    pub as_dataset: bool,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

pub fn run(a: &RenderArgs) -> Result<()> {
    let desc = load_scene_or_dataset(&a.scene)?;
    let spp = a.spp.or(desc.render.spp).unwrap_or(64);
    anyhow::ensure!(spp > 0, "--spp must be at least 1");
    let seed = a.seed.or(desc.render.seed).unwrap_or(0);
    let max_depth = a
        .max_depth
        .or(desc.render.max_depth)
        .unwrap_or(volpath::DEFAULT_MAX_DEPTH);
    anyhow::ensure!(max_depth > 0, "--max-depth must be at least 1");
    let names: Vec<String> = (0..desc.views.len())
        .map(|i| format!("view_{i:03}"))
        .collect();
    check_output_free(&a.out, &names, *a.overwrite)?;
    let derivative_names: Vec<Vec<String>> = names
        .iter()
        .map(|n| {
            ["d_sigma_t", "d_albedo", "d_g"]
                .map(|d| format!("{n}_{d}"))
                .to_vec()
        })
        .collect();
    if a.derivatives {
        check_output_free(&a.out, &derivative_names.concat(), *a.overwrite)?;
    }
    if a.as_dataset && !*a.overwrite && a.out.join("dataset.json").exists() {
        bail!(
            "{} already holds a dataset; pass --overwrite to replace it",
            a.out.display()
        );
    }
    let (mesh, warnings) = desc
        .load_mesh()
        .with_context(|| format!("loading the mesh of {}", a.scene.display()))?;
    let accel = build_accel(mesh, &warnings, &desc.mesh.describe());
    let views = &desc.views;
    let settings = tracer_settings(a, max_depth)?;
    let job = inverse::views::Job {
        accel: &accel,
        medium: &desc.medium,
        views,
        spp,
        seed,
    };
    let kind = a.learned.renderer(&a.method, ModelKind::Volpath)?;
    for gap in kind.physics_gaps(&scene::Object::of(&desc.medium)) {
        tracing::warn!("{gap}");
    }
    let networks = match kind {
        ModelKind::Learned => Some(a.learned.load_model()?),
        _ => None,
    };
    let (spec, renderer) = match (kind, &networks) {
        (ModelKind::Learned, Some(n)) => (
            ModelSpec::Learned(LearnedSpec::new(n, a.learned.settings(), seed)),
            format!("learned BSSRDF ({})", a.learned.describe()),
        ),
        (ModelKind::Dipole, _) => (
            ModelSpec::Dipole {
                estimator: Default::default(),
            },
            "planar dipole".to_string(),
        ),
        _ => (ModelSpec::tracer(settings), "volpath".to_string()),
    };
    let rep = by_rows(views, kind.name(), |pb| {
        inverse::views::render(spec, &job, a.derivatives, pb)
    })?;
    if a.as_dataset {
        let mut ds = Dataset::from_scene(&desc);
        ds.render = RenderInfo {
            spp: Some(spp),
            max_depth: Some(max_depth),
            seed: Some(seed),
            renderer: Some(format!(
                "translucent {} {renderer}",
                env!("CARGO_PKG_VERSION")
            )),
        };
        for (v, img) in ds.views.iter_mut().zip(&rep.images) {
            v.image = Some(img.clone());
        }
        ds.save(&a.out, *a.overwrite)
            .with_context(|| format!("writing the dataset {}", a.out.display()))?;
    } else {
        write_outputs(&a.out, &names, &rep.images, *a.overwrite)?;
    }
    if a.derivatives {
        write_derivatives(&a.out, &derivative_names, &rep.derivatives, *a.overwrite)?;
    }
    let total: f64 = rep.seconds_per_view.iter().sum();
    println!(
        "rendered {} view(s) at {spp} spp in {total:.2} s ({:.3} s/view) -> {}",
        views.len(),
        total / views.len().max(1) as f64,
        a.out.display()
    );
    for (n, img) in names.iter().zip(&rep.images) {
        let m = img.mean();
        println!("  {n}: mean RGB = ({:.5}, {:.5}, {:.5})", m[0], m[1], m[2]);
    }
    Ok(())
}

/// Writes each view's derivative images (∂I/∂σ_t, ∂I/∂α and, where the model has it, ∂I/∂g) as
/// EXR and as false-colour PNG, one colour range per parameter over all views (the largest of
/// the views' 99th percentiles of |∂I|).
fn write_derivatives(
    dir: &std::path::Path,
    names: &[Vec<String>],
    derivatives: &[Vec<scene::Image>],
    overwrite: bool,
) -> Result<()> {
    let zero = |i: &scene::Image| scene::Image::new(i.width, i.height);
    let mut range = [0.0f32; 3];
    for d in derivatives {
        for k in 0..d.len() {
            let (_, r) = scene::Image::false_colour_diff_with_range(&d[k], &zero(&d[k]), None)?;
            range[k] = range[k].max(r);
        }
    }
    for (names, d) in names.iter().zip(derivatives) {
        for k in 0..d.len() {
            d[k].write_exr(&dir.join(format!("{}.exr", names[k])), overwrite)?;
            let (fc, _) =
                scene::Image::false_colour_diff_with_range(&d[k], &zero(&d[k]), Some(range[k]))?;
            fc.write_png(&dir.join(format!("{}.png", names[k])), 1.0, overwrite)?;
        }
    }
    Ok(())
}

/// A scene file, or the truth of a dataset: folders and `dataset.json` are datasets; a file named
/// `scene.json` is read as a scene file first and, if that fails, as a Mitsuba reference folder's
/// description (the error of the scene-file reading is the one reported when both fail).
fn load_scene_or_dataset(path: &std::path::Path) -> Result<SceneDesc> {
    let dataset = |p: &std::path::Path| -> Result<SceneDesc> {
        let ds = Dataset::load(p)?;
        let Some(truth) = ds.truth else {
            bail!(
                "{}: the dataset records no medium (truth) to render",
                p.display()
            )
        };
        Ok(ds.scene(truth))
    };
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if path.is_dir() || name == "dataset.json" {
        return dataset(path);
    }
    match SceneDesc::load(path) {
        Ok(d) => Ok(d),
        Err(e) if name == "scene.json" => dataset(path).map_err(|_| e.into()),
        Err(e) => Err(e.into()),
    }
}

/// The tracer's settings from the command line.
fn tracer_settings(a: &RenderArgs, max_depth: u32) -> Result<VolpathSettings> {
    anyhow::ensure!(
        (0.0..=1.0).contains(&a.guided_walks),
        "--guided-walks must lie between 0 and 1 (the share of guided walks), not {}",
        a.guided_walks
    );
    Ok(VolpathSettings {
        max_depth,
        rr_depth: a.rr_depth,
        channel_sampling: if a.single_channel {
            ChannelSampling::SingleChannel
        } else {
            ChannelSampling::SpectralMis
        },
        shadow: a.shadow,
        spawn_offset: a.spawn_offset,
        walks: if a.guided_walks > 0.0 {
            WalkSampling::Guided {
                probability: a.guided_walks,
            }
        } else {
            WalkSampling::Classical
        },
        ..Default::default()
    })
}
