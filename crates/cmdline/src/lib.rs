//! What the command-line programs (`translucent` and the maintainers' `translucent-dev`) share:
//! the learned renderer's option group ([`LearnedArgs`]) and the value parsers of options,
//! progress bars that honour `--quiet`, EXR + PNG outputs that refuse to overwrite, and the
//! `--help` headings. Errors are typed ([`CmdlineError`]); the binaries add their context.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use indicatif::{ProgressBar, ProgressStyle};
use scene::Image;
use scene::scene_file::ViewDesc;

/// The errors of the shared option handling and output writing.
#[derive(Debug, thiserror::Error)]
pub enum CmdlineError {
    #[error("{}: cannot create output folder", dir.display())]
    CreateDir {
        dir: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// An output file exists and `--overwrite` was not given.
    #[error(
        "{} already exists; pass --overwrite to replace it (or choose another --out)",
        path.display()
    )]
    OutputExists { path: PathBuf },
    /// A learned model's file given to a model that has no networks.
    #[error(
        "{0}: only the learned model reads a model file; drop --model-file or use --model learned"
    )]
    NotLearned(String),
    /// `--method` on `render` or `validate-mitsuba`, which choose the renderer with `--model`.
    #[error(
        "--method {0}: the renderer is chosen with --model (learned, volpath or dipole; a learned model file with --model-file)"
    )]
    MethodFlag(String),
    /// An option's value, or a combination of options, that cannot run (the message names them).
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Recovery(#[from] recovery::RecoveryError),
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error(transparent)]
    Model(#[from] bssrdf::model::ModelError),
}

pub type Result<T, E = CmdlineError> = std::result::Result<T, E>;

pub mod groups;
pub mod optimize;

pub use groups::{Output, Overwrite, Quick, Resolution, Seed, Spp, Views};

/// The options every command of a program takes (`--threads`, `--quiet`).
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct GlobalArgs {
    /// Worker threads (default: all cores; same seed and threads, same output).
    #[arg(long, global = true)]
    pub threads: Option<usize>,
    /// Less output (no progress bars).
    #[arg(long, short, global = true)]
    pub quiet: bool,
}

impl GlobalArgs {
    /// Sets up the process: log lines on stderr (warnings only with `--quiet`; the
    /// `TRANSLUCENT_LOG` filter overrides), progress bars unless `--quiet`, and the worker
    /// threads.
    pub fn apply(&self) -> Result<()> {
        let filter =
            tracing_subscriber::EnvFilter::try_from_env("TRANSLUCENT_LOG").unwrap_or_else(|_| {
                tracing_subscriber::EnvFilter::new(if self.quiet { "warn" } else { "info" })
            });
        tracing_subscriber::fmt()
            .with_env_filter(filter)
            .with_target(false)
            .without_time()
            .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
            .with_writer(std::io::stderr)
            .init();
        set_quiet(self.quiet);
        if let Some(n) = self.threads {
            if n == 0 {
                return Err(CmdlineError::Invalid("--threads must be at least 1".into()));
            }
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build_global()
                .map_err(|e| CmdlineError::Invalid(format!("--threads {n}: {e}")))?;
        }
        Ok(())
    }
}

/// The terminal as an observer of the library's work ([`recovery::Observer`]): its
/// lines on stdout, its progress bars on stderr (hidden with `--quiet`).
pub struct Terminal;

impl recovery::Observer for Terminal {
    fn progress(&self, len: u64, label: &str) -> ProgressBar {
        progress(len, label)
    }
    fn say(&self, line: &str) {
        println!("{line}");
    }
}

static QUIET: AtomicBool = AtomicBool::new(false);

pub fn set_quiet(q: bool) {
    QUIET.store(q, Ordering::Relaxed);
}

/// A progress bar on stderr (hidden with `--quiet` or when stderr is not a terminal).
pub fn progress(len: u64, msg: &str) -> ProgressBar {
    if QUIET.load(Ordering::Relaxed) {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg:>12} [{elapsed_precise}] {wide_bar} {pos}/{len} ({eta} left)",
        )
        .unwrap(),
    );
    pb.set_message(msg.to_string());
    pb
}

/// A command's arguments with every default, given the values of its required arguments
/// (`["--out", "o"]`), for commands that run other commands with their defaults.
///
/// # Panics
/// If `required` does not satisfy the argument definitions (a programming error).
pub fn arg_defaults<T: clap::Args + clap::FromArgMatches>(required: &[&str]) -> T {
    let m = T::augment_args(clap::Command::new("defaults"))
        .try_get_matches_from(std::iter::once("defaults").chain(required.iter().copied()))
        .expect("the required arguments parse");
    T::from_arg_matches(&m).expect("the defaults parse")
}

/// Parse "a,b,c" or "a" into an RGB triple.
pub fn parse_rgb(s: &str) -> Result<[f32; 3], String> {
    let v: Result<Vec<f32>, _> = s.split(',').map(|x| x.trim().parse::<f32>()).collect();
    match v {
        Ok(v) if v.len() == 1 => Ok([v[0]; 3]),
        Ok(v) if v.len() == 3 => Ok([v[0], v[1], v[2]]),
        Ok(_) => Err(format!(
            "expected one value or three comma-separated values, got '{s}'"
        )),
        Err(e) => Err(format!("'{s}': {e}")),
    }
}

/// Runs a render of `views` ([`inverse::views`]) with a progress bar of one step per image row
/// (hidden with `--quiet`), labelled `label`.
pub fn by_rows<T>(views: &[ViewDesc], label: &str, render: impl FnOnce(&ProgressBar) -> T) -> T {
    let pb = progress(inverse::views::total_rows(views), label);
    let out = render(&pb);
    pb.finish_and_clear();
    out
}

/// Write `name.exr` and `name.png` into `dir` with a shared exposure.
pub fn write_outputs(
    dir: &Path,
    names: &[String],
    images: &[Image],
    overwrite: bool,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|source| CmdlineError::CreateDir {
        dir: dir.to_path_buf(),
        source,
    })?;
    let exposure = scene::image::auto_exposure(images);
    for (name, img) in names.iter().zip(images) {
        img.write_exr(&dir.join(format!("{name}.exr")), overwrite)?;
        img.write_png(&dir.join(format!("{name}.png")), exposure, overwrite)?;
    }
    Ok(())
}

/// Refuse to write into a folder that already holds files we would replace, unless allowed.
pub fn check_output_free(dir: &Path, names: &[String], overwrite: bool) -> Result<()> {
    if overwrite {
        return Ok(());
    }
    for n in names {
        for ext in ["exr", "png"] {
            let p = dir.join(format!("{n}.{ext}"));
            if p.exists() {
                return Err(CmdlineError::OutputExists { path: p });
            }
        }
    }
    Ok(())
}

/// The `--help` heading of the options a user rarely needs: the defaults are the measured best.
pub const RESEARCH_OPTIONS: &str =
    "Advanced: research options (the defaults are the measured best)";
/// The `--help` heading of the learned BSSRDF's options.
pub const LEARNED_OPTIONS: &str =
    "Advanced: learned BSSRDF options (the defaults are the measured best)";
/// The `--help` heading of a run's outputs and checks after the fit.
pub const CHECK_OPTIONS: &str = "Advanced: outputs and checks after the fit";

/// Options of the learned BSSRDF, shared by the commands that render.
#[derive(clap::Args, Clone, Debug)]
pub struct LearnedArgs {
    /// The forward model: `learned` (the learned BSSRDF, by default the one shipped in
    /// `models/` and built into the binary; the default of `optimize`), `volpath` (the
    /// volumetric path tracer: the default of `render` and `validate-mitsuba`, in `optimize`
    /// the volumetric baseline) or `dipole` (the planar dipole baseline of Deng et al. 2022).
    #[arg(long)]
    pub model: Option<inverse::forward::ModelKind>,
    /// The learned model's networks from a file (translucent safetensors format, written by
    /// `translucent train` or `translucent model import-son24`) in place of the shipped ones.
    #[arg(long, value_name = "FILE")]
    pub model_file: Option<std::path::PathBuf>,
    /// Planar-features ablation: the shape descriptor is the plane p = u_z and the projection
    /// goes along −n(x_o).
    #[arg(help_heading = LEARNED_OPTIONS, long)]
    pub planar_features: bool,
    /// Projection rule of the proposals onto the mesh.
    #[arg(help_heading = LEARNED_OPTIONS, long, value_enum, default_value_t)]
    pub projection: bssrdf::projection::ProjectionKind,
    /// Reach of the `son24` projection in units of σ_n (SON24's scripts: 2; ours: 8, measured in
    /// docs/notes/light-side.md). Proposals farther than this from the mesh along the polynomial
    /// gradient are invalid samples (value 0).
    #[arg(help_heading = LEARNED_OPTIONS, long, default_value_t = bssrdf::projection::DEFAULT_MAX_DIST_SCALE, value_parser = parse_reach, allow_hyphen_values = true)]
    pub max_dist_scale: f32,
    /// Frame convention of features and outputs (default: the model's own; docs/model.md A4).
    #[arg(help_heading = LEARNED_OPTIONS, long, value_enum)]
    pub frames: Option<bssrdf::model::FrameConvention>,
    /// Keep the polynomial descriptor exactly as fitted while σ_t, α change (SON24) instead of
    /// rescaling it to the current σ_n (c_m·k^(deg−1), k = σ_n/σ_n,fit; the default). Only
    /// matters when the features were fitted at another medium (optimize).
    #[arg(help_heading = LEARNED_OPTIONS, long)]
    pub frozen_descriptor: bool,
    /// Trace camera rays through the BVH instead of the per-pixel triangle lists of the view
    /// (the reference path: identical images, slower).
    #[arg(help_heading = LEARNED_OPTIONS, long)]
    pub bvh_camera_rays: bool,
    /// Light-side exit law.
    #[arg(help_heading = LEARNED_OPTIONS, long, value_enum, default_value_t)]
    pub exit_law: bssrdf::exit::ExitLaw,
    /// Light-side incidence.
    #[arg(help_heading = LEARNED_OPTIONS, long, value_enum, default_value_t)]
    pub incidence: bssrdf::render::Incidence,
    /// Where the entry points come from (`walks` is not available with `--estimator naive`).
    #[arg(help_heading = LEARNED_OPTIONS, long, value_enum, default_value_t)]
    pub entry_sampler: bssrdf::render::EntrySampler,
    /// Curvature correction of the light side.
    #[arg(help_heading = LEARNED_OPTIONS, long, value_enum, default_value_t)]
    pub light_curvature: bssrdf::render::LightCurvature,
    /// How a pixel's samples are spread over the colour channels.
    #[arg(help_heading = LEARNED_OPTIONS, long, value_enum, default_value_t)]
    pub pixel_sampling: bssrdf::render::PixelSampling,
}

/// `--max-dist-scale`: a finite, positive multiple of σ_n.
pub fn parse_reach(s: &str) -> std::result::Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number; give the reach in units of σ_n, e.g. 3"))?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!(
            "the projection reach must be a positive multiple of σ_n, got {s}"
        ))
    }
}

/// `cmd` with `f` applied to it and to every subcommand under it.
pub fn for_every_command(
    cmd: clap::Command,
    f: &dyn Fn(clap::Command) -> clap::Command,
) -> clap::Command {
    let names: Vec<String> = cmd
        .get_subcommands()
        .map(|s| s.get_name().to_string())
        .collect();
    names.into_iter().fold(f(cmd), |c, n| {
        c.mut_subcommand(n, |s| for_every_command(s, f))
    })
}

impl LearnedArgs {
    /// One line naming the model and the settings that differ between runs (for report headers).
    pub fn describe(&self) -> String {
        self.learned().describe()
    }

    /// The model, its file and the learned renderer's settings these options choose.
    pub fn learned(&self) -> recovery::settings::LearnedModel {
        recovery::settings::LearnedModel {
            kind: self.kind(),
            file: self.model_file.clone(),
            renderer: self.settings(),
        }
    }

    pub fn settings(&self) -> bssrdf::render::LearnedSettings {
        bssrdf::render::LearnedSettings {
            projection: self.projection.rule(self.max_dist_scale),
            planar_features: self.planar_features,
            frames: self.frames,
            frozen_descriptor: self.frozen_descriptor,
            bvh_camera_rays: self.bvh_camera_rays,
            exit: self.exit_law,
            incidence: self.incidence,
            entry: self.entry_sampler,
            light_curvature: self.light_curvature,
            sampling: self.pixel_sampling,
        }
    }

    /// Sets the model, its file and the learned renderer's settings of `s` to these options
    /// (the estimator stays).
    pub fn apply(&self, s: &mut recovery::RecoverySettings) {
        self.learned().apply(s);
    }

    /// The learned model's networks: `--model-file`, or the shipped ones.
    pub fn load_model(&self) -> Result<bssrdf::nn::ShapeAdaptiveModel> {
        match &self.model_file {
            Some(path) => load_model_arg(path),
            None => Self::shipped_model(),
        }
    }

    /// `--model-file` where the model is the learned one; an error naming the flags for a
    /// model file given to another model, which has no networks.
    pub fn model_file_of(
        &self,
        kind: inverse::forward::ModelKind,
    ) -> Result<Option<std::path::PathBuf>> {
        match (&self.model_file, kind) {
            (Some(f), k) if k != inverse::forward::ModelKind::Learned => Err(
                CmdlineError::NotLearned(format!("--model-file {} with --model {k}", f.display())),
            ),
            (f, _) => Ok(f.clone()),
        }
    }

    /// The renderer of `render` and `validate-mitsuba`: `--model`, `default` when it is not
    /// given; an error for `--method`, which names the renderer in other tools.
    pub fn renderer(
        &self,
        method: &Option<String>,
        default: inverse::forward::ModelKind,
    ) -> Result<inverse::forward::ModelKind> {
        if let Some(m) = method {
            return Err(CmdlineError::MethodFlag(m.clone()));
        }
        let kind = self.kind_or(default);
        self.model_file_of(kind)?;
        Ok(kind)
    }

    /// Which forward model `--model` names, `default` when it is not given (`render` and
    /// `validate-mitsuba` render with the volumetric path tracer unless told otherwise).
    pub fn kind_or(&self, default: inverse::forward::ModelKind) -> inverse::forward::ModelKind {
        self.model.unwrap_or(default)
    }

    /// Which forward model `--model` names; the learned BSSRDF when it is not given.
    pub fn kind(&self) -> inverse::forward::ModelKind {
        self.model.unwrap_or_default()
    }

    /// The model shipped in `models/` (see `models/MODEL_CARD.md`), built into the library
    /// ([`bssrdf::model::shipped`]).
    pub fn shipped_model() -> Result<bssrdf::nn::ShapeAdaptiveModel> {
        Ok(bssrdf::model::shipped()?)
    }
}

/// Loads a learned model file, or the built-in model for `shipped` (or `learned`).
pub fn load_model_arg(path: &std::path::Path) -> Result<bssrdf::nn::ShapeAdaptiveModel> {
    match path.as_os_str().to_str() {
        Some("shipped" | "learned") => LearnedArgs::shipped_model(),
        _ => Ok(bssrdf::model::load(path)?),
    }
}

/// The flag that sets a library [`scene::setting::Setting`]: the binaries register it with
/// [`scene::setting::name_settings`], so that library errors name the flags.
pub fn flag_of(setting: scene::setting::Setting) -> &'static str {
    use scene::setting::Setting;
    match setting {
        Setting::Overwrite => "--overwrite",
        Setting::Resume => "--resume",
        Setting::Out => "--out",
        Setting::ViewSubset => "--view-subset",
        Setting::Spp => "--spp",
        Setting::MaxDepth => "--max-depth",
        Setting::Model => "--model",
        Setting::ModelFile => "--model-file",
        Setting::RefineSpp => "--refine-spp",
        Setting::BiasCorrection => "--bias-correction",
        Setting::ViewWeightFloor => "--view-weight-floor",
        Setting::Starts => "--starts",
        Setting::Iterations => "--iterations",
        Setting::Refine => "--refine",
        Setting::BiasCorrectionSteps => "--bias-correction-steps",
        Setting::InitSigmaT => "--init-sigma-t",
        Setting::InitAlbedo => "--init-albedo",
        Setting::FreeG => "--free g",
        Setting::FreeGRgb => "--free g-rgb",
        Setting::InitG => "--init-g",
        Setting::FreeLightScale => "--free light-scale",
        Setting::InitLightScale => "--init-light-scale",
        Setting::EntrySampler => "--entry-sampler",
        Setting::Estimator => "--estimator",
        Setting::Widths => "--widths",
        Setting::Init => "--init",
        Setting::PositionWeight => "--position-weight",
        Setting::Lr => "--lr",
        Setting::Clip => "--clip",
        Setting::NoC19Quirk => "--no-c19-quirk",
        Setting::MakeTrainingData => "translucent train data --out",
        Setting::Case => "--case",
        Setting::ListJobs => "--list-jobs",
        Setting::Cases => "--cases",
        Setting::Perturbations => "--perturbations",
        Setting::Shapes => "--shapes",
        Setting::Methods => "--methods",
        Setting::Media => "--media",
        Setting::Inits => "--inits",
        Setting::InitsCase => "--inits-case",
        Setting::Seeds => "--seeds",
        Setting::Targets => "--targets",
        Setting::Mesh => "--mesh",
        Setting::MitsubaScript => "--mitsuba-script",
    }
}
