//! `translucent import …`: a capture made with other tools as a dataset folder (dataset.json,
//! the images, the masks, the mesh) that `optimize`, `render` and `compare` take.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use glam::Vec3;
use scene::Object;
use scene::capture::{Capture, CaptureLight};
use scene::colmap::ColmapModel;
use scene::image::{PhotoSettings, Transfer};
use scene::measured::LengthUnit;
use scene::nerf::NerfTransforms;

use cmdline::parse_rgb;

#[derive(Subcommand)]
pub enum ImportCommand {
    /// A COLMAP sparse model (cameras and images, text or binary: PINHOLE, SIMPLE_PINHOLE, or a
    /// distortion model with zero distortion) with its photos (PNG, JPEG or linear EXR) and
    /// optional masks, the object's mesh in the model's frame and the light of each image.
    ///
    /// Lengths are the model's own: σ_t comes out in 1/those units. A light of unknown
    /// strength is given as 1 and recovered with `optimize --free light-scale`.
    Colmap(ColmapArgs),
    /// A NeRF-style transforms.json (Blender scenes, instant-ngp, nerfstudio: camera_angle_x or
    /// fl_x/fl_y/cx/cy, OpenGL camera-to-world matrices), a light per frame from the file
    /// (light_position) or the command line, with its images and the object's mesh.
    Nerf(NerfArgs),
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("light").required(true).args(["flash", "light_positions"])))]
pub struct ColmapArgs {
    /// The model's folder (e.g. `sparse/0`, or the `sparse` folder `colmap image_undistorter`
    /// writes).
    pub model: PathBuf,
    /// The folder of images: the model's own (`IMG_0001.JPG`, 8/16-bit PNG or JPEG), or linear
    /// EXRs named like them (`IMG_0001.exr`), subfolders kept. Saturated pixels leave the fit.
    #[arg(long, value_name = "DIR")]
    pub images: PathBuf,
    #[command(flatten)]
    pub capture: CaptureArgs,
}

#[derive(Args)]
pub struct NerfArgs {
    /// The transforms.json.
    pub transforms: PathBuf,
    /// The folder the frames' file_path are relative to [default: the file's folder].
    #[arg(long, value_name = "DIR")]
    pub images: Option<PathBuf>,
    #[command(flatten)]
    pub capture: CaptureArgs,
}

/// What every capture states beside its cameras.
#[derive(Args)]
#[command(mut_arg("out", cmdline::groups::help("The dataset folder to write")))]
#[command(mut_arg("overwrite", cmdline::groups::help("Replace a dataset in --out")))]
pub struct CaptureArgs {
    /// A folder of masks, white where the pixel shows the object (`IMG_0001.JPG.png`, COLMAP's
    /// naming, or `IMG_0001.png`): the pixels outside leave the fit.
    #[arg(long, value_name = "DIR")]
    pub masks: Option<PathBuf>,
    /// The photos' transfer function [default: srgb for PNG and JPEG; EXR is linear].
    #[arg(long, value_enum)]
    pub transfer: Option<Transfer>,
    /// A scale on every image's linear values (e.g. 2 for photos taken one stop darker than
    /// the reference exposure).
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
    /// The object's mesh (PLY or OBJ) in the cameras' frame and units (e.g. the
    /// `meshed-poisson.ply` of COLMAP's dense reconstruction).
    #[arg(long, value_name = "FILE")]
    pub mesh: PathBuf,
    /// A flash fixed to the camera: its offset from the lens in the camera frame of COLMAP and
    /// OpenCV (x to the image's right, y down, z forward), in the cameras' units (`0,0,0`: at
    /// the lens).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_negative_numbers = true)]
    pub flash: Option<Vec3>,
    /// The light of each image: a text file of lines `NAME X Y Z` (the image's name as the
    /// cameras' file gives it, the light's position in their frame).
    #[arg(long, value_name = "FILE", conflicts_with = "flash")]
    pub light_positions: Option<PathBuf>,
    /// The light's radiant intensity in W/sr (one value or R,G,B): relative where it is not
    /// measured (recover its scale with `optimize --free light-scale`).
    #[arg(long, value_parser = parse_rgb, default_value = "1")]
    pub intensity: [f32; 3],
    /// The boundary's relative index of refraction, where it is known (1: index-matched). With
    /// none of --eta, --roughness and --g the dataset states nothing about the object, and a
    /// recovery assumes (and says it assumes) an index-matched, isotropic one.
    #[arg(long)]
    pub eta: Option<f32>,
    /// The boundary's roughness as GGX α (0: smooth), where it is known.
    #[arg(long)]
    pub roughness: Option<f32>,
    /// The medium's Henyey–Greenstein g, where it is known: one value, or R,G,B.
    #[arg(long, value_parser = parse_rgb, allow_negative_numbers = true)]
    pub g: Option<[f32; 3]>,
    /// What one unit of the cameras' lengths is (scale the reconstruction to a known size
    /// first): a recovery then reports σ_t in mm⁻¹ and the nearest measured media.
    #[arg(long, value_enum)]
    pub units: Option<LengthUnit>,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

/// `X,Y,Z` as a vector.
fn parse_vec3(s: &str) -> std::result::Result<Vec3, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("'{s}': {e}")))
        .collect::<std::result::Result<_, _>>()?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("'{s}': give three finite numbers X,Y,Z")),
    }
}

pub fn run(cmd: &ImportCommand) -> Result<()> {
    match cmd {
        ImportCommand::Colmap(a) => colmap(a),
        ImportCommand::Nerf(a) => nerf(a),
    }
}

fn colmap(a: &ColmapArgs) -> Result<()> {
    let model = ColmapModel::read(&a.model)?;
    let light = a.capture.light()?.expect("clap requires a light");
    let capture = a.capture.capture(&a.images, light)?;
    let ds = model.dataset(&capture)?;
    let from = format!("{} ({} cameras)", model.dir.display(), model.cameras.len());
    a.capture.save(&ds, &from, "the model's")
}

fn nerf(a: &NerfArgs) -> Result<()> {
    let t = NerfTransforms::read(&a.transforms)?;
    let light = match (a.capture.light()?, t.lights()?) {
        (Some(l), _) | (None, Some(l)) => l,
        (None, None) => bail!(
            "{}: no frame states a light; fix: give --flash X,Y,Z or --light-positions FILE",
            a.transforms.display()
        ),
    };
    let images = a.images.clone().unwrap_or_else(|| t.dir());
    let capture = a.capture.capture(&images, light)?;
    let ds = t.dataset(&capture)?;
    a.capture
        .save(&ds, &a.transforms.display().to_string(), "the file's")
}

impl CaptureArgs {
    /// The light the command line states, if it states one.
    fn light(&self) -> Result<Option<CaptureLight>> {
        Ok(match (&self.flash, &self.light_positions) {
            (Some(offset), _) => Some(CaptureLight::Flash { offset: *offset }),
            (None, Some(p)) => Some(CaptureLight::read_positions(p)?),
            (None, None) => None,
        })
    }

    /// The capture of images in `images` lit by `light`.
    fn capture(&self, images: &Path, light: CaptureLight) -> Result<Capture> {
        let object =
            (self.eta.is_some() || self.roughness.is_some() || self.g.is_some()).then(|| Object {
                eta: self.eta.unwrap_or(1.0),
                roughness: self.roughness.unwrap_or(0.0),
                g: scene::Anisotropy(self.g.unwrap_or([0.0; 3])),
            });
        if let Some(o) = &object {
            o.validate("command line: the object")?;
        }
        Ok(Capture {
            images: images.to_path_buf(),
            masks: self.masks.clone(),
            photo: PhotoSettings {
                transfer: self.transfer,
                exposure: self.exposure,
                saturation: None,
            },
            mesh: self.mesh.clone(),
            light,
            intensity: self.intensity,
            object,
            length_unit: self.units,
        })
    }

    /// Writes the dataset and says what it holds (`from`: where the cameras came from; `units`:
    /// whose lengths they are).
    fn save(&self, ds: &scene::Dataset, from: &str, units: &str) -> Result<()> {
        ds.save(&self.out, *self.overwrite)
            .with_context(|| format!("writing the dataset {}", self.out.display()))?;
        println!(
            "{} views from {from} -> {}",
            ds.views.len(),
            self.out.display()
        );
        let (measured, total) = ds.views.iter().fold((0, 0), |(m, t), v| {
            let n = v.camera.width as usize * v.camera.height as usize;
            (m + v.camera.mask.as_ref().map_or(n, |k| k.count()), t + n)
        });
        println!(
            "pixels in the fit: {measured} of {total} ({:.1} %; the rest saturated or masked out)",
            100.0 * measured as f64 / total.max(1) as f64
        );
        println!(
            "object: {}",
            match &ds.object {
                Some(o) => o.describe(),
                None =>
                    "nothing stated (a recovery assumes an index-matched, isotropic object)".into(),
            }
        );
        let lengths = match self.units {
            Some(u) => format!("lengths are in {} (σ_t in 1/{})", u.name(), u.name()),
            None => format!(
                "lengths are {units} own units (σ_t in 1/those units; state them with --units)"
            ),
        };
        println!(
            "{lengths}; the light's intensity {:?} W/sr{}",
            self.intensity,
            if self.intensity == [1.0; 3] {
                " (relative: recover its scale with `optimize --free light-scale`)"
            } else {
                ""
            }
        );
        Ok(())
    }
}
