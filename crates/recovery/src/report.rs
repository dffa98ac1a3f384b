//! Outputs of an inverse run: the per-iteration CSV, the result JSON and the convergence plots.

use std::fmt::Write as _;
use std::path::Path;

use scene::image::Image;
use serde_json::json;

use inverse::optimize::{InverseError, IterationRecord, OptimizeConfig};
use inverse::params::{OneOrRgb, Params};

const CHANNELS: [&str; 3] = ["R", "G", "B"];

pub mod advice;
mod convergence;
mod intervals;
mod units;

#[cfg(test)]
use convergence::relative_loss_series;
pub use convergence::{relative_loss, write_plots};
pub use intervals::interval_lines;
pub use units::real_units;

/// `iterations.csv`: one row per iteration (parameters before the step, loss, gradient).
/// A run that recovers g has two more columns at the end: g and ∂ℓ/∂g (empty in the
/// iterations whose model holds g), or six with one g per channel (g_r, g_g, g_b, then
/// ∂ℓ/∂g_c); one that recovers the light scale two more: k and ∂ℓ/∂ln k, or six with one scale
/// per channel (k_r, k_g, k_b, then ∂ℓ/∂ln k_c).
pub fn write_csv(history: &[IterationRecord], path: &Path) -> Result<(), InverseError> {
    let free_g = history.iter().any(|r| r.params.g.is_some());
    let g_rgb = (history.iter()).any(|r| matches!(r.params.g, Some(OneOrRgb::Rgb(_))));
    let free_k = history.iter().any(|r| r.params.light_scale.is_some());
    let k_rgb = (history.iter()).any(|r| matches!(r.params.light_scale, Some(OneOrRgb::Rgb(_))));
    let mut s = String::from(
        "iteration,loss,sigma_t_r,sigma_t_g,sigma_t_b,albedo_r,albedo_g,albedo_b,\
         d_sigma_t_r,d_sigma_t_g,d_sigma_t_b,d_albedo_r,d_albedo_g,d_albedo_b,views,seconds,crops,misfit",
    );
    s.push_str(match (free_g, g_rgb) {
        (false, _) => "",
        (true, false) => ",g,d_g",
        (true, true) => ",g_r,g_g,g_b,d_g_r,d_g_g,d_g_b",
    });
    s.push_str(match (free_k, k_rgb) {
        (false, _) => "\n",
        (true, false) => ",light_scale,d_ln_light_scale\n",
        (true, true) => {
            ",light_scale_r,light_scale_g,light_scale_b,\
             d_ln_light_scale_r,d_ln_light_scale_g,d_ln_light_scale_b\n"
        }
    });
    for r in history {
        let _ = write!(s, "{},{:.6e}", r.iteration, r.loss);
        for v in r.params.sigma_t.iter().chain(&r.params.albedo) {
            let _ = write!(s, ",{v:.6}");
        }
        for v in r.d_sigma_t.iter().chain(&r.d_albedo) {
            let _ = write!(s, ",{v:.6e}");
        }
        let views: Vec<String> = r.views.iter().map(|v| v.to_string()).collect();
        // Crop origins as `x0:y0`, one per view, space-separated (empty without `--crop`).
        let crops: Vec<String> = r
            .crop_origins
            .iter()
            .map(|[x, y]| format!("{x}:{y}"))
            .collect();
        // The noise-free misfit (empty where the run's gradient has none).
        let misfit = r.misfit.map(|m| format!("{m:.6e}")).unwrap_or_default();
        let _ = write!(
            s,
            ",{},{:.4},{},{misfit}",
            views.join(" "),
            r.seconds,
            crops.join(" ")
        );
        // One column per variable; empty where the iteration has none.
        let column = |v: Option<OneOrRgb<f64>>, c: usize, e: bool| {
            v.map(|v| match e {
                true => format!("{:.6e}", v.values()[c.min(v.values().len() - 1)]),
                false => format!("{:.6}", v.values()[c.min(v.values().len() - 1)]),
            })
            .unwrap_or_default()
        };
        if free_g {
            let cols = if g_rgb { 3 } else { 1 };
            for c in 0..cols {
                let _ = write!(s, ",{}", column(r.params.g, c, false));
            }
            for c in 0..cols {
                let _ = write!(s, ",{}", column(r.d_g, c, true));
            }
        }
        if free_k {
            let cols = if k_rgb { 3 } else { 1 };
            for c in 0..cols {
                let _ = write!(s, ",{}", column(r.params.light_scale, c, false));
            }
            for c in 0..cols {
                let _ = write!(s, ",{}", column(r.d_ln_light_scale, c, true));
            }
        }
        s.push('\n');
    }
    scene::fsutil::atomic_write(path, s.as_bytes(), true)?;
    Ok(())
}

/// Relative σ_t error and absolute α error per channel, and the paper-style RMSEs (σ_t in units
/// of 100, over the channels).
pub fn errors(est: &Params, truth: &Params) -> serde_json::Value {
    let rel: Vec<f64> = (0..3)
        .map(|c| est.sigma_t[c] / truth.sigma_t[c] - 1.0)
        .collect();
    let abs: Vec<f64> = (0..3).map(|c| est.albedo[c] - truth.albedo[c]).collect();
    let rmse = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let d100: Vec<f64> = (0..3)
        .map(|c| (est.sigma_t[c] - truth.sigma_t[c]) / 100.0)
        .collect();
    let mut out = json!({
        "sigma_t_relative": rel,
        "albedo_absolute": abs,
        "sigma_t_rmse_units_of_100": rmse(&d100),
        "sigma_t_rmse": 100.0 * rmse(&d100),
        "albedo_rmse": rmse(&abs),
    });
    if let (Some(e), Some(t)) = (est.g, truth.g) {
        out["g_absolute"] = json!(e.zip_with(t, |e, t| e - t));
    }
    out
}

/// `result.json`: estimate, truth and errors, the run's settings and timings.
pub fn result_json(
    config: &OptimizeConfig,
    history: &[IterationRecord],
    estimate: &Params,
    truth: Option<&Params>,
    seconds_total: f64,
) -> serde_json::Value {
    let iters = history.len().max(1) as f64;
    let per_iter: f64 = history.iter().map(|r| r.seconds).sum::<f64>() / iters;
    json!({
        "estimate": estimate,
        "truth": truth,
        "errors": truth.map(|t| errors(estimate, t)),
        "initial": config.init,
        "iterations": history.len(),
        "spp": config.spp,
        "views_per_iteration": config.views_per_iter,
        "seconds_per_iteration": per_iter,
        "seconds_total": seconds_total,
        "method": config.model.estimator_name(),
        "seed": config.seed,
        "final_loss": history.last().map(|r| r.loss),
        "config": config,
    })
}

/// Adds `status` ("ok" or "failed"), `problems` and, when computed, `interval95`,
/// `determined` and `uncertainty` to a `result.json` value.
pub fn add_assessment(
    result: &mut serde_json::Value,
    problems: &[inverse::health::Problem],
    uncertainty: Option<&inverse::uncertainty::Uncertainty>,
) {
    let obj = result.as_object_mut().expect("result.json is an object");
    obj.insert(
        "status".into(),
        json!(if problems.is_empty() { "ok" } else { "failed" }),
    );
    obj.insert("problems".into(), json!(problems));
    if let Some(serde_json::Value::Object(m)) = uncertainty.map(|u| u.to_json()) {
        obj.extend(m);
    }
}

/// Largest side of one tile of the contact sheet, in pixels.
pub const CONTACT_TILE: u32 = 128;

/// The contact sheet of a run: for every view its target, its re-render at the estimate and
/// the signed difference (re-render − target, blue–white–red at one range shared by all views),
/// side by side; [`CONTACT_COLUMNS`] views per row. Targets and re-renders are scaled by
/// `exposure`; tiles are box-filtered to at most [`CONTACT_TILE`] pixels a side. The image is
/// meant for [`Image::write_png`] at exposure 1.
pub fn contact_sheet(
    targets: &[&Image],
    renders: &[&Image],
    exposure: f32,
) -> Result<Image, InverseError> {
    if targets.len() != renders.len() || targets.is_empty() {
        return Err(InverseError::Invalid(format!(
            "a contact sheet needs one re-render per target ({} targets, {} re-renders)",
            targets.len(),
            renders.len()
        )));
    }
    // One difference range for all views: the automatic range of all of them side by side.
    let row = |v: &[&Image]| Image::grid(&[v.to_vec()], 0);
    let (_, range) = Image::false_colour_diff_with_range(&row(renders), &row(targets), None)?;
    let mut tiles: Vec<Vec<Image>> = Vec::new();
    for (t, r) in targets.iter().zip(renders) {
        let (diff, _) = Image::false_colour_diff_with_range(r, t, Some(range))?;
        let factor = t.width.max(t.height).div_ceil(CONTACT_TILE).max(1);
        let small = |im: &Image| im.downsample(factor);
        tiles.push(vec![
            small(&t.scaled(exposure))?,
            small(&r.scaled(exposure))?,
            small(&diff)?,
        ]);
    }
    let rows: Vec<Vec<&Image>> = tiles
        .chunks(CONTACT_COLUMNS)
        .map(|views| views.iter().flatten().collect())
        .collect();
    Ok(Image::grid(&rows, 2))
}

/// Views per row of the contact sheet (three tiles each).
pub const CONTACT_COLUMNS: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed albedo stays fixed, without an interval, through the widening along the σ_t
    /// valley and through a correction, and reads as fixed in the report's interval lines.
    #[test]
    fn a_fixed_albedo_stays_fixed_and_reads_as_fixed() {
        use inverse::sensitivity::Sensitivity;
        use inverse::uncertainty::Uncertainty;
        let narrow = Some([0.02f64.powi(2), 0.0, 0.0]);
        let at = Params {
            sigma_t: [80.0; 3],
            albedo: [0.9; 3],
            g: None,
            light_scale: None,
        };
        let mut u = Uncertainty::new(at.sigma_t, at.albedo, [narrow; 3], [narrow; 3], 8);
        u.albedo = [None; 3];
        u.sd_albedo = [None; 3];
        u.determined_albedo = [false; 3];
        u.fixed = [false, true];
        let s = Sensitivity {
            slope: [0.0; 3],
            learned: [1.0; 3],
            volpath: [0.5; 3],
            volpath_se: [0.0; 3],
            ratio: [2.0; 3],
            views: vec![0],
            spp: 16,
        };
        let corrected = Params {
            sigma_t: [82.0; 3],
            ..at
        };
        for (what, v) in [
            ("widened", u.with_sensitivity(&at, &s)),
            ("corrected", u.corrected(&at, &corrected)),
        ] {
            assert_eq!(v.fixed, [false, true], "{what}");
            assert_eq!(v.albedo, [None; 3], "{what}");
            let lines = interval_lines(&at, &v).join("\n");
            assert!(lines.contains("α = 0.9000 (fixed)"), "{what}: {lines}");
            assert!(!lines.contains("α is NOT determined"), "{what}: {lines}");
            assert!(!lines.contains("no finite interval"), "{what}: {lines}");
        }
    }

    fn record(iteration: u32, view: usize, loss: f64) -> IterationRecord {
        IterationRecord {
            iteration,
            loss,
            params: Params {
                sigma_t: [50.0; 3],
                albedo: [0.5; 3],
                g: None,
                light_scale: None,
            },
            d_sigma_t: [0.0; 3],
            d_albedo: [0.0; 3],
            d_g: None,
            d_ln_light_scale: None,
            views: vec![view],
            crop_origins: vec![],
            seconds: 0.0,
            misfit: None,
        }
    }

    /// A run that keeps α fixed: α is shown as fixed, not as undetermined, and an open σ_t is
    /// not blamed on a trade with α.
    #[test]
    fn a_fixed_albedo_is_reported_as_fixed() {
        use inverse::uncertainty::Uncertainty;
        let wide = Some([0.3f64.powi(2), 0.0, 0.0]);
        let mut u = Uncertainty::new([72.0; 3], [0.9; 3], [wide; 3], [wide; 3], 4);
        (u.albedo, u.fixed) = ([None; 3], [false, true]);
        let est = Params {
            sigma_t: [72.0; 3],
            albedo: [0.9; 3],
            g: None,
            light_scale: None,
        };
        let text = interval_lines(&est, &u).join("\n");
        assert!(text.contains("α = 0.9000 (fixed)"), "{text}");
        assert!(!text.contains("α is NOT determined"), "{text}");
        assert!(text.contains("σ_t is NOT determined") && text.contains("with α fixed"));
        assert!(!text.contains("trades σ_t against α"), "{text}");
    }

    /// An interval spanning orders of magnitude prints as what it means, not as
    /// "[0.0, 358671928.4]"; bounds of moderately wide ones in scientific notation when small.
    #[test]
    fn a_decades_wide_interval_prints_as_what_it_means() {
        use inverse::uncertainty::Uncertainty;
        let narrow = Some([0.1f64.powi(2), 0.0, 1e-4]);
        let flat = Some([3.9f64.powi(2), 0.0, 1e-4]);
        let u = Uncertainty::new([70.3; 3], [0.9; 3], [narrow, flat, narrow], [narrow; 3], 4);
        let est = Params {
            sigma_t: [70.3; 3],
            albedo: [0.9; 3],
            g: None,
            light_scale: None,
        };
        let lines = interval_lines(&est, &u);
        assert!(lines[1].contains("σ_t = 70.3 [57.8, 85.5]"), "{}", lines[1]);
        assert!(
            lines[2].contains("σ_t = 70.3 [not determined: any value fits these images]"),
            "{}",
            lines[2]
        );
        let mut one_sided = u.clone();
        one_sided.sigma_t[1] = Some([20.0, 3.6e8]);
        one_sided.sigma_t[2] = Some([1.4e-5, 95.0]);
        let lines = interval_lines(&est, &one_sided);
        assert!(
            lines[2].contains("σ_t = 70.3 [not determined: anything above 20.0 fits"),
            "{}",
            lines[2]
        );
        assert!(
            lines[3].contains("σ_t = 70.3 [not determined: anything below 95.0 fits"),
            "{}",
            lines[3]
        );
        // Wide but within a factor 100 of the estimate: the numbers.
        one_sided.sigma_t[1] = Some([0.9, 5000.0]);
        let lines = interval_lines(&est, &one_sided);
        assert!(
            lines[2].contains("σ_t = 70.3 [0.9, 5000.0]"),
            "{}",
            lines[2]
        );
    }

    /// Five views of 40×30: two rows of sheet (four views of three tiles, then one), 2-pixel
    /// gaps; a view re-rendered exactly is white in the difference, and the difference scale is
    /// shared (the view with the larger error saturates, the smaller one does not).
    #[test]
    fn the_contact_sheet_shows_every_view_on_one_scale() {
        let img = |v: f32| {
            let mut i = Image::new(40, 30);
            for p in &mut i.data {
                *p = [v; 3];
            }
            i
        };
        let targets: Vec<Image> = (0..5).map(|_| img(0.5)).collect();
        let renders = [img(0.5), img(0.6), img(0.9), img(0.5), img(0.5)];
        let t: Vec<&Image> = targets.iter().collect();
        let r: Vec<&Image> = renders.iter().collect();
        let sheet = contact_sheet(&t, &r, 1.0).unwrap();
        assert_eq!((sheet.width, sheet.height), (12 * 40 + 11 * 2, 2 * 30 + 2));
        // The difference tile of view v (row v / 4, column v % 4).
        let diff = |v: usize| {
            let x = ((v % 4) * 3 + 2) as u32 * 42 + 20;
            let y = (v / 4) as u32 * 32 + 15;
            sheet.get(x, y)
        };
        assert_eq!(diff(0), [1.0; 3], "no difference: white");
        assert_eq!(diff(4), [1.0; 3]);
        assert_eq!(diff(2), [1.0, 0.0, 0.0], "the largest error saturates red");
        let p = diff(1);
        assert!(
            p[0] == 1.0 && p[1] > 0.6 && p[1] < 0.8,
            "a quarter of the range: {p:?}"
        );
        // Targets and re-renders keep their values at exposure 1.
        assert_eq!(
            sheet.get(4 * 42 + 20, 15),
            [0.6; 3],
            "the re-render of view 1"
        );
        assert!(contact_sheet(&t, &r[..2], 1.0).is_err());
    }

    /// Two views 1000× apart in brightness whose losses fall by e⁻ⁱᐟ¹⁰ to a floor: the relative
    /// loss no longer jumps between them, starts near 1 + 9 = 10 and ends at 1; a view drawn only
    /// early is divided by its smallest loss.
    #[test]
    fn the_relative_loss_removes_the_view_s_brightness() {
        let mut h: Vec<IterationRecord> = (0..300)
            .map(|i| {
                let v = i % 2;
                let scale = if v == 0 { 1.0 } else { 1000.0 };
                record(
                    i as u32,
                    v,
                    scale * (1.0 + 9.0 * (-(i as f64) / 10.0).exp()),
                )
            })
            .collect();
        h[3] = record(3, 7, 5.0);
        let r = relative_loss(&h);
        assert_eq!(r.len(), 300);
        // The level carries the tail's remainder 9·e⁻²⁰ at most.
        assert!((r[0].1 - 10.0).abs() < 1e-6, "{:?}", r[0]);
        assert!((r[1].1 - (1.0 + 9.0 * (-1.0f64 / 10.0).exp())).abs() < 1e-6);
        assert_eq!(r[3].1, 1.0, "a view drawn once: its own smallest loss");
        for p in &r[200..] {
            assert!((p.1 - 1.0).abs() < 1e-3, "{p:?}");
        }
        let s = relative_loss_series(&h);
        assert_eq!(s.len(), 2);
    }
}
