//! `translucent-dev`: the maintainers' measurements behind BENCHMARKS.md and docs/notes (the
//! tracer's speed, the learned model's accuracy against the tracer and against random walks,
//! loss scans, pixel and gradient noise, guided walks). Users need only `translucent`; these diagnostics are
//! kept apart so that its commands stay the product's.

mod learned;
mod noise;
mod plane;
mod scan;
mod spread;
mod volpath_bench;
mod walks;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "translucent-dev",
    version,
    about = "translucent's maintainer diagnostics: the measurements behind BENCHMARKS.md"
)]
struct Cli {
    #[command(flatten)]
    global: cmdline::GlobalArgs,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Paths per second of the volumetric path tracer on the reference sphere scene.
    Volpath(volpath_bench::VolpathBenchArgs),
    /// Accuracy of the learned BSSRDF (real and planar features) against the volumetric tracer.
    #[command(name = "learned-vs-volpath")]
    LearnedVsVolpath(learned::LearnedBenchArgs),
    /// Learned models against directly simulated random walks on a half-space: absorption and
    /// the radial distribution of exit points.
    Plane(plane::PlaneBenchArgs),
    /// Learned models against their held-out training data, binned by the surface's mean
    /// curvature: exit distances (mean and tail quantiles) and absorption.
    Spread(spread::SpreadBenchArgs),
    /// The learned renderer's loss against a dataset's targets at scaled σ_t (α at the truth):
    /// where its minimum lies, without an optimiser.
    #[command(name = "loss-scan")]
    LossScan(scan::LossScanArgs),
    /// Per-pixel and loss-gradient variance of the learned renderer (each pixel-sampling scheme)
    /// against the volumetric path tracer at equal time, on coloured media, and the ceiling of
    /// any scheme that lets each sample serve every channel.
    Noise(noise::NoiseBenchArgs),
    /// Guided random walks against classical ones: variance × time of the tracer's images, its
    /// derivative images and the loss gradient.
    Walks(walks::WalksBenchArgs),
}

fn main() {
    scene::setting::name_settings(cmdline::flag_of);
    let cli = Cli::parse();
    if let Err(e) = run(cli) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    cli.global.apply()?;
    match cli.command {
        Command::Volpath(a) => volpath_bench::run(&a),
        Command::LearnedVsVolpath(a) => learned::run(&a),
        Command::Plane(a) => plane::run(&a),
        Command::Spread(a) => spread::run(&a),
        Command::LossScan(a) => scan::run(&a),
        Command::Noise(a) => noise::run(&a),
        Command::Walks(a) => walks::run(&a),
    }
}
