//! The validated scene: where the mesh comes from, the medium, the views (camera and light) and
//! the render settings, whichever file format it was read from.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::measured::LengthUnit;
use crate::{Camera, Medium, PointLight, SceneError};

/// Where the mesh comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshSource {
    /// A mesh file (path resolved relative to the scene file).
    File(PathBuf),
    /// A built-in shape.
    Shape(geometry::Shape),
    /// A mesh file placed in the world by an affine transform (a Mitsuba shape's `to_world`:
    /// p_world = M·p_file).
    Placed { path: PathBuf, to_world: glam::Mat4 },
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
            MeshSource::Placed { path, to_world } => {
                let (mut mesh, mut warnings) = MeshSource::File(path.clone()).load()?;
                mesh.transform(*to_world);
                warnings.extend(geometry::mesh::validate(
                    &mut mesh,
                    &format!("{} (to_world applied)", path.display()),
                )?);
                Ok((mesh, warnings))
            }
        }
    }

    /// Short description for logs: the file path or the shape name.
    pub fn describe(&self) -> String {
        match self {
            MeshSource::File(p) => p.display().to_string(),
            MeshSource::Shape(s) => format!("built-in shape '{}'", s.name()),
            MeshSource::Placed { path, .. } => format!("{} (to_world applied)", path.display()),
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
    /// What one unit of the scene's lengths is, when the file states it (`length_unit`): σ_t is
    /// then in 1/that unit, and a dataset made from the scene carries it.
    pub length_unit: Option<LengthUnit>,
}
