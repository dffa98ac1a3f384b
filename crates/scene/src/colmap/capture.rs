//! A COLMAP model's registered images as the views of a [`Capture`].

use super::ColmapModel;
use crate::SceneError;
use crate::capture::{Capture, CapturedView};
use crate::dataset::Dataset;

impl ColmapModel {
    /// The capture as a dataset: a view per registered image, in the model's order.
    pub fn dataset(&self, capture: &Capture) -> Result<Dataset, SceneError> {
        let views = self
            .images
            .iter()
            .map(|im| {
                Ok(CapturedView {
                    name: im.name.clone(),
                    camera: self.camera(im)?,
                })
            })
            .collect::<Result<Vec<_>, SceneError>>()?;
        let units = format!(
            "lengths in the units of the COLMAP model {} (sigma_t in 1/those units); light \
             intensity in W/sr, relative unless measured; images linear radiance",
            self.dir.display()
        );
        let fix = "pass the images the model was made from (undistorted, unscaled)";
        capture.dataset(&views, units, "COLMAP import", fix)
    }
}
