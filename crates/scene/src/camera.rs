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

use crate::SceneError;
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
#[allow(clippy::excessive_precision, clippy::type_complexity)] // numbers copied verbatim from Mitsuba's scene.json
mod tests {
    use super::*;

    fn cam(w: u32, h: u32) -> Camera {
        Camera::look_at(
            Vec3::new(0.3, 0.8, 2.5),
            Vec3::new(0.1, -0.2, 0.0),
            Vec3::Y,
            40.0,
            w,
            h,
        )
    }

    fn calibrated(w: u32, h: u32) -> Camera {
        cam(w, h).with_intrinsics(&Intrinsics {
            fx: 61.5,
            fy: 66.0,
            cx: 0.5 * w as f32 + 7.25,
            cy: 0.5 * h as f32 - 4.5,
        })
    }

    /// A calibrated camera's rays and projections are inverse (a crop's too), and its
    /// intrinsics read back as given.
    #[test]
    fn a_calibrated_camera_projects_its_rays_back_to_their_pixels() {
        let c = calibrated(64, 48);
        let k = c.intrinsics();
        assert!(
            (k.fx - 61.5).abs() < 1e-3 && (k.fy - 66.0).abs() < 1e-3,
            "{k:?}"
        );
        assert_eq!((k.cx, k.cy), (39.25, 19.5));
        for cam in [c.clone(), c.cropped(6, 3, 40, 30).unwrap()] {
            for (px, py) in [(0.0, 0.0), (3.5, 2.25), (21.0, 17.5), (39.9, 29.9)] {
                let (o, d) = cam.ray(px, py);
                let (qx, qy) = cam.project(o + 2.5 * d).unwrap();
                assert!(
                    (qx - px).abs() < 2e-3 && (qy - py).abs() < 2e-3,
                    "{px},{py}: {qx},{qy}"
                );
            }
        }
        // The ray through the principal point is the view direction.
        let (_, d) = c.ray(k.cx, k.cy);
        assert!((d - c.direction()).length() < 1e-6, "{d:?}");
        let back: Camera = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
        assert_eq!(back, c);
    }

    /// The centred, square-pixel intrinsics are the plain camera (no pinhole, the same rays);
    /// a principal point moved by whole pixels moves the image by as many pixels.
    #[test]
    fn the_centred_intrinsics_are_the_plain_camera() {
        let plain = cam(64, 48);
        let same = plain.clone().with_intrinsics(&plain.intrinsics());
        assert_eq!(same.pinhole, None);
        assert!((same.fov_x_deg - plain.fov_x_deg).abs() < 1e-4);
        let k = plain.intrinsics();
        let shifted = plain.clone().with_intrinsics(&Intrinsics {
            cx: k.cx + 3.0,
            cy: k.cy - 2.0,
            ..k
        });
        for (px, py) in [(0.5, 0.5), (10.25, 30.75), (40.0, 20.0)] {
            let (_, a) = plain.ray(px, py);
            let (_, b) = shifted.ray(px + 3.0, py - 2.0);
            assert!((a - b).length() < 1e-6, "{px},{py}: {a:?} {b:?}");
        }
        let e = plain
            .clone()
            .with_intrinsics(&Intrinsics { cx: 500.0, ..k })
            .validate("test")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("test.cx") && e.contains("within one image size"),
            "{e}"
        );
    }

    /// A crop sees exactly what the full camera sees at the shifted pixels, crops compose, and
    /// projection returns crop-local coordinates.
    #[test]
    fn crops_are_windows_of_the_full_film() {
        let full = cam(64, 48);
        let c = full.cropped(10, 7, 20, 16).unwrap();
        assert_eq!((c.width, c.height), (20, 16));
        for (px, py) in [(0.0, 0.0), (3.5, 2.25), (19.9, 15.9)] {
            assert_eq!(c.ray(px, py), full.ray(px + 10.0, py + 7.0));
        }
        let cc = c.cropped(4, 5, 8, 8).unwrap();
        assert_eq!(cc.ray(1.5, 2.5), full.ray(15.5, 14.5));
        let p = full.ray(33.25, 20.5).1 * 2.0 + full.origin;
        let (fx, fy) = full.project(p).unwrap();
        let (cx, cy) = c.project(p).unwrap();
        assert!((cx + 10.0 - fx).abs() < 1e-3 && (cy + 7.0 - fy).abs() < 1e-3);
        // Survives serialization (datasets and checkpoints store cameras).
        let back: Camera = serde_json::from_str(&serde_json::to_string(&cc).unwrap()).unwrap();
        assert_eq!(back, cc);
        for (x0, y0, w, h) in [
            (60, 0, 5, 5),
            (0, 40, 4, 9),
            (0, 0, 0, 4),
            (u32::MAX, 0, 2, 2),
        ] {
            let e = full.cropped(x0, y0, w, h).unwrap_err().to_string();
            assert!(e.contains("does not fit in the 64×48 image"), "{e}");
        }
    }

    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).abs().max_element() <= tol
    }

    #[test]
    fn centre_pixel_ray_is_the_view_direction() {
        for (w, h) in [(64, 64), (65, 33), (100, 40)] {
            let c = cam(w, h);
            let (o, d) = c.ray(w as f32 / 2.0, h as f32 / 2.0);
            assert_eq!(o, c.origin);
            let z = (Vec3::new(0.1, -0.2, 0.0) - c.origin).normalize();
            assert!(close(d, z, 1e-6), "{d} vs {z}");
        }
    }

    #[test]
    fn px_zero_is_image_left_and_py_zero_is_up() {
        let c = cam(80, 60);
        let (x, y, z) = (c.rotation.x_axis, c.rotation.y_axis, c.rotation.z_axis);
        // x = normalize(cross(up, z)) is image LEFT: column 0 looks towards +x.
        assert!(close(x, Vec3::Y.cross(z).normalize(), 1e-6));
        let (_, left) = c.ray(0.0, 30.0);
        let (_, right) = c.ray(80.0, 30.0);
        assert!(left.dot(x) > 0.0 && right.dot(x) < 0.0);
        assert!(left.dot(y).abs() < 1e-6);
        // Row 0 looks up (+y), the last row down.
        let (_, top) = c.ray(40.0, 0.0);
        let (_, bottom) = c.ray(40.0, 60.0);
        assert!(top.dot(y) > 0.0 && bottom.dot(y) < 0.0);
        // fov along x: the left edge is at angle fov/2 from the axis; the top edge at
        // atan(tan(fov/2)·H/W).
        let t = 20f32.to_radians().tan();
        assert!((left.dot(x) / left.dot(z) - t).abs() < 1e-5);
        assert!((top.dot(y) / top.dot(z) - t * 60.0 / 80.0).abs() < 1e-5);
        // World up (+Y) appears at the top of the image for this camera.
        assert!(y.dot(Vec3::Y) > 0.0);
    }

    #[test]
    fn project_round_trips_ray() {
        let c = cam(97, 41);
        for &(px, py) in &[
            (0.0, 0.0),
            (0.5, 0.5),
            (96.5, 40.5),
            (48.5, 20.5),
            (10.25, 33.75),
            (97.0, 41.0),
        ] {
            let (o, d) = c.ray(px, py);
            for t in [0.5f32, 2.0, 7.0] {
                let (qx, qy) = c.project(o + t * d).expect("in front of the camera");
                assert!(
                    (qx - px).abs() < 2e-3 && (qy - py).abs() < 2e-3,
                    "({px},{py}) -> ({qx},{qy})"
                );
            }
        }
        assert!(c.project(c.origin - c.direction()).is_none());
    }

    #[test]
    fn camera_from_to_world_equals_look_at() {
        // View 0 of the Mitsuba reference render (numbers copied from its scene.json).
        let rows = [
            [
                -0.29552020666133955,
                -0.8359194279849053,
                -0.4625002890509669,
                0.23125014452548345,
            ],
            [0.0, 0.4841229182759271, -0.875, 0.4375],
            [
                0.955336489125606,
                -0.2585801808286721,
                -0.14306810485839278,
                0.07153405242919639,
            ],
            [0.0, 0.0, 0.0, 1.0],
        ]
        .map(|r: [f64; 4]| r.map(|v| v as f32));
        let a = Camera::from_to_world(rows, 40.0, 64, 64);
        let b = Camera::look_at(
            Vec3::new(0.23125014452548345, 0.4375, 0.07153405242919639),
            Vec3::ZERO,
            Vec3::Y,
            40.0,
            64,
            64,
        );
        assert!(close(a.origin, b.origin, 1e-7));
        for i in 0..3 {
            assert!(
                close(a.rotation.col(i), b.rotation.col(i), 1e-6),
                "column {i}"
            );
        }
        for &(px, py) in &[(0.0, 0.0), (32.0, 32.0), (16.0, 44.8)] {
            assert!(close(a.ray(px, py).1, b.ray(px, py).1, 1e-6));
        }
        // And back to rows.
        let back = b.to_world_rows();
        for r in 0..4 {
            for c in 0..4 {
                assert!((back[r][c] - rows[r][c]).abs() < 1e-6);
            }
        }
        a.validate("test").unwrap();
    }

    #[test]
    fn validate_names_the_field() {
        let mut c = cam(8, 8);
        c.width = 0;
        assert!(c.validate("x").unwrap_err().to_string().contains("x.width"));
        let mut c = cam(8, 8);
        c.fov_x_deg = 180.0;
        assert!(c.validate("x").unwrap_err().to_string().contains("x.fov"));
        let mut c = cam(8, 8);
        c.rotation *= 2.0;
        assert!(
            c.validate("x")
                .unwrap_err()
                .to_string()
                .contains("orthonormal")
        );
        let mut c = cam(8, 8);
        c.rotation.x_axis = -c.rotation.x_axis;
        assert!(
            c.validate("x")
                .unwrap_err()
                .to_string()
                .contains("reflection")
        );
    }
}
