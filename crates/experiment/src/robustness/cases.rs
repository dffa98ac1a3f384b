//! The twelve cases of the robustness suite: capture × optical size, the shapes taking turns,
//! each with its medium from the paper's ranges and its scene scaled to the size (module docs of
//! [`super`]); the rig of a case and its mesh.

use std::path::Path;

use glam::Vec3;
use scene::rig::{Rig, RigLight};
use scene::{Medium, MeshSource};
use volpath::rng::Sampler;

use crate::error::{Context, Result};

/// The renderer of a case's target images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Targets {
    /// Our volumetric path tracer.
    Volpath,
    /// Mitsuba 3's `volpath` (`tools/mitsuba/render_dataset.py`).
    Mitsuba,
}

impl Targets {
    pub fn name(self) -> &'static str {
        match self {
            Targets::Volpath => "volpath",
            Targets::Mitsuba => "mitsuba",
        }
    }

    /// The folder name of a case's dataset and run: `{case}-r{rep}` for our renders,
    /// `{case}-mitsuba-r{rep}` for Mitsuba's.
    pub(super) fn tag(self, case: &str, rep: u64) -> String {
        match self {
            Targets::Volpath => format!("{case}-r{rep}"),
            Targets::Mitsuba => format!("{case}-mitsuba-r{rep}"),
        }
    }
}

/// How the scene is lit (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Capture {
    Flash,
    Fixed,
    Turntable,
    Backlit,
}

impl Capture {
    pub const ALL: [Capture; 4] = [
        Capture::Flash,
        Capture::Fixed,
        Capture::Turntable,
        Capture::Backlit,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Capture::Flash => "flash",
            Capture::Fixed => "fixed",
            Capture::Turntable => "turntable",
            Capture::Backlit => "backlit",
        }
    }

    /// The light of the house rig (cameras at distance 2), before scaling.
    pub(super) fn light(self) -> RigLight {
        let around = |deg: f32| {
            let t = deg.to_radians();
            // In the camera's frame (x image left, z forward), at distance 2 from the object.
            RigLight::Attached {
                offset: Vec3::new(2.0 * t.sin(), 0.0, 2.0 * (1.0 - t.cos())),
            }
        };
        match self {
            Capture::Flash => RigLight::Attached {
                offset: Vec3::new(0.1, 0.1, 0.0),
            },
            Capture::Fixed => RigLight::Fixed {
                position: Vec3::new(1.2, 1.6, 0.8),
            },
            Capture::Turntable => around(60.0),
            Capture::Backlit => around(150.0),
        }
    }
}

/// One case of the suite.
#[derive(Clone, Debug)]
pub struct Case {
    pub name: String,
    pub capture: Capture,
    pub mfp: f32,
    pub shape: &'static str,
    pub medium: Medium,
    /// The scene's scale (object radius / 0.5).
    pub scale: f32,
}

/// The twelve cases (module docs), media drawn from `seed`.
pub fn cases(seed: u64) -> Vec<Case> {
    const SIZES: [(f32, f32, f32); 3] =
        [(5.0, 30.0, 50.0), (15.0, 30.0, 100.0), (50.0, 70.0, 100.0)];
    const SHAPES: [&str; 3] = ["blob", "torus", "spot"];
    let mut out = Vec::new();
    for (k, &(mfp, lo, hi)) in SIZES.iter().enumerate() {
        for (j, &capture) in Capture::ALL.iter().enumerate() {
            let i = k * 4 + j;
            let shape = SHAPES[i % 3];
            let mut s = Sampler::new(seed, 0x0B05_7000, i as u64, 0);
            let sigma_t = [0; 3].map(|_| lo + (hi - lo) * s.next_f32());
            let albedo = [0; 3].map(|_| 0.8 + 0.18 * s.next_f32());
            let mean = sigma_t.iter().sum::<f32>() / 3.0;
            out.push(Case {
                name: format!("{}-{}-{}", capture.name(), mfp as u32, shape),
                capture,
                mfp,
                shape,
                medium: Medium {
                    sigma_t,
                    albedo,
                    g: 0.0,
                    eta: 1.0,
                    roughness: 0.0,
                },
                // Every shape is made 0.5 in radius, then the scene is scaled by this.
                scale: mfp / (0.5 * mean),
            });
        }
    }
    out
}

/// The rig of `case`: the house rig (cameras at distance 2, fov 35°) scaled with the object.
pub(super) fn rig(case: &Case, views: usize, res: u32) -> Rig {
    let k = case.scale;
    let light = match case.capture.light() {
        RigLight::Fixed { position } => RigLight::Fixed {
            position: position * k,
        },
        RigLight::Attached { offset } => RigLight::Attached { offset: offset * k },
    };
    Rig {
        views,
        radius: 2.0 * k,
        target: Vec3::ZERO,
        fov_x_deg: 35.0,
        width: res,
        height: res,
        light,
        intensity: [12.0 * k * k; 3],
        elevation_deg: (-90.0, 90.0),
    }
}

/// The mesh of `case` at radius 0.5·scale: a built-in shape, or the mesh file centred on its
/// bounding box and scaled to its bounding radius, written into `dir`. With `as_file`, a
/// built-in shape is written into `dir` too (for renderers that read only mesh files).
pub(super) fn mesh_source(
    case: &Case,
    mesh_file: &Path,
    dir: &Path,
    as_file: bool,
) -> Result<MeshSource> {
    let mesh = if case.shape != "spot" {
        let shape = geometry::Shape::from_name(case.shape)?.scaled(case.scale);
        if !as_file {
            return Ok(MeshSource::Shape(shape));
        }
        shape.build()?
    } else {
        let (mut mesh, _) = geometry::io::load_mesh(mesh_file).with_context(|| {
            format!(
                "{}: the robustness suite's third shape (run from the repository root, or pass --mesh)",
                mesh_file.display()
            )
        })?;
        let (lo, hi) = mesh.bounds();
        let centre = 0.5 * (lo + hi);
        let radius = mesh
            .positions
            .iter()
            .map(|p| (*p - centre).length())
            .fold(0.0f32, f32::max);
        let s = 0.5 * case.scale / radius;
        mesh.transform(
            glam::Mat4::from_scale(Vec3::splat(s)) * glam::Mat4::from_translation(-centre),
        );
        mesh
    };
    std::fs::create_dir_all(dir)?;
    let path = dir.join("mesh-input.obj");
    geometry::io::save_obj(&mesh, &path)?;
    Ok(MeshSource::File(path))
}
