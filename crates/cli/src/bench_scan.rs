//! `translucent bench loss-scan`: where the learned renderer's loss has its minimum, without an
//! optimiser.
//!
//! For a dataset with a known medium (its truth), the learned renderer draws the first `--views`
//! views at the truth with σ_t scaled by each `--scales` factor (all channels, α at the truth),
//! with the polynomial features fitted at that medium, twice with independent random numbers
//! (seeds `seed` and `seed + 1`). Per channel it reports
//!
//! * the decorrelated loss L = Σ (I₁ − T)(I₂ − T) over the views' pixels, an unbiased estimate
//!   of Σ (E[I] − T)²: a plain L2 of one render adds the render's own variance, which grows as
//!   σ_t falls and would put the minimum at the truth by itself (BENCHMARKS.md, session 16);
//! * the brightness ratio Σ ½(I₁ + I₂) / Σ T.
//!
//! A renderer that agrees with the targets has its minimum at scale 1. `--entry-sampler walks`
//! replaces the decoder by the walks it imitates ([`bssrdf::render::EntrySampler`]), so the two
//! scans separate the decoder's share of the error from the rest of the model (session 29).
//! Writes `OUT/loss-scan.csv`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use scene::{Dataset, Image};

use crate::common::{LearnedArgs, build_accel, render_views_learned};

#[derive(Args)]
pub struct LossScanArgs {
    /// Dataset folder (ours or a Mitsuba reference folder) whose medium is known.
    #[arg(long)]
    pub dataset: PathBuf,
    /// Factors applied to the true σ_t (all channels).
    #[arg(long, value_delimiter = ',', default_value = "0.8,0.9,1,1.1,1.2")]
    pub scales: Vec<f32>,
    /// Number of views used (the first ones).
    #[arg(long, default_value_t = 12)]
    pub views: usize,
    /// Samples per pixel of each of the two renders.
    #[arg(long, default_value_t = 32)]
    pub spp: u32,
    #[command(flatten)]
    pub learned: LearnedArgs,
    /// Output folder.
    #[arg(long, default_value = "out/bench-loss-scan")]
    pub out: PathBuf,
    /// Seed of the first render (the second uses seed + 1).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Replace existing outputs.
    #[arg(long)]
    pub overwrite: bool,
}

/// Per channel: Σ (a − t)(b − t) and Σ ½(a + b) / Σ t over the pixels of every image triple.
pub fn decorrelated_loss(a: &[Image], b: &[Image], t: &[Image]) -> ([f64; 3], [f64; 3]) {
    let (mut l, mut s, mut st) = ([0.0f64; 3], [0.0f64; 3], [0.0f64; 3]);
    for ((ia, ib), it) in a.iter().zip(b).zip(t) {
        for ((pa, pb), pt) in ia.data.iter().zip(&ib.data).zip(&it.data) {
            for c in 0..3 {
                let (x, y, z) = (pa[c] as f64, pb[c] as f64, pt[c] as f64);
                l[c] += (x - z) * (y - z);
                s[c] += 0.5 * (x + y);
                st[c] += z;
            }
        }
    }
    (l, std::array::from_fn(|c| s[c] / st[c]))
}

pub fn run(a: &LossScanArgs) -> Result<()> {
    anyhow::ensure!(a.spp > 0, "--spp must be at least 1");
    anyhow::ensure!(
        a.scales.iter().all(|s| s.is_finite() && *s > 0.0),
        "--scales must be positive factors of the true σ_t"
    );
    let ds = Dataset::load(&a.dataset)?;
    let Some(truth) = ds.truth else {
        bail!(
            "{}: the dataset records no medium (truth); the scan needs one",
            a.dataset.display()
        )
    };
    let n = a.views.min(ds.views.len());
    anyhow::ensure!(n > 0, "--views must be at least 1");
    let mut targets = Vec::with_capacity(n);
    for (i, v) in ds.views.iter().take(n).enumerate() {
        let Some(img) = &v.image else {
            bail!("{}: view {i} has no image", a.dataset.display())
        };
        targets.push(img.clone());
    }
    let views: Vec<_> = ds.views.iter().take(n).map(|v| v.desc()).collect();
    let (mesh, warnings) = ds
        .load_mesh()
        .with_context(|| format!("loading the mesh of {}", a.dataset.display()))?;
    let accel = build_accel(mesh, &warnings, &ds.mesh.describe());
    let model = a.learned.load_model()?;
    println!("{}; {n} views, 2 × {} spp", a.learned.describe(), a.spp);
    println!(
        "{:>7} | {:>30} | {:>24}",
        "σ_t ×", "decorrelated loss (R, G, B)", "brightness (R, G, B)"
    );
    let mut csv =
        String::from("scale,loss_r,loss_g,loss_b,brightness_r,brightness_g,brightness_b\n");
    for &s in &a.scales {
        let mut m = truth;
        m.sigma_t = m.sigma_t.map(|v| v * s);
        let render = |seed| {
            render_views_learned(
                &accel,
                &m,
                &views,
                a.spp,
                seed,
                &model,
                a.learned.settings(),
            )
        };
        let (r1, r2) = (render(a.seed)?, render(a.seed + 1)?);
        let (l, b) = decorrelated_loss(&r1.images, &r2.images, &targets);
        println!(
            "{s:>7.3} | {:>9.2} {:>9.2} {:>9.2} | {:>7.4} {:>7.4} {:>7.4}",
            l[0], l[1], l[2], b[0], b[1], b[2]
        );
        csv.push_str(&format!(
            "{s},{},{},{},{},{},{}\n",
            l[0], l[1], l[2], b[0], b[1], b[2]
        ));
    }
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let path = a.out.join("loss-scan.csv");
    scene::fsutil::atomic_write(&path, csv.as_bytes(), a.overwrite)?;
    println!("wrote {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(v: [f32; 3]) -> Image {
        let mut im = Image::new(2, 1);
        im.data.iter_mut().for_each(|p| *p = v);
        im
    }

    /// Two renders with opposite noise around the target-plus-bias: the cross term keeps the
    /// bias² and cancels the noise; identical renders give the plain squared error.
    #[test]
    fn decorrelated_loss_removes_independent_noise() {
        let t = [image([1.0, 2.0, 4.0])];
        let a = [image([1.5, 2.0, 4.25])];
        let b = [image([1.1, 2.0, 3.75])];
        let (l, bright) = decorrelated_loss(&a, &b, &t);
        // (0.5)(0.1)·2 pixels, 0, (0.25)(−0.25)·2.
        assert!((l[0] - 0.1).abs() < 1e-6 && l[1] == 0.0 && (l[2] + 0.125).abs() < 1e-6);
        assert!((bright[0] - 1.3).abs() < 1e-6 && (bright[2] - 1.0).abs() < 1e-6);
        let (l2, _) = decorrelated_loss(&a, &a, &t);
        assert!((l2[0] - 0.5).abs() < 1e-6);
    }
}
