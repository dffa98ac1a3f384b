//! The recovery's first stage: the dataset (and its view subset), the mesh's BVH, the learned
//! model's networks where the model has them, the checkpoint of a resumed run, the output
//! folder's lock, and the optimiser started or resumed on them.

use std::path::PathBuf;
use std::time::Instant;

use geometry::Accel;
use scene::setting::Setting;
use scene::{Dataset, Medium, Object};

use super::{RecoveryConfig, RecoveryError, check_resume_settings, resume_budget, select_views};
use inverse::forward::ModelKind;
use inverse::optimize::{Checkpoint, Optimizer, TargetView};
use inverse::params::{OneOrRgb, Params};
use inverse::views::build_accel;

/// What a run works on, loaded and checked.
pub(super) struct Prepared {
    /// The dataset, reduced to the run's views.
    pub(super) ds: Dataset,
    pub(super) accel: Accel,
    /// The learned model's networks, when the run renders with it.
    pub(super) networks: Option<bssrdf::nn::ShapeAdaptiveModel>,
    /// The object's boundary and phase function in a medium (the parameters come from the
    /// configuration).
    pub(super) base: Medium,
    /// The object as the run renders it, and whether the dataset stated it (or it is assumed).
    pub(super) object: (Object, bool),
    /// What the run's models do not render of the object ([`ModelKind::physics_gaps`]).
    pub(super) gaps: Vec<String>,
    /// The dataset's truth, for the report only.
    pub(super) truth: Option<Params>,
    /// The run's checkpoint file.
    pub(super) ckpt: PathBuf,
    /// One run per output folder; released when the run ends (or the process dies).
    _lock: scene::fsutil::FolderLock,
}

/// Loads and checks what `cfg` runs on (module docs), with the checkpoint to resume from.
pub(super) fn prepare(
    cfg: &RecoveryConfig,
) -> Result<(Prepared, Option<Checkpoint>), RecoveryError> {
    let mut ds = Dataset::load(&cfg.dataset)?;
    let lock = scene::fsutil::lock_folder(&cfg.out)?;
    let ckpt = cfg.out.join("checkpoint.json");
    let checkpoint = if cfg.resume {
        let c = Checkpoint::read(&ckpt)?;
        check_resume_settings(&cfg.optimize, &c.config, &ckpt)?;
        Some(c)
    } else {
        None
    };
    // A resumed run fits the views it started with.
    let subset = match &checkpoint {
        Some(c) => {
            let given = &cfg.optimize.view_subset;
            if given.is_some() && *given != c.config.view_subset {
                return Err(RecoveryError::Invalid(format!(
                    "{vs} {:?} differs from the views of the run in {} ({:?}); resume \
                     without {vs} or start a new run",
                    given.as_deref().unwrap_or_default(),
                    cfg.out.display(),
                    c.config
                        .view_subset
                        .as_deref()
                        .map_or("all".into(), |v| format!("{v:?}")),
                    vs = Setting::ViewSubset
                )));
            }
            c.config.view_subset.clone()
        }
        None => cfg.optimize.view_subset.clone(),
    };
    if let Some(s) = &subset {
        select_views(&mut ds, s, &cfg.dataset)?;
    }
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &cfg.dataset.display().to_string());
    // Every iteration's light term asks for them; decide them once, in parallel, before the
    // first iteration rather than lazily in the first iterations.
    let t0 = Instant::now();
    let supporting = accel.decide_all_supporting();
    tracing::debug!(
        "supporting planes: {supporting} of {} triangles in {:.0} ms",
        accel.mesh().triangle_count(),
        t0.elapsed().as_secs_f64() * 1e3
    );
    if cfg.optimize.model.kind() == ModelKind::Volpath {
        let depth = cfg.max_depth.unwrap_or(volpath::DEFAULT_MAX_DEPTH);
        if let Some(d) = ds
            .render
            .max_depth
            .filter(|d| cfg.max_depth.is_some() && *d != depth)
        {
            tracing::warn!(
                "the dataset was rendered with maximum depth {d}, the model traces to \
                 {} {depth}",
                Setting::MaxDepth
            );
        }
    }
    let networks = load_networks(cfg)?;
    let (object, stated) = match ds.object {
        Some(o) => (o, true),
        None => (Object::INDEX_MATCHED_ISOTROPIC, false),
    };
    if stated {
        tracing::info!("the object: {}", object.describe());
    } else {
        tracing::warn!(
            "{} states no boundary or phase function (object); assumed: {}",
            cfg.dataset.display(),
            object.describe()
        );
    }
    let mut gaps = Vec::new();
    for kind in [cfg.optimize.model.kind(), cfg.optimize.final_model()] {
        for gap in kind.physics_gaps(&object) {
            if !gaps.contains(&gap) {
                tracing::warn!("{gap}");
                gaps.push(gap);
            }
        }
    }
    let base = object.medium([50.0; 3], [0.5; 3]);
    // A recovered g is reported against the truth's g (the truth stays report-only).
    let truth = ds.truth.as_ref().map(|m| Params {
        g: cfg.optimize.params.free_g.then(|| {
            let g = m.g.channels().map(f64::from);
            match m.g.as_uniform() {
                Some(g) => OneOrRgb::One(g as f64),
                None => OneOrRgb::Rgb(g),
            }
        }),
        ..Params::of(m)
    });
    say_free(&cfg.optimize, &object, stated);
    std::fs::create_dir_all(&cfg.out).map_err(|source| RecoveryError::CreateDir {
        path: cfg.out.clone(),
        source,
    })?;
    let prepared = Prepared {
        ds,
        accel,
        networks,
        base,
        object: (object, stated),
        gaps,
        truth,
        ckpt,
        _lock: lock,
    };
    Ok((prepared, checkpoint))
}

/// The learned model's networks when `cfg` renders with it (the shipped ones unless a file is
/// named); the volumetric and dipole models have none.
fn load_networks(
    cfg: &RecoveryConfig,
) -> Result<Option<bssrdf::nn::ShapeAdaptiveModel>, RecoveryError> {
    if cfg.optimize.model.kind() != ModelKind::Learned {
        return Ok(None);
    }
    Ok(Some(match &cfg.model_file {
        Some(path) => bssrdf::model::load(path)?,
        None => bssrdf::model::shipped()?,
    }))
}

impl Prepared {
    /// The optimiser on the prepared targets: resumed from the checkpoint, or new (refused over
    /// another run's checkpoint unless overwriting, whose bootstrap folders it then removes).
    pub(super) fn start<'p>(
        &'p self,
        cfg: &RecoveryConfig,
        checkpoint: Option<Checkpoint>,
    ) -> Result<Optimizer<'p>, RecoveryError> {
        let targets = TargetView::of_dataset(&self.ds, &cfg.dataset.display().to_string())?;
        let networks = self.networks.as_ref();
        if let Some(c) = checkpoint {
            let budget = resume_budget(cfg, &c);
            return Ok(Optimizer::resume(
                c,
                Some(budget),
                &self.accel,
                networks,
                self.base,
                targets,
            )?);
        }
        if self.ckpt.exists() && !cfg.overwrite {
            return Err(RecoveryError::Invalid(format!(
                "{} already holds an optimisation run; pass {} to continue it or \
                 {} to start again",
                cfg.out.display(),
                Setting::Resume,
                Setting::Overwrite
            )));
        }
        // The bootstrap folders belong to the run being replaced.
        let boot = cfg.out.join("bootstrap");
        if cfg.overwrite && boot.is_dir() {
            std::fs::remove_dir_all(&boot)
                .map_err(|source| RecoveryError::RemoveDir { path: boot, source })?;
        }
        Ok(Optimizer::new(
            cfg.optimize.clone(),
            &self.accel,
            networks,
            self.base,
            targets,
        )?)
    }
}

/// Says which unknowns besides σ_t and α the run recovers, where they start and when they move.
fn say_free(c: &inverse::optimize::OptimizeConfig, object: &Object, stated: bool) {
    if c.params.free_light_scale {
        let k = c.init.light_scale.unwrap_or(OneOrRgb::One(1.0));
        let what = if c.params.light_scale_per_channel {
            "the lights' strength and the camera's white balance are recovered: a factor k_c \
             per channel on every light's stated intensity"
        } else {
            "the lights' strength is recovered: a factor k on every light's stated intensity"
        };
        tracing::info!(
            "{what}, from k = {k}, held there until iteration {} while σ_t and α fit the \
             images under the lights as stated",
            c.light_scale_start()
        );
    }
    if c.params.free_g {
        // As the optimiser starts it: the stated g per channel, or their mean for one g.
        let start = match c.init.g {
            Some(g) => g.to_string(),
            None if c.params.g_per_channel => object
                .g
                .channels()
                .map(f64::from)
                .map(|g| g.to_string())
                .join(", "),
            None => object.g.mean().to_string(),
        };
        let from = if c.init.g.is_some() {
            "as asked"
        } else if stated {
            "the dataset's stated g"
        } else {
            "the assumed g"
        };
        let moves = (c.effective_albedo_warmup()..c.iterations)
            .filter(|&k| c.model_at(k).differentiates_g())
            .count();
        let what = if c.params.g_per_channel {
            "g is recovered per channel (g_R, g_G, g_B)"
        } else {
            "g is recovered (one for every channel)"
        };
        tracing::info!(
            "{what}: it starts at {start} ({from}) and moves in the iterations the volumetric \
             path tracer renders ({moves} of {})",
            c.iterations
        );
    }
}
