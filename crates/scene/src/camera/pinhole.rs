//! A calibrated pinhole's intrinsics, where they differ from Mitsuba's centred camera with square
//! pixels: the principal point off the film's centre, and a focal length along y that differs
//! from the one along x (the intrinsic matrix K of OpenCV and COLMAP, without skew).
//!
//! In pixels of the full film (pixel (i, j) covers [i, i + 1) × [j, j + 1), row 0 at the top,
//! as in COLMAP and OpenCV), with f_x = W / (2 tan(fov_x/2)) from the camera's field of view:
//! d_cam = ((c_x − p_x)/f_x, (c_y − p_y)/f_y, 1) (the camera's x axis points to the image's left,
//! its y axis up). The centred camera is c = (W/2, H/2), f_y = f_x, which gives the formula of
//! [`crate::camera`] exactly; a camera whose intrinsics are that has none ([`Pinhole::of`]).

use serde::{Deserialize, Serialize};

use crate::SceneError;

/// The principal point and the focal lengths' ratio of a calibrated camera ([module](self)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pinhole {
    /// Principal point, x, in pixels of the full film from its left edge.
    pub cx: f32,
    /// Principal point, y, in pixels of the full film from its top edge.
    pub cy: f32,
    /// f_y / f_x: 1 for square pixels.
    pub aspect: f32,
}

/// The intrinsics (f_x, f_y, c_x, c_y) in pixels of a `film_width × film_height` film.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
}

impl Pinhole {
    /// The pinhole of intrinsics `k` on a `film_width × film_height` film: `None` for the
    /// centred camera with square pixels (which the camera's field of view alone describes).
    pub fn of(k: &Intrinsics, film_width: u32, film_height: u32) -> Option<Pinhole> {
        let centred = k.cx == 0.5 * film_width as f32 && k.cy == 0.5 * film_height as f32;
        (!(centred && k.fy == k.fx)).then_some(Pinhole {
            cx: k.cx,
            cy: k.cy,
            aspect: k.fy / k.fx,
        })
    }

    /// Checks the values (`context` names the camera in the error): finite, a positive aspect
    /// within 1/100 … 100, the principal point within one film size of the film.
    pub fn validate(
        &self,
        context: &str,
        film_width: u32,
        film_height: u32,
    ) -> Result<(), SceneError> {
        let bad = |field: &str, reason: String| SceneError::Invalid {
            location: format!("{context}.{field}"),
            reason,
        };
        let a = self.aspect;
        if !(a.is_finite() && (0.01..=100.0).contains(&a)) {
            return Err(bad(
                "fy",
                format!(
                    "f_y/f_x = {a}: the focal lengths must be positive and within a factor of 100 \
                     of each other; fix: give f_x and f_y in pixels"
                ),
            ));
        }
        for (field, v, size) in [("cx", self.cx, film_width), ("cy", self.cy, film_height)] {
            let s = size as f32;
            if !(v.is_finite() && v >= -s && v <= 2.0 * s) {
                return Err(bad(
                    field,
                    format!(
                        "= {v}: the principal point must lie within one image size of the {s}-pixel \
                         image; fix: give it in pixels from the image's top-left corner"
                    ),
                ));
            }
        }
        Ok(())
    }
}
