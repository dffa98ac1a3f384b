//! # translucent-scene
//!
//! Everything that describes what is rendered, apart from the geometry itself:
//!
//! * [`camera`]: the Mitsuba 3 `perspective` camera (look-at, fov along x, py down).
//! * [`light`]: point lights of radiant intensity I (irradiance I/r², no 1/4π), and a constant
//!   environment emitter (used by energy tests).
//! * [`medium`]: the homogeneous medium (σ_t, α per RGB channel, HG g, relative IOR η).
//! * [`anisotropy`]: the Henyey–Greenstein g, one for all channels or one per channel.
//! * [`measured`]: lengths in real units and published measurements of real media.
//! * [`object`]: what a capture states about the object besides σ_t and α: the boundary (η,
//!   roughness) and the phase function (g).
//! * [`image`]: RGB float images with EXR (linear f32) and PNG (tone-mapped sRGB) I/O.
//! * [`scene_file`]: the scene file format (TOML or JSON), validated with precise errors.
//! * [`capture`]: a photographed object (images, masks, lights, mesh) as a dataset, with its
//!   cameras from [`colmap`] or [`nerf`].
//! * [`rig`]: multi-view rigs (N views on a Fibonacci sphere, light fixed or attached).
//! * [`setting`]: the settings library errors ask the user to change, spelled by the front end.
//! * [`dataset`]: dataset folders (`dataset.json` + EXRs, DATASET.md) and the Mitsuba
//!   reference-render folder format (`scene.json` + mesh + `view_XXX.exr`).

pub mod anisotropy;
pub mod camera;
pub mod capture;
pub mod colmap;
pub mod dataset;
pub mod error;
pub mod fsutil;
pub mod image;
pub mod light;
pub mod loss;
pub mod measured;
pub mod medium;
pub mod mitsuba_xml;
pub mod nerf;
pub mod object;
pub mod rig;
pub mod scene_file;
pub mod setting;

pub use anisotropy::Anisotropy;
pub use camera::{Camera, Crop, Intrinsics, Pinhole, RayGen};
pub use dataset::{Dataset, DatasetKind, DatasetMetadata, View, load_reference_folder};
pub use error::SceneError;
pub use image::Image;
pub use light::{Environment, PointLight};
pub use medium::Medium;
pub use object::Object;
pub use rig::{Rig, RigLight, fibonacci_sphere};
pub use scene_file::{MediumSpec, MeshSource, RenderInfo, Rgb, SceneDesc, ShapeSpec, ViewDesc};
