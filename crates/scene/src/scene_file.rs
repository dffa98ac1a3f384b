//! Scene files (TOML or JSON, by extension): mesh or built-in shape, medium, cameras and per-view
//! point lights, or a multi-view rig. Documented in SCENE.md.
//!
//! SKELETON: helper H3 owns this file.

use std::path::{Path, PathBuf};

use crate::{Camera, Medium, PointLight, SceneError};

/// Where the mesh comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshSource {
    /// A mesh file (path resolved relative to the scene file).
    File(PathBuf),
    /// A built-in shape.
    Shape(geometry::Shape),
}

/// One view: camera and its point light.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewDesc {
    pub camera: Camera,
    pub light: PointLight,
}

/// A fully validated scene.
#[derive(Clone, Debug)]
pub struct SceneDesc {
    pub mesh: MeshSource,
    pub medium: Medium,
    pub views: Vec<ViewDesc>,
}

impl SceneDesc {
    /// Load and validate a scene file.
    pub fn load(path: &Path) -> Result<SceneDesc, SceneError> {
        todo!()
    }
    /// Build (shape) or load (file) the mesh, validated.
    pub fn load_mesh(&self) -> Result<(geometry::Mesh, Vec<geometry::MeshWarning>), SceneError> {
        todo!()
    }
}
