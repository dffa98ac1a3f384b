//! `translucent validate-mitsuba DIR`: render a Mitsuba 3 reference-render folder (scene.json +
//! mesh + view_XXX.exr) with our volumetric path tracer and compare per-view, per-channel means.
//!
//! Tolerances: |mean ratio − 1| ≤ 1 % on lit views and ≤ 3 % on dark,
//! back-lit views. A view counts as dark when its reference mean luminance is below
//! `--dark-fraction` (default 5 %) of the brightest view's: there the reference itself is
//! noisier (two 1024-spp Mitsuba renders differ by 1–2.5 % in mean) because few paths reach the
//! light. Exits non-zero when any view is outside its tolerance.
//!
//! The agreement is meant at equal or lower render time than Mitsuba's. `--equal-time` renders
//! for the time Mitsuba took (scene.json's median seconds per view, or `--time-per-view`): every
//! view advances by passes of 32 spp ([`inverse::views::volpath_equal_time`], which continues
//! each pixel's random streams, so the result is the image of a single render at the spp
//! reached) until the next pass would overrun the budget. The spp reached depends on the
//! machine; it is printed, and `--spp` with it reproduces the images bit for bit.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;
use inverse::forward::learned::LearnedSpec;
use inverse::forward::{ModelKind, ModelSpec};
use scene::scene_file::ViewDesc;
use scene::{Dataset, Image};
use volpath::VolpathSettings;

use cmdline::{LearnedArgs, by_rows, check_output_free, progress, write_outputs};
use inverse::views::build_accel;
use scene::image::pair_stats;

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(
        "out/validate-mitsuba",
        "Output folder for our renders (view_XXX.exr/.png, same names as the reference)"
    )
))]
#[command(mut_arg(
    "overwrite",
    cmdline::groups::help("Replace existing images in the output folder")
))]
pub struct ValidateArgs {
    /// Reference folder (scene.json + mesh + view_XXX.exr).
    pub dir: PathBuf,
    #[command(flatten)]
    pub out: cmdline::Output,
    /// Samples per pixel of our renders (the reference's own spp by default, so both renders
    /// carry comparable noise).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Equal-time comparison: render for as long as Mitsuba did (scene.json's
    /// `render.seconds_per_view_median_excl_first` per view, or `--time-per-view`), in passes of
    /// 32 spp over all views until the next pass would overrun that budget. Prints the spp
    /// reached; `--spp N` with that N reproduces the images bit for bit.
    #[arg(long, conflicts_with = "spp")]
    pub equal_time: bool,
    /// Time budget per view in seconds for `--equal-time` (default: Mitsuba's render time
    /// recorded in scene.json).
    #[arg(long, requires = "equal_time")]
    pub time_per_view: Option<f64>,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Replaced by `--model` (learned, volpath, dipole or a model file).
    #[arg(long, hide = true)]
    pub method: Option<String>,
    #[command(flatten)]
    pub learned: LearnedArgs,
    /// Shadow-ray transmittance estimator of the volumetric tracer.
    #[arg(long, value_enum, default_value_t)]
    pub shadow: volpath::ShadowTransmittance,
    /// Ray origins after boundary crossings. Default `mitsuba`: emulate Mitsuba 3's spawn offset
    /// (entering rays skip a 10⁻⁴ sliver of medium, which makes Mitsuba's images 0.1–0.7 %
    /// darker than the exact medium on the reference sphere), so that both renders estimate the
    /// same thing; `robust` renders the exact medium, as `translucent render` does.
    #[arg(long, value_enum, default_value = "mitsuba")]
    pub spawn_offset: volpath::SpawnOffset,
    /// Tolerance on |mean ratio − 1| for lit views.
    #[arg(long, default_value_t = 0.01)]
    pub lit_tolerance: f64,
    /// Tolerance on |mean ratio − 1| for dark (back-lit) views.
    #[arg(long, default_value_t = 0.03)]
    pub dark_tolerance: f64,
    /// A view is dark when its mean luminance is below this fraction of the brightest view's.
    #[arg(long, default_value_t = 0.05)]
    pub dark_fraction: f64,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

fn luminance(m: [f64; 3]) -> f64 {
    0.2126 * m[0] + 0.7152 * m[1] + 0.0722 * m[2]
}

/// Mitsuba's own render time per view, when scene.json records it.
fn mitsuba_seconds(dir: &std::path::Path) -> Option<(f64, u32)> {
    let text = std::fs::read_to_string(dir.join("scene.json")).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    let r = v.get("render")?;
    let s = r.get("seconds_per_view_median_excl_first")?.as_f64()?;
    let spp = r.get("spp")?.as_u64()? as u32;
    Some((s, spp))
}

/// The `--equal-time` budget in seconds per view: `--time-per-view`, else Mitsuba's render time
/// from scene.json. `None` without `--equal-time`.
fn equal_time_budget(a: &ValidateArgs) -> Result<Option<f64>> {
    if !a.equal_time {
        return Ok(None);
    }
    let s = match a.time_per_view {
        Some(s) => s,
        None => mitsuba_seconds(&a.dir).map(|(s, _)| s).with_context(|| {
            format!(
                "--equal-time: {} records no render time (render.seconds_per_view_median_excl_first \
                 and render.spp); give the budget with --time-per-view SECONDS",
                a.dir.join("scene.json").display()
            )
        })?,
    };
    anyhow::ensure!(
        s.is_finite() && s > 0.0,
        "--time-per-view must be a positive number of seconds (got {s})"
    );
    Ok(Some(s))
}

pub fn run(a: &ValidateArgs) -> Result<()> {
    let ds = Dataset::load_reference(&a.dir)
        .with_context(|| format!("reading the reference folder {}", a.dir.display()))?;
    for w in &ds.warnings {
        tracing::warn!("{w}");
    }
    let Some(medium) = ds.truth else {
        bail!(
            "{}: scene.json has no medium; cannot render",
            a.dir.display()
        )
    };
    let refs: Vec<&Image> = ds
        .views
        .iter()
        .map(|v| v.image.as_ref())
        .collect::<Option<_>>()
        .context("reference folder without images")?;
    let names: Vec<String> = ds
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.image_path
                .as_ref()
                .and_then(|p| p.file_stem())
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| format!("view_{i:03}"))
        })
        .collect();
    check_output_free(&a.out, &names, *a.overwrite)?;
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &ds.mesh.describe());
    let settings = VolpathSettings {
        max_depth: ds.render.max_depth.unwrap_or(volpath::DEFAULT_MAX_DEPTH),
        shadow: a.shadow,
        spawn_offset: a.spawn_offset,
        ..Default::default()
    };
    let views: Vec<ViewDesc> = ds.views.iter().map(|v| v.desc()).collect();
    let budget = equal_time_budget(a)?;
    let t0 = Instant::now();
    let (rep, spp, learned) = render_views(a, &ds, &accel, &medium, &views, &settings, budget)?;
    let total = t0.elapsed().as_secs_f64();
    write_outputs(&a.out, &names, &rep.images, *a.overwrite)?;

    let brightest = refs.iter().map(|r| luminance(r.mean())).fold(0.0, f64::max);
    println!(
        "validate-mitsuba {}: {} views {}×{}, {} spp, max_depth {}, σ_t = {:?}, α = {:?}, g = {}, η = {}, spawn offset {}",
        a.dir.display(),
        views.len(),
        views[0].camera.width,
        views[0].camera.height,
        spp,
        settings.max_depth,
        medium.sigma_t,
        medium.albedo,
        medium.g,
        medium.eta,
        match a.spawn_offset {
            volpath::SpawnOffset::Mitsuba => "mitsuba (Mitsuba 3's 1e-4 ray offset emulated)",
            volpath::SpawnOffset::Robust => "robust (exact medium)",
        }
    );
    println!(
        "{:<10} {:>5} {:>6} {:>27} {:>27} {:>27} {:>8}",
        "view",
        "kind",
        "tol",
        "mean ratio ours/ref (R G B)",
        "rel. RMSE full res (R G B)",
        "rel. RMSE 4×4 blocks",
        "status"
    );
    let failures = compare_views(a, &rep.images, &refs, &names, brightest)?;
    let per_view = total / views.len() as f64;
    if let Some(budget) = budget {
        println!(
            "equal time: {spp} spp in {per_view:.3} s/view against a budget of {budget:.3} s/view \
             (passes of {} spp; `--spp {spp}` gives the same images)",
            inverse::views::EQUAL_TIME_PASS
        );
    }
    match mitsuba_seconds(&a.dir) {
        Some((ms, mspp)) => println!(
            "time: ours {per_view:.3} s/view at {spp} spp; Mitsuba 3 {ms:.3} s/view at {mspp} spp \
             (scene.json): ours {:.2}× Mitsuba's time",
            per_view / ms
        ),
        None => println!("time: ours {per_view:.3} s/view at {spp} spp"),
    }
    println!("wrote {}", a.out.display());
    if failures > 0 && learned {
        println!(
            "{failures} view(s) outside the volumetric tolerances (reported, not enforced for the \
             learned BSSRDF, an approximate model)"
        );
        return Ok(());
    }
    if failures > 0 {
        bail!("{failures} view(s) outside tolerance");
    }
    println!("all {} views within tolerance", views.len());
    Ok(())
}

/// The views rendered by the model `--model` names (the tracer, at `--spp` or in equal time
/// with Mitsuba's render; or a learned model): the images, the samples per pixel reached and
/// whether the model is a learned one.
fn render_views(
    a: &ValidateArgs,
    ds: &Dataset,
    accel: &geometry::Accel,
    medium: &scene::Medium,
    views: &[ViewDesc],
    settings: &VolpathSettings,
    budget: Option<f64>,
) -> Result<(inverse::views::RenderReport, u32, bool)> {
    let (accel, medium, settings) = (accel, medium, *settings);
    let mut spp = a.spp.or(ds.render.spp).unwrap_or(1024);
    anyhow::ensure!(spp > 0, "--spp must be at least 1");
    let kind = a.learned.renderer(&a.method, ModelKind::Volpath)?;
    for gap in kind.physics_gaps(&scene::Object::of(medium)) {
        tracing::warn!("{gap}");
    }
    let learned = match kind {
        ModelKind::Volpath => false,
        ModelKind::Learned => true,
        ModelKind::Dipole => bail!(
            "validate-mitsuba checks the volumetric path tracer or a learned model; --model \
             dipole is neither"
        ),
    };
    let job = inverse::views::Job {
        accel,
        medium,
        views,
        spp,
        seed: *a.seed,
    };
    let rep = match (learned, budget) {
        (false, Some(budget)) => {
            let pb = progress(0, "equal time");
            let (images, reached) = inverse::views::volpath_equal_time(
                accel, medium, views, *a.seed, &settings, budget, &pb,
            );
            spp = reached;
            images
        }
        (false, None) => by_rows(views, "volpath", |pb| {
            inverse::views::render(ModelSpec::tracer(settings), &job, false, pb)
        })?,
        (true, Some(_)) => bail!(
            "--equal-time renders with the volumetric path tracer; drop it or --model learned"
        ),
        (true, None) => {
            let model = a.learned.load_model()?;
            let spec = LearnedSpec::new(&model, a.learned.settings(), *a.seed);
            by_rows(views, "learned", |pb| {
                inverse::views::render(ModelSpec::Learned(spec), &job, false, pb)
            })?
        }
    };
    Ok((rep, spp, learned))
}

/// The per-view table: each view's mean ratio against the reference (within the lit or the
/// dark tolerance), its relative RMSE at full resolution and in 4×4 blocks. Returns the
/// number of views outside their tolerance.
fn compare_views(
    a: &ValidateArgs,
    images: &[Image],
    refs: &[&Image],
    names: &[String],
    brightest: f64,
) -> Result<usize> {
    let mut failures = 0;
    for (i, (ours, reference)) in images.iter().zip(refs).enumerate() {
        let dark = luminance(reference.mean()) < a.dark_fraction * brightest;
        let tol = if dark {
            a.dark_tolerance
        } else {
            a.lit_tolerance
        };
        let st = pair_stats(ours, reference)?;
        let block = match (ours.downsample(4), reference.downsample(4)) {
            (Ok(x), Ok(y)) => pair_stats(&x, &y)?.rel_rmse,
            _ => [f64::NAN; 3],
        };
        let ok = st.mean_ratio.iter().all(|r| (r - 1.0).abs() <= tol);
        if !ok {
            failures += 1;
        }
        let r = st.mean_ratio;
        println!(
            "{:<10} {:>5} {:>5.1}% {:>8.4} {:>8.4} {:>8.4}  {:>8.4} {:>8.4} {:>8.4}  {:>8.4} {:>8.4} {:>8.4} {:>8}",
            names[i],
            if dark { "dark" } else { "lit" },
            tol * 100.0,
            r[0],
            r[1],
            r[2],
            st.rel_rmse[0],
            st.rel_rmse[1],
            st.rel_rmse[2],
            block[0],
            block[1],
            block[2],
            if ok { "ok" } else { "FAIL" }
        );
    }
    Ok(failures)
}
