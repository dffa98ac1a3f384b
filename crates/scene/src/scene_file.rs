//! Scene files (TOML or JSON, by extension): mesh or built-in shape, medium, cameras and per-view
//! point lights, or a multi-view rig. Documented in SCENE.md (the full example there is
//! [`EXAMPLE_SCENE_TOML`]).
//!
//! Parsing is strict: unknown fields are errors (with the line and column for TOML and JSON), and
//! every value is range-checked with an error that names the file, the field and the fix.

use std::fmt;
use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use crate::rig::{Rig, RigLight, check_intensity};
use crate::{Camera, Medium, PointLight, SceneError};

/// Where the mesh comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshSource {
    /// A mesh file (path resolved relative to the scene file).
    File(PathBuf),
    /// A built-in shape.
    Shape(geometry::Shape),
}

impl MeshSource {
    /// Build (shape) or load (file: OBJ or PLY) the mesh, validated by the geometry crate; the
    /// warnings say what was repaired (flipped orientation, dropped degenerate triangles, …).
    pub fn load(&self) -> Result<(geometry::Mesh, Vec<geometry::MeshWarning>), SceneError> {
        match self {
            MeshSource::File(path) => {
                if !path.exists() {
                    return Err(SceneError::Invalid {
                        location: format!("{}", path.display()),
                        reason: "mesh file not found; fix: check the path (relative paths are \
                                 resolved from the folder of the scene / dataset file)"
                            .into(),
                    });
                }
                Ok(geometry::io::load_mesh(path)?)
            }
            MeshSource::Shape(shape) => Ok((shape.build()?, Vec::new())),
        }
    }

    /// Short description for logs: the file path or the shape name.
    pub fn describe(&self) -> String {
        match self {
            MeshSource::File(p) => p.display().to_string(),
            MeshSource::Shape(s) => format!("built-in shape '{}'", s.name()),
        }
    }
}

/// One view: camera and its point light.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewDesc {
    pub camera: Camera,
    pub light: PointLight,
}

/// Render settings carried by a scene file (`[render]`) or a dataset (`render`). All optional;
/// in a dataset they are informational (how the images were made).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderInfo {
    /// Samples per pixel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spp: Option<u32>,
    /// Mitsuba `volpath` max_depth (32: scattering vertices 1…31 contribute).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_depth: Option<u32>,
    /// Base seed of every random stream.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Free text naming the renderer (e.g. "translucent volpath", "mitsuba 3.9.1 volpath").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub renderer: Option<String>,
}

impl RenderInfo {
    pub(crate) fn validate(&self, context: &str) -> Result<(), SceneError> {
        if self.spp == Some(0) {
            return Err(SceneError::Invalid {
                location: format!("{context}.spp = 0"),
                reason: "samples per pixel must be ≥ 1; fix: use e.g. 64".into(),
            });
        }
        if self.max_depth == Some(0) {
            return Err(SceneError::Invalid {
                location: format!("{context}.max_depth = 0"),
                reason: "max_depth must be ≥ 1 (Mitsuba volpath semantics; 32 is the paper's \
                         setting); fix: use 32"
                    .into(),
            });
        }
        Ok(())
    }
}

/// A fully validated scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDesc {
    pub mesh: MeshSource,
    pub medium: Medium,
    pub views: Vec<ViewDesc>,
    /// The optional `[render]` section (all fields `None` when absent).
    pub render: RenderInfo,
    /// The file this scene was read from.
    pub path: PathBuf,
}

impl SceneDesc {
    /// Load and validate a scene file.
    pub fn load(path: &Path) -> Result<SceneDesc, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parse and validate scene text as if read from `path`: the extension (`.toml` / `.json`)
    /// chooses the syntax and a relative mesh path is resolved from `path`'s folder.
    pub fn parse(text: &str, path: &Path) -> Result<SceneDesc, SceneError> {
        let raw: RawScene = parse_by_extension(text, path)?;
        raw.validate(path)
    }

    /// Build (shape) or load (file) the mesh, validated.
    pub fn load_mesh(&self) -> Result<(geometry::Mesh, Vec<geometry::MeshWarning>), SceneError> {
        self.mesh.load()
    }
}

/// The full example of SCENE.md (a rig of 8 views around a built-in blob).
pub const EXAMPLE_SCENE_TOML: &str = r#"# A translucent blob seen from 8 directions (SCENE.md).
shape = { name = "blob", scale = 0.5 }   # or: mesh = "bunny.ply" (relative to this file)

[medium]
sigma_t = [50.0, 60.0, 70.0]   # extinction, 1/scene unit (or one number for all channels)
albedo = [0.95, 0.90, 0.85]    # single-scattering albedo in [0, 1)
g = 0.0                        # Henyey–Greenstein anisotropy in (-1, 1)
eta = 1.0                      # relative IOR n_inside/n_outside; 1 = index-matched

[rig]
views = 8
radius = 2.0                   # distance from the target
target = [0.0, 0.0, 0.0]
fov = 40.0                     # degrees, along the image x axis
width = 128
height = 128
light = "fixed"                # or "attached" (with light_offset in the camera frame)
light_position = [1.0, 1.5, 0.5]
intensity = 4.0                # W/sr per channel (or [r, g, b])
elevation = [-60.0, 75.0]      # degrees; default [-90, 90]

[render]
spp = 256
max_depth = 32
seed = 0
"#;

// ---------------------------------------------------------------------------------------------
// Building blocks shared with dataset.json.

/// Three numbers given either as `[a, b, c]` or as one number used for all three.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rgb(pub [f32; 3]);

impl Serialize for Rgb {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

impl<'de> Deserialize<'de> for Rgb {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Rgb;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of 3 numbers [r, g, b]")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Rgb, E> {
                Ok(Rgb([v as f32; 3]))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Rgb, E> {
                Ok(Rgb([v as f32; 3]))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Rgb, E> {
                Ok(Rgb([v as f32; 3]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Rgb, A::Error> {
                let mut out = [0.0f32; 3];
                for (i, o) in out.iter_mut().enumerate() {
                    *o = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(Rgb(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// The medium as written in files: `sigma_t` and `albedo` per channel or one number; `g`
/// (default 0) and `eta` (default 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumSpec {
    pub sigma_t: Rgb,
    pub albedo: Rgb,
    #[serde(default)]
    pub g: f32,
    #[serde(default = "one")]
    pub eta: f32,
}

fn one() -> f32 {
    1.0
}

impl MediumSpec {
    /// The validated medium; `context` is e.g. "scene.toml: medium".
    pub fn to_medium(&self, context: &str) -> Result<Medium, SceneError> {
        let m = Medium {
            sigma_t: self.sigma_t.0,
            albedo: self.albedo.0,
            g: self.g,
            eta: self.eta,
        };
        m.validate(context)?;
        Ok(m)
    }
}

impl From<&Medium> for MediumSpec {
    fn from(m: &Medium) -> Self {
        MediumSpec {
            sigma_t: Rgb(m.sigma_t),
            albedo: Rgb(m.albedo),
            g: m.g,
            eta: m.eta,
        }
    }
}

/// A built-in shape as written in files: `{ name = "blob", scale = 0.5, radius = …, … }`.
/// Parameters not given keep the shape's defaults ([`geometry::Shape::from_name`]); `scale`
/// (default 1) then multiplies every length. Which parameters exist depends on the shape:
///
/// | name | parameters |
/// |---|---|
/// | sphere | radius, subdivisions |
/// | cone | height, radius, tip_radius, segments |
/// | torus | major, minor, segments |
/// | rounded-box | size (`[x, y, z]` or one number), radius, segments |
/// | blob | radius, amplitude, bumps, seed, subdivisions |
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeSpec {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subdivisions: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tip_radius: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segments: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub major: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub minor: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<Rgb>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bumps: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

impl ShapeSpec {
    /// The shape described (parameters applied, then scaled). `context` is e.g.
    /// "scene.toml: shape". Errors on an unknown name, a parameter the shape does not have, and
    /// non-finite numbers; the geometry crate checks the remaining ranges when building.
    pub fn to_shape(&self, context: &str) -> Result<geometry::Shape, SceneError> {
        use geometry::Shape;
        let mut shape = Shape::from_name(&self.name).map_err(|e| SceneError::Invalid {
            location: format!("{context}.name = \"{}\"", self.name),
            reason: e.to_string(),
        })?;
        let floats = [
            ("scale", self.scale),
            ("radius", self.radius),
            ("height", self.height),
            ("tip_radius", self.tip_radius),
            ("major", self.major),
            ("minor", self.minor),
            ("amplitude", self.amplitude),
        ];
        for (name, v) in floats {
            if let Some(v) = v
                && !v.is_finite()
            {
                return Err(SceneError::Invalid {
                    location: format!("{context}.{name} = {v}"),
                    reason: "must be a finite number".into(),
                });
            }
        }
        if let Some(Rgb(s)) = self.size
            && s.iter().any(|v| !v.is_finite())
        {
            return Err(SceneError::Invalid {
                location: format!("{context}.size = {s:?}"),
                reason: "must be finite".into(),
            });
        }
        fn set<T: Copy>(dst: &mut T, src: Option<T>) {
            if let Some(v) = src {
                *dst = v;
            }
        }
        let allowed: &[&str] = match &mut shape {
            Shape::Sphere {
                radius,
                subdivisions,
            } => {
                set(radius, self.radius);
                set(subdivisions, self.subdivisions);
                &["radius", "subdivisions"]
            }
            Shape::Cone {
                height,
                radius,
                tip_radius,
                segments,
            } => {
                set(height, self.height);
                set(radius, self.radius);
                set(tip_radius, self.tip_radius);
                set(segments, self.segments);
                &["height", "radius", "tip_radius", "segments"]
            }
            Shape::Torus {
                major,
                minor,
                segments,
            } => {
                set(major, self.major);
                set(minor, self.minor);
                set(segments, self.segments);
                &["major", "minor", "segments"]
            }
            Shape::RoundedBox {
                size,
                radius,
                segments,
            } => {
                set(size, self.size.map(|s| s.0));
                set(radius, self.radius);
                set(segments, self.segments);
                &["size", "radius", "segments"]
            }
            Shape::Blob {
                radius,
                amplitude,
                bumps,
                seed,
                subdivisions,
            } => {
                set(radius, self.radius);
                set(amplitude, self.amplitude);
                set(bumps, self.bumps);
                set(seed, self.seed);
                set(subdivisions, self.subdivisions);
                &["radius", "amplitude", "bumps", "seed", "subdivisions"]
            }
        };
        let given = [
            ("radius", self.radius.is_some()),
            ("subdivisions", self.subdivisions.is_some()),
            ("height", self.height.is_some()),
            ("tip_radius", self.tip_radius.is_some()),
            ("segments", self.segments.is_some()),
            ("major", self.major.is_some()),
            ("minor", self.minor.is_some()),
            ("size", self.size.is_some()),
            ("amplitude", self.amplitude.is_some()),
            ("bumps", self.bumps.is_some()),
            ("seed", self.seed.is_some()),
        ];
        for (name, is_given) in given {
            if is_given && !allowed.contains(&name) {
                return Err(SceneError::Invalid {
                    location: format!("{context}.{name}"),
                    reason: format!(
                        "shape '{}' has no parameter '{name}'; fix: remove it (its parameters: \
                         scale, {})",
                        self.name,
                        allowed.join(", ")
                    ),
                });
            }
        }
        if let Some(s) = self.scale {
            if s <= 0.0 {
                return Err(SceneError::Invalid {
                    location: format!("{context}.scale = {s}"),
                    reason: "scale must be > 0; fix: use e.g. 0.25 for an object about 0.25 \
                             units across"
                        .into(),
                });
            }
            shape = shape.scaled(s);
        }
        Ok(shape)
    }

    /// The spec that reproduces `shape` exactly (every parameter written, no scale).
    pub fn from_shape(shape: &geometry::Shape) -> ShapeSpec {
        use geometry::Shape;
        let mut s = ShapeSpec {
            name: shape.name().to_string(),
            ..Default::default()
        };
        match *shape {
            Shape::Sphere {
                radius,
                subdivisions,
            } => {
                s.radius = Some(radius);
                s.subdivisions = Some(subdivisions);
            }
            Shape::Cone {
                height,
                radius,
                tip_radius,
                segments,
            } => {
                s.height = Some(height);
                s.radius = Some(radius);
                s.tip_radius = Some(tip_radius);
                s.segments = Some(segments);
            }
            Shape::Torus {
                major,
                minor,
                segments,
            } => {
                s.major = Some(major);
                s.minor = Some(minor);
                s.segments = Some(segments);
            }
            Shape::RoundedBox {
                size,
                radius,
                segments,
            } => {
                s.size = Some(Rgb(size));
                s.radius = Some(radius);
                s.segments = Some(segments);
            }
            Shape::Blob {
                radius,
                amplitude,
                bumps,
                seed,
                subdivisions,
            } => {
                s.radius = Some(radius);
                s.amplitude = Some(amplitude);
                s.bumps = Some(bumps);
                s.seed = Some(seed);
                s.subdivisions = Some(subdivisions);
            }
        }
        s
    }
}

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
            reason: "unknown file type; fix: name the file *.toml or *.json".into(),
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
    };
    probe.validate_named(ctx, fov_field)?;
    let cam = Camera::look_at(o, t, u, fov, width, height);
    cam.validate_named(ctx, fov_field)?;
    Ok(cam)
}

// ---------------------------------------------------------------------------------------------
// The scene file as written.

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    mesh: Option<PathBuf>,
    shape: Option<ShapeSpec>,
    medium: MediumSpec,
    views: Option<Vec<RawView>>,
    rig: Option<RawRig>,
    render: Option<RenderInfo>,
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
    fn validate(self, path: &Path) -> Result<SceneDesc, SceneError> {
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
        let medium = self.medium.to_medium(&format!("{file}: medium"))?;
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
            (Some(v), None) => {
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
                    let position =
                        check_finite3(view.light.position, &format!("{ctx}.light.position"))?;
                    check_intensity(&view.light.intensity.0, &format!("{ctx}.light.intensity"))?;
                    out.push(ViewDesc {
                        camera,
                        light: PointLight {
                            position,
                            intensity: view.light.intensity.0,
                        },
                    });
                }
                out
            }
            (None, Some(r)) => {
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
                };
                probe.validate_named(&ctx, "fov")?;
                let views = rig.build();
                for (i, v) in views.iter().enumerate() {
                    v.camera.validate(&format!("{ctx} (view {i})"))?;
                }
                views
            }
        };
        let render = self.render.unwrap_or_default();
        render.validate(&format!("{file}: render"))?;
        Ok(SceneDesc {
            mesh,
            medium,
            views,
            render,
            path: path.to_path_buf(),
        })
    }
}

#[cfg(test)]
#[allow(clippy::excessive_precision, clippy::type_complexity)] // numbers copied verbatim from Mitsuba's scene.json
pub(crate) mod tests {
    use super::*;

    const FULL_TOML: &str = r#"
mesh = "meshes/object.ply"

[medium]
sigma_t = [50, 60.5, 70]
albedo = 0.9
g = 0.2
eta = 1.3

[[views]]
camera = { origin = [0, 0, 3], target = [0, 0, 0], up = [0, 1, 0], fov = 35, width = 64, height = 48 }
light = { position = [1, 2, 3], intensity = [1, 2, 3] }

[[views]]
camera = { origin = [3, 1, 0], target = [0, 0.1, 0], width = 32, height = 32 }
light = { position = [0, 5, 0], intensity = 2.5 }

[render]
spp = 128
max_depth = 32
seed = 7
renderer = "volpath"
"#;

    const FULL_JSON: &str = r#"{
  "mesh": "meshes/object.ply",
  "medium": { "sigma_t": [50, 60.5, 70], "albedo": 0.9, "g": 0.2, "eta": 1.3 },
  "views": [
    { "camera": { "origin": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 35, "width": 64, "height": 48 },
      "light": { "position": [1, 2, 3], "intensity": [1, 2, 3] } },
    { "camera": { "origin": [3, 1, 0], "target": [0, 0.1, 0], "width": 32, "height": 32 },
      "light": { "position": [0, 5, 0], "intensity": 2.5 } }
  ],
  "render": { "spp": 128, "max_depth": 32, "seed": 7, "renderer": "volpath" }
}"#;

    /// A temp folder with an (empty) mesh file at meshes/object.ply.
    fn folder() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("meshes")).unwrap();
        std::fs::write(dir.path().join("meshes/object.ply"), b"ply\n").unwrap();
        dir
    }

    fn parse_toml(text: &str) -> Result<SceneDesc, SceneError> {
        let dir = folder();
        SceneDesc::parse(text, &dir.path().join("scene.toml"))
    }

    fn err_toml(text: &str) -> String {
        parse_toml(text).expect_err("must be rejected").to_string()
    }

    #[test]
    fn full_example_parses_the_same_in_toml_and_json() {
        let dir = folder();
        let st = dir.path().join("scene.toml");
        let sj = dir.path().join("scene.json");
        std::fs::write(&st, FULL_TOML).unwrap();
        std::fs::write(&sj, FULL_JSON).unwrap();
        let a = SceneDesc::load(&st).unwrap();
        let b = SceneDesc::load(&sj).unwrap();
        assert_eq!(
            a.mesh,
            MeshSource::File(dir.path().join("meshes/object.ply"))
        );
        assert_eq!(a.mesh, b.mesh);
        assert_eq!(
            a.medium,
            Medium {
                sigma_t: [50.0, 60.5, 70.0],
                albedo: [0.9; 3],
                g: 0.2,
                eta: 1.3
            }
        );
        assert_eq!(a.medium, b.medium);
        assert_eq!(a.views, b.views);
        assert_eq!(a.render, b.render);
        assert_eq!(
            a.render,
            RenderInfo {
                spp: Some(128),
                max_depth: Some(32),
                seed: Some(7),
                renderer: Some("volpath".into())
            }
        );
        assert_eq!(a.views.len(), 2);
        let v0 = &a.views[0];
        assert_eq!(
            v0.camera,
            Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 35.0, 64, 48)
        );
        assert_eq!(
            v0.light,
            PointLight {
                position: Vec3::new(1.0, 2.0, 3.0),
                intensity: [1.0, 2.0, 3.0]
            }
        );
        let v1 = &a.views[1];
        assert_eq!(v1.camera.fov_x_deg, 40.0, "default fov");
        assert_eq!(
            v1.camera,
            Camera::look_at(
                Vec3::new(3.0, 1.0, 0.0),
                Vec3::new(0.0, 0.1, 0.0),
                Vec3::Y,
                40.0,
                32,
                32
            )
        );
        assert_eq!(
            v1.light.intensity, [2.5; 3],
            "scalar intensity is broadcast"
        );
        assert_eq!(a.path, st);
    }

    #[test]
    fn example_scene_with_shape_and_rig_parses() {
        let s = parse_toml(EXAMPLE_SCENE_TOML).unwrap();
        assert_eq!(s.views.len(), 8);
        let MeshSource::Shape(shape) = &s.mesh else {
            panic!("shape expected")
        };
        assert_eq!(shape.name(), "blob");
        let default = geometry::Shape::from_name("blob").unwrap().scaled(0.5);
        assert_eq!(*shape, default);
        for v in &s.views {
            assert!((v.camera.origin.length() - 2.0).abs() < 1e-5);
            assert_eq!(v.light.position, Vec3::new(1.0, 1.5, 0.5));
            assert_eq!(v.light.intensity, [4.0; 3]);
            assert_eq!((v.camera.width, v.camera.height), (128, 128));
        }
        assert_eq!(s.render.spp, Some(256));
    }

    #[test]
    fn shape_parameters_override_defaults_then_scale() {
        let s = parse_toml(
            r#"shape = { name = "sphere", radius = 0.125, subdivisions = 3, scale = 2 }
               medium = { sigma_t = 1, albedo = 0.5 }
               rig = { views = 2, radius = 1, width = 4, height = 4, light = "attached", intensity = 1 }"#,
        )
        .unwrap();
        assert_eq!(
            s.mesh,
            MeshSource::Shape(geometry::Shape::Sphere {
                radius: 0.25,
                subdivisions: 3
            })
        );
        assert_eq!(s.medium.g, 0.0);
        assert_eq!(s.medium.eta, 1.0);
        // Attached light without an offset sits at the camera.
        assert_eq!(s.views[1].light.position, s.views[1].camera.origin);
        let spec = ShapeSpec::from_shape(&geometry::Shape::Torus {
            major: 1.0,
            minor: 0.25,
            segments: 9,
        });
        assert_eq!(
            spec.to_shape("x").unwrap(),
            geometry::Shape::Torus {
                major: 1.0,
                minor: 0.25,
                segments: 9
            }
        );
        let msg = err_toml(
            r#"shape = { name = "sphere", major = 1 }
               medium = { sigma_t = 1, albedo = 0.5 }
               rig = { views = 2, radius = 1, width = 4, height = 4, light = "attached", intensity = 1 }"#,
        );
        assert!(
            msg.contains("shape.major") && msg.contains("radius, subdivisions"),
            "{msg}"
        );
        let msg = err_toml(
            r#"shape = { name = "teapot" }
               medium = { sigma_t = 1, albedo = 0.5 }
               rig = { views = 2, radius = 1, width = 4, height = 4, light = "attached", intensity = 1 }"#,
        );
        assert!(
            msg.contains("shape.name = \"teapot\"") && msg.contains("sphere"),
            "{msg}"
        );
    }

    /// A valid scene with one view, with `replace` substituted into it.
    fn one_view(replace: &[(&str, &str)]) -> String {
        let mut s = r#"
mesh = "meshes/object.ply"
[medium]
sigma_t = [50, 60, 70]
albedo = [0.9, 0.9, 0.9]
g = 0
eta = 1
[[views]]
camera = { origin = [0, 0, 3], target = [0, 0, 0], up = [0, 1, 0], fov = 40, width = 16, height = 16 }
light = { position = [1, 1, 1], intensity = 1 }
"#
        .to_string();
        for (a, b) in replace {
            assert!(s.contains(a), "{a}");
            s = s.replace(a, b);
        }
        s
    }

    #[test]
    fn one_view_base_is_valid() {
        parse_toml(&one_view(&[])).unwrap();
    }

    #[test]
    fn validation_errors_name_the_field() {
        let cases: &[(&[(&str, &str)], &[&str])] = &[
            (
                &[("sigma_t = [50, 60, 70]", "sigma_t = [50, 0, 70]")],
                &[
                    "scene.toml: medium.sigma_t[1] = 0",
                    "extinction must be > 0",
                ],
            ),
            (
                &[("sigma_t = [50, 60, 70]", "sigma_t = -3")],
                &["medium.sigma_t[0] = -3"],
            ),
            (
                &[("albedo = [0.9, 0.9, 0.9]", "albedo = [0.9, 1.0, 0.9]")],
                &["medium.albedo[1] = 1", "[0, 1)"],
            ),
            (
                &[("albedo = [0.9, 0.9, 0.9]", "albedo = -0.5")],
                &["medium.albedo[0] = -0.5"],
            ),
            (&[("g = 0", "g = 1")], &["medium.g = 1"]),
            (&[("g = 0", "g = -1.2")], &["medium.g = -1.2"]),
            (&[("eta = 1", "eta = 0.8")], &["medium.eta = 0.8"]),
            (
                &[("width = 16", "width = 0")],
                &["views[0].camera.width", "resolution"],
            ),
            (
                &[("height = 16", "height = 0")],
                &["views[0].camera.height"],
            ),
            (
                &[("fov = 40", "fov = 0")],
                &["views[0].camera.fov", "(0, 180)"],
            ),
            (&[("fov = 40", "fov = 180")], &["views[0].camera.fov"]),
            (
                &[
                    ("up = [0, 1, 0]", "up = [0, 2, 0]"),
                    ("origin = [0, 0, 3]", "origin = [0, 3, 0]"),
                ],
                &["views[0].camera.up", "parallel"],
            ),
            (
                &[("origin = [0, 0, 3]", "origin = [0, 0, 0]")],
                &["views[0].camera.target", "sits at its target"],
            ),
            (
                &[("intensity = 1", "intensity = [1, -1, 1]")],
                &["views[0].light.intensity[1] = -1"],
            ),
            (
                &[("intensity = 1", "intensity = nan")],
                &["views[0].light.intensity[0] = NaN"],
            ),
            (
                &[("position = [1, 1, 1]", "position = [1, inf, 1]")],
                &["views[0].light.position"],
            ),
            (
                &[(
                    "mesh = \"meshes/object.ply\"",
                    "mesh = \"meshes/object.ply\"\nshape = { name = \"sphere\" }",
                )],
                &["mesh, shape", "exactly one"],
            ),
            (
                &[("mesh = \"meshes/object.ply\"", "")],
                &["scene.toml: mesh", "no geometry"],
            ),
            (
                &[("mesh = \"meshes/object.ply\"", "mesh = \"nope.obj\"")],
                &["mesh = \"nope.obj\"", "not found", "relative"],
            ),
        ];
        for (repl, wants) in cases {
            let msg = err_toml(&one_view(repl));
            for w in *wants {
                assert!(msg.contains(w), "{repl:?}: {msg:?} should contain {w:?}");
            }
            assert!(msg.contains("scene.toml"), "{msg}");
        }
    }

    #[test]
    fn unknown_fields_are_errors_with_line_and_column() {
        let msg = err_toml(&one_view(&[("g = 0", "g = 0\nsigma_s = 3")]));
        assert!(
            msg.contains("sigma_s") && msg.contains("line 7") && msg.contains("column"),
            "{msg}"
        );
        let msg = err_toml(&one_view(&[("fov = 40", "fov_y = 40")]));
        assert!(
            msg.contains("fov_y") && msg.contains("line 9, column 68"),
            "{msg}"
        );
        let msg = err_toml(&one_view(&[("mesh = ", "mesh_file = ")]));
        assert!(msg.contains("mesh_file"), "{msg}");
        // JSON too (line/column from serde_json).
        let dir = folder();
        let msg = SceneDesc::parse(
            &FULL_JSON.replace("\"g\": 0.2", "\"gg\": 0.2"),
            &dir.path().join("s.json"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            msg.contains("unknown field `gg`") && msg.contains("line 3"),
            "{msg}"
        );
        // Wrong type and unknown extension.
        let msg = err_toml(&one_view(&[("width = 16", "width = -16")]));
        assert!(msg.contains("line 9") && msg.contains("width"), "{msg}");
        let msg = SceneDesc::parse("", &dir.path().join("scene.yaml"))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("scene.yaml") && msg.contains(".toml"), "{msg}");
    }

    #[test]
    fn views_and_rig_are_exclusive_and_rig_lights_checked() {
        let rig = r#"
[rig]
views = 3
radius = 2
width = 8
height = 8
light = "fixed"
light_position = [0, 3, 0]
intensity = [1, 1, 1]
"#;
        let msg = err_toml(&(one_view(&[]) + rig));
        assert!(msg.contains("views, rig"), "{msg}");
        let no_views = |extra: &str| {
            let base = one_view(&[]);
            let cut = base.find("[[views]]").unwrap();
            format!("{}{extra}", &base[..cut])
        };
        let s = parse_toml(&no_views(rig)).unwrap();
        assert_eq!(s.views.len(), 3);
        let msg = err_toml(&no_views(&rig.replace("light_position = [0, 3, 0]\n", "")));
        assert!(
            msg.contains("rig.light_position") && msg.contains("missing"),
            "{msg}"
        );
        let msg = err_toml(&no_views(&rig.replace("\"fixed\"", "\"attached\"")));
        assert!(
            msg.contains("rig.light_position") && msg.contains("attached"),
            "{msg}"
        );
        let msg = err_toml(&no_views(&rig.replace("\"fixed\"", "\"orbiting\"")));
        assert!(
            msg.contains("orbiting") && msg.contains("fixed") && msg.contains("line"),
            "{msg}"
        );
        let msg = err_toml(&no_views(&rig.replace("views = 3", "views = 0")));
        assert!(msg.contains("rig.views"), "{msg}");
        let msg = err_toml(&no_views(&rig.replace("width = 8", "width = 0")));
        assert!(msg.contains("rig.width"), "{msg}");
        let msg = err_toml(&no_views(""));
        assert!(msg.contains("no cameras"), "{msg}");
        let msg = err_toml(&format!("views = []\n{}", no_views("")));
        assert!(msg.contains("empty"), "{msg}");
        let msg = err_toml(&(one_view(&[]) + "[render]\nspp = 0\n"));
        assert!(msg.contains("render.spp"), "{msg}");
    }

    #[test]
    fn load_mesh_builds_shapes_and_reads_files() {
        let dir = tempfile::tempdir().unwrap();
        let rig = r#"rig = { views = 1, radius = 3, width = 4, height = 4, light = "attached", intensity = 1 }
medium = { sigma_t = 1, albedo = 0.5 }
"#;
        let s = SceneDesc::parse(
            &format!("shape = {{ name = \"sphere\", subdivisions = 1 }}\n{rig}"),
            &dir.path().join("a.toml"),
        )
        .unwrap();
        let (mesh, warnings) = s.load_mesh().unwrap();
        assert_eq!(mesh.triangle_count(), 80);
        assert!(warnings.is_empty());
        // A tetrahedron with inward-facing triangles: loads, flipped, with a warning.
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n";
        let inward = {
            // Orient every face outward, then reverse them all.
            let p = [
                [0.0f32, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ]
            .map(Vec3::from_array);
            let centre = (p[0] + p[1] + p[2] + p[3]) / 4.0;
            let mut text: String = obj
                .lines()
                .filter(|l| l.starts_with('v'))
                .map(|l| format!("{l}\n"))
                .collect();
            for f in [[0usize, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]] {
                let n = (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]);
                let out = n.dot(p[f[0]] - centre) > 0.0;
                let f = if out { [f[0], f[2], f[1]] } else { f };
                text.push_str(&format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1));
            }
            text
        };
        std::fs::write(dir.path().join("tet.obj"), inward).unwrap();
        let s = SceneDesc::parse(
            &format!("mesh = \"tet.obj\"\n{rig}"),
            &dir.path().join("b.toml"),
        )
        .unwrap();
        let (mesh, warnings) = s.load_mesh().unwrap();
        assert_eq!(mesh.triangle_count(), 4);
        assert!(mesh.signed_volume() > 0.0);
        assert!(
            warnings
                .iter()
                .any(|w| matches!(w, geometry::MeshWarning::Flipped { .. })),
            "{warnings:?}"
        );
    }

    /// The fenced blocks of a markdown file with the given language tag.
    pub(crate) fn code_blocks(md: &str, lang: &str) -> Vec<String> {
        let mut out = Vec::new();
        let mut cur: Option<String> = None;
        for line in md.lines() {
            match &mut cur {
                None if line.trim_start() == format!("```{lang}") => cur = Some(String::new()),
                Some(block) if line.trim_start() == "```" => {
                    out.push(std::mem::take(block));
                    cur = None;
                }
                Some(block) => {
                    block.push_str(line);
                    block.push('\n');
                }
                None => {}
            }
        }
        out
    }

    #[test]
    fn scene_md_examples_parse() {
        let md = include_str!("../../../SCENE.md");
        assert!(
            md.contains(EXAMPLE_SCENE_TOML),
            "SCENE.md must show EXAMPLE_SCENE_TOML verbatim"
        );
        let dir = folder();
        std::fs::write(dir.path().join("bunny.ply"), b"ply\n").unwrap();
        let tomls = code_blocks(md, "toml");
        let jsons = code_blocks(md, "json");
        assert_eq!((tomls.len(), jsons.len()), (2, 1));
        let a = SceneDesc::parse(&tomls[1], &dir.path().join("s.toml")).unwrap();
        let b = SceneDesc::parse(&jsons[0], &dir.path().join("s.json")).unwrap();
        assert_eq!(
            (&a.mesh, &a.medium, &a.views),
            (&b.mesh, &b.medium, &b.views)
        );
        assert_eq!(a.medium.sigma_t, [60.0; 3]);
        SceneDesc::parse(&tomls[0], &dir.path().join("e.toml")).unwrap();
    }

    #[test]
    fn rgb_accepts_scalar_or_three_numbers_only() {
        let msg = err_toml(&one_view(&[(
            "sigma_t = [50, 60, 70]",
            "sigma_t = [50, 60]",
        )]));
        assert!(msg.contains("array of 3 numbers"), "{msg}");
        let msg = err_toml(&one_view(&[(
            "sigma_t = [50, 60, 70]",
            "sigma_t = [50, 60, 70, 80]",
        )]));
        assert!(msg.contains("array of 3 numbers"), "{msg}");
        let s = parse_toml(&one_view(&[("sigma_t = [50, 60, 70]", "sigma_t = 42")])).unwrap();
        assert_eq!(s.medium.sigma_t, [42.0; 3]);
    }
}
