//! The planar dipole baseline (Deng et al. 2022) as a [`ForwardModel`]: the Jensen dipole
//! between the camera point and entry points found by probe rays ([`bssrdf::dipole`]). Nothing
//! is kept across media; each view sets up its camera rays once. Estimators: `ad`, the analytic
//! derivative of the dipole profile with the sample positions held fixed (DLW22), and `fd`,
//! central differences of full renders ([`super::fd`]).

use bssrdf::diff::{DiffImages, DiffMethod, Loss, LossGradient};
use bssrdf::dipole::{DipoleScene, DipoleView, render_derivatives, render_image};
use bssrdf::render::RenderSettings;
use geometry::Accel;
use scene::{Camera, Image, Medium, PointLight};

use super::fd::central_differences;
use super::{ForwardModel, MediumRenderer, ViewRenderer};
use crate::optimize::{InverseError, decorrelated_gradient};

/// The dipole over one mesh.
pub struct Dipole<'a> {
    accel: &'a Accel,
    method: DiffMethod,
    delta_rel: f32,
    delta_albedo: f32,
}

impl<'a> Dipole<'a> {
    /// The dipole over `accel`, differentiated by `method` (`ad` or `fd`, the latter with
    /// relative σ_t step `delta_rel` and albedo step `delta_albedo`).
    pub fn new(accel: &'a Accel, method: DiffMethod, delta_rel: f32, delta_albedo: f32) -> Self {
        Dipole {
            accel,
            method,
            delta_rel,
            delta_albedo,
        }
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
    fn value(&self, rs: &RenderSettings) -> Result<Image, InverseError> {
        Ok(render_image(&self.at.scene, &self.view, rs))
    }

    fn derivatives(&self, rs: &RenderSettings) -> Result<DiffImages, InverseError> {
        let model = self.at.model;
        match model.method {
            DiffMethod::Fd => central_differences(
                |m| {
                    let scene = DipoleScene::new(model.accel, m)?;
                    Ok(render_image(&scene, &self.view, rs))
                },
                self.at.scene.medium,
                model.delta_rel,
                model.delta_albedo,
            ),
            _ => Ok(render_derivatives(&self.at.scene, &self.view, rs)),
        }
    }

    /// From one derivative render (the single-render estimator; the default split-sample
    /// gradient pairs two).
    fn loss_gradient(
        &self,
        rs: &RenderSettings,
        target: &Image,
        loss: Loss,
    ) -> Result<LossGradient, InverseError> {
        let d = self.derivatives(rs)?;
        Ok(decorrelated_gradient(&d.value, &d, target, loss))
    }
}
