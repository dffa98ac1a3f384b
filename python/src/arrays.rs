//! Images between `scene::Image` and NumPy: (H, W, 3) float32 arrays, row 0 at the top, linear
//! RGB. Out of Rust without a copy (the image's pixels become the array's buffer); into Rust
//! one copy, since a dataset owns its images.

use std::path::PathBuf;

use numpy::{PyArray1, PyArray3, PyArrayMethods, PyReadonlyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors;

/// The image as a (H, W, 3) float32 array that owns its pixels (no copy).
pub fn image_to_array(py: Python<'_>, img: scene::Image) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let (w, h) = (img.width as usize, img.height as usize);
    let flat: Vec<f32> = bytemuck::allocation::cast_vec(img.data);
    PyArray1::from_vec(py, flat).reshape([h, w, 3])
}

/// Any Python object that should be an image: a (H, W, 3) float32 array, else a `ValueError`
/// that names it (`what`), says what it is and how to convert it.
pub fn image_arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<scene::Image> {
    if let Ok(a) = obj.cast::<PyArray3<f32>>() {
        return array_to_image(&a.readonly(), what);
    }
    let attr = |n: &str| {
        obj.getattr(n)
            .and_then(|v| v.str().map(|s| s.to_string()))
            .ok()
    };
    let found = match (attr("dtype"), attr("shape")) {
        (Some(d), Some(s)) => format!("an array of dtype {d} and shape {s}"),
        _ => format!(
            "a {}",
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ),
    };
    Err(PyValueError::new_err(format!(
        "{what}: expected a float32 array of shape (height, width, 3) (linear RGB), got {found}; \
         convert with numpy.asarray(x, dtype=numpy.float32)"
    )))
}

/// A (H, W, 3) float32 array as an image; `what` names it in errors (non-finite pixels, a
/// third axis other than 3).
pub fn array_to_image(a: &PyReadonlyArray3<f32>, what: &str) -> PyResult<scene::Image> {
    let v = a.as_array();
    let (h, w, c) = v.dim();
    if c != 3 || h == 0 || w == 0 {
        return Err(PyValueError::new_err(format!(
            "{what}: shape {:?}; an image is a (height, width, 3) float32 array of linear RGB",
            v.shape()
        )));
    }
    let data: Vec<[f32; 3]> = match a.as_slice() {
        Ok(s) => s.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
        Err(_) => v
            .outer_iter()
            .flat_map(|row| {
                row.outer_iter()
                    .map(|p| [p[0], p[1], p[2]])
                    .collect::<Vec<_>>()
            })
            .collect(),
    };
    let img = scene::Image {
        width: w as u32,
        height: h as u32,
        data,
    };
    img.check_finite(what).map_err(errors::scene)?;
    Ok(img)
}

/// Reads an image as a (H, W, 3) float32 array of linear RGB: an OpenEXR file as stored, as
/// the CLI's outputs and datasets hold them.
#[pyfunction]
pub fn read_image(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let img = py
        .detach(|| scene::Image::read_exr(&path))
        .map_err(errors::scene)?;
    image_to_array(py, img)
}

/// Writes a (H, W, 3) float32 array of linear RGB as an OpenEXR file (`.exr`) or as an 8-bit
/// sRGB PNG (`.png`, scaled by `exposure` first), atomically; an existing file is replaced only
/// with overwrite=True.
#[pyfunction]
#[pyo3(signature = (path, image, exposure = 1.0, overwrite = false))]
pub fn write_image(
    py: Python<'_>,
    path: PathBuf,
    image: &Bound<'_, PyAny>,
    exposure: f32,
    overwrite: bool,
) -> PyResult<()> {
    let img = image_arg(image, "image")?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    py.detach(|| match ext.as_deref() {
        Some("exr") => img.write_exr(&path, overwrite).map_err(errors::scene),
        Some("png") => img
            .write_png(&path, exposure, overwrite)
            .map_err(errors::scene),
        _ => Err(PyValueError::new_err(format!(
            "{}: write an image as .exr (linear float) or .png (8-bit sRGB)",
            path.display()
        ))),
    })
}
