//! `translucent model …`: model files of the learned BSSRDF.
//!
//! * `import-son24 DIR OUT`: import the reference weights of Son et al. 2024 (`variables/*.bin`
//!   and `data_stats.json`) into our format, reload the written file and check it on the plane
//!   case of the reference README against its golden values (exit status 1 if any differs by
//!   more than 1e-4).
//! * `info FILE`: architecture, parameter counts per block, normalisation, conventions,
//!   provenance, and the plane-case outputs.
//! * `exit-table OUT`: simulate the light-side exit law of a medium ([`bssrdf::exit`]); with
//!   the defaults it writes the table shipped in `crates/tables/data/exit-g0-eta1.json`.
//! * `curvature-table OUT`: simulate the light side's curvature correction on balls
//!   ([`bssrdf::curvature`]).
//! * `incidence-table OUT`: simulate the light-side incidence factor of a medium
//!   ([`bssrdf::incidence`]); with the defaults it writes the table shipped in
//!   `crates/tables/data/incidence-g0-eta1.json`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use bssrdf::model::{self, FORMAT_NAME, FORMAT_VERSION};
use bssrdf::nn::{ALBEDO_INPUT, ETA_INPUT, INPUT_DIM, N_POLY, ShapeAdaptiveModel, Workspace};
use clap::Subcommand;

#[derive(Subcommand)]
pub enum ModelCommand {
    /// Import the reference weights of Son et al. 2024 (a folder with variables/*.bin and
    /// data_stats.json) into our model format, then check the written file on the plane case
    /// against the golden values of the reference README (exit status 1 on a mismatch).
    #[command(name = "import-son24")]
    ImportSon24 {
        /// Reference weights folder (e.g. reference-weights/son24_light).
        dir: PathBuf,
        /// Model file to write (.safetensors).
        out: PathBuf,
        /// Replace OUT if it exists.
        #[arg(long)]
        overwrite: bool,
    },
    /// Show a model file: architecture, parameter counts, normalisation, conventions,
    /// provenance, and its outputs on the plane case.
    Info {
        /// Model file (.safetensors), or `shipped` for the built-in model.
        file: PathBuf,
    },
    /// Simulate the light-side exit law f(α; μ_cam, μ_l) of a medium from half-space random
    /// walks (bssrdf::exit) and write it as JSON. The defaults reproduce the table built into
    /// the binary for g = 0, η = 1 (crates/tables/data/exit-g0-eta1.json).
    #[command(name = "exit-table")]
    ExitTable(WalkTableArgs),
    /// Simulate the light-side incidence factor A(α; μ_l, ρ, ψ) of a medium (where light that
    /// entered obliquely leaves, relative to its direction; bssrdf::incidence) from half-space
    /// random walks and write it as JSON. The defaults reproduce the table built into the binary
    /// for g = 0, η = 1 (crates/tables/data/incidence-g0-eta1.json).
    #[command(name = "incidence-table")]
    IncidenceTable(WalkTableArgs),
    /// Simulate the light side's curvature correction C = exact/model on balls of the paper's
    /// media (g = 0, η = 1; bssrdf::curvature) and write it as JSON. The defaults reproduce the
    /// table built into the binary (crates/tables/data/curvature-g0-eta1.json).
    #[command(name = "curvature-table")]
    CurvatureTable {
        /// Output file (.json).
        out: PathBuf,
        /// Collisions per batch (albedo, camera cosine, curvature).
        #[arg(long, default_value_t = 1_000_000)]
        collisions: u64,
        /// Seed of the walks.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Replace OUT if it exists.
        #[arg(long)]
        overwrite: bool,
    },
}

/// Options of `model exit-table` and `model incidence-table`.
#[derive(clap::Args)]
pub struct WalkTableArgs {
    /// Output file (.json).
    out: PathBuf,
    /// Henyey–Greenstein g.
    #[arg(long, default_value_t = 0.0)]
    g: f32,
    /// Relative index of refraction n_inside/n_outside (≥ 1).
    #[arg(long, default_value_t = 1.0)]
    eta: f32,
    /// GGX roughness α of the boundary (0 = smooth; exit tables only, with --eta above 1).
    #[arg(long, default_value_t = 0.0)]
    roughness: f32,
    /// Walks per albedo and cosine bin.
    #[arg(long, default_value_t = 1_000_000)]
    walks: u32,
    /// Seed of the walks.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Replace OUT if it exists.
    #[arg(long)]
    overwrite: bool,
}

/// Which half-space table `model exit-table` / `model incidence-table` writes.
#[derive(Clone, Copy)]
enum WalkTable {
    Exit,
    Incidence,
}

pub fn run(cmd: &ModelCommand) -> Result<()> {
    match cmd {
        ModelCommand::ImportSon24 {
            dir,
            out,
            overwrite,
        } => import_son24(dir, out, *overwrite),
        ModelCommand::Info { file } => info(file),
        ModelCommand::ExitTable(args) => walk_table(WalkTable::Exit, args),
        ModelCommand::IncidenceTable(args) => walk_table(WalkTable::Incidence, args),
        ModelCommand::CurvatureTable {
            out,
            collisions,
            seed,
            overwrite,
        } => curvature_table(out, *collisions, *seed, *overwrite),
    }
}

fn curvature_table(
    out: &std::path::Path,
    collisions: u64,
    seed: u64,
    overwrite: bool,
) -> Result<()> {
    if collisions == 0 {
        bail!("--collisions must be at least 1");
    }
    let t0 = std::time::Instant::now();
    let table = bssrdf::curvature::CurvatureTable::generate(bssrdf::curvature::CurvatureSettings {
        g: 0.0,
        collisions,
        seed,
    })
    .rounded(4);
    write_table(
        out,
        &serde_json::to_string(&table)?,
        overwrite,
        &format!("curvature table ({collisions} collisions per batch)"),
        t0,
    )
}

/// Writes a simulated table's JSON to `out` (atomically) and reports `what` and the time since
/// `t0`.
fn write_table(
    out: &std::path::Path,
    json: &str,
    overwrite: bool,
    what: &str,
    t0: std::time::Instant,
) -> Result<()> {
    scene::fsutil::atomic_write(out, json.as_bytes(), overwrite)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!(
        "{what} in {:.1} s -> {}",
        t0.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}

fn walk_table(kind: WalkTable, args: &WalkTableArgs) -> Result<()> {
    let &WalkTableArgs {
        ref out,
        g,
        eta,
        roughness,
        walks,
        seed,
        overwrite,
    } = args;
    if !(g > -1.0 && g < 1.0) {
        bail!("--g {g}: the Henyey–Greenstein g must lie in (−1, 1)");
    }
    if !(eta >= 1.0 && eta.is_finite()) {
        bail!("--eta {eta}: the relative index of refraction must be ≥ 1");
    }
    if !(0.0..=1.0).contains(&roughness) || (roughness > 0.0 && eta <= 1.0) {
        bail!(
            "--roughness {roughness}: the GGX roughness must lie in [0, 1], and be 0 unless --eta is above 1"
        );
    }
    if roughness > 0.0 && matches!(kind, WalkTable::Incidence) {
        bail!(
            "--roughness {roughness}: the incidence table's walks cross a smooth boundary; fix: leave out --roughness"
        );
    }
    if walks == 0 {
        bail!("--walks must be at least 1");
    }
    let t0 = std::time::Instant::now();
    let (json, name) = match kind {
        WalkTable::Exit => (
            serde_json::to_string(&bssrdf::exit::ExitTable::generate(
                bssrdf::exit::ExitTableSettings {
                    g,
                    eta,
                    roughness,
                    walks,
                    seed,
                },
            ))?,
            "exit",
        ),
        WalkTable::Incidence => (
            serde_json::to_string(
                &bssrdf::incidence::IncidenceTable::generate(
                    bssrdf::incidence::IncidenceSettings {
                        g,
                        eta,
                        roughness: 0.0,
                        walks,
                        seed,
                    },
                )
                .rounded(4),
            )?,
            "incidence",
        ),
    };
    write_table(
        out,
        &json,
        overwrite,
        &format!("{name} table (g = {g}, η = {eta}, {walks} walks per row)"),
        t0,
    )
}

/// Golden values of the reference README (plane p = u_z, α = 0.9, g = 0, η = 1, z = 0).
const GOLDEN_INPUTS: [f32; 3] = [-0.67780, -1.13785, -0.5];
const GOLDEN_ABSORB: f32 = 0.54834;
const GOLDEN_DECODE: [f32; 3] = [0.03295, 0.00027, 0.05841];
const GOLDEN_TOLERANCE: f32 = 1e-4;

/// Outputs of a model on the plane case.
struct PlaneCase {
    /// Normalised inputs 20..22 (α_eff, g, η).
    inputs: [f32; 3],
    absorb: f32,
    decode: [f32; 3],
}

/// Effective albedo α_eff(a) = −ln(1 − a(1 − e⁻⁸))/8 (docs/model.md §2).
fn eff_albedo(a: f64) -> f64 {
    -(1.0 - a * (1.0 - (-8.0f64).exp())).ln() / 8.0
}

/// The plane case of the reference README: light-space polynomial p(u) = u_z (coefficient 3 is
/// 1, the others 0), α = 0.9, g = 0 (so α' = α), η = 1; the decoder at z = 0.
fn plane_case(m: &ShapeAdaptiveModel) -> Result<PlaneCase> {
    let mut poly = [0.0f32; N_POLY];
    poly[3] = 1.0;
    let x: [f32; INPUT_DIM] = m
        .normalisation()
        .inputs(&poly, eff_albedo(0.9) as f32, 0.0, 1.0);
    let mut ws = Workspace::new();
    let mut f = vec![0.0; m.feature_dim()];
    m.features_with(&[x], &mut f, &mut ws)?;
    let mut a = [0.0f32];
    m.absorb_with(&f, &mut a, &mut ws)?;
    let mut y = [[0.0f32; 3]];
    m.decode_with(&f, &[[0.0; 4]], &[0], &mut y, &mut ws)?;
    Ok(PlaneCase {
        inputs: [x[ALBEDO_INPUT], x[ALBEDO_INPUT + 1], x[ETA_INPUT]],
        absorb: a[0],
        decode: y[0],
    })
}

fn import_son24(dir: &Path, out: &Path, overwrite: bool) -> Result<()> {
    if out.exists() && !overwrite {
        bail!("{} exists; pass --overwrite to replace it", out.display());
    }
    let m = bssrdf::son24::import(dir)?;
    m.save(out)?;
    // Check the file as written, not the model in memory.
    let back = model::load(out).with_context(|| format!("reloading {}", out.display()))?;
    println!(
        "imported {} -> {} ({} render-time parameters)",
        dir.display(),
        out.display(),
        back.render_params()
    );
    let p = plane_case(&back)?;
    println!("golden check: plane p(u) = u_z, alpha 0.9, g 0, eta 1, decoder at z = 0");
    println!(
        "  {:<28} {:>10} {:>10} {:>10}",
        "quantity", "ours", "golden", "|diff|"
    );
    let mut rows: Vec<(String, f32, f32)> = Vec::new();
    for (i, name) in ["input[20] (albedo)", "input[21] (g)", "input[22] (eta)"]
        .iter()
        .enumerate()
    {
        rows.push((name.to_string(), p.inputs[i], GOLDEN_INPUTS[i]));
    }
    rows.push(("Absorb".to_string(), p.absorb, GOLDEN_ABSORB));
    for (i, c) in ["x", "y", "z"].iter().enumerate() {
        rows.push((format!("decode(z = 0).{c}"), p.decode[i], GOLDEN_DECODE[i]));
    }
    let mut worst = 0.0f32;
    for (name, ours, golden) in &rows {
        let d = (ours - golden).abs();
        worst = worst.max(d);
        let flag = if d > GOLDEN_TOLERANCE {
            "  <-- MISMATCH"
        } else {
            ""
        };
        println!("  {name:<28} {ours:>10.6} {golden:>10.5} {d:>10.1e}{flag}");
    }
    if worst > GOLDEN_TOLERANCE || !worst.is_finite() {
        std::fs::remove_file(out).ok();
        bail!(
            "golden check failed (largest difference {worst:.1e} > {GOLDEN_TOLERANCE:.0e}); {} \
             was removed. Is DIR the son24_light folder with its own data_stats.json?",
            out.display()
        );
    }
    println!("golden check passed (largest difference {worst:.1e} <= {GOLDEN_TOLERANCE:.0e})");
    Ok(())
}

fn info(file: &Path) -> Result<()> {
    let m = cmdline::load_model_arg(file)?;
    let i = m.info();
    println!(
        "model file    {} ({FORMAT_NAME} v{FORMAT_VERSION})",
        file.display()
    );
    println!(
        "conventions   frame {}, c_19 quirk {}",
        i.frame_convention.name(),
        if i.c19_quirk {
            "yes (world z^3 coefficient dropped)"
        } else {
            "no"
        }
    );
    let counts = model::parameter_counts(&m);
    let count = |name: &str| counts.iter().find(|c| c.0 == name).map_or(0, |c| c.1);
    println!("architecture  (ReLU hidden layers, latent dim 4, {INPUT_DIM} inputs)");
    println!(
        "  feature     {:<34} {:>7} parameters",
        format!("{} (ReLU on all)", model::widths_string(m.feature_mlp())),
        count("feature")
    );
    println!(
        "  absorption  {:<34} {:>7}",
        format!("{}, sigmoid", model::widths_string(m.absorption_mlp())),
        count("absorption")
    );
    println!(
        "  decoder     {:<34} {:>7}",
        format!("[z(4) + f] {}", model::widths_string(m.decoder())),
        count("decoder")
    );
    match m.encoder() {
        Some(e) => println!(
            "  encoder     {:<34} {:>7}",
            format!("[x(3) + f] {} -> (4, 4)", model::widths_string(e.hidden())),
            count("encoder")
        ),
        None => println!("  encoder     none (render-only model)"),
    }
    println!("  render-time total {:>36}", m.render_params());
    let n = m.normalisation();
    println!("normalisation");
    println!(
        "  albedo      (alpha_eff - {:.6}) * {:.6}",
        n.eff_albedo_mean, n.eff_albedo_stdinv
    );
    println!("  g           (g - {:.6}) * {:.6}", n.g_mean, n.g_stdinv);
    println!("  eta         2 * (eta - 1.25)");
    println!("  poly mean   {}", fmt_list(&n.poly_mean));
    println!("  poly stdinv {}", fmt_list(&n.poly_stdinv));
    println!("provenance");
    let text = serde_json::to_string_pretty(&i.provenance)?;
    for line in text.lines() {
        println!("  {line}");
    }
    let p = plane_case(&m)?;
    println!(
        "plane case    (p = u_z, alpha 0.9, g 0, eta 1): inputs[20..22] = {}, Absorb = {:.5}, \
         decode(z = 0) = {}",
        fmt_list(&p.inputs),
        p.absorb,
        fmt_list(&p.decode)
    );
    Ok(())
}

fn fmt_list(v: &[f32]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:.5}")).collect();
    format!("[{}]", items.join(", "))
}
