//! The volumetric path tracer as a [`ForwardModel`]: the ground truth's own renderer,
//! differentiated per path ([`volpath::derivative`]: a path's throughput depends on the medium
//! only through (α σ_t)^k e^{−σ_t ℓ}). Its derivative images are the derivatives of exactly
//! the images it renders, with the same paths, so a recovery with it has no model error
//! against targets it rendered; each view keeps its shadow-ray triangle lists. Estimators: `ad`
//! (those per-path derivatives) and `fd` (central differences of full renders, [`super::fd`]).

use bssrdf::diff::DiffImages;
use bssrdf::render::RenderSettings;
use geometry::{Accel, LightBins};
use scene::{Camera, Image, Medium, PointLight};
use volpath::{VolpathScene, VolpathSettings};

use super::fd::Differencing;
use super::{ForwardModel, MediumRenderer, ViewRenderer};
use crate::optimize::InverseError;

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
            model: self,
            accel: self.accel,
            settings: self.settings,
            medium,
        }))
    }
}

struct VolpathAt<'s> {
    model: &'s Volpath<'s>,
    accel: &'s Accel,
    settings: VolpathSettings,
    medium: Medium,
}

impl MediumRenderer for VolpathAt<'_> {
    fn view<'v>(&'v self, camera: &'v Camera, light: &'v PointLight) -> Box<dyn ViewRenderer + 'v> {
        let scene = self.scene(light, None);
        let bins = volpath::shadow_lists(&scene, &self.settings);
        Box::new(VolpathView {
            at: self,
            camera,
            light,
            bins,
        })
    }
}

impl<'s> VolpathAt<'s> {
    fn scene<'b>(&self, light: &PointLight, bins: Option<&'b LightBins>) -> VolpathScene<'b>
    where
        's: 'b,
    {
        VolpathScene {
            accel: self.accel,
            medium: self.medium,
            light: Some(*light),
            environment: None,
            light_bins: bins,
        }
    }
}

struct VolpathView<'v> {
    at: &'v VolpathAt<'v>,
    camera: &'v Camera,
    light: &'v PointLight,
    bins: Option<LightBins>,
}

impl ViewRenderer for VolpathView<'_> {
    fn value(&self, rs: &RenderSettings) -> Result<Image, InverseError> {
        let scene = self.at.scene(self.light, self.bins.as_ref());
        Ok(volpath::render_image(
            &scene,
            &self.at.settings,
            self.camera,
            rs,
            None,
        ))
    }

    fn derivatives(&self, rs: &RenderSettings) -> Result<DiffImages, InverseError> {
        let scene = self.at.scene(self.light, self.bins.as_ref());
        let settings = &self.at.settings;
        self.at.model.estimator.derivatives(
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
                let d = volpath::render_derivatives(&scene, settings, self.camera, rs, None);
                Ok(DiffImages {
                    value: d.value,
                    d_sigma_t: d.d_sigma_t,
                    d_albedo: d.d_albedo,
                })
            },
        )
    }
}
