//! `translucent compare A B`: per-view, per-channel image statistics of A against B (B is the
//! reference): mean ratio mean(A)/mean(B), RMSE, relative MSE Σ(A − B)² / Σ(B² + 1e-2·mean(B)²)
//! (the pbrt `imgtool diff` relMSE with a floor that keeps dark pixels from dominating), and an
//! optional false-colour difference PNG per view.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use scene::Image;

use scene::image::{PairStats, pair_stats};

/// Expand a path into the list of EXR files it names: the file itself, or every `*.exr` of a
/// folder sorted by name.
pub fn exr_list(path: &Path) -> Result<Vec<PathBuf>> {
    if path.is_dir() {
        let mut v: Vec<PathBuf> = std::fs::read_dir(path)
            .with_context(|| format!("{}: cannot list folder", path.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")))
            .collect();
        v.sort();
        if v.is_empty() {
            bail!("{}: folder contains no .exr images", path.display());
        }
        Ok(v)
    } else if path.exists() {
        Ok(vec![path.to_path_buf()])
    } else {
        bail!("{}: no such file or folder", path.display())
    }
}

/// Run the command: prints a table, writes diff PNGs into `diff_dir` when given.
pub fn run(
    a: &Path,
    b: &Path,
    diff_dir: Option<&Path>,
    overwrite: bool,
) -> Result<Vec<(String, PairStats)>> {
    let la = exr_list(a)?;
    let lb = exr_list(b)?;
    let pairs: Vec<(PathBuf, PathBuf)> = if la.len() == 1 && lb.len() == 1 {
        vec![(la[0].clone(), lb[0].clone())]
    } else {
        // Match by file name.
        let mut v = Vec::new();
        for pa in &la {
            let name = pa.file_name().unwrap();
            let pb = lb.iter().find(|p| p.file_name() == Some(name));
            match pb {
                Some(pb) => v.push((pa.clone(), pb.clone())),
                None => bail!(
                    "{}: no image named {:?} in {}",
                    pa.display(),
                    name,
                    b.display()
                ),
            }
        }
        v
    };
    if let Some(d) = diff_dir {
        std::fs::create_dir_all(d)
            .with_context(|| format!("{}: cannot create folder", d.display()))?;
    }
    println!(
        "{:<16} {:>26} {:>26} {:>26}",
        "image", "mean ratio A/B (R G B)", "relative RMSE (R G B)", "relMSE (R G B)"
    );
    let mut out = Vec::new();
    for (pa, pb) in pairs {
        let ia = Image::read_exr(&pa)?;
        let ib = Image::read_exr(&pb)?;
        let st = pair_stats(&ia, &ib)
            .with_context(|| format!("comparing {} with {}", pa.display(), pb.display()))?;
        let name = pa.file_stem().unwrap().to_string_lossy().to_string();
        println!(
            "{:<16} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.2e} {:>8.2e} {:>8.2e}",
            name,
            st.mean_ratio[0],
            st.mean_ratio[1],
            st.mean_ratio[2],
            st.rel_rmse[0],
            st.rel_rmse[1],
            st.rel_rmse[2],
            st.rel_mse[0],
            st.rel_mse[1],
            st.rel_mse[2]
        );
        if let Some(d) = diff_dir {
            let diff = Image::false_colour_diff(&ia, &ib)?;
            diff.write_png(&d.join(format!("{name}_diff.png")), 1.0, overwrite)?;
        }
        out.push((name, st));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_scaled_image() {
        let mut b = Image::new(4, 4);
        for (i, p) in b.data.iter_mut().enumerate() {
            *p = [i as f32 + 1.0, 2.0, 0.0];
        }
        let a = b.scaled(1.1);
        let st = pair_stats(&a, &b).unwrap();
        assert!((st.mean_ratio[0] - 1.1).abs() < 1e-6);
        assert!((st.mean_ratio[1] - 1.1).abs() < 1e-6);
        assert_eq!(st.mean_ratio[2], 1.0);
        assert!((st.rmse[1] - 0.2).abs() < 1e-6);
        assert!(pair_stats(&a, &Image::new(2, 2)).is_err());
    }
}
