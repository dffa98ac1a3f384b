//! `translucent.import_colmap` and `translucent.import_nerf`: a photographed capture as a
//! dataset, as `translucent import colmap|nerf` makes it (`scene::capture`): the cameras from a
//! COLMAP sparse model or a NeRF-style `transforms.json`, the photos decoded to linear radiance
//! (sRGB by default for PNG and JPEG, EXR as stored) with their saturated and masked-out pixels
//! left out of the fit, the object's mesh, and a light per image (a flash at a fixed offset from
//! the lens, or a position per image). The dataset stays in memory until saved.

use std::path::PathBuf;

use glam::Vec3;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use scene::capture::{Capture, CaptureLight};
use scene::image::{PhotoSettings, Transfer};

use crate::dataset::PyDataset;
use crate::errors;
use crate::medium::{Rgb, parse_unit};

/// What every capture states beside its cameras (the CLI's import options).
struct Stated {
    mesh: PathBuf,
    masks: Option<PathBuf>,
    transfer: Option<String>,
    exposure: f32,
    intensity: Rgb,
    object: (Option<f32>, Option<f32>, Option<[f32; 3]>),
    units: Option<String>,
}

/// The light given as `flash` (an offset from the lens in COLMAP's camera frame: x right, y down,
/// z forward) or `light_positions` (a file of lines `NAME X Y Z`).
fn stated_light(
    flash: Option<[f32; 3]>,
    light_positions: Option<PathBuf>,
) -> PyResult<Option<CaptureLight>> {
    match (flash, light_positions) {
        (Some(_), Some(_)) => Err(PyValueError::new_err(
            "give the light as flash=(x, y, z) or as light_positions=FILE, not both",
        )),
        (Some(o), None) => Ok(Some(CaptureLight::Flash {
            offset: Vec3::from_array(o),
        })),
        (None, Some(p)) => Ok(Some(
            CaptureLight::read_positions(&p).map_err(errors::scene)?,
        )),
        (None, None) => Ok(None),
    }
}

impl Stated {
    fn capture(self, images: PathBuf, light: CaptureLight) -> PyResult<Capture> {
        let transfer = match self.transfer.as_deref() {
            None => None,
            Some("srgb") => Some(Transfer::Srgb),
            Some("linear") => Some(Transfer::Linear),
            Some(t) => {
                return Err(PyValueError::new_err(format!(
                    "transfer = {t:?}: the photos' transfer function is \"srgb\" or \"linear\""
                )));
            }
        };
        let (eta, roughness, g) = self.object;
        let object = (eta.is_some() || roughness.is_some() || g.is_some()).then(|| scene::Object {
            eta: eta.unwrap_or(1.0),
            roughness: roughness.unwrap_or(0.0),
            g: scene::Anisotropy(g.unwrap_or([0.0; 3])),
        });
        if let Some(o) = &object {
            o.validate("the object").map_err(errors::scene)?;
        }
        Ok(Capture {
            images,
            masks: self.masks,
            photo: PhotoSettings {
                transfer,
                exposure: self.exposure,
                saturation: None,
            },
            mesh: self.mesh,
            light,
            intensity: self.intensity.rgb(),
            object,
            length_unit: self.units.as_deref().map(parse_unit).transpose()?,
        })
    }
}

/// The dataset of a COLMAP sparse model (`model`: its folder, text or binary; PINHOLE,
/// SIMPLE_PINHOLE, or a distortion model with zero distortion), its photos in `images`, the
/// object's `mesh` in the model's frame and units, and the light: `flash` (x, y, z) from the
/// lens in the camera frame, or `light_positions` (a file of lines `NAME X Y Z`).
#[pyfunction]
#[pyo3(signature = (model, images, mesh, *, flash = None, light_positions = None, intensity = Rgb::One(1.0), masks = None, transfer = None, exposure = 1.0, eta = None, roughness = None, g = None, units = None))]
#[allow(clippy::too_many_arguments)]
pub fn import_colmap(
    py: Python<'_>,
    model: PathBuf,
    images: PathBuf,
    mesh: PathBuf,
    flash: Option<[f32; 3]>,
    light_positions: Option<PathBuf>,
    intensity: Rgb,
    masks: Option<PathBuf>,
    transfer: Option<String>,
    exposure: f32,
    eta: Option<f32>,
    roughness: Option<f32>,
    g: Option<Rgb>,
    units: Option<String>,
) -> PyResult<PyDataset> {
    let light = stated_light(flash, light_positions)?.ok_or_else(|| {
        PyValueError::new_err("give the light: flash=(x, y, z) or light_positions=FILE")
    })?;
    let stated = Stated {
        mesh,
        masks,
        transfer,
        exposure,
        intensity,
        object: (eta, roughness, g.map(|g| g.rgb())),
        units,
    };
    let capture = stated.capture(images, light)?;
    let ds = py
        .detach(|| {
            let m = scene::colmap::ColmapModel::read(&model)?;
            m.dataset(&capture)
        })
        .map_err(errors::scene)?;
    Ok(in_memory(ds))
}

/// The dataset of a NeRF-style `transforms.json` (`camera_angle_x` or `fl_x/fl_y/cx/cy`,
/// OpenGL camera-to-world matrices), its frames' images (relative to `images`, by default the
/// file's folder), the object's `mesh`, and the light: the frames' own `light_position`s, or
/// `flash` / `light_positions` as for COLMAP.
#[pyfunction]
#[pyo3(signature = (transforms, mesh, *, images = None, flash = None, light_positions = None, intensity = Rgb::One(1.0), masks = None, transfer = None, exposure = 1.0, eta = None, roughness = None, g = None, units = None))]
#[allow(clippy::too_many_arguments)]
pub fn import_nerf(
    py: Python<'_>,
    transforms: PathBuf,
    mesh: PathBuf,
    images: Option<PathBuf>,
    flash: Option<[f32; 3]>,
    light_positions: Option<PathBuf>,
    intensity: Rgb,
    masks: Option<PathBuf>,
    transfer: Option<String>,
    exposure: f32,
    eta: Option<f32>,
    roughness: Option<f32>,
    g: Option<Rgb>,
    units: Option<String>,
) -> PyResult<PyDataset> {
    let t = scene::nerf::NerfTransforms::read(&transforms).map_err(errors::scene)?;
    let light = match (
        stated_light(flash, light_positions)?,
        t.lights().map_err(errors::scene)?,
    ) {
        (Some(l), _) | (None, Some(l)) => l,
        (None, None) => {
            return Err(PyValueError::new_err(format!(
                "{}: no frame states a light; give flash=(x, y, z) or light_positions=FILE",
                transforms.display()
            )));
        }
    };
    let stated = Stated {
        mesh,
        masks,
        transfer,
        exposure,
        intensity,
        object: (eta, roughness, g.map(|g| g.rgb())),
        units,
    };
    let capture = stated.capture(images.unwrap_or_else(|| t.dir()), light)?;
    let ds = py.detach(|| t.dataset(&capture)).map_err(errors::scene)?;
    Ok(in_memory(ds))
}

/// A dataset read from elsewhere, not yet saved as a dataset folder.
fn in_memory(mut ds: scene::Dataset) -> PyDataset {
    ds.root = PathBuf::new();
    PyDataset {
        inner: ds,
        mesh: None,
    }
}
