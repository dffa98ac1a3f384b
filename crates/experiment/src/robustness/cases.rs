//! The cases of the robustness suite (module docs of [`super`]): twelve index-matched, isotropic
//! ones (capture × optical size, the shapes taking turns) and nine with a dielectric boundary and
//! a forward-scattering medium (boundary × anisotropy × optical size in two orthogonal Latin
//! squares), each with its medium from the paper's ranges and its scene scaled to the size; the
//! rig of a case and its mesh.

use scene::setting::Setting;
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

    /// Whether this renderer draws `case`'s targets. Mitsuba 3's `volpath` does not draw a
    /// smooth dielectric object lit by a point light: light reaches the medium only along a
    /// refracted path through one point of the surface (a delta connection), which its
    /// next-event estimation cannot take through the boundary and no sampled path can hit, so
    /// every view would be black. Ours takes it by manifold next-event estimation.
    pub fn renders(self, case: &Case) -> bool {
        let m = &case.medium;
        self != Targets::Mitsuba || m.eta == 1.0 || m.roughness > 0.0
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

/// Which of the suite's cases run. The default is the twelve that every published run of the
/// suite measured, so that their commands still mean those runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Suite {
    /// The twelve index-matched, isotropic cases.
    #[default]
    IndexMatched,
    /// The nine cases with a dielectric boundary (smooth or rough) and an HG medium.
    Dielectric,
    /// Both.
    All,
}

impl Suite {
    /// The cases of this suite, media drawn from `seed`.
    pub fn cases(self, seed: u64) -> Vec<Case> {
        match self {
            Suite::IndexMatched => cases(seed),
            Suite::Dielectric => dielectric_cases(seed),
            Suite::All => [cases(seed), dielectric_cases(seed)].concat(),
        }
    }
}

/// The optical sizes (mean free paths across the radius) and the range of σ_t drawn at each.
const SIZES: [(f32, f32, f32); 3] = [(5.0, 30.0, 50.0), (15.0, 30.0, 100.0), (50.0, 70.0, 100.0)];
const SHAPES: [&str; 3] = ["blob", "torus", "spot"];

/// A case's medium: σ_t from [lo, hi] per channel, α ~ U[0.8, 0.98], drawn from stream `i` of
/// `seed` under `key`, with the object's `g`, `eta` and `roughness`.
fn draw_medium(seed: u64, key: u64, i: usize, lo: f32, hi: f32, object: (f32, f32, f32)) -> Medium {
    let mut s = Sampler::new(seed, key, i as u64, 0);
    let sigma_t = [0; 3].map(|_| lo + (hi - lo) * s.next_f32());
    let albedo = [0; 3].map(|_| 0.8 + 0.18 * s.next_f32());
    let (g, eta, roughness) = object;
    Medium {
        sigma_t,
        albedo,
        g: g.into(),
        eta,
        roughness,
    }
}

/// A case of `medium` scaled to `mfp` mean free paths across the radius (every shape is made
/// 0.5 in radius, then the scene is scaled).
fn case(name: String, capture: Capture, mfp: f32, shape: &'static str, medium: Medium) -> Case {
    let mean = medium.sigma_t.iter().sum::<f32>() / 3.0;
    Case {
        name,
        capture,
        mfp,
        shape,
        medium,
        scale: mfp / (0.5 * mean),
    }
}

/// The twelve index-matched, isotropic cases (module docs), media drawn from `seed`.
pub fn cases(seed: u64) -> Vec<Case> {
    let mut out = Vec::new();
    for (k, &(mfp, lo, hi)) in SIZES.iter().enumerate() {
        for (j, &capture) in Capture::ALL.iter().enumerate() {
            let i = k * 4 + j;
            let shape = SHAPES[i % 3];
            let medium = draw_medium(seed, 0x0B05_7000, i, lo, hi, (0.0, 1.0, 0.0));
            let name = format!("{}-{}-{}", capture.name(), mfp as u32, shape);
            out.push(case(name, capture, mfp, shape, medium));
        }
    }
    out
}

/// The boundaries of the dielectric cases: (name, η, GGX α): wax or jade polished, water-like
/// and lightly rough, glass-like and rough.
const BOUNDARIES: [(&str, f32, f32); 3] = [
    ("smooth1.5", 1.5, 0.0),
    ("rough1.33a0.1", 1.33, 0.1),
    ("rough1.5a0.3", 1.5, 0.3),
];
/// Their media's anisotropy: weakly forward, milk-like, strongly forward.
const ANISOTROPIES: [f32; 3] = [0.3, 0.7, 0.9];
/// Their optical sizes with σ_t's range: 15 and 50 as the index-matched cases, and 300, a
/// real object's (marble in a 5 cm statue is about 100 across its radius).
const DIELECTRIC_SIZES: [(f32, f32, f32); 3] = [
    (15.0, 30.0, 100.0),
    (50.0, 70.0, 100.0),
    (300.0, 70.0, 100.0),
];

/// The captures of the dielectric cases by size and boundary ([size][boundary]): every capture
/// at least twice, a back light only at 15 and 50 mean free paths. At 300 the light a back
/// light sends in is absorbed before it crosses the object, and every view is black.
const DIELECTRIC_CAPTURES: [[Capture; 3]; 3] = [
    [Capture::Flash, Capture::Backlit, Capture::Fixed],
    [Capture::Fixed, Capture::Turntable, Capture::Backlit],
    [Capture::Turntable, Capture::Fixed, Capture::Flash],
];

/// The nine cases with a dielectric boundary and an HG medium: boundary b and j = 0, 1, 2 give
/// the anisotropy (j + b) mod 3 and the size (j + 2b) mod 3 (two orthogonal Latin squares:
/// every boundary meets every g and every size once, every g every size once), the shape j and
/// the capture of [`DIELECTRIC_CAPTURES`]. Media drawn from `seed` (a stream of their own).
pub fn dielectric_cases(seed: u64) -> Vec<Case> {
    let mut out = Vec::new();
    for (b, &(boundary, eta, roughness)) in BOUNDARIES.iter().enumerate() {
        for j in 0..3 {
            let i = 3 * b + j;
            let g = ANISOTROPIES[(j + b) % 3];
            let size = (j + 2 * b) % 3;
            let (mfp, lo, hi) = DIELECTRIC_SIZES[size];
            let capture = DIELECTRIC_CAPTURES[size][b];
            let shape = SHAPES[j];
            let medium = draw_medium(seed, 0x0B05_7001, i, lo, hi, (g, eta, roughness));
            let name = format!("{}-{}-{shape}-{boundary}-g{g}", capture.name(), mfp as u32);
            out.push(case(name, capture, mfp, shape, medium));
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

/// The mesh of `case` at radius 0.5·scale: a built-in shape (at a smoke test's resolution with
/// `coarse`, [`geometry::Shape::coarse`]), or the mesh file centred on its bounding box and
/// scaled to its bounding radius, written into `dir`. With `as_file`, a built-in shape is
/// written into `dir` too (for renderers that read only mesh files).
pub(super) fn mesh_source(
    case: &Case,
    mesh_file: &Path,
    dir: &Path,
    (as_file, coarse): (bool, bool),
) -> Result<MeshSource> {
    let mesh = if case.shape != "spot" {
        let shape = geometry::Shape::from_name(case.shape)?.scaled(case.scale);
        let shape = if coarse { shape.coarse() } else { shape };
        if !as_file {
            return Ok(MeshSource::Shape(shape));
        }
        shape.build()?
    } else {
        let (mut mesh, _) = geometry::io::load_mesh(mesh_file).with_context(|| {
            format!(
                "{}: the robustness suite's third shape (run from the repository root, or set {})",
                mesh_file.display(),
                Setting::Mesh
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The dielectric cases cross boundary, anisotropy and size as two orthogonal Latin squares,
    /// state their object in the medium, and leave the index-matched cases' media as they were.
    #[test]
    fn the_dielectric_cases_cross_boundary_anisotropy_and_size() {
        let d = dielectric_cases(0);
        assert_eq!(d.len(), 9);
        let key = |c: &Case| (c.medium.eta, c.medium.roughness);
        for (i, a) in d.iter().enumerate() {
            for b in &d[i + 1..] {
                assert_ne!(a.name, b.name);
                // No two cases share a boundary and a g, a boundary and a size, or a g and a
                // size: with three of each, every pair occurs once.
                assert!(
                    key(a) != key(b) || a.medium.g != b.medium.g,
                    "{} {}",
                    a.name,
                    b.name
                );
                assert!(key(a) != key(b) || a.mfp != b.mfp, "{} {}", a.name, b.name);
                assert!(
                    a.medium.g != b.medium.g || a.mfp != b.mfp,
                    "{} {}",
                    a.name,
                    b.name
                );
            }
            assert!(a.medium.eta > 1.0 && a.medium.g.mean() > 0.0, "{}", a.name);
            let mean = a.medium.sigma_t.iter().sum::<f32>() / 3.0;
            assert!(
                (0.5 * a.scale * mean - a.mfp).abs() < 1e-3 * a.mfp,
                "{}",
                a.name
            );
        }
        assert!(d.iter().any(|c| c.mfp == 300.0 && c.medium.roughness > 0.0));
        // Every capture, none of them back-lit at 300 mean free paths (black views).
        for capture in Capture::ALL {
            assert!(d.iter().filter(|c| c.capture == capture).count() >= 2);
        }
        assert!(
            d.iter()
                .all(|c| c.capture != Capture::Backlit || c.mfp < 300.0)
        );
        let all = Suite::All.cases(0);
        assert_eq!(all.len(), 21);
        assert_eq!(Suite::IndexMatched.cases(0).len(), 12);
        for c in &all[..12] {
            assert_eq!(
                (c.medium.g, c.medium.eta, c.medium.roughness),
                (scene::Anisotropy::ISOTROPIC, 1.0, 0.0)
            );
        }
        assert_eq!(all[0].name, "flash-5-blob");
    }

    /// Mitsuba 3 draws the targets of every case but the smooth dielectric ones (black in its
    /// volpath under a point light); our tracer draws them all.
    #[test]
    fn mitsuba_draws_no_smooth_dielectric_targets() {
        let all = Suite::All.cases(0);
        let smooth = |c: &Case| c.medium.eta > 1.0 && c.medium.roughness == 0.0;
        assert_eq!(all.iter().filter(|c| smooth(c)).count(), 3);
        for c in &all {
            assert!(Targets::Volpath.renders(c), "{}", c.name);
            assert_eq!(Targets::Mitsuba.renders(c), !smooth(c), "{}", c.name);
        }
    }
}
