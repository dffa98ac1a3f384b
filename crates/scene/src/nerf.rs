//! NeRF-style `transforms.json` (the synthetic scenes of Mildenhall et al. 2020, instant-ngp,
//! nerfstudio, light-stage OLAT sets): the cameras, poses and lights of a capture, read as the
//! views of a [`Capture`].
//!
//! Intrinsics, at the top level or per frame (a frame's own value wins):
//! - `w`, `h`: the image size in pixels (taken from the image file where absent);
//! - `fl_x`, `fl_y` (pixels; `fl_y` defaults to `fl_x`), or `camera_angle_x` (radians, the full
//!   horizontal field of view: f_x = w / (2 tan(angle/2))) with an optional `camera_angle_y`;
//! - `cx`, `cy` (pixels from the image's top-left corner; default w/2, h/2);
//! - distortion `k1`…`k4`, `p1`, `p2`: refused unless 0 (undistort the images first), as is a
//!   `camera_model` other than a pinhole (`OPENCV` with zero distortion is one).
//!
//! Each frame: `file_path` (relative to the file's folder; without an extension as in the
//! Blender scenes, `./train/r_0`, it names `r_0.png`), and `transform_matrix`, the camera-to-world
//! matrix (4 rows of 4, or 3 rows) in OpenGL's camera convention: columns x to the image's right,
//! y up, z **backwards** (the camera looks along −z), then the camera's position. Ours
//! ([`crate::camera`]) has x to the left and z forwards: its axes are (−c₀, c₁, −c₂). World
//! coordinates are kept as they are: the mesh must be in the same frame.
//!
//! A light per frame (OLAT captures): `light_position` or `light_pos` ([x, y, z]), or
//! `light_transform` or `light_pose` (a 4 × 4 light-to-world matrix: its translation). instant-ngp's
//! `scale`, `offset` and `aabb_scale` configure its own normalisation of the poses, not the
//! capture, and are not read.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3, Mat3, Vec3};
use serde_json::{Map, Value};

use crate::SceneError;
use crate::camera::{Camera, Intrinsics};
use crate::capture::{CaptureLight, CapturedView};

#[cfg(test)]
mod tests;

/// One frame: its image, its pose and intrinsics, its light if it states one.
#[derive(Clone, Debug, PartialEq)]
pub struct NerfFrame {
    /// `file_path` as written.
    pub file_path: String,
    /// The camera-to-world matrix, OpenGL convention.
    pub transform: [[f64; 4]; 4],
    /// The frame's intrinsic fields merged over the file's (the frame's win).
    pub intrinsics: Map<String, Value>,
    pub light: Option<Vec3>,
}

/// A `transforms.json`.
#[derive(Clone, Debug, PartialEq)]
pub struct NerfTransforms {
    /// The file it was read from.
    pub file: PathBuf,
    pub frames: Vec<NerfFrame>,
}

/// The intrinsic keys, read at the top level and per frame.
const INTRINSIC_KEYS: [&str; 15] = [
    "w",
    "h",
    "fl_x",
    "fl_y",
    "cx",
    "cy",
    "camera_angle_x",
    "camera_angle_y",
    "k1",
    "k2",
    "k3",
    "k4",
    "p1",
    "p2",
    "camera_model",
];

impl NerfTransforms {
    /// Read a `transforms.json`; errors name the file, the field and the fix.
    pub fn read(file: &Path) -> Result<NerfTransforms, SceneError> {
        let text = std::fs::read_to_string(file).map_err(|source| SceneError::Io {
            path: file.to_path_buf(),
            source,
        })?;
        let root: Value = serde_json::from_str(&text).map_err(|e| SceneError::Parse {
            path: file.to_path_buf(),
            reason: e.to_string(),
        })?;
        let ctx = file.display().to_string();
        let top = root
            .as_object()
            .ok_or_else(|| invalid(&ctx, "", "must be a JSON object"))?;
        let shared = intrinsic_fields(top);
        let frames = top
            .get("frames")
            .and_then(Value::as_array)
            .filter(|f| !f.is_empty())
            .ok_or_else(|| {
                invalid(
                    &ctx,
                    "frames",
                    "must be a non-empty array of {file_path, transform_matrix}",
                )
            })?;
        let frames = frames
            .iter()
            .enumerate()
            .map(|(i, f)| frame(f, &shared, &format!("frames[{i}]"), &ctx))
            .collect::<Result<_, _>>()?;
        Ok(NerfTransforms {
            file: file.to_path_buf(),
            frames,
        })
    }

    /// The folder the frames' `file_path`s are relative to.
    pub fn dir(&self) -> PathBuf {
        crate::scene_file::parse::base_dir(&self.file)
    }

    /// The lights the frames state, by `file_path`, when every frame states one; `None` when
    /// none does; an error naming the first frame without one when only some do.
    pub fn lights(&self) -> Result<Option<CaptureLight>, SceneError> {
        let stated: BTreeMap<String, Vec3> = self
            .frames
            .iter()
            .filter_map(|f| f.light.map(|l| (f.file_path.clone(), l)))
            .collect();
        if stated.is_empty() {
            return Ok(None);
        }
        match self.frames.iter().position(|f| f.light.is_none()) {
            Some(i) => Err(invalid(
                &self.file.display().to_string(),
                &format!("frames[{i}]"),
                "states no light, while other frames do; fix: give every frame a \
                 light_position (or none, and the light on the command line)",
            )),
            None => Ok(Some(CaptureLight::Positions(stated))),
        }
    }

    /// The dataset of `capture` with these frames' cameras: each frame's image read from
    /// `capture.images` (its size from the image where the file states none).
    pub fn dataset(&self, capture: &crate::capture::Capture) -> Result<crate::Dataset, SceneError> {
        let views = self.views(|name| capture.image_size(name))?;
        let units = format!(
            "lengths in the units of {} (sigma_t in 1/those units); light intensity in W/sr, \
             relative unless measured; images linear radiance",
            self.file.display()
        );
        let fix = "pass the images the poses were made from, or correct w and h";
        capture.dataset(&views, units, "transforms.json import", fix)
    }

    /// Each frame as a view: its camera, with the image size from `size` (called with the
    /// frame's `file_path`) where the file states none.
    pub fn views(
        &self,
        mut size: impl FnMut(&str) -> Result<(u32, u32), SceneError>,
    ) -> Result<Vec<CapturedView>, SceneError> {
        let ctx = self.file.display().to_string();
        self.frames
            .iter()
            .enumerate()
            .map(|(i, f)| {
                let at = format!("frames[{i}]");
                let camera = frame_camera(f, &mut size, &at, &ctx)?;
                Ok(CapturedView {
                    name: f.file_path.clone(),
                    camera,
                })
            })
            .collect()
    }
}

fn intrinsic_fields(obj: &Map<String, Value>) -> Map<String, Value> {
    INTRINSIC_KEYS
        .iter()
        .filter_map(|k| obj.get(*k).map(|v| (k.to_string(), v.clone())))
        .collect()
}

fn frame(
    f: &Value,
    shared: &Map<String, Value>,
    at: &str,
    ctx: &str,
) -> Result<NerfFrame, SceneError> {
    let obj = f
        .as_object()
        .ok_or_else(|| invalid(ctx, at, "must be an object {file_path, transform_matrix}"))?;
    let file_path = obj
        .get("file_path")
        .and_then(Value::as_str)
        .filter(|s| !s.is_empty())
        .ok_or_else(|| {
            invalid(
                ctx,
                &format!("{at}.file_path"),
                "must name the frame's image",
            )
        })?
        .to_string();
    let transform = matrix(
        obj.get("transform_matrix"),
        &format!("{at}.transform_matrix"),
        ctx,
    )?;
    let mut intrinsics = shared.clone();
    intrinsics.extend(intrinsic_fields(obj));
    let light = match (
        obj.get("light_position").or(obj.get("light_pos")),
        obj.get("light_transform").or(obj.get("light_pose")),
    ) {
        (Some(p), _) => Some(vec3(p, &format!("{at}.light_position"), ctx)?),
        (None, Some(m)) => {
            let m = matrix(Some(m), &format!("{at}.light_transform"), ctx)?;
            Some(Vec3::new(m[0][3] as f32, m[1][3] as f32, m[2][3] as f32))
        }
        (None, None) => None,
    };
    Ok(NerfFrame {
        file_path,
        transform,
        intrinsics,
        light,
    })
}

/// A 4 × 4 (or 3 × 4, the last row taken as [0, 0, 0, 1]) matrix of finite numbers.
fn matrix(v: Option<&Value>, at: &str, ctx: &str) -> Result<[[f64; 4]; 4], SceneError> {
    let bad = || {
        invalid(
            ctx,
            at,
            "must be 4 rows (or 3) of 4 finite numbers, row-major",
        )
    };
    let rows = v.and_then(Value::as_array).ok_or_else(bad)?;
    if !(rows.len() == 3 || rows.len() == 4) {
        return Err(bad());
    }
    let mut m = [
        [0.0, 0.0, 0.0, 0.0],
        [0.0; 4],
        [0.0; 4],
        [0.0, 0.0, 0.0, 1.0],
    ];
    for (r, row) in rows.iter().enumerate() {
        let row = row.as_array().filter(|r| r.len() == 4).ok_or_else(bad)?;
        for (c, x) in row.iter().enumerate() {
            m[r][c] = x.as_f64().filter(|x| x.is_finite()).ok_or_else(bad)?;
        }
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(invalid(ctx, at, "its last row must be [0, 0, 0, 1]"));
    }
    Ok(m)
}

fn vec3(v: &Value, at: &str, ctx: &str) -> Result<Vec3, SceneError> {
    let bad = || invalid(ctx, at, "must be [x, y, z], finite numbers");
    let a = v.as_array().filter(|a| a.len() == 3).ok_or_else(bad)?;
    let x: Vec<f64> = a
        .iter()
        .map(|x| x.as_f64().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(bad)?;
    Ok(Vec3::new(x[0] as f32, x[1] as f32, x[2] as f32))
}

/// A frame's camera: its size, intrinsics and pose, checked.
fn frame_camera(
    f: &NerfFrame,
    size: &mut impl FnMut(&str) -> Result<(u32, u32), SceneError>,
    at: &str,
    ctx: &str,
) -> Result<Camera, SceneError> {
    let k = &f.intrinsics;
    let num = |key: &str| -> Result<Option<f64>, SceneError> {
        match k.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite())
                .map(Some)
                .ok_or_else(|| invalid(ctx, &format!("{at}: {key}"), "must be a finite number")),
        }
    };
    if let Some(model) = k.get("camera_model").and_then(Value::as_str)
        && !matches!(model, "OPENCV" | "PINHOLE" | "SIMPLE_PINHOLE")
    {
        return Err(invalid(
            ctx,
            &format!("{at}: camera_model"),
            &format!("{model:?} is not a pinhole; fix: undistort the images to a pinhole camera"),
        ));
    }
    for key in ["k1", "k2", "k3", "k4", "p1", "p2"] {
        if num(key)?.is_some_and(|x| x != 0.0) {
            return Err(invalid(
                ctx,
                &format!("{at}: {key}"),
                "the camera distorts, and distortion is not modelled; fix: undistort the images \
                 (e.g. nerfstudio's or COLMAP's undistorter) and write a pinhole",
            ));
        }
    }
    let (w, h) = match (num("w")?, num("h")?) {
        (Some(w), Some(h)) => (pixels(w, "w", at, ctx)?, pixels(h, "h", at, ctx)?),
        _ => size(&f.file_path)?,
    };
    let fx = match (num("fl_x")?, num("camera_angle_x")?) {
        (Some(fx), _) => fx,
        (None, Some(a)) if a > 0.0 && a < std::f64::consts::PI => 0.5 * w as f64 / (0.5 * a).tan(),
        (None, Some(a)) => {
            return Err(invalid(
                ctx,
                &format!("{at}: camera_angle_x"),
                &format!("{a} must be in (0, π): the horizontal field of view in radians"),
            ));
        }
        (None, None) => {
            return Err(invalid(
                ctx,
                at,
                "states no focal length; fix: give fl_x (pixels) or camera_angle_x (radians)",
            ));
        }
    };
    let fy = match (num("fl_y")?, num("camera_angle_y")?) {
        (Some(fy), _) => fy,
        (None, Some(a)) if a > 0.0 && a < std::f64::consts::PI => 0.5 * h as f64 / (0.5 * a).tan(),
        _ => fx,
    };
    if !(fx > 0.0 && fy > 0.0) {
        return Err(invalid(
            ctx,
            at,
            &format!("focal lengths f_x = {fx}, f_y = {fy}: they must be positive (pixels)"),
        ));
    }
    let intrinsics = Intrinsics {
        fx: fx as f32,
        fy: fy as f32,
        cx: num("cx")?.unwrap_or(0.5 * w as f64) as f32,
        cy: num("cy")?.unwrap_or(0.5 * h as f64) as f32,
    };
    let m = &f.transform;
    let col = |c: usize| DVec3::new(m[0][c], m[1][c], m[2][c]);
    let r = DMat3::from_cols(-col(0), col(1), -col(2));
    let camera = Camera {
        origin: col(3).as_vec3(),
        rotation: Mat3::from_cols(r.x_axis.as_vec3(), r.y_axis.as_vec3(), r.z_axis.as_vec3()),
        fov_x_deg: 40.0,
        width: w,
        height: h,
        crop: None,
        pinhole: None,
        mask: None,
    };
    let camera = camera.with_intrinsics(&intrinsics);
    camera.validate(&format!("{ctx}: {at}"))?;
    Ok(camera)
}

fn pixels(x: f64, key: &str, at: &str, ctx: &str) -> Result<u32, SceneError> {
    if (1.0..=65536.0).contains(&x) && x.fract() == 0.0 {
        Ok(x as u32)
    } else {
        Err(invalid(
            ctx,
            &format!("{at}: {key}"),
            &format!("{x} must be a whole number of pixels in 1…65536"),
        ))
    }
}

fn invalid(ctx: &str, at: &str, reason: &str) -> SceneError {
    SceneError::Invalid {
        location: if at.is_empty() {
            ctx.to_string()
        } else {
            format!("{ctx}: {at}")
        },
        reason: reason.to_string(),
    }
}
