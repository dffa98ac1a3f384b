//! The learned renderer's settings in words, for the headers of reports that compare runs.

use super::{EntrySampler, LearnedSettings, LightCurvature, PixelSampling};
use crate::projection::ProjectionRule;

/// A choice's name as the settings files spell it (`half-space`, `walks`).
fn name<T: serde::Serialize>(v: &T) -> String {
    match serde_json::to_value(v) {
        Ok(serde_json::Value::String(s)) => s,
        _ => String::new(),
    }
}

impl LearnedSettings {
    /// One line naming the exit law, the incidence factor and the projection, and every
    /// setting that is not the default (planar features, a frozen descriptor, entry points from
    /// walks, no curvature correction, one-hot channels).
    pub fn describe(&self) -> String {
        let projection = match self.projection {
            ProjectionRule::Vkj19 => "vkj19 projection".to_string(),
            ProjectionRule::Son24 { max_dist_scale, .. } => {
                format!("son24 projection (reach {max_dist_scale}σ_n)")
            }
        };
        let flag = |on: bool, text: &'static str| if on { text } else { "" };
        format!(
            "{} exit law, {} incidence, {projection}{}{}{}{}{}",
            name(&self.exit),
            name(&self.incidence),
            flag(self.planar_features, ", planar features"),
            flag(self.frozen_descriptor, ", frozen descriptor"),
            flag(
                self.entry == EntrySampler::Walks,
                ", entry points from walks (no decoder)"
            ),
            if self.light_curvature == LightCurvature::None {
                ", light side without curvature correction"
            } else {
                ", curvature-corrected light side"
            },
            flag(self.sampling == PixelSampling::OneHot, ", one-hot channels"),
        )
    }
}
