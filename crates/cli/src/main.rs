//! `translucent`: measure what a translucent object is made of from images of it.
//!
//! This binary is the only place that uses `anyhow`; the library crates return typed errors.

mod compare;
mod dataset_cmd;
mod demo;
#[cfg(test)]
mod docs_options;
mod experiment_cmd;
mod generate_cmd;
mod gradcheck_cmd;
mod import_cmd;
mod model_cmd;
mod optimize_cmd;
mod render_cmd;
mod train_cmd;
mod validate;

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};

const UNITS_HELP: &str = "\
Units and conventions: lengths in scene units (default objects are about 1 unit across, centred \
at the origin); extinction sigma_t in 1/unit (mean free path = 1/sigma_t); albedo alpha = \
sigma_s/sigma_t in [0, 1); point-light intensity I in W/sr (irradiance I/r^2 facing the light); \
images are linear RGB float32 EXR with sRGB PNG previews. Cameras follow Mitsuba 3's \
`perspective` (fov along x, row 0 at the top).";

#[derive(Parser)]
#[command(name = "translucent", version, about = "Inverse rendering of translucent objects (Son et al. 2024) — forward renderers, datasets and tools", long_about = None, after_help = UNITS_HELP)]
struct Cli {
    #[command(flatten)]
    global: cmdline::GlobalArgs,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a hidden medium, recover it from the images, print truth against estimate.
    ///
    /// The whole round trip on the built-in scene: render a bumpy blob in a hidden paper-range
    /// medium, recover σ_t and α from the images with `optimize`'s defaults, print truth
    /// against estimate and write the plots.
    Demo(demo::DemoArgs),
    /// Render a scene file (TOML/JSON, see SCENE.md) or a dataset's views.
    Render(render_cmd::RenderArgs),
    /// Render a multi-view dataset (dataset.json + EXRs, see DATASET.md).
    ///
    /// The views are rendered by the volumetric path tracer.
    Dataset(dataset_cmd::DatasetArgs),
    /// Compare images A against reference B (ratios, errors, difference images).
    ///
    /// Per image: mean ratio, RMSE, relative MSE, and false-colour differences.
    Compare(CompareArgs),
    /// Check our tracer against a Mitsuba 3 reference folder.
    ///
    /// Renders a Mitsuba 3 reference-render folder (scene.json + mesh + view_XXX.exr) with our
    /// volumetric path tracer and checks the per-view means against Mitsuba's.
    #[command(name = "validate-mitsuba")]
    ValidateMitsuba(validate::ValidateArgs),
    /// Model files of the learned BSSRDF: import reference weights, show a model.
    #[command(subcommand)]
    Model(model_cmd::ModelCommand),
    /// Recover σ_t and α from a dataset's images, with 95 % intervals.
    ///
    /// Differentiable rendering with the learned BSSRDF (Son et al. 2024) or a baseline model:
    /// Adam, checkpoints, intervals, a consistency check, convergence plots, result.json.
    Optimize(Box<cmdline::optimize::OptimizeArgs>),
    /// Derivative images of one view by each estimator against finite differences.
    ///
    /// ∂I/∂σ_t and ∂I/∂α of one view by several gradient estimators against central
    /// differences (Son et al. Fig. 3, 5).
    Gradcheck(Box<gradcheck_cmd::GradcheckArgs>),
    /// Train the learned BSSRDF from our random walks.
    ///
    /// Generates training data with random walks and fits the networks.
    #[command(subcommand)]
    Train(train_cmd::TrainCommand),
    /// The paper's experiments and the robustness suite, with tables and plots.
    #[command(subcommand)]
    Experiment(experiment_cmd::ExperimentCommand),
    /// A COLMAP or NeRF capture (photos, masks, mesh, lights) as a dataset folder
    #[command(subcommand)]
    Import(import_cmd::ImportCommand),
    /// Shell completions and man pages.
    #[command(subcommand)]
    Generate(generate_cmd::GenerateCommand),
}

#[derive(Args)]
struct CompareArgs {
    /// Image or folder of images to test (EXR).
    a: PathBuf,
    /// Reference image or folder (EXR); folders are matched by file name.
    b: PathBuf,
    /// Write false-colour difference PNGs (blue: A < B, red: A > B) into this folder.
    #[arg(long)]
    diff: Option<PathBuf>,
    /// Replace existing difference images.
    #[arg(long)]
    overwrite: bool,
}

fn main() {
    // Die quietly on a closed pipe (`translucent compare A B | head`) like other Unix tools,
    // instead of panicking inside println!.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    scene::setting::name_settings(cmdline::flag_of);
    let cli = parse_args();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

/// The command line with negative numbers taken as values everywhere, so that `--spp -1` or
/// `--init-sigma-t -5` reaches a validation that names the option, not clap's "unexpected
/// argument '-1'".
fn parse_args() -> Cli {
    let matches = cmdline::for_every_command(Cli::command(), &|c| c.allow_negative_numbers(true))
        .try_get_matches()
        .unwrap_or_else(|e| negative_count_error(e).exit());
    Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}

/// A negative value for a count (`--spp -1`, an unsigned integer): says so in our words; other
/// errors unchanged.
fn negative_count_error(e: clap::Error) -> clap::Error {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    let value = match e.get(ContextKind::InvalidValue) {
        Some(ContextValue::String(v)) => v.clone(),
        _ => return e,
    };
    let arg = match e.get(ContextKind::InvalidArg) {
        Some(ContextValue::String(a)) => a.clone(),
        _ => return e,
    };
    // Only the unsigned-integer parser's own error ("-1 is not in 0..=4294967295"): a value
    // parser of ours already says what is wrong.
    let from_integer_parser = std::error::Error::source(&e).is_some_and(|s| {
        let m = s.to_string();
        s.downcast_ref::<std::num::ParseIntError>().is_some() || m.contains(" is not in 0..")
    });
    if e.kind() != ErrorKind::ValueValidation || !value.starts_with('-') || !from_integer_parser {
        return e;
    }
    let option = arg.split_whitespace().next().unwrap_or(&arg).to_string();
    Cli::command().error(
        ErrorKind::ValueValidation,
        format!(
            "{option} {value}: this option counts something (samples, views, iterations, …) and \
             cannot be negative; fix: give a whole number, e.g. {option} {}",
            value.trim_start_matches('-')
        ),
    )
}

fn run(cli: Cli) -> Result<()> {
    cli.global.apply()?;
    match cli.command {
        Command::Demo(a) => demo::run(&a),
        Command::Render(a) => render_cmd::run(&a),
        Command::Dataset(a) => dataset_cmd::run(&a),
        Command::Compare(a) => compare::run(&a.a, &a.b, a.diff.as_deref(), a.overwrite).map(|_| ()),
        Command::ValidateMitsuba(a) => validate::run(&a),
        Command::Experiment(e) => Ok(experiment::run(&e.experiment(), &cmdline::Terminal)?),
        Command::Import(i) => import_cmd::run(&i),
        Command::Generate(g) => generate_cmd::run(&g, Cli::command()),
        Command::Model(m) => model_cmd::run(&m),
        Command::Train(t) => train_cmd::run(&t),
        Command::Optimize(a) => optimize_cmd::run(&a),
        Command::Gradcheck(a) => gradcheck_cmd::run(&a),
    }
}
