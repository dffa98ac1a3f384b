//! `translucent demo`: the main job on the built-in default scene, the whole round trip. It renders
//! a small multi-view dataset of the bumpy blob in a hidden medium drawn from the paper's ranges
//! with the volumetric path tracer, then recovers σ_t and α from the images with the learned
//! BSSRDF and the paper's gradient estimator (`translucent optimize`, estimator `ours`), refined in
//! its last half by the volumetric path tracer (`optimize --refine`; the learned model's own loss
//! minimum lies off the true σ_t, docs/notes/learned-model-bias.md), prints the estimate with its
//! interval against the truth and writes the convergence plots and re-renders.

use anyhow::Result;
use clap::Args;
use geometry::Shape;
use scene::MeshSource;

use inverse::views::random_medium;
use inverse::views::{RenderOpts, make_dataset};
use scene::rig::paper_rig;

/// Marker file identifying a folder written by `translucent demo` (safe to overwrite).
const MARKER: &str = ".translucent-demo";

#[derive(Args)]
#[command(mut_arg(
    "out",
    cmdline::groups::default_and_help(
        "out/demo",
        "Output folder (reused by later runs of the demo; other folders are never overwritten)"
    )
))]
#[command(mut_arg(
    "seed",
    cmdline::groups::default_and_help("1", "Seed of the hidden medium and of the renders")
))]
#[command(mut_arg("spp", cmdline::groups::default("64")))]
#[command(mut_arg("res", cmdline::groups::default_and_help("128", "Image size")))]
#[command(mut_arg("views", cmdline::groups::default("8")))]
pub struct DemoArgs {
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    #[command(flatten)]
    pub views: cmdline::Views,
    /// Optimisation iterations of each recovery (0: only render the dataset).
    #[arg(long, default_value_t = 200)]
    pub iterations: u32,
    /// The volumetric refinement (`optimize --refine`): the last N iterations use the
    /// volumetric path tracer. Default: half of --iterations; 0: the learned model alone.
    #[arg(long, value_name = "N")]
    pub refine: Option<u32>,
}

pub fn run(a: &DemoArgs) -> Result<()> {
    // Only a missing or empty folder, or one the demo wrote before, may be written.
    let ours = a.out.join(MARKER).exists();
    let empty = std::fs::read_dir(&a.out)
        .map(|mut d| d.next().is_none())
        .unwrap_or(true);
    if !ours && !empty {
        anyhow::bail!(
            "{} already holds files not written by `translucent demo`; choose another --out",
            a.out.display()
        );
    }
    if ours {
        // Remove the previous demo's images so a run with fewer views leaves no stale ones.
        for e in std::fs::read_dir(&a.out)?.flatten() {
            let p = e.path();
            let stale = p.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                n.starts_with("view_") && (n.ends_with(".exr") || n.ends_with(".png"))
            });
            if stale {
                std::fs::remove_file(&p)?;
            }
        }
    }
    let medium = random_medium(*a.seed);
    // One fixed light for all views, as in the paper's data (docs/model.md §8.3): the views from
    // the unlit side see light that crossed the object, the strongest σ_t signal.
    let rig = paper_rig(*a.views, *a.res);
    rig.validate("demo")?;
    println!(
        "translucent demo: bumpy blob, {} views {}×{} at {} spp (volumetric path tracer)",
        *a.views, *a.res, *a.res, *a.spp
    );
    let ds = make_dataset(
        &rig,
        MeshSource::Shape(Shape::from_name("blob")?),
        medium,
        RenderOpts {
            spp: *a.spp,
            seed: *a.seed,
            max_depth: 32,
            shadow: Default::default(),
        },
        &a.out,
        true,
        &cmdline::Terminal,
    )?;
    std::fs::write(
        a.out.join(MARKER),
        "written by `translucent demo`; the demo may overwrite this folder\n",
    )?;
    println!(
        "medium (paper ranges, seed {}): σ_t = ({:.2}, {:.2}, {:.2}) 1/unit, α = ({:.4}, {:.4}, {:.4})",
        *a.seed,
        medium.sigma_t[0],
        medium.sigma_t[1],
        medium.sigma_t[2],
        medium.albedo[0],
        medium.albedo[1],
        medium.albedo[2]
    );
    for (i, v) in ds.views.iter().enumerate() {
        if let Some(img) = &v.image {
            let m = img.mean();
            println!(
                "  view_{i:03}: mean RGB = ({:.5}, {:.5}, {:.5})",
                m[0], m[1], m[2]
            );
        }
    }
    println!(
        "wrote {} (dataset.json, view_XXX.exr + .png)",
        a.out.display()
    );
    if a.iterations == 0 {
        return Ok(());
    }
    let o = recovery_args(a);
    let c = cmdline::optimize::recovery_config(&o)?.optimize;
    println!(
        "recovering the medium from the images: {} iterations from σ_t = 50, α = 0.5 (Adam on \
         ln σ_t and α, α alone for the first {}), the learned BSSRDF (shipped model, estimator \
         `ours`){}",
        c.iterations,
        c.effective_albedo_warmup(),
        match c.refine_iterations {
            0 => String::new(),
            k => format!(
                " for the first {}, then the volumetric path tracer for the last {k}",
                c.iterations - k
            ),
        }
    );
    crate::optimize_cmd::run(&o)
}

/// The demo's recovery: `optimize`'s defaults with the demo's iterations, seed and refinement,
/// into `OUT/optimize`.
pub(crate) fn recovery_args(a: &DemoArgs) -> cmdline::optimize::OptimizeArgs {
    let mut o =
        cmdline::optimize::OptimizeArgs::with_defaults(a.out.to_path_buf(), a.out.join("optimize"));
    o.budget.iterations = a.iterations;
    o.seed = a.seed;
    o.overwrite = true.into();
    o.refine = a.refine;
    o
}
