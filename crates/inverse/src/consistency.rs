//! Whether a recovered medium explains the images without the learned model: the estimate is
//! rendered by the volumetric path tracer (the ground-truth simulator, independent of the
//! learned BSSRDF) and compared with the targets.
//!
//! Per view and channel, over the pixels where the target or the render is positive:
//!
//! * brightness ratio  m = Σ_v Σ_p I_p / Σ_v Σ_p T_p over all checked views (1 when the
//!   estimate is as bright as the object; pooled, so that dim back-lit views, whose own ratio
//!   is mostly noise, weigh by their light), and per view;
//! * L2 relative to the noise floor  q = Σ_p (I¹_p − T_p)² / Σ_p (I¹_p − I²_p)²
//!   with I¹, I² two renders with independent seeds at the targets' samples per pixel. If the
//!   estimate were the truth and the targets were rendered like I¹, E(I¹ − T)² = 2·Var and
//!   E(I¹ − I²)² = 2·Var: q ≈ 1. q ≫ 1 means the medium does not reproduce the images.
//!
//! A recovery is *inconsistent* when a channel's mean ratio over the views is off by more than
//! [`RATIO_TOLERANCE`] or its q exceeds [`Q_TOLERANCE`] (the numbers are chosen so that the
//! suite's cases recovered within a few percent pass; BENCHMARKS.md, "Robustness").

use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};
use serde::{Deserialize, Serialize};
use volpath::{RenderSettings, VolpathScene, VolpathSettings, render_image, shadow_lists};

/// A channel's mean ratio may differ from 1 by at most this.
pub const RATIO_TOLERANCE: f64 = 0.05;
/// A channel's L2 may be at most this many times the noise floor.
pub const Q_TOLERANCE: f64 = 2.0;

/// The consistency figures of an estimate (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Consistency {
    /// Mean ratio per view and channel.
    pub view_ratio: Vec<[f64; 3]>,
    /// The pooled brightness ratio over the views, per channel.
    pub mean_ratio: [f64; 3],
    /// L2 over the noise floor per channel (all views together).
    pub l2_over_noise: [f64; 3],
    /// The dataset views used.
    pub views: Vec<usize>,
    /// Samples per pixel of each render.
    pub spp: u32,
}

impl Consistency {
    /// Whether a channel fails the tolerances (module docs).
    pub fn inconsistent_channels(&self) -> Vec<usize> {
        (0..3)
            .filter(|&c| {
                (self.mean_ratio[c] - 1.0).abs() > RATIO_TOLERANCE
                    || self.l2_over_noise[c] > Q_TOLERANCE
                    || !self.mean_ratio[c].is_finite()
            })
            .collect()
    }
}

/// One view to check: camera, light, target image, and its index in the dataset.
pub struct CheckView<'a> {
    pub camera: &'a Camera,
    pub light: &'a PointLight,
    pub target: &'a Image,
    pub index: usize,
}

/// Render `medium` in every view twice (seeds `seed`, `seed + 1`) with the volumetric path
/// tracer at `spp` and compare with the targets.
pub fn check(
    accel: &Accel,
    medium: &Medium,
    views: &[CheckView],
    spp: u32,
    seed: u64,
) -> Consistency {
    let settings = VolpathSettings::default();
    let mut view_ratio = Vec::with_capacity(views.len());
    let (mut num, mut floor) = ([0.0f64; 3], [0.0f64; 3]);
    let (mut sum_i, mut sum_t) = ([0.0f64; 3], [0.0f64; 3]);
    for v in views {
        let mut scene = VolpathScene {
            accel,
            medium: *medium,
            light: Some(*v.light),
            environment: None,
            light_bins: None,
        };
        let lists = shadow_lists(&scene, &settings);
        scene.light_bins = lists.as_ref();
        let render = |s: u64| {
            let rs = RenderSettings {
                spp,
                seed: s,
                view: v.index as u64,
            };
            render_image(&scene, &settings, v.camera, &rs, None)
        };
        let (a, b) = (render(seed), render(seed + 1));
        let (mut vi, mut vt) = ([0.0f64; 3], [0.0f64; 3]);
        for ((pa, pb), pt) in a.data.iter().zip(&b.data).zip(&v.target.data) {
            for c in 0..3 {
                let (x, y, t) = (pa[c] as f64, pb[c] as f64, pt[c] as f64);
                if !(x > 0.0 || t > 0.0) || !t.is_finite() {
                    continue;
                }
                vi[c] += x;
                vt[c] += t;
                num[c] += (x - t) * (x - t);
                floor[c] += (x - y) * (x - y);
            }
        }
        view_ratio.push(std::array::from_fn(|c| vi[c] / vt[c]));
        for c in 0..3 {
            sum_i[c] += vi[c];
            sum_t[c] += vt[c];
        }
    }
    Consistency {
        mean_ratio: std::array::from_fn(|c| sum_i[c] / sum_t[c]),
        l2_over_noise: std::array::from_fn(|c| num[c] / floor[c]),
        view_ratio,
        views: views.iter().map(|v| v.index).collect(),
        spp,
    }
}
