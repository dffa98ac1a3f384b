//! Derivative images of one view by several estimators of the learned renderer, against central
//! differences of full renders (Son et al. 2024, Fig. 3 and 5): per estimator the image-summed
//! derivative per channel, its relative error against the differences,
//! ‖Σ∂I − Σ∂I_fd‖/‖Σ∂I_fd‖ over the three channels, and the per-pixel Pearson correlation with
//! them (all channels together). The differences are the reference; `naive` lacks the boundary
//! term, which shows as a low correlation along silhouettes and shadow edges.

use std::time::Instant;

use bssrdf::diff::{DiffImages, DiffSettings, Estimator, Primal};
use bssrdf::render::RenderSettings;
use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};

use crate::error::InverseError;
use crate::forward::ModelSpec;
use crate::forward::learned::LearnedSpec;

/// One estimator's derivative images and render time.
pub struct EstimatorImages {
    pub estimator: Estimator,
    pub images: DiffImages,
    pub seconds: f64,
}

/// How an estimator's derivative images agree with the differences'.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Agreement {
    /// Σ_pixels ∂I_c/∂σ_t,c and Σ_pixels ∂I_c/∂α_c.
    pub sum_d_sigma_t: [f64; 3],
    pub sum_d_albedo: [f64; 3],
    /// Relative error of the sums against the differences' (σ_t, α).
    pub relative_error: [f64; 2],
    /// Per-pixel correlation with the differences (σ_t, α).
    pub correlation: [f64; 2],
}

/// Σ over the pixels, per channel.
pub fn image_sums(img: &Image) -> [f64; 3] {
    let mut s = [0.0; 3];
    for p in &img.data {
        for c in 0..3 {
            s[c] += p[c] as f64;
        }
    }
    s
}

/// Pearson correlation of the per-pixel values (all channels together).
pub fn correlation(a: &Image, b: &Image) -> f64 {
    let n = (a.data.len() * 3).max(1) as f64;
    let pairs = || {
        a.data
            .iter()
            .zip(&b.data)
            .flat_map(|(p, q)| (0..3).map(move |c| (p[c] as f64, q[c] as f64)))
    };
    let (ma, mb) = pairs().fold((0.0, 0.0), |(x, y), (p, q)| (x + p / n, y + q / n));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in pairs() {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt().max(1e-300)
}

/// ‖s − f‖/‖f‖ over the three channels.
pub fn relative_error(s: [f64; 3], f: [f64; 3]) -> f64 {
    let num: f64 = (0..3).map(|c| (s[c] - f[c]).powi(2)).sum::<f64>().sqrt();
    let den: f64 = (0..3).map(|c| f[c].powi(2)).sum::<f64>().sqrt();
    num / den.max(1e-300)
}

/// The agreement of `img` with the differences `fd` (module docs).
pub fn agreement(img: &DiffImages, fd: &DiffImages) -> Agreement {
    let (st, sa) = (image_sums(&img.d_sigma_t), image_sums(&img.d_albedo));
    Agreement {
        sum_d_sigma_t: st,
        sum_d_albedo: sa,
        relative_error: [
            relative_error(st, image_sums(&fd.d_sigma_t)),
            relative_error(sa, image_sums(&fd.d_albedo)),
        ],
        correlation: [
            correlation(&img.d_sigma_t, &fd.d_sigma_t),
            correlation(&img.d_albedo, &fd.d_albedo),
        ],
    }
}

/// The derivative images of one view by each of `methods` (with `rs`) and, last, by `fd` (added
/// when missing; with `reference`), with relative σ_t step `delta_rel` and the value image
/// `primal`. `ours` is itself a central difference of samples with common random numbers, so
/// against `fd` with the same settings it agrees to rounding; an independent reference (another
/// seed, more samples) measures its noise and bias.
#[allow(clippy::too_many_arguments)]
pub fn render_estimators(
    accel: &Accel,
    learned: LearnedSpec,
    medium: Medium,
    camera: &Camera,
    light: &PointLight,
    rs: &RenderSettings,
    reference: &RenderSettings,
    estimators: &[Estimator],
    delta_rel: f32,
    primal: Primal,
) -> Result<Vec<EstimatorImages>, InverseError> {
    let mut estimators: Vec<Estimator> = estimators.to_vec();
    estimators.retain(|m| *m != Estimator::Fd);
    estimators.push(Estimator::Fd);
    estimators
        .into_iter()
        .map(|estimator| {
            let diff = DiffSettings {
                estimator,
                delta_rel,
                primal,
                ..DiffSettings::default()
            };
            let mut model = ModelSpec::Learned(LearnedSpec { diff, ..learned }).build(accel);
            model.prepare(&medium)?;
            let t0 = Instant::now();
            let rs = if estimator == Estimator::Fd {
                reference
            } else {
                rs
            };
            let images = model
                .at(medium)?
                .view(camera, light)
                .derivatives(rs, None)?;
            Ok(EstimatorImages {
                estimator,
                images,
                seconds: t0.elapsed().as_secs_f64(),
            })
        })
        .collect()
}

/// Writes each estimator's two derivative images as EXR and as false-colour PNG
/// (`<method>_d_sigma_t`, `<method>_d_albedo`), one colour range per parameter: the 99th
/// percentile of the differences' |∂I| (the last of `results`), so the estimators compare.
pub fn write_estimators(
    results: &[EstimatorImages],
    out: &std::path::Path,
    overwrite: bool,
) -> Result<(), scene::SceneError> {
    let Some(fd) = results.last().map(|r| &r.images) else {
        return Ok(());
    };
    let zero = Image::new(fd.value.width, fd.value.height);
    let (_, r_t) = Image::false_colour_diff_with_range(&fd.d_sigma_t, &zero, None)?;
    let (_, r_a) = Image::false_colour_diff_with_range(&fd.d_albedo, &zero, None)?;
    for r in results {
        for (what, d, range) in [
            ("d_sigma_t", &r.images.d_sigma_t, r_t),
            ("d_albedo", &r.images.d_albedo, r_a),
        ] {
            let stem = format!("{}_{what}", r.estimator.name());
            d.write_exr(&out.join(format!("{stem}.exr")), overwrite)?;
            let (fc, _) = Image::false_colour_diff_with_range(d, &zero, Some(range))?;
            fc.write_png(&out.join(format!("{stem}.png")), 1.0, overwrite)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(v: &[[f32; 3]]) -> Image {
        let mut img = Image::new(v.len() as u32, 1);
        img.data.copy_from_slice(v);
        img
    }

    #[test]
    fn statistics() {
        let a = image(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        let b = image(&[[2.0, 4.0, 6.0], [8.0, 10.0, 12.0]]);
        assert!((correlation(&a, &b) - 1.0).abs() < 1e-12);
        let neg = image(&[[-1.0, -2.0, -3.0], [-4.0, -5.0, -6.0]]);
        assert!((correlation(&a, &neg) + 1.0).abs() < 1e-12);
        assert_eq!(image_sums(&a), [5.0, 7.0, 9.0]);
        assert!((relative_error([1.0, 0.0, 0.0], [2.0, 0.0, 0.0]) - 0.5).abs() < 1e-12);
    }
}
