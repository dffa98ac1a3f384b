//! Dataset folders (`dataset.json` + EXRs, DATASET.md) and the Mitsuba reference-render format.
//!
//! SKELETON: helper H3 owns this file.

use crate::{Camera, Image, PointLight};

/// One view of a dataset.
#[derive(Clone, Debug)]
pub struct View {
    pub camera: Camera,
    pub light: PointLight,
    pub image: Option<Image>,
}

/// A loaded dataset.
#[derive(Clone, Debug)]
pub struct Dataset {
    pub views: Vec<View>,
}
