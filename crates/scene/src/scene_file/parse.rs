//! Parsing and validating scene files: TOML or JSON chosen by the extension, the file as written
//! (`RawScene`, strict: unknown fields are errors) validated into a [`SceneDesc`], and the checks
//! shared with dataset files (mesh paths, finite coordinates, checked look-at cameras).

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Deserialize;

use super::desc::{MeshSource, RenderInfo, SceneDesc, ViewDesc};
use super::spec::{MediumSpec, Rgb, ShapeSpec};
use crate::measured::{LengthUnit, MeasuredMedium};
use crate::rig::{Rig, RigLight, check_intensity};
use crate::{Camera, Medium, PointLight, SceneError};

/// Resolve `mesh` against `base_dir` and check that the file exists.
pub(crate) fn resolve_mesh_path(
    mesh: &Path,
    base_dir: &Path,
    location: &str,
) -> Result<PathBuf, SceneError> {
    let resolved = if mesh.is_absolute() {
        mesh.to_path_buf()
    } else {
        base_dir.join(mesh)
    };
    if !resolved.is_file() {
        return Err(SceneError::Invalid {
            location: format!("{location} = \"{}\"", mesh.display()),
            reason: format!(
                "mesh file not found (looked for {}); fix: relative paths are resolved from the \
                 folder of this file — check the name or give an absolute path",
                resolved.display()
            ),
        });
    }
    Ok(resolved)
}

/// The folder relative paths in `file` are resolved from.
pub(crate) fn base_dir(file: &Path) -> PathBuf {
    match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Deserialize TOML (`.toml`) or JSON (`.json`) by the extension of `path`.
pub(crate) fn parse_by_extension<T: serde::de::DeserializeOwned>(
    text: &str,
    path: &Path,
) -> Result<T, SceneError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("toml") => toml::from_str(text).map_err(|e| SceneError::Parse {
            path: path.to_path_buf(),
            reason: e.to_string().trim_end().to_string(),
        }),
        Some("json") => serde_json::from_str(text).map_err(|e| SceneError::Parse {
            path: path.to_path_buf(),
            reason: e.to_string(),
        }),
        _ => Err(SceneError::Parse {
            path: path.to_path_buf(),
            reason: "unknown file type; fix: name the file *.toml or *.json (or *.xml for a Mitsuba 3 scene)".into(),
        }),
    }
}

pub(crate) fn check_finite3(v: [f32; 3], location: &str) -> Result<Vec3, SceneError> {
    let p = Vec3::from_array(v);
    if !p.is_finite() {
        return Err(SceneError::Invalid {
            location: format!("{location} = {v:?}"),
            reason: "coordinates must be finite numbers".into(),
        });
    }
    Ok(p)
}

/// A look-at camera, validated: origin ≠ target, up not parallel to the view direction,
/// resolution and fov in range. `ctx` is e.g. "scene.toml: views[0].camera".
#[allow(clippy::too_many_arguments)]
pub(crate) fn look_at_checked(
    ctx: &str,
    origin: [f32; 3],
    target: [f32; 3],
    up: [f32; 3],
    fov: f32,
    fov_field: &str,
    width: u32,
    height: u32,
) -> Result<Camera, SceneError> {
    let o = check_finite3(origin, &format!("{ctx}.origin"))?;
    let t = check_finite3(target, &format!("{ctx}.target"))?;
    let u = check_finite3(up, &format!("{ctx}.up"))?;
    let dist = (t - o).length();
    if dist <= 1e-6 * o.length().max(1.0) {
        return Err(SceneError::Invalid {
            location: format!("{ctx}.target = {target:?}"),
            reason: format!(
                "the camera sits at its target (origin = {origin:?}); fix: move the origin away \
                 from the target"
            ),
        });
    }
    let z = (t - o) / dist;
    if u.length() < 1e-12 || u.normalize().cross(z).length() < 1e-3 {
        return Err(SceneError::Invalid {
            location: format!("{ctx}.up = {up:?}"),
            reason: "up is zero or parallel to the view direction (target − origin), so the image \
                     orientation is undefined; fix: use another up, e.g. [0, 0, 1] for a camera \
                     looking straight down"
                .into(),
        });
    }
    // Resolution and fov first (so that they are reported even with a degenerate frame).
    let probe = Camera {
        origin: o,
        rotation: glam::Mat3::IDENTITY,
        fov_x_deg: fov,
        width,
        height,
        crop: None,
        pinhole: None,
        mask: None,
    };
    probe.validate_named(ctx, fov_field)?;
    let cam = Camera::look_at(o, t, u, fov, width, height);
    cam.validate_named(ctx, fov_field)?;
    Ok(cam)
}

// The scene file as written.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawScene {
    length_unit: Option<LengthUnit>,
    mesh: Option<PathBuf>,
    shape: Option<ShapeSpec>,
    medium: RawMedium,
    views: Option<Vec<RawView>>,
    rig: Option<RawRig>,
    render: Option<RenderInfo>,
}

/// The scene's `[medium]` as written: σ_t and α, or a measured medium by name (`measured`, in
/// the scene's `length_unit`), and the object's g, η and boundary roughness.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMedium {
    measured: Option<String>,
    sigma_t: Option<Rgb>,
    albedo: Option<Rgb>,
    #[serde(default)]
    g: crate::Anisotropy,
    #[serde(default = "crate::medium::one")]
    eta: f32,
    #[serde(default)]
    roughness: f32,
}

impl RawMedium {
    /// The validated medium; `file` names the scene file, `unit` is its `length_unit`.
    fn medium(self, file: &str, unit: Option<LengthUnit>) -> Result<Medium, SceneError> {
        let inv = |field: &str, reason: String| SceneError::Invalid {
            location: format!("{file}: medium.{field}"),
            reason,
        };
        let (sigma_t, albedo) = match (&self.measured, self.sigma_t, self.albedo) {
            (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
                return Err(inv(
                    "measured",
                    "a measured medium gives σ_t and α itself; fix: remove sigma_t and albedo, \
                     or remove measured"
                        .into(),
                ));
            }
            (Some(name), None, None) => {
                let m = MeasuredMedium::find(name).map_err(|e| match e {
                    SceneError::Invalid { reason, .. } => {
                        let shown: String = name.chars().take(40).collect();
                        let more = if shown.len() < name.len() { "…" } else { "" };
                        inv("measured", format!("= {shown:?}{more}: {reason}"))
                    }
                    e => e,
                })?;
                let Some(unit) = unit else {
                    return Err(SceneError::Invalid {
                        location: format!("{file}: length_unit"),
                        reason: format!(
                            "missing: the measured medium {:?} is known in 1/mm, so the scene \
                             must say what one of its units is; fix: add length_unit = \"mm\" \
                             (or \"cm\", \"m\") at the top of the file",
                            m.name
                        ),
                    });
                };
                if let Some((c, g)) = self.g.out_of_range() {
                    return Err(inv(
                        &self.g.field(c),
                        format!("= {g} must be in (−1, 1); fix: e.g. g = 0"),
                    ));
                }
                let (sigma_t, albedo) = m.medium_rgb(self.g.channels().map(f64::from), unit);
                (Rgb(sigma_t), Rgb(albedo))
            }
            (None, Some(sigma_t), Some(albedo)) => (sigma_t, albedo),
            (None, sigma_t, _) => {
                let field = if sigma_t.is_none() {
                    "sigma_t"
                } else {
                    "albedo"
                };
                return Err(inv(
                    field,
                    "missing; fix: add sigma_t (extinction in 1/scene unit) and albedo, three \
                     numbers or one each, or name a measured medium with measured = \"marble\" \
                     (and length_unit)"
                        .into(),
                ));
            }
        };
        MediumSpec {
            sigma_t,
            albedo,
            g: self.g,
            eta: self.eta,
            roughness: self.roughness,
        }
        .to_medium(&format!("{file}: medium"))
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawView {
    camera: RawCamera,
    light: RawLight,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

fn default_fov() -> f32 {
    40.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCamera {
    origin: [f32; 3],
    target: [f32; 3],
    #[serde(default = "default_up")]
    up: [f32; 3],
    #[serde(default = "default_fov")]
    fov: f32,
    width: u32,
    height: u32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    position: [f32; 3],
    intensity: Rgb,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Debug)]
#[serde(rename_all = "lowercase")]
enum RawRigLight {
    Fixed,
    Attached,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRig {
    views: usize,
    radius: f32,
    #[serde(default)]
    target: [f32; 3],
    #[serde(default = "default_fov")]
    fov: f32,
    width: u32,
    height: u32,
    light: RawRigLight,
    light_position: Option<[f32; 3]>,
    light_offset: Option<[f32; 3]>,
    intensity: Rgb,
    elevation: Option<[f32; 2]>,
}

impl RawScene {
    pub(super) fn validate(self, path: &Path) -> Result<SceneDesc, SceneError> {
        let file = path.display().to_string();
        let inv = |location: String, reason: &str| SceneError::Invalid {
            location,
            reason: reason.into(),
        };
        let mesh = match (self.mesh, self.shape) {
            (Some(_), Some(_)) => {
                return Err(inv(
                    format!("{file}: mesh, shape"),
                    "both `mesh` and `shape` are given; fix: keep exactly one of them",
                ));
            }
            (None, None) => {
                return Err(inv(
                    format!("{file}: mesh"),
                    "no geometry: fix: add `mesh = \"object.ply\"` (OBJ or PLY, relative to this \
                     file) or `shape = { name = \"sphere\" }`",
                ));
            }
            (Some(m), None) => MeshSource::File(resolve_mesh_path(
                &m,
                &base_dir(path),
                &format!("{file}: mesh"),
            )?),
            (None, Some(s)) => MeshSource::Shape(s.to_shape(&format!("{file}: shape"))?),
        };
        let medium = self.medium.medium(&file, self.length_unit)?;
        let views = match (self.views, self.rig) {
            (Some(_), Some(_)) => {
                return Err(inv(
                    format!("{file}: views, rig"),
                    "both `[[views]]` and `[rig]` are given; fix: keep exactly one of them",
                ));
            }
            (None, None) => {
                return Err(inv(
                    format!("{file}: views"),
                    "no cameras: fix: add `[[views]]` entries (camera + light) or a `[rig]`",
                ));
            }
            (Some(v), None) => listed_views(v, &file)?,
            (None, Some(r)) => rig_views(r, &file)?,
        };
        let render = self.render.unwrap_or_default();
        render.validate(&format!("{file}: render"))?;
        Ok(SceneDesc {
            mesh,
            medium,
            views,
            render,
            path: path.to_path_buf(),
            length_unit: self.length_unit,
        })
    }
}

/// The scene's `[[views]]`, each camera and light checked (`file` names the scene file).
fn listed_views(v: Vec<RawView>, file: &str) -> Result<Vec<ViewDesc>, SceneError> {
    let inv = |location: String, reason: &str| SceneError::Invalid {
        location,
        reason: reason.into(),
    };
    if v.is_empty() {
        return Err(inv(
            format!("{file}: views"),
            "the list of views is empty; fix: add at least one view",
        ));
    }
    let mut out = Vec::with_capacity(v.len());
    for (i, view) in v.into_iter().enumerate() {
        let ctx = format!("{file}: views[{i}]");
        let c = &view.camera;
        let camera = look_at_checked(
            &format!("{ctx}.camera"),
            c.origin,
            c.target,
            c.up,
            c.fov,
            "fov",
            c.width,
            c.height,
        )?;
        let position = check_finite3(view.light.position, &format!("{ctx}.light.position"))?;
        check_intensity(&view.light.intensity.0, &format!("{ctx}.light.intensity"))?;
        out.push(ViewDesc {
            camera,
            light: PointLight {
                position,
                intensity: view.light.intensity.0,
            },
        });
    }
    Ok(out)
}

/// The views of the scene's `[rig]`, checked (`file` names the scene file).
fn rig_views(r: RawRig, file: &str) -> Result<Vec<ViewDesc>, SceneError> {
    let inv = |location: String, reason: &str| SceneError::Invalid {
        location,
        reason: reason.into(),
    };
    let ctx = format!("{file}: rig");
    let light = match (r.light, r.light_position, r.light_offset) {
        (RawRigLight::Fixed, Some(p), None) => RigLight::Fixed {
            position: Vec3::from_array(p),
        },
        (RawRigLight::Fixed, None, _) => {
            return Err(inv(
                format!("{ctx}.light_position"),
                "missing: a fixed light needs `light_position = [x, y, z]` (world \
                 coordinates); fix: add it, or use light = \"attached\"",
            ));
        }
        (RawRigLight::Fixed, Some(_), Some(_)) => {
            return Err(inv(
                format!("{ctx}.light_offset"),
                "only used with light = \"attached\"; fix: remove it",
            ));
        }
        (RawRigLight::Attached, None, off) => RigLight::Attached {
            offset: Vec3::from_array(off.unwrap_or_default()),
        },
        (RawRigLight::Attached, Some(_), _) => {
            return Err(inv(
                format!("{ctx}.light_position"),
                "only used with light = \"fixed\"; an attached light is placed with \
                 `light_offset` (camera frame); fix: remove it",
            ));
        }
    };
    let elevation = r.elevation.unwrap_or([-90.0, 90.0]);
    let rig = Rig {
        views: r.views,
        radius: r.radius,
        target: Vec3::from_array(r.target),
        fov_x_deg: r.fov,
        width: r.width,
        height: r.height,
        light,
        intensity: r.intensity.0,
        elevation_deg: (elevation[0], elevation[1]),
    };
    rig.validate(&ctx)?;
    let probe = Camera {
        origin: Vec3::ZERO,
        rotation: glam::Mat3::IDENTITY,
        fov_x_deg: r.fov,
        width: r.width,
        height: r.height,
        crop: None,
        pinhole: None,
        mask: None,
    };
    probe.validate_named(&ctx, "fov")?;
    let views = rig.build();
    for (i, v) in views.iter().enumerate() {
        v.camera.validate(&format!("{ctx} (view {i})"))?;
    }
    Ok(views)
}
