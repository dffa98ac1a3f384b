//! Scene files (TOML or JSON, by extension): mesh or built-in shape, medium, cameras and per-view
//! point lights, or a multi-view rig. Documented in SCENE.md (the full example there is
//! [`EXAMPLE_SCENE_TOML`]).
//!
//! Parsing is strict: unknown fields are errors (with the line and column for TOML and JSON), and
//! every value is range-checked with an error that names the file, the field and the fix.
//!
//! This module holds the validated scene ([`SceneDesc`]) and its parts; `scene_file/spec.rs` has
//! the value types shared with dataset.json ([`Rgb`], [`MediumSpec`], [`ShapeSpec`]) and
//! `scene_file/parse.rs` the file as written, its validation and the checks shared with datasets.

use std::path::Path;

use crate::SceneError;

pub(crate) mod desc;
pub(crate) mod parse;
mod spec;
#[cfg(test)]
// Numbers copied verbatim from Mitsuba's scene.json.
#[allow(clippy::excessive_precision, clippy::type_complexity)]
pub(crate) mod tests;

pub use desc::{MeshSource, RenderInfo, SceneDesc, ViewDesc};
use parse::RawScene;
pub(crate) use parse::{
    base_dir, check_finite3, look_at_checked, parse_by_extension, resolve_mesh_path,
};
pub use spec::{MediumSpec, Rgb, ShapeSpec};

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
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("xml"))
        {
            return crate::mitsuba_xml::parse(text, path);
        }
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
