//! `translucent import …`: a capture made with other tools as a dataset folder (dataset.json,
//! the images, the mesh) that `optimize`, `render` and `compare` take.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use glam::Vec3;
use scene::Object;
use scene::colmap::{Capture, CaptureLight, ColmapModel};

use cmdline::parse_rgb;

#[derive(Subcommand)]
pub enum ImportCommand {
    /// A COLMAP sparse model (cameras and images, text or binary: PINHOLE, SIMPLE_PINHOLE, or a
    /// distortion model with zero distortion) with a linear EXR per image, the object's mesh in
    /// the model's frame and the light of each image.
    ///
    /// Lengths are the model's own: σ_t comes out in 1/those units. A light of unknown
    /// strength is given as 1 and recovered with `optimize --free light-scale`.
    Colmap(ColmapArgs),
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("light").required(true).args(["flash", "light_positions"])))]
#[command(mut_arg("out", cmdline::groups::help("The dataset folder to write")))]
#[command(mut_arg("overwrite", cmdline::groups::help("Replace a dataset in --out")))]
pub struct ColmapArgs {
    /// The model's folder (e.g. `sparse/0`, or the `sparse` folder `colmap image_undistorter`
    /// writes).
    pub model: PathBuf,
    /// The folder of linear EXR images, named like the model's images with the extension
    /// `.exr` (`IMG_0001.JPG` → `IMG_0001.exr`, subfolders kept).
    #[arg(long, value_name = "DIR")]
    pub images: PathBuf,
    /// The object's mesh (PLY or OBJ) in the model's frame and units (e.g. the
    /// `meshed-poisson.ply` of COLMAP's dense reconstruction).
    #[arg(long, value_name = "FILE")]
    pub mesh: PathBuf,
    /// A flash fixed to the camera: its offset from the lens in COLMAP's camera frame (x to the
    /// image's right, y down, z forward), in the model's units (`0,0,0`: at the lens).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_negative_numbers = true)]
    pub flash: Option<Vec3>,
    /// The light of each image: a text file of lines `NAME X Y Z` (the image's name in the
    /// model, the light's position in the model's frame).
    #[arg(long, value_name = "FILE")]
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
    /// The medium's Henyey–Greenstein g, where it is known.
    #[arg(long, allow_negative_numbers = true)]
    pub g: Option<f32>,
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
    }
}

fn colmap(a: &ColmapArgs) -> Result<()> {
    let model = ColmapModel::read(&a.model)?;
    let light = match (&a.flash, &a.light_positions) {
        (Some(offset), _) => CaptureLight::Flash { offset: *offset },
        (None, Some(p)) => CaptureLight::read_positions(p)?,
        (None, None) => unreachable!("clap requires one of --flash, --light-positions"),
    };
    let object = (a.eta.is_some() || a.roughness.is_some() || a.g.is_some()).then(|| Object {
        eta: a.eta.unwrap_or(1.0),
        roughness: a.roughness.unwrap_or(0.0),
        g: a.g.unwrap_or(0.0),
    });
    if let Some(o) = &object {
        o.validate("command line: the object")?;
    }
    let capture = Capture {
        images: a.images.clone(),
        mesh: a.mesh.clone(),
        light,
        intensity: a.intensity,
        object,
    };
    let ds = model.dataset(&capture)?;
    ds.save(&a.out, *a.overwrite)
        .with_context(|| format!("writing the dataset {}", a.out.display()))?;
    println!(
        "{} views from {} ({} cameras) -> {}",
        ds.views.len(),
        model.dir.display(),
        model.cameras.len(),
        a.out.display()
    );
    println!(
        "object: {}",
        match &ds.object {
            Some(o) => o.describe(),
            None => "nothing stated (a recovery assumes an index-matched, isotropic object)".into(),
        }
    );
    println!(
        "lengths are the model's own units: σ_t comes out in 1/those units; the light's \
         intensity {:?} W/sr{}",
        a.intensity,
        if a.intensity == [1.0; 3] {
            " (relative: recover its scale with `optimize --free light-scale`)"
        } else {
            ""
        }
    );
    Ok(())
}
