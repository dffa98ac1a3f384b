//! `translucent.render`: every view of a dataset or scene file at a medium, by one forward model
//! (`inverse::forward`), as `translucent render` renders them: the same model settings, seeds
//! and view indices, so the same seed and thread count give the CLI's images bit for bit.
//!
//! The views render one after another on the calling thread's pool, without the GIL; Ctrl-C
//! is honoured between views (`KeyboardInterrupt`).

use std::path::PathBuf;

use base::pixel::RenderSettings;
use inverse::forward::learned::LearnedSpec;
use inverse::forward::{ModelKind, ModelSpec};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::image_to_array;
use crate::dataset::PyDataset;
use crate::errors;
use crate::medium::PyMedium;

/// What is rendered: cameras, lights, mesh and the medium of the scene or the dataset's truth.
struct Source {
    views: Vec<scene::ViewDesc>,
    mesh: geometry::Mesh,
    warnings: Vec<geometry::MeshWarning>,
    what: String,
    medium: Option<scene::Medium>,
    render: scene::RenderInfo,
}

/// A dataset object, or a path: a scene file (.toml, .json, a Mitsuba 3 .xml) or a dataset
/// folder (or its description file), as `translucent render SCENE` reads it.
fn source(obj: &Bound<'_, PyAny>) -> PyResult<Source> {
    if let Ok(ds) = obj.cast::<PyDataset>() {
        let ds = ds.get();
        let (mesh, warnings) = ds.load_mesh()?;
        return Ok(Source {
            views: ds.inner.views.iter().map(|v| v.desc()).collect(),
            mesh,
            warnings,
            what: ds.inner.mesh.describe(),
            medium: ds.inner.truth,
            render: ds.inner.render.clone(),
        });
    }
    let path: PathBuf = obj.extract().map_err(|_| {
        PyValueError::new_err(
            "source: give a Dataset, or the path of a scene file or dataset folder",
        )
    })?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let dataset = |p: &std::path::Path| -> PyResult<(scene::SceneDesc, Option<scene::Medium>)> {
        let ds = scene::Dataset::load(p).map_err(errors::scene)?;
        let object = ds.object.unwrap_or(scene::Object::INDEX_MATCHED_ISOTROPIC);
        Ok((
            ds.scene(ds.truth.unwrap_or(object.medium([1.0; 3], [0.5; 3]))),
            ds.truth,
        ))
    };
    let (desc, medium) = if path.is_dir() || name == "dataset.json" {
        dataset(&path)?
    } else {
        match scene::SceneDesc::load(&path) {
            Ok(d) => {
                let m = d.medium;
                (d, Some(m))
            }
            Err(e) if name == "scene.json" => dataset(&path).map_err(|_| errors::scene(e))?,
            Err(e) => return Err(errors::scene(e)),
        }
    };
    let (mesh, warnings) = desc.load_mesh().map_err(errors::scene)?;
    Ok(Source {
        views: desc.views.clone(),
        mesh,
        warnings,
        what: desc.mesh.describe(),
        medium,
        render: desc.render.clone(),
    })
}

/// Renders every view of `source` at `medium` (the scene's medium or the dataset's truth when
/// None) with `model` ("volpath", "learned", "dipole"); returns a dict of lists: "images" and,
/// with derivatives, "d_sigma_t", "d_albedo" ("d_g" from the tracer), each an (H, W, 3)
/// float32 array per view, and "seconds_per_view".
#[pyfunction]
#[pyo3(signature = (source, medium = None, *, model = "volpath", spp = None, seed = None, derivatives = false, max_depth = None, threads = None, model_file = None))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    medium: Option<PyMedium>,
    model: &str,
    spp: Option<u32>,
    seed: Option<u64>,
    derivatives: bool,
    max_depth: Option<u32>,
    threads: Option<usize>,
    model_file: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let src = self::source(source)?;
    let kind: ModelKind = model.parse().map_err(PyValueError::new_err)?;
    let medium = match (medium, src.medium) {
        (Some(m), _) => m.inner,
        (None, Some(m)) => m,
        (None, None) => {
            return Err(PyValueError::new_err(
                "medium: the dataset records no medium (truth) to render; give one, e.g. \
                 Medium(sigma_t=50, albedo=0.9)",
            ));
        }
    };
    medium.validate("medium").map_err(errors::scene)?;
    let spp = spp.or(src.render.spp).unwrap_or(64);
    let seed = seed.or(src.render.seed).unwrap_or(0);
    let max_depth = max_depth
        .or(src.render.max_depth)
        .unwrap_or(volpath::DEFAULT_MAX_DEPTH);
    if spp == 0 || max_depth == 0 {
        return Err(PyValueError::new_err(
            "spp and max_depth must be at least 1",
        ));
    }
    if model_file.is_some() && kind != ModelKind::Learned {
        return Err(PyValueError::new_err(format!(
            "model_file is read by the learned model only, not by model={model:?}"
        )));
    }
    let networks = match (kind, &model_file) {
        (ModelKind::Learned, Some(f)) => Some(bssrdf::model::load(f).map_err(errors::model)?),
        (ModelKind::Learned, None) => Some(bssrdf::model::shipped().map_err(errors::model)?),
        _ => None,
    };
    let spec = match (kind, &networks) {
        (ModelKind::Learned, Some(n)) => ModelSpec::Learned(LearnedSpec::new(
            n,
            recovery::settings::LearnedModel::default().renderer,
            seed,
        )),
        (ModelKind::Dipole, _) => ModelSpec::Dipole {
            estimator: Default::default(),
        },
        _ => ModelSpec::tracer(volpath::VolpathSettings {
            max_depth,
            ..Default::default()
        }),
    };
    let pool = crate::pool(threads)?;
    let pool = pool.as_ref();
    let (mesh, warnings, what) = (src.mesh, src.warnings, src.what);
    let accel = py.detach(|| inverse::views::build_accel(mesh, &warnings, &what));
    let mut forward = spec.build(&accel);
    let fw = &mut forward;
    crate::on_pool(py, pool, || fw.prepare(&medium)).map_err(errors::inverse)?;
    let at = forward.at(medium).map_err(errors::inverse)?;
    let at = &*at;
    let (images, d_sigma_t, d_albedo, d_g, seconds) = (
        pyo3::types::PyList::empty(py),
        pyo3::types::PyList::empty(py),
        pyo3::types::PyList::empty(py),
        pyo3::types::PyList::empty(py),
        pyo3::types::PyList::empty(py),
    );
    for (i, v) in src.views.iter().enumerate() {
        let rs = RenderSettings {
            spp,
            seed,
            view: i as u64,
        };
        let t0 = std::time::Instant::now();
        let one = || -> Result<scene::loss::DiffImages, inverse::optimize::InverseError> {
            let view = at.view(&v.camera, &v.light);
            if derivatives {
                view.derivatives(&rs, None)
            } else {
                let value = view.value(&rs, None)?;
                let zero = scene::Image::new(0, 0);
                Ok(scene::loss::DiffImages {
                    value,
                    d_sigma_t: zero.clone(),
                    d_albedo: zero,
                    d_g: None,
                })
            }
        };
        let d = crate::on_pool(py, pool, one).map_err(errors::inverse)?;
        seconds.append(t0.elapsed().as_secs_f64())?;
        images.append(image_to_array(py, d.value)?)?;
        if derivatives {
            d_sigma_t.append(image_to_array(py, d.d_sigma_t)?)?;
            d_albedo.append(image_to_array(py, d.d_albedo)?)?;
            match d.d_g {
                Some(g) => d_g.append(image_to_array(py, g)?)?,
                None => d_g.append(py.None())?,
            }
        }
        py.check_signals()?;
    }
    let out = PyDict::new(py);
    out.set_item("images", images)?;
    out.set_item("d_sigma_t", derivatives.then_some(d_sigma_t))?;
    out.set_item("d_albedo", derivatives.then_some(d_albedo))?;
    out.set_item("d_g", derivatives.then_some(d_g))?;
    out.set_item("seconds_per_view", seconds)?;
    out.set_item("model", kind.name())?;
    out.set_item("spp", spp)?;
    out.set_item("seed", seed)?;
    Ok(out)
}
