//! The images a recovery fits: each with the camera that saw it and the light that lit it.

use scene::{Camera, Image, PointLight};

use super::InverseError;

/// One target view.
pub struct TargetView<'a> {
    /// Camera.
    pub camera: &'a Camera,
    /// Point light.
    pub light: &'a PointLight,
    /// Target image.
    pub image: &'a Image,
}

impl<'a> TargetView<'a> {
    /// Every view of `ds` with its image (`what` names the dataset in errors): an error names
    /// the first view without an image or with a non-finite pixel, and refuses a dataset whose
    /// every measured pixel is black (nothing to fit: no camera sees the lit object).
    pub fn of_dataset(ds: &'a scene::Dataset, what: &str) -> Result<Vec<Self>, InverseError> {
        let lit = |v: &scene::View| {
            v.image
                .as_ref()
                .is_some_and(|im| im.data.iter().flatten().any(|&x| x != 0.0))
        };
        if !ds.views.is_empty() && !ds.views.iter().any(lit) {
            return Err(InverseError::Invalid(format!(
                "{what}: every pixel of all {} views is black, so there is nothing to fit; fix: \
                 check that the cameras see the object (not from inside it, e.g. after scaling \
                 it) and that its light reaches the side they see",
                ds.views.len()
            )));
        }
        ds.views
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let image = v.image.as_ref().ok_or_else(|| {
                    InverseError::Invalid(format!("{what}: view {i} has no image to fit"))
                })?;
                image.check_finite(&format!("{what} view {i}"))?;
                Ok(TargetView {
                    camera: &v.camera,
                    light: &v.light,
                    image,
                })
            })
            .collect()
    }
}
