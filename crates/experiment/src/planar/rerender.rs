//! The first view of a case re-rendered by the volumetric path tracer at the truth and at each
//! method's estimate, and the figures that compare them (the module docs of
//! [`super`](crate::planar), "Re-renders").

use std::fmt::Write as _;
use std::path::Path;

use inverse::consistency::CheckView;
use recovery::Observer;
use scene::{Image, Medium};
use serde::{Deserialize, Serialize};

use crate::error::{Context, Result};
use crate::report::Row;

/// The label of the noise-floor row: the truth rendered again with another seed.
pub const FLOOR: &str = "truth (another seed)";

/// One re-render against the truth's, per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Compared {
    pub case: String,
    /// A method, or [`FLOOR`].
    pub method: String,
    /// Σ I / Σ I_T.
    pub brightness: [f64; 3],
    /// √(Σ (I − I_T)² / Σ I_T²).
    pub rel_rms: [f64; 3],
    /// The same after scaling I to the truth's brightness, √(Σ (I/m − I_T)² / Σ I_T²) with m
    /// the brightness ratio: what differs besides the overall brightness (the spread of the
    /// light, its contrast), plus noise.
    pub rel_rms_shape: [f64; 3],
}

/// A case's re-renders: the figure (truth, then each method), its exposure and the comparisons.
pub struct CaseRerenders {
    pub figure: Image,
    pub exposure: f32,
    pub rows: Vec<Compared>,
}

/// What a kept re-render was made with; a render is reused only when all of it matches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Made {
    medium: Medium,
    spp: u32,
    seed: u64,
    max_depth: u32,
    view: usize,
}

/// The re-renders of `case` (runs `rows`, datasets in `out/data`) at `spp`: the truth with
/// seeds s and s + 1, each estimate with seed s.
pub fn case(
    out: &Path,
    case: &str,
    rows: &[&Row],
    spp: u32,
    seed: u64,
    obs: &dyn Observer,
) -> Result<CaseRerenders> {
    let data = out.join("data").join(case);
    let ds = scene::Dataset::load(&data)?;
    let truth = ds
        .truth
        .with_context(|| format!("{}: the dataset records no truth medium", data.display()))?;
    let view = ds
        .views
        .first()
        .with_context(|| format!("{}: the dataset has no views", data.display()))?;
    let target = view
        .image
        .as_ref()
        .with_context(|| format!("{}: the dataset has no images", data.display()))?;
    let (mesh, warnings) = ds.load_mesh()?;
    let accel = inverse::views::build_accel(mesh, &warnings, &data.display().to_string());
    let check = CheckView {
        camera: &view.camera,
        light: &view.light,
        target,
        index: 0,
    };
    let max_depth = ds.render.max_depth.unwrap_or(volpath::DEFAULT_MAX_DEPTH);
    let dir = out.join("rerenders");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let seed = seed ^ 0x5E_4E4D;
    let render = |label: &str, medium: Medium, seed: u64| -> Result<Image> {
        let name: String = label
            .chars()
            .filter(|c| c.is_ascii_alphanumeric() || *c == '-')
            .collect();
        let file = dir.join(format!("{case}-{name}.exr"));
        let made = Made {
            medium,
            spp,
            seed,
            max_depth,
            view: 0,
        };
        let made_file = file.with_extension("json");
        let kept = std::fs::read(&made_file)
            .ok()
            .and_then(|b| serde_json::from_slice::<Made>(&b).ok());
        if kept.as_ref() == Some(&made)
            && let Ok(img) = Image::read_exr(&file)
        {
            return Ok(img);
        }
        let pb = obs.progress(0, &format!("re-rendering {case}: {label} ({spp} spp)"));
        let img = check.trace(&accel, &medium, max_depth, |view, rs| {
            view.value(&rs(spp, seed), None)
        })?;
        pb.finish_and_clear();
        img.write_exr(&file, true)?;
        scene::fsutil::atomic_write(&made_file, &serde_json::to_vec_pretty(&made)?, true)?;
        Ok(img)
    };
    let reference = render("truth", truth, seed)?;
    let floor = render(FLOOR, truth, seed + 1)?;
    let mut images = vec![reference.clone()];
    let mut compared = vec![compare(case, FLOOR, &floor, &reference)];
    for r in rows {
        let img = render(&r.method, r.estimate.medium(&truth), seed)?;
        compared.push(compare(case, &r.method, &img, &reference));
        images.push(img);
    }
    let exposure = scene::image::auto_exposure(&images);
    let tiles: Vec<&Image> = images.iter().collect();
    Ok(CaseRerenders {
        figure: Image::grid(&[tiles], 0),
        exposure,
        rows: compared,
    })
}

/// `img` against the truth's re-render `reference` (module docs of [`super`]).
pub fn compare(case: &str, method: &str, img: &Image, reference: &Image) -> Compared {
    let pairs = || img.data.iter().zip(&reference.data);
    let sum = |f: &dyn Fn(f64, f64) -> f64| -> [f64; 3] {
        std::array::from_fn(|c| pairs().map(|(p, q)| f(p[c] as f64, q[c] as f64)).sum())
    };
    let (s, st) = (sum(&|x, _| x), sum(&|_, t| t));
    let t2 = sum(&|_, t| t * t);
    let brightness: [f64; 3] = std::array::from_fn(|c| s[c] / st[c]);
    let d2 = sum(&|x, t| (x - t) * (x - t));
    let shape: [f64; 3] = std::array::from_fn(|c| {
        let m = brightness[c];
        pairs()
            .map(|(p, q)| (p[c] as f64 / m - q[c] as f64).powi(2))
            .sum()
    });
    Compared {
        case: case.into(),
        method: method.into(),
        brightness,
        rel_rms: std::array::from_fn(|c| (d2[c] / t2[c]).sqrt()),
        rel_rms_shape: std::array::from_fn(|c| (shape[c] / t2[c]).sqrt()),
    }
}

/// The Markdown table of the comparisons.
pub fn table(rows: &[Compared], spp: u32) -> String {
    let mut s = format!(
        "First view re-rendered by the volumetric path tracer at {spp} spp, against the truth's \
         re-render (same seed; `{FLOOR}`: the truth with another seed, the noise floor)\n\n\
         | case | re-render | brightness ratio (R, G, B) | relative RMS difference % (R, G, B) | \
         the same at equal brightness % |\n\
         |---|---|---|---|---|\n"
    );
    for r in rows {
        let pct = |v: &[f64; 3]| join(v, |x| format!("{:.1}", 100.0 * x), ", ");
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            r.case,
            r.method,
            join(&r.brightness, |x| format!("{x:.3}"), ", "),
            pct(&r.rel_rms),
            pct(&r.rel_rms_shape)
        );
    }
    s
}

/// The comparisons as CSV.
pub fn csv(rows: &[Compared], spp: u32) -> String {
    let mut s = String::from(
        "case,rerender,spp,brightness_r,brightness_g,brightness_b,rel_rms_r,rel_rms_g,rel_rms_b,\
         rel_rms_shape_r,rel_rms_shape_g,rel_rms_shape_b\n",
    );
    for r in rows {
        let values = [r.brightness, r.rel_rms, r.rel_rms_shape].concat();
        let _ = writeln!(
            s,
            "{},{},{spp},{}",
            r.case,
            r.method,
            join(&values, |x| x.to_string(), ",")
        );
    }
    s
}

/// `values`, each formatted by `f`, separated by `sep`.
fn join(values: &[f64], f: impl Fn(f64) -> String, sep: &str) -> String {
    values.iter().map(|&x| f(x)).collect::<Vec<_>>().join(sep)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(v: [f32; 3]) -> Image {
        let mut img = Image::new(2, 2);
        img.data.fill(v);
        img
    }

    #[test]
    fn compare_measures_brightness_and_difference_against_the_reference() {
        let reference = image([1.0, 2.0, 4.0]);
        let same = compare("c", "m", &reference, &reference);
        assert_eq!(same.brightness, [1.0; 3]);
        assert_eq!(same.rel_rms, [0.0; 3]);
        let r = compare("c", "m", &image([1.5, 2.0, 2.0]), &reference);
        assert_eq!(r.brightness, [1.5, 1.0, 0.5]);
        assert_eq!(r.rel_rms, [0.5, 0.0, 0.5]);
        // A uniform scale is all brightness, no shape.
        assert_eq!(r.rel_rms_shape, [0.0; 3]);
        // Half the image twice as bright, the other half as before: brightness 1.5, and at
        // equal brightness the halves are 4/3 and 2/3 of the truth: √((1/9 + 1/9)/2) = 1/3.
        let mut uneven = reference.clone();
        uneven.data[0] = [2.0, 4.0, 8.0];
        uneven.data[1] = [2.0, 4.0, 8.0];
        let r = compare("c", "m", &uneven, &reference);
        for c in 0..3 {
            assert!((r.brightness[c] - 1.5).abs() < 1e-12);
            assert!(
                (r.rel_rms_shape[c] - 1.0 / 3.0).abs() < 1e-12,
                "{:?}",
                r.rel_rms_shape
            );
        }
    }

    #[test]
    fn the_csv_has_a_row_per_comparison_under_its_header() {
        let rows = [
            compare("c", FLOOR, &image([1.0; 3]), &image([1.0; 3])),
            compare("c", "ours", &image([2.0; 3]), &image([1.0; 3])),
        ];
        let csv = csv(&rows, 8);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[2], "c,ours,8,2,2,2,1,1,1,0,0,0");
        assert!(
            table(&rows, 8).contains(
                "| c | ours | 2.000, 2.000, 2.000 | 100.0, 100.0, 100.0 | 0.0, 0.0, 0.0 |"
            )
        );
    }
}
