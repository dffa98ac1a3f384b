//! The Mitsuba 3 `perspective` camera (CONVENTIONS.md, fixed convention).
//!
//! `to_world = look_at(origin, target, up)`: z = normalize(target − origin) (view direction),
//! x = normalize(cross(up, z)) (image LEFT), y = cross(z, x) (image up). With t = tan(fov_x/2),
//! film coordinates (px, py) in pixels (py down):
//! d_cam = ((1 − 2px/W)·t, (1 − 2py/H)·t·H/W, 1), d_world = normalize(R·d_cam).
//!
//! A calibrated camera (COLMAP, OpenCV, a NeRF `transforms.json`) whose principal point is off
//! the film's centre, or whose pixels are not square, carries its intrinsics ([`Pinhole`]):
//! d_cam = ((c_x − p_x)/f_x, (c_y − p_y)/f_y, 1) with f_x = W/(2t).

use geometry::{Accel, PixelBins};
use glam::{Mat3, Vec3};

use std::sync::Arc;

use crate::SceneError;
use crate::image::PixelMask;
use serde::{Deserialize, Serialize};

mod pinhole;

pub use pinhole::{Intrinsics, Pinhole};

/// A pinhole perspective camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Camera position.
    pub origin: Vec3,
    /// Rotation columns [x (image left), y (image up), z (view direction)].
    pub rotation: Mat3,
    /// Horizontal field of view in degrees (Mitsuba `fov_axis = "x"`).
    pub fov_x_deg: f32,
    pub width: u32,
    pub height: u32,
    /// A crop window of a larger film (the paper's released optimiser renders random crops):
    /// this camera's pixel (px, py) is pixel (x0 + px, y0 + py) of the full film. `None`: the
    /// film is `width × height`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crop: Option<Crop>,
    /// The intrinsics of a calibrated camera where they differ from the centred, square-pixel
    /// camera that `fov_x_deg` describes ([`Pinhole`]); `None`: that camera.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pinhole: Option<Pinhole>,
    /// The film's pixels that measure the object (over the full film when cropped; a photo's
    /// saturated or masked-out pixels are clear); `None`: every pixel. Renderers leave the
    /// others black with zero derivatives ([`Camera::measures`]). Not serialised: it comes with
    /// the view's images.
    #[serde(skip)]
    pub mask: Option<Arc<PixelMask>>,
}

/// [`Camera::ray`] with the camera's constants precomputed (the same arithmetic, bit for bit).
#[derive(Clone, Copy, Debug)]
pub struct RayGen {
    origin: Vec3,
    rotation: Mat3,
    tan_half_fov: f32,
    /// (x0, y0, film width, film height) in pixels.
    film: [f32; 4],
    /// A calibrated camera's (c_x, c_y, 1/f_x, 1/f_y) in pixels of the full film.
    pinhole: Option<[f32; 4]>,
}

impl RayGen {
    /// Primary ray through film position (px, py) (pixels, py down): (origin, unit direction).
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> (Vec3, Vec3) {
        let t = self.tan_half_fov;
        let [x0, y0, w, h] = self.film;
        let (px, py) = (px + x0, py + y0);
        let d = match self.pinhole {
            None => Vec3::new(
                (1.0 - 2.0 * px / w) * t,
                (1.0 - 2.0 * py / h) * t * h / w,
                1.0,
            ),
            Some([cx, cy, ifx, ify]) => Vec3::new((cx - px) * ifx, (cy - py) * ify, 1.0),
        };
        (self.origin, (self.rotation * d).normalize())
    }
}

/// Where a cropped [`Camera`]'s pixels lie on its full film.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Crop {
    pub x0: u32,
    pub y0: u32,
    pub film_width: u32,
    pub film_height: u32,
}

impl Camera {
    /// Mitsuba `look_at`. `up` must not be parallel to `target − origin` (checked by the scene
    /// validation, which reports it as an error).
    pub fn look_at(
        origin: Vec3,
        target: Vec3,
        up: Vec3,
        fov_x_deg: f32,
        width: u32,
        height: u32,
    ) -> Self {
        let z = (target - origin).normalize();
        let x = up.cross(z).normalize();
        let y = z.cross(x);
        Camera {
            origin,
            rotation: Mat3::from_cols(x, y, z),
            fov_x_deg,
            width,
            height,
            crop: None,
            pinhole: None,
            mask: None,
        }
    }

    /// Primary ray through film position (px, py) (pixels, py down): (origin, unit direction).
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> (Vec3, Vec3) {
        self.ray_gen().ray(px, py)
    }

    /// The constants of [`ray`](Self::ray), computed once for generating many rays.
    pub fn ray_gen(&self) -> RayGen {
        let (x0, y0, w, h) = self.film();
        let tan_half_fov = (0.5 * self.fov_x_deg.to_radians()).tan();
        RayGen {
            origin: self.origin,
            rotation: self.rotation,
            tan_half_fov,
            film: [x0, y0, w, h],
            pinhole: self.pinhole.map(|p| {
                let inv_fx = 2.0 * tan_half_fov / w;
                [p.cx, p.cy, inv_fx, inv_fx / p.aspect]
            }),
        }
    }

    /// The intrinsics (f_x, f_y, c_x, c_y) in pixels of the full film (a crop's included).
    pub fn intrinsics(&self) -> Intrinsics {
        let (_, _, w, h) = self.film();
        let fx = 0.5 * w / (0.5 * self.fov_x_deg.to_radians()).tan();
        match self.pinhole {
            None => Intrinsics {
                fx,
                fy: fx,
                cx: 0.5 * w,
                cy: 0.5 * h,
            },
            Some(p) => Intrinsics {
                fx,
                fy: fx * p.aspect,
                cx: p.cx,
                cy: p.cy,
            },
        }
    }

    /// This camera with the intrinsics `k` (pixels of its full film): the field of view from
    /// f_x, and a [`Pinhole`] unless `k` is the centred, square-pixel camera.
    pub fn with_intrinsics(self, k: &Intrinsics) -> Camera {
        let (_, _, w, h) = self.film();
        Camera {
            fov_x_deg: 2.0 * (0.5 * w / k.fx).atan().to_degrees(),
            pinhole: Pinhole::of(k, w as u32, h as u32),
            ..self
        }
    }

    /// Project a world point to film coordinates (px, py) of this camera's pixels, or `None`
    /// behind the camera.
    pub fn project(&self, p: Vec3) -> Option<(f32, f32)> {
        self.project_depth(p).map(|(px, py, _)| (px, py))
    }

    /// [`project`](Self::project) plus the depth `(p − origin)·z` along the view direction.
    pub fn project_depth(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        self.projector()(p)
    }

    /// [`project_depth`](Self::project_depth) with its per-camera constants (the field of view's
    /// tangent, the film) computed once, for projecting many points.
    pub fn projector(&self) -> impl Fn(Vec3) -> Option<(f32, f32, f32)> + use<> {
        let t = (0.5 * self.fov_x_deg.to_radians()).tan();
        let (x0, y0, w, h) = self.film();
        let (to_cam, origin) = (self.rotation.transpose(), self.origin);
        let pinhole = self.pinhole.map(|p| {
            let fx = 0.5 * w / t;
            [p.cx, p.cy, fx, fx * p.aspect]
        });
        move |p| {
            let d = to_cam * (p - origin);
            if d.z <= 0.0 {
                return None;
            }
            let (px, py) = match pinhole {
                None => (
                    (1.0 - d.x / d.z / t) * 0.5 * w,
                    (1.0 - d.y / d.z / (t * h / w)) * 0.5 * h,
                ),
                Some([cx, cy, fx, fy]) => (cx - fx * d.x / d.z, cy - fy * d.y / d.z),
            };
            Some((px - x0, py - y0, d.z))
        }
    }

    /// Per-pixel candidate triangles of `accel` for this camera's primary rays
    /// ([`PixelBins`]): [`PixelBins::closest`] then answers `accel.closest(o, d, …)` for the
    /// ray `(o, d) = self.ray(x + jx, y + jy)` with `jx, jy ∈ [0, 1)` exactly. `None` when the
    /// bins cannot be built (geometry on or behind the camera plane, a rotation that is not
    /// orthonormal, too many overlaps); use the BVH then.
    pub fn pixel_bins(&self, accel: &Accel) -> Option<PixelBins> {
        let r = self.rotation;
        let gram = r.transpose() * r;
        let off = (gram - Mat3::IDENTITY).to_cols_array();
        if !off.iter().all(|e| e.abs() <= 1e-5) {
            return None;
        }
        PixelBins::build(
            accel,
            self.width,
            self.height,
            self.origin,
            self.projector(),
        )
    }

    /// (x0, y0, film width, film height) in pixels, as f32.
    #[inline]
    fn film(&self) -> (f32, f32, f32, f32) {
        match self.crop {
            Some(c) => (
                c.x0 as f32,
                c.y0 as f32,
                c.film_width as f32,
                c.film_height as f32,
            ),
            None => (0.0, 0.0, self.width as f32, self.height as f32),
        }
    }

    /// Whether this camera's pixel (x, y) measures the object (the mask's bit at the same pixel
    /// of the full film; true without a mask).
    #[inline]
    pub fn measures(&self, x: u32, y: u32) -> bool {
        match &self.mask {
            None => true,
            Some(m) => {
                let (x0, y0) = self.crop.map_or((0, 0), |c| (c.x0, c.y0));
                m.get(x0 + x, y0 + y)
            }
        }
    }

    /// The camera that renders the `width × height` pixels from (x0, y0) of this camera's
    /// image: its pixel (px, py) sees exactly what pixel (x0 + px, y0 + py) of this one sees.
    pub fn cropped(&self, x0: u32, y0: u32, width: u32, height: u32) -> Result<Camera, SceneError> {
        if width == 0
            || height == 0
            || x0.checked_add(width).is_none_or(|x1| x1 > self.width)
            || y0.checked_add(height).is_none_or(|y1| y1 > self.height)
        {
            return Err(SceneError::Invalid {
                location: "camera: crop".into(),
                reason: format!(
                    "{width}×{height} at ({x0}, {y0}) does not fit in the {}×{} image; use a \
                     smaller crop",
                    self.width, self.height
                ),
            });
        }
        let base = self.crop.unwrap_or(Crop {
            x0: 0,
            y0: 0,
            film_width: self.width,
            film_height: self.height,
        });
        Ok(Camera {
            width,
            height,
            crop: Some(Crop {
                x0: base.x0 + x0,
                y0: base.y0 + y0,
                ..base
            }),
            ..self.clone()
        })
    }

    /// Build from a Mitsuba `to_world` matrix given row-major (`rows[r][c]`): columns 0, 1, 2 are
    /// x (image left), y (image up), z (view direction), column 3 is the origin. The matrix is
    /// used as is; [`Camera::validate`] checks that its rotation is orthonormal.
    pub fn from_to_world(rows: [[f32; 4]; 4], fov_x_deg: f32, width: u32, height: u32) -> Self {
        let col = |c: usize| Vec3::new(rows[0][c], rows[1][c], rows[2][c]);
        Camera {
            origin: col(3),
            rotation: Mat3::from_cols(col(0), col(1), col(2)),
            fov_x_deg,
            width,
            height,
            crop: None,
            pinhole: None,
            mask: None,
        }
    }

    /// The Mitsuba `to_world` matrix, row-major (`rows[r][c]`), columns [x, y, z, origin].
    pub fn to_world_rows(&self) -> [[f32; 4]; 4] {
        let (x, y, z, o) = (
            self.rotation.x_axis,
            self.rotation.y_axis,
            self.rotation.z_axis,
            self.origin,
        );
        [
            [x.x, y.x, z.x, o.x],
            [x.y, y.y, z.y, o.y],
            [x.z, y.z, z.z, o.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// View direction (unit, the camera's z axis).
    pub fn direction(&self) -> Vec3 {
        self.rotation.z_axis
    }

    /// Check the camera: resolution > 0 (at most 65536 per side), fov in (0°, 180°), finite
    /// origin, rotation orthonormal and right-handed (tolerance 1e-3). `context` (e.g.
    /// "dataset.json: views\[3\].camera") goes into the error.
    pub fn validate(&self, context: &str) -> Result<(), SceneError> {
        self.validate_named(context, "fov")
    }

    /// [`Camera::validate`] with the name the file format gives the fov field.
    pub(crate) fn validate_named(&self, context: &str, fov_field: &str) -> Result<(), SceneError> {
        let bad = |field: &str, reason: String| SceneError::Invalid {
            location: format!("{context}.{field}"),
            reason,
        };
        for (field, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 || v > 65536 {
                return Err(bad(
                    field,
                    format!(
                        "= {v}: image resolution must be between 1 and 65536 pixels; fix: use e.g. 256"
                    ),
                ));
            }
        }
        let f = self.fov_x_deg;
        if !(f.is_finite() && f > 0.0 && f < 180.0) {
            return Err(bad(
                fov_field,
                format!(
                    "= {f}: horizontal field of view must be in (0, 180) degrees; fix: use e.g. 40"
                ),
            ));
        }
        if let Some(p) = &self.pinhole {
            let (_, _, w, h) = self.film();
            p.validate(context, w as u32, h as u32)?;
        }
        if !self.origin.is_finite() {
            return Err(bad(
                "origin",
                format!("= {:?}: must be finite", self.origin.to_array()),
            ));
        }
        let r = self.rotation;
        let ortho_err = (r.transpose() * r - Mat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        if !(ortho_err.is_finite() && ortho_err < 1e-3) {
            return Err(bad(
                "to_world",
                format!(
                    "rotation part is not orthonormal (max |RᵀR − I| = {ortho_err:.3e}); fix: the \
                     first three columns must be unit, mutually orthogonal axes (no scale or shear)"
                ),
            ));
        }
        if r.determinant() < 0.0 {
            return Err(bad(
                "to_world",
                "rotation part is a reflection (determinant −1); fix: use a right-handed frame, \
                 x = normalize(cross(up, z)), y = cross(z, x)"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// A camera from a row-major 4×4 Mitsuba to_world, validated (finite, last row [0, 0, 0, 1],
/// orthonormal right-handed rotation, resolution, fov).
pub(crate) fn camera_from_matrix(
    m: &[[f64; 4]; 4],
    fov: f32,
    width: u32,
    height: u32,
    ctx: &str,
) -> Result<Camera, SceneError> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        return Err(SceneError::Invalid {
            location: format!("{ctx}.to_world"),
            reason: "contains NaN or infinite entries; fix: write finite numbers".into(),
        });
    }
    let last = m[3];
    if last[0].abs() > 1e-6
        || last[1].abs() > 1e-6
        || last[2].abs() > 1e-6
        || (last[3] - 1.0).abs() > 1e-6
    {
        return Err(SceneError::Invalid {
            location: format!("{ctx}.to_world[3] = {last:?}"),
            reason: "the last row of a camera to_world must be [0, 0, 0, 1] (rows are stored \
                     first: to_world[r][c]); fix: check that the matrix is row-major"
                .into(),
        });
    }
    let rows = m.map(|r| r.map(|v| v as f32));
    let cam = Camera::from_to_world(rows, fov, width, height);
    let probe = Camera {
        rotation: glam::Mat3::IDENTITY,
        ..cam.clone()
    };
    probe.validate_named(ctx, "fov_x_deg")?;
    cam.validate_named(ctx, "fov_x_deg")?;
    Ok(cam)
}

#[cfg(test)]
#[allow(clippy::excessive_precision, clippy::type_complexity)]
// numbers copied verbatim from Mitsuba's scene.json
mod tests;
