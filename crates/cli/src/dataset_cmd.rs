//! `translucent dataset`: render N views of a mesh or built-in shape with the volumetric path
//! tracer into a dataset folder (dataset.json + EXRs + PNG previews, DATASET.md), the ground
//! truth medium included. With `--random-medium` the medium is drawn from the paper's ranges
//! (σ_t ~ U[30, 100], α ~ U[0.8, 0.98] per channel) with the given seed.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use glam::Vec3;
use scene::measured::{LengthUnit, MeasuredMedium};
use scene::rig::{Rig, RigLight};
use scene::{Medium, MeshSource, ShapeSpec};

use cmdline::parse_rgb;
use inverse::views::random_medium;

mod capture;

/// Where the object comes from and how it is viewed and lit.
#[derive(Args, Clone)]
#[command(mut_arg(
    "views",
    cmdline::groups::default_and_help(
        "40",
        "Number of views (cameras on a Fibonacci sphere around the object)"
    )
))]
#[command(mut_arg("res", cmdline::groups::default("256")))]
pub struct RigArgs {
    /// Mesh file (OBJ or PLY). Mutually exclusive with --shape.
    #[arg(long, conflicts_with = "shape")]
    pub mesh: Option<PathBuf>,
    /// Built-in shape: sphere, cone, torus, rounded-box, blob (default blob), with optional
    /// parameters as NAME[:KEY=VALUE]… (the keys of a scene file's `shape` table, e.g.
    /// `blob:amplitude=0.05:bumps=6`).
    #[arg(long)]
    pub shape: Option<String>,
    /// Uniform scale of the built-in shape (default objects are about 1 unit across; not
    /// allowed with --mesh).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f32,
    #[command(flatten)]
    pub views: cmdline::Views,
    #[command(flatten)]
    pub res: cmdline::Resolution,
    /// Horizontal field of view in degrees.
    #[arg(long, default_value_t = 35.0)]
    pub fov: f32,
    /// Camera distance from the origin (scene units).
    #[arg(long, default_value_t = 2.0)]
    pub radius: f32,
    /// Light placement: `attached` (moves with each camera, offset up-left of it) or `fixed`.
    #[arg(long, value_enum, default_value_t)]
    pub light: scene::rig::RigLightKind,
    /// Fixed light position "x,y,z" (with --light fixed).
    #[arg(long, default_value = "1.2,1.6,0.8")]
    pub light_position: String,
    /// Attached light offset "x,y,z" in the camera frame (x = image left, y = up, z = forward).
    #[arg(long, default_value = "0.8,0.8,0")]
    pub light_offset: String,
    /// Point-light radiant intensity in W/sr (one value or R,G,B); irradiance I/r².
    #[arg(long, default_value = "12", value_parser = parse_rgb, allow_negative_numbers = true)]
    pub intensity: [f32; 3],
}

impl RigArgs {
    pub fn mesh_source(&self) -> Result<MeshSource> {
        if self.scale <= 0.0 || !self.scale.is_finite() {
            bail!("--scale must be a positive number, got {}", self.scale);
        }
        if let (Some(p), true) = (&self.mesh, self.scale != 1.0) {
            bail!(
                "--scale {} applies to built-in shapes only; {} is used as it is (scale the \
                 mesh file itself, or place the cameras with --radius)",
                self.scale,
                p.display()
            );
        }
        Ok(match &self.mesh {
            Some(p) => MeshSource::File(p.clone()),
            None => MeshSource::Shape(
                ShapeSpec::parse_compact(self.shape.as_deref().unwrap_or("blob"), "--shape")?
                    .to_shape("--shape")?
                    .scaled(self.scale),
            ),
        })
    }

    pub fn rig(&self) -> Result<Rig> {
        let v3 = |s: &str, flag: &str| -> Result<Vec3> {
            let p: Vec<f32> = s
                .split(',')
                .map(|x| x.trim().parse::<f32>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("{flag} '{s}': expected x,y,z"))?;
            anyhow::ensure!(
                p.len() == 3,
                "{flag} '{s}': expected three comma-separated numbers x,y,z"
            );
            Ok(Vec3::new(p[0], p[1], p[2]))
        };
        let light = match self.light {
            scene::rig::RigLightKind::Fixed => RigLight::Fixed {
                position: v3(&self.light_position, "--light-position")?,
            },
            scene::rig::RigLightKind::Attached => RigLight::Attached {
                offset: v3(&self.light_offset, "--light-offset")?,
            },
        };
        let rig = Rig {
            views: *self.views,
            radius: self.radius,
            target: Vec3::ZERO,
            fov_x_deg: self.fov,
            width: *self.res,
            height: *self.res,
            light,
            intensity: self.intensity,
            elevation_deg: (-90.0, 90.0),
        };
        rig.validate("command line")?;
        anyhow::ensure!(
            *self.res > 0 && *self.res <= 16384,
            "--res must be between 1 and 16384"
        );
        anyhow::ensure!(
            self.fov > 0.0 && self.fov < 180.0,
            "--fov must be in (0, 180) degrees"
        );
        Ok(rig)
    }
}

/// The medium of a dataset: given explicitly or drawn from the paper's ranges.
#[derive(Args, Clone)]
pub struct MediumArgs {
    /// Extinction σ_t in 1/unit (one value or R,G,B).
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true, default_value = "60,45,35")]
    pub sigma_t: [f32; 3],
    /// Single-scattering albedo α in [0, 1) (one value or R,G,B).
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true, default_value = "0.95,0.9,0.85")]
    pub albedo: [f32; 3],
    /// Henyey–Greenstein anisotropy g in (−1, 1): one value, or R,G,B for a medium whose
    /// forward scattering differs by channel.
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true, default_value = "0")]
    pub g: [f32; 3],
    /// Relative index of refraction (1 = index-matched boundary, the paper's data).
    #[arg(long, default_value_t = 1.0)]
    pub eta: f32,
    /// Roughness of the boundary as GGX α (Mitsuba's roughdielectric alpha), in [0, 1]; 0 = a
    /// smooth surface. Needs --eta > 1.
    #[arg(long, default_value_t = 0.0)]
    pub roughness: f32,
    /// Draw σ_t ~ U[30, 100] and α ~ U[0.8, 0.98] per channel from --seed instead (the
    /// boundary and g as given).
    #[arg(long, conflicts_with = "measured")]
    pub random_medium: bool,
    /// A measured medium by name instead of --sigma-t and --albedo (Jensen et al. 2001's
    /// marble, skin1, wholemilk…; Narasimhan et al. 2006's regular-milk, espresso…): its
    /// reduced scattering and absorption, with --g, in 1/--units (an unknown name lists
    /// them all).
    #[arg(long, value_name = "NAME", requires = "units")]
    pub measured: Option<String>,
    /// What one unit of the scene is (mm, cm, m): with --measured, the object's size in real
    /// units (a built-in shape is about 1 unit across: --scale 30 --units mm is a 3 cm object).
    #[arg(long, value_enum)]
    pub units: Option<LengthUnit>,
}

impl MediumArgs {
    pub fn medium(&self, seed: u64) -> Result<Medium> {
        let (sigma_t, albedo) = if self.random_medium {
            let r = random_medium(seed);
            (r.sigma_t, r.albedo)
        } else if let (Some(name), Some(unit)) = (&self.measured, self.units) {
            anyhow::ensure!(
                self.g.iter().all(|g| *g < 1.0),
                "--g {} must be below 1 for a measured medium",
                scene::Anisotropy(self.g)
            );
            MeasuredMedium::find(name)?.medium_rgb(self.g.map(f64::from), unit)
        } else {
            (self.sigma_t, self.albedo)
        };
        let m = Medium {
            sigma_t,
            albedo,
            g: scene::Anisotropy(self.g),
            eta: self.eta,
            roughness: self.roughness,
        };
        m.validate("command line: medium")?;
        Ok(m)
    }
}

#[derive(Args)]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed of the render and of --random-medium")
))]
#[command(mut_arg("out", cmdline::groups::help("Output dataset folder")))]
#[command(mut_arg(
    "overwrite",
    cmdline::groups::help("Replace an existing dataset in --out")
))]
#[command(mut_arg("spp", cmdline::groups::default("256")))]
pub struct DatasetArgs {
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub medium: MediumArgs,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Maximum depth (Mitsuba volpath semantics).
    #[arg(long, default_value_t = 32)]
    pub max_depth: u32,
    /// Shadow-ray transmittance estimator of the volumetric tracer.
    #[arg(long, value_enum, default_value_t)]
    pub shadow: volpath::ShadowTransmittance,
    #[command(flatten)]
    pub capture: CaptureOutArgs,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

/// Writing the render as a photographed capture would arrive.
#[derive(Args, Clone)]
pub struct CaptureOutArgs {
    /// Write the views as a photographed capture instead of a dataset: a COLMAP model
    /// (OUT/sparse), sRGB JPEG photos (OUT/images), silhouette masks (OUT/masks), the mesh
    /// (OUT/object.ply), the lights (OUT/lights.txt) and the truth (OUT/truth.json); the
    /// rendered dataset goes to OUT/rendered. `import colmap` reads it back.
    #[arg(long)]
    pub as_capture: bool,
    /// The photos' exposure: linear radiance × this before the sRGB encoding [default: the
    /// 99.5th percentile of the brightest channel at 0.9].
    #[arg(long, requires = "as_capture")]
    pub photo_exposure: Option<f32>,
    /// Noise on the written mesh, as a scan has it: each vertex moved along its normal by a
    /// Gaussian of this standard deviation, as a fraction of the bounding-box diagonal.
    #[arg(long, default_value_t = 0.0, requires = "as_capture")]
    pub mesh_noise: f32,
}

use inverse::views::{RenderOpts, make_dataset};

pub fn run(a: &DatasetArgs) -> Result<()> {
    let rig = a.rig.rig()?;
    let medium = a.medium.medium(*a.seed)?;
    let dir = if a.capture.as_capture {
        a.out.join("rendered")
    } else {
        a.out.to_path_buf()
    };
    let mut ds = make_dataset(
        &rig,
        a.rig.mesh_source()?,
        medium,
        RenderOpts {
            spp: *a.spp,
            seed: *a.seed,
            max_depth: a.max_depth,
            shadow: a.shadow,
        },
        &dir,
        *a.overwrite,
        &cmdline::Terminal,
    )?;
    if let Some(unit) = a.medium.units {
        // The lengths' unit goes into dataset.json beside the rendered images.
        ds.metadata.length_unit = Some(unit);
        ds.metadata.units = None; // the note then names the unit
        ds.save(&dir, true)?;
    }
    if a.capture.as_capture {
        return capture::write(a, &ds, &rig, medium);
    }
    println!(
        "dataset: {} views of {}×{} at {} spp -> {}",
        ds.views.len(),
        *a.rig.res,
        *a.rig.res,
        *a.spp,
        a.out.display()
    );
    println!(
        "truth: σ_t = ({:.3}, {:.3}, {:.3}) 1/{}, α = ({:.4}, {:.4}, {:.4}), g = {}, η = {}",
        medium.sigma_t[0],
        medium.sigma_t[1],
        medium.sigma_t[2],
        a.medium.units.map_or("unit", |u| u.name()),
        medium.albedo[0],
        medium.albedo[1],
        medium.albedo[2],
        medium.g,
        medium.eta
    );
    Ok(())
}
