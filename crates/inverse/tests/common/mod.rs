//! Scenes shared by the inverse crate's integration tests.

use geometry::{Accel, Shape};

/// The built-in sphere scaled to `scale` (radius `scale`), with its BVH.
pub fn sphere(scale: f32) -> Accel {
    Accel::new(
        Shape::from_name("sphere")
            .unwrap()
            .scaled(scale)
            .build()
            .unwrap(),
    )
}
