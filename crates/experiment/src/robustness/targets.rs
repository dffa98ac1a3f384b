//! The targets of the suite's cases: each case's dataset rendered by our volumetric path tracer
//! or by Mitsuba 3 (through `--mitsuba-script`), made once and reused, and which renderers a
//! run uses.

use scene::setting::Setting;
use std::path::Path;

use inverse::views::{RenderOpts, make_dataset};
use recovery::Observer;
use scene::{Dataset, MeshSource, RenderInfo, SceneDesc};

use super::cases::{mesh_source, rig};
use super::{Case, RobustnessConfig, Targets};
use crate::bail;
use crate::error::{Context, Result};

/// Render the dataset unless `dir` holds it already.
pub(crate) fn ensure_dataset(
    a: &RobustnessConfig,
    case: &Case,
    rep: u64,
    targets: Targets,
    dir: &Path,
    obs: &dyn Observer,
) -> Result<()> {
    let w = a.workload();
    let (views, res, spp) = (w.views, w.res, w.target_spp);
    if dir.join("dataset.json").exists() {
        let ds = Dataset::load(dir)?;
        let by_mitsuba = ds
            .render
            .renderer
            .as_deref()
            .is_some_and(|r| r.starts_with("Mitsuba"));
        let same = ds.truth == Some(case.medium)
            && ds.views.len() == views
            && ds.render.spp == Some(spp)
            && ds.views.first().is_some_and(|v| v.camera.width == res)
            && by_mitsuba == (targets == Targets::Mitsuba);
        if same {
            return Ok(());
        }
        return Err(crate::other_dataset(dir));
    }
    obs.say(&format!(
        "dataset {} (repetition {rep}, {} targets): {views} views {res}² at {spp} spp, σ_t = {:.1?}, α = {:.3?}, radius {:.3}",
        case.name,
        targets.name(),
        case.medium.sigma_t,
        case.medium.albedo,
        0.5 * case.scale
    ));
    // `{dir}.mesh`: the case names hold dots (`smooth1.5`), which `with_extension` would cut at.
    let mut mesh_dir = dir.as_os_str().to_owned();
    mesh_dir.push(".mesh");
    let mesh_dir = std::path::PathBuf::from(mesh_dir);
    match targets {
        Targets::Volpath => {
            let mesh = mesh_source(case, &a.mesh, &mesh_dir, (false, a.quick))?;
            make_dataset(
                &rig(case, views, res),
                mesh,
                case.medium,
                RenderOpts {
                    spp,
                    seed: a.seed + rep,
                    max_depth: MAX_DEPTH,
                    shadow: Default::default(),
                },
                dir,
                false,
                obs,
            )?;
        }
        Targets::Mitsuba => {
            let mesh = mesh_source(case, &a.mesh, &mesh_dir, (true, a.quick))?;
            render_with_mitsuba(a, case, mesh, (views, res, spp), a.seed + rep, dir)?;
        }
    }
    Ok(())
}

/// Depth limit of the target renders (Mitsuba's `max_depth` semantics).
const MAX_DEPTH: u32 = 128;

/// The case's views rendered by Mitsuba 3 into the dataset `dir`: our layout of the case (mesh,
/// medium, cameras, lights; blank images) goes to `DIR.layout`, `--mitsuba-script` renders it
/// into `DIR.mitsuba`, and that is saved as `dir` with PNG previews. A staged render that
/// finished is reused.
fn render_with_mitsuba(
    a: &RobustnessConfig,
    case: &Case,
    mesh: MeshSource,
    (views, res, spp): (usize, u32, u32),
    seed: u64,
    dir: &Path,
) -> Result<()> {
    let layout = dir.with_extension("layout");
    let staged = dir.with_extension("mitsuba");
    if !staged.join("dataset.json").exists() {
        let desc = SceneDesc {
            mesh,
            medium: case.medium,
            views: rig(case, views, res).build(),
            render: RenderInfo {
                max_depth: Some(MAX_DEPTH),
                ..Default::default()
            },
            path: layout.join("dataset.json"),
            length_unit: None,
        };
        let mut ds = Dataset::from_scene(&desc);
        for v in &mut ds.views {
            v.image = Some(scene::Image::new(v.camera.width, v.camera.height));
        }
        ds.save(&layout, true)?;
        let status = std::process::Command::new(&a.python)
            .arg(&a.mitsuba_script)
            .arg(&layout)
            .arg("--out")
            .arg(&staged)
            .args(["--spp", &spp.to_string(), "--seed", &seed.to_string()])
            .args(["--max-depth", &MAX_DEPTH.to_string(), "--overwrite"])
            .stdout(std::process::Stdio::null())
            .status()
            .with_context(|| {
                format!(
                    "running {} {}",
                    a.python.display(),
                    a.mitsuba_script.display()
                )
            })?;
        if !status.success() {
            bail!(
                "{} {} {} failed ({status}); its error is above",
                a.python.display(),
                a.mitsuba_script.display(),
                layout.display()
            );
        }
    }
    let ds = Dataset::load(&staged)?;
    ds.save(dir, false)?;
    for d in [&layout, &staged] {
        let _ = std::fs::remove_dir_all(d);
    }
    Ok(())
}

/// Whether `--mitsuba-script --check` finds Mitsuba 3: `Ok(version line)` or `Err(why not)`.
fn mitsuba_available(a: &RobustnessConfig) -> std::result::Result<String, String> {
    if !a.mitsuba_script.exists() {
        return Err(format!(
            "{} not found (run from the repository root, or set {})",
            a.mitsuba_script.display(),
            Setting::MitsubaScript
        ));
    }
    let out = std::process::Command::new(&a.python)
        .arg(&a.mitsuba_script)
        .arg("--check")
        .output()
        .map_err(|e| format!("{}: {e}", a.python.display()))?;
    let text = String::from_utf8_lossy(&out.stdout).trim().to_string();
    if out.status.success() {
        Ok(text)
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        Err(err.lines().last().unwrap_or("no output").to_string())
    }
}

/// The target renderers of this run (`--targets`, or the default: ours, and Mitsuba's when
/// found and not `--quick`).
pub(super) fn target_renderers(a: &RobustnessConfig, obs: &dyn Observer) -> Result<Vec<Targets>> {
    if let Some(t) = &a.targets {
        crate::ensure!(
            !t.is_empty(),
            "{}: name volpath, mitsuba or both",
            Setting::Targets
        );
        if t.contains(&Targets::Mitsuba)
            && let Err(why) = mitsuba_available(a)
        {
            bail!(
                "{} mitsuba: Mitsuba 3 is not usable: {why}; fix: `pip install mitsuba numpy` \
                 (on Debian also `apt-get install libllvm19`), or leave mitsuba out",
                Setting::Targets
            );
        }
        return Ok(t.clone());
    }
    if a.quick {
        return Ok(vec![Targets::Volpath]);
    }
    // A list of jobs is only the commands.
    let say = a.jobs.list.is_none();
    match mitsuba_available(a) {
        Ok(v) => {
            if say {
                obs.say(&format!("targets: our volumetric path tracer and {v}"));
            }
            Ok(vec![Targets::Volpath, Targets::Mitsuba])
        }
        Err(_) if !say => Ok(vec![Targets::Volpath]),
        Err(why) => {
            obs.say(&format!(
                "targets: our volumetric path tracer only (Mitsuba 3 not usable: {why}; `pip install mitsuba numpy` adds its renders as an independent check)"
            ));
            Ok(vec![Targets::Volpath])
        }
    }
}
