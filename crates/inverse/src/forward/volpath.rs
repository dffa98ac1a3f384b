//! The volumetric path tracer as a [`ForwardModel`]: the ground truth's own renderer,
//! differentiated per path ([`volpath::derivative`]: a path's throughput depends on the medium
//! only through (α σ_t)^k e^{−σ_t ℓ}). Its derivative images are the derivatives of exactly
//! the images it renders, with the same paths, so a recovery with it has no model error
//! against targets it rendered. Each medium keeps the shadow-ray lists of every light position
//! it has rendered from ([`volpath::Lit`]). Estimators: `ad` (those per-path derivatives) and
//! `fd` (central differences of full renders, [`super::fd`]).

use bssrdf::diff::DiffImages;
use bssrdf::render::RenderSettings;
use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};
use volpath::{Lit, SharedLists, VolpathScene, VolpathSettings};

use super::fd::Differencing;
use super::{ForwardModel, MediumRenderer, Progress, ViewRenderer};
use crate::error::InverseError;

/// The volumetric path tracer over one mesh.
pub struct Volpath<'a> {
    accel: &'a Accel,
    settings: VolpathSettings,
    estimator: Differencing,
}

impl<'a> Volpath<'a> {
    /// The tracer over `accel` with `settings` (the dataset's maximum depth), differentiated by
    /// `estimator` (`ad` or `fd`).
    pub fn new(accel: &'a Accel, settings: VolpathSettings, estimator: Differencing) -> Self {
        Volpath {
            accel,
            settings,
            estimator,
        }
    }
}

impl ForwardModel for Volpath<'_> {
    fn prepare(&mut self, _medium: &Medium) -> Result<(), InverseError> {
        Ok(())
    }

    fn at<'s>(&'s self, medium: Medium) -> Result<Box<dyn MediumRenderer + 's>, InverseError> {
        medium
            .validate("medium")
            .map_err(|e| InverseError::Invalid(e.to_string()))?;
        Ok(Box::new(VolpathAt {
            estimator: self.estimator,
            lit: Lit::new(self.accel, medium, self.settings),
        }))
    }
}

struct VolpathAt<'s> {
    estimator: Differencing,
    lit: Lit<'s>,
}

impl MediumRenderer for VolpathAt<'_> {
    fn view<'v>(&'v self, camera: &'v Camera, light: &'v PointLight) -> Box<dyn ViewRenderer + 'v> {
        Box::new(VolpathView {
            at: self,
            camera,
            light,
            lists: self.lit.lists(light),
        })
    }
}

struct VolpathView<'v> {
    at: &'v VolpathAt<'v>,
    camera: &'v Camera,
    light: &'v PointLight,
    lists: SharedLists,
}

impl VolpathView<'_> {
    fn scene(&self) -> VolpathScene<'_> {
        self.at.lit.scene(self.light, &self.lists)
    }
}

impl ViewRenderer for VolpathView<'_> {
    fn value(&self, rs: &RenderSettings, progress: Progress) -> Result<Image, InverseError> {
        let settings = &self.at.lit.settings;
        Ok(volpath::render_image(
            &self.scene(),
            settings,
            self.camera,
            rs,
            progress,
        ))
    }

    fn derivatives(
        &self,
        rs: &RenderSettings,
        progress: Progress,
    ) -> Result<DiffImages, InverseError> {
        let scene = self.scene();
        let settings = &self.at.lit.settings;
        self.at.estimator.derivatives(
            scene.medium,
            |medium| {
                let scene = VolpathScene { medium, ..scene };
                Ok(volpath::render_image(
                    &scene,
                    settings,
                    self.camera,
                    rs,
                    None,
                ))
            },
            || {
                let d = volpath::render_derivatives(&scene, settings, self.camera, rs, progress);
                Ok(DiffImages {
                    value: d.value,
                    d_sigma_t: d.d_sigma_t,
                    d_albedo: d.d_albedo,
                    d_g: Some(d.d_g),
                })
            },
        )
    }
}
