//! The tracer set up over one mesh and medium ([`Lit`]): the scene of each point light with the
//! shadow-ray lists of its position ([`shadow_lists`]), built at the first view lit from there
//! and shared by every later one (a fixed light, a turntable's few light positions). Every render
//! of a list of views by the tracer goes through it, so the lists are built in one place.

use std::sync::{Arc, Mutex};

use geometry::{Accel, LightBins};
use glam::Vec3;
use scene::{Medium, PointLight};

use crate::integrator::{VolpathScene, VolpathSettings};
use crate::render::shadow_lists;

/// One light position's shadow-ray lists (`None` where the settings do not use them).
pub type SharedLists = Arc<Option<LightBins>>;

/// The tracer over one mesh and medium, with the shadow-ray lists of each light position seen.
pub struct Lit<'a> {
    pub accel: &'a Accel,
    pub medium: Medium,
    pub settings: VolpathSettings,
    lists: Mutex<Vec<(Vec3, SharedLists)>>,
}

impl<'a> Lit<'a> {
    /// The tracer over `accel` in `medium` with `settings`; no lists built yet.
    pub fn new(accel: &'a Accel, medium: Medium, settings: VolpathSettings) -> Self {
        Lit {
            accel,
            medium,
            settings,
            lists: Mutex::new(Vec::new()),
        }
    }

    /// The scene lit by `light`, without shadow-ray lists.
    pub fn bare(&self, light: &PointLight) -> VolpathScene<'a> {
        VolpathScene {
            accel: self.accel,
            medium: self.medium,
            light: Some(*light),
            environment: None,
            light_bins: None,
        }
    }

    /// The shadow-ray lists of `light`'s position: built at the first call for it, shared after.
    pub fn lists(&self, light: &PointLight) -> SharedLists {
        let mut seen = self.lists.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, l)) = seen.iter().find(|(p, _)| *p == light.position) {
            return l.clone();
        }
        let l: SharedLists = Arc::new(shadow_lists(&self.bare(light), &self.settings));
        seen.push((light.position, l.clone()));
        l
    }

    /// The scene lit by `light` with the shadow-ray lists `lists` (from [`Lit::lists`]).
    pub fn scene<'b>(&self, light: &PointLight, lists: &'b SharedLists) -> VolpathScene<'b>
    where
        'a: 'b,
    {
        VolpathScene {
            light_bins: lists.as_ref().as_ref(),
            ..self.bare(light)
        }
    }
}
