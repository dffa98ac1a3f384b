//! Fixtures shared by the renderer tests: deterministic random layers, a model assembled from
//! them, and a slab mesh with sharp edges.

#![allow(dead_code)]

use bssrdf::model::{FrameConvention, ModelInfo};
use bssrdf::nn::{Dense, Normalisation, ShapeAdaptiveModel};
use geometry::{Accel, Vec3};

/// A dense layer with xorshift weights uniform in ±`scale` (biases ±0.1·`scale`).
pub fn layer(n_in: usize, n_out: usize, scale: f32, seed: u32) -> Dense {
    let mut s = seed.wrapping_mul(2_654_435_761).wrapping_add(1);
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        (s as f32 / u32::MAX as f32 - 0.5) * 2.0 * scale
    };
    let w = (0..n_in * n_out).map(|_| next()).collect();
    let b = (0..n_out).map(|_| next() * 0.1).collect();
    Dense::new(n_in, n_out, w, b).unwrap()
}

/// A render-only model (no encoder) with identity normalisation and VKJ19 frames.
pub fn assemble(
    feature: Vec<Dense>,
    absorption: Vec<Dense>,
    decoder: Vec<Dense>,
) -> ShapeAdaptiveModel {
    let info = ModelInfo {
        frame_convention: FrameConvention::Vkj19,
        ..Default::default()
    };
    ShapeAdaptiveModel::new(
        feature,
        absorption,
        decoder,
        None,
        Normalisation::identity(),
        info,
    )
    .unwrap()
}

/// Slab |x|, |z| ≤ 0.5, −0.5 ≤ y ≤ 0 (sharp edges), CCW outward.
pub fn slab() -> Accel {
    let mut mesh = geometry::sharp_box(Vec3::new(-0.5, -0.5, -0.5), Vec3::new(0.5, 0.0, 0.5));
    geometry::mesh::validate(&mut mesh, "slab").unwrap();
    Accel::new(mesh)
}
