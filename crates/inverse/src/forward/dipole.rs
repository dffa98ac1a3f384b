//! The planar dipole baseline (Deng et al. 2022) as a [`ForwardModel`]: the Jensen dipole
//! between the camera point and entry points found by probe rays ([`::dipole`]). Nothing
//! is kept across media; each view sets up its camera rays once. Estimators: `ad`, the analytic
//! derivative of the dipole profile with the sample positions held fixed (DLW22), and `fd`,
//! central differences of full renders ([`super::fd`]).

use ::dipole::{DipoleScene, DipoleView, render_derivatives, render_image};
use bssrdf::diff::DiffImages;
use bssrdf::render::RenderSettings;
use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};

use super::fd::Differencing;
use super::{ForwardModel, MediumRenderer, Progress, ViewRenderer};
use crate::error::InverseError;

/// The dipole over one mesh.
pub struct Dipole<'a> {
    accel: &'a Accel,
    estimator: Differencing,
}

impl<'a> Dipole<'a> {
    /// The dipole over `accel`, differentiated by `estimator` (`ad` or `fd`).
    pub fn new(accel: &'a Accel, estimator: Differencing) -> Self {
        Dipole { accel, estimator }
    }
}

impl ForwardModel for Dipole<'_> {
    fn prepare(&mut self, _medium: &Medium) -> Result<(), InverseError> {
        Ok(())
    }

    fn at<'s>(&'s self, medium: Medium) -> Result<Box<dyn MediumRenderer + 's>, InverseError> {
        Ok(Box::new(DipoleAt {
            model: self,
            scene: DipoleScene::new(self.accel, medium)?,
        }))
    }
}

struct DipoleAt<'s> {
    model: &'s Dipole<'s>,
    scene: DipoleScene<'s>,
}

impl MediumRenderer for DipoleAt<'_> {
    fn view<'v>(&'v self, camera: &'v Camera, light: &'v PointLight) -> Box<dyn ViewRenderer + 'v> {
        Box::new(DipoleViewRenderer {
            at: self,
            view: DipoleView::new(self.model.accel, camera, light),
        })
    }
}

struct DipoleViewRenderer<'v> {
    at: &'v DipoleAt<'v>,
    view: DipoleView<'v>,
}

impl ViewRenderer for DipoleViewRenderer<'_> {
    fn value(&self, rs: &RenderSettings, progress: Progress) -> Result<Image, InverseError> {
        let image = render_image(&self.at.scene, &self.view, rs);
        rows_done(progress, &image);
        Ok(image)
    }

    fn derivatives(
        &self,
        rs: &RenderSettings,
        progress: Progress,
    ) -> Result<DiffImages, InverseError> {
        let accel = self.at.model.accel;
        let d = self.at.model.estimator.derivatives(
            self.at.scene.medium,
            |m| Ok(render_image(&DipoleScene::new(accel, m)?, &self.view, rs)),
            || Ok(render_derivatives(&self.at.scene, &self.view, rs)),
        )?;
        rows_done(progress, &d.value);
        Ok(d)
    }
}

/// The dipole renders a view whole: its progress advances by all the rows at the end.
fn rows_done(progress: Progress, image: &Image) {
    if let Some(pb) = progress {
        pb.inc(image.height as u64);
    }
}
