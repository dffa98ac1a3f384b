//! `translucent.Dataset`: a capture's views (camera, light, image), its object's mesh, what it
//! states about the object (boundary, phase function) and, for a synthetic one, its truth; read
//! from every folder format the CLI reads (`scene::Dataset::load`: `dataset.json`, a Mitsuba
//! reference folder, a Mitsuba 3 scene folder), or made from NumPy arrays and saved as a
//! `dataset.json` folder (DATASET.md).
//!
//! Cameras follow Mitsuba 3's convention (CONVENTIONS.md): `to_world` is the 4 × 4 matrix whose
//! columns are x (image left), y (image up), z (view direction) and the position; intrinsics are
//! (f_x, f_y, c_x, c_y) in pixels with row 0 at the top.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{image_arg, image_to_array};
use crate::errors;
use crate::medium::{PyMedium, parse_unit, short};

/// A dataset: views, mesh, object and (when synthetic) truth.
///
/// Dataset.load(path) reads a dataset folder (dataset.json, a Mitsuba reference folder with
/// scene.json, a Mitsuba 3 scene folder with scene.xml) or its description file;
/// Dataset.from_arrays(...) makes one from NumPy arrays; save(path) writes a dataset.json folder.
#[pyclass(name = "Dataset", module = "translucent", frozen)]
#[derive(Clone)]
pub struct PyDataset {
    pub inner: scene::Dataset,
    /// A mesh given as arrays (the dataset's `mesh` names no file until it is saved).
    pub mesh: Option<Arc<geometry::Mesh>>,
}

impl PyDataset {
    /// The object's mesh: the arrays it was made from, or its file or built-in shape.
    pub fn load_mesh(&self) -> PyResult<(geometry::Mesh, Vec<geometry::MeshWarning>)> {
        match &self.mesh {
            Some(m) => Ok((m.as_ref().clone(), Vec::new())),
            None => self.inner.load_mesh().map_err(errors::scene),
        }
    }

    /// The folder it was read from (`None` for one made from arrays and not saved).
    pub fn folder(&self) -> Option<&Path> {
        (!self.inner.root.as_os_str().is_empty()).then_some(self.inner.root.as_path())
    }
}

/// A mesh as (vertices (V, 3) float32, faces (F, 3) uint32).
type MeshArrays<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<u32>>);

fn bad(m: String) -> PyErr {
    PyValueError::new_err(m)
}

#[pymethods]
impl PyDataset {
    /// Reads the dataset at `path`: a folder (dataset.json, scene.json of a Mitsuba reference
    /// folder, scene.xml of a Mitsuba 3 scene folder) or the description file itself.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<PyDataset> {
        Ok(PyDataset {
            inner: scene::Dataset::load(&path).map_err(errors::scene)?,
            mesh: None,
        })
    }

    /// The cameras, lights, mesh and medium of a scene file (.toml, .json, or a Mitsuba 3
    /// scene .xml; SCENE.md) as a dataset without images: the scene's medium is its truth and
    /// states its object. Render it and give it the images with `with_images`.
    #[staticmethod]
    fn from_scene(path: PathBuf) -> PyResult<PyDataset> {
        let desc = scene::SceneDesc::load(&path).map_err(errors::scene)?;
        Ok(PyDataset {
            inner: scene::Dataset::from_scene(&desc),
            mesh: None,
        })
    }

    /// A dataset from arrays (the Python layer checks shapes and dtypes first):
    /// vertices (V, 3) float32, faces (F, 3) uint32, to_world (N, 4, 4) float32, intrinsics
    /// (N, 4) float32 (f_x, f_y, c_x, c_y in pixels), resolution (N, 2) uint32 (width, height),
    /// light positions and intensities (N, 3) float32, images: N arrays (H, W, 3) float32 or
    /// None.
    #[staticmethod]
    #[pyo3(signature = (vertices, faces, to_world, intrinsics, resolution, light_positions, light_intensities, images, eta, roughness, g, truth, length_unit))]
    #[allow(clippy::too_many_arguments)]
    fn _from_arrays(
        vertices: PyReadonlyArray2<f32>,
        faces: PyReadonlyArray2<u32>,
        to_world: PyReadonlyArray3<f32>,
        intrinsics: PyReadonlyArray2<f32>,
        resolution: PyReadonlyArray2<u32>,
        light_positions: PyReadonlyArray2<f32>,
        light_intensities: PyReadonlyArray2<f32>,
        images: Option<Vec<Bound<'_, PyAny>>>,
        eta: f32,
        roughness: f32,
        g: crate::medium::Rgb,
        truth: Option<PyMedium>,
        length_unit: Option<&str>,
    ) -> PyResult<PyDataset> {
        let vertices = vertices.as_array();
        let faces = faces.as_array();
        let mut mesh = geometry::Mesh {
            positions: vertices
                .rows()
                .into_iter()
                .map(|r| Vec3::new(r[0], r[1], r[2]))
                .collect(),
            normals: None,
            indices: faces
                .rows()
                .into_iter()
                .map(|r| [r[0], r[1], r[2]])
                .collect(),
        };
        let mesh_warnings = geometry::mesh::validate(&mut mesh, "vertices/faces")
            .map_err(|e| bad(errors::chain(&e)))?;
        let (tw, k, res) = (
            to_world.as_array(),
            intrinsics.as_array(),
            resolution.as_array(),
        );
        let (lp, li) = (light_positions.as_array(), light_intensities.as_array());
        let n = tw.shape()[0];
        let mut views = Vec::with_capacity(n);
        for i in 0..n {
            let rows: [[f32; 4]; 4] =
                std::array::from_fn(|r| std::array::from_fn(|c| tw[[i, r, c]]));
            let (w, h) = (res[[i, 0]], res[[i, 1]]);
            let k = scene::camera::Intrinsics {
                fx: k[[i, 0]],
                fy: k[[i, 1]],
                cx: k[[i, 2]],
                cy: k[[i, 3]],
            };
            if !(k.fx > 0.0 && k.fy > 0.0 && k.fx.is_finite() && k.fy.is_finite()) {
                return Err(bad(format!(
                    "intrinsics[{i}] = ({}, {}, {}, {}): the focal lengths f_x, f_y must be \
                     positive pixels",
                    k.fx, k.fy, k.cx, k.cy
                )));
            }
            let camera = scene::Camera::from_to_world(rows, 90.0, w, h).with_intrinsics(&k);
            camera
                .validate(&format!("to_world[{i}] / intrinsics[{i}]"))
                .map_err(errors::scene)?;
            let light = scene::PointLight {
                position: Vec3::new(lp[[i, 0]], lp[[i, 1]], lp[[i, 2]]),
                intensity: [li[[i, 0]], li[[i, 1]], li[[i, 2]]],
            };
            let image = match &images {
                Some(imgs) => Some(image_arg(&imgs[i], &format!("images[{i}]"))?),
                None => None,
            };
            if let Some(img) = &image
                && (img.width, img.height) != (w, h)
            {
                return Err(bad(format!(
                    "images[{i}] is {} × {} pixels but resolution[{i}] is {w} × {h}; give each \
                     view's image at its camera's resolution (array shape (height, width, 3))",
                    img.width, img.height
                )));
            }
            views.push(scene::View {
                camera,
                light,
                image,
                image_path: None,
                expected_mean: None,
            });
        }
        let g = scene::Anisotropy(g.rgb());
        let object = scene::Object { eta, roughness, g };
        object.validate("object").map_err(errors::scene)?;
        let mut ds = scene::Dataset::from_scene(&scene::SceneDesc {
            mesh: scene::MeshSource::File(PathBuf::from("mesh.ply")),
            medium: truth
                .as_ref()
                .map_or(object.medium([1.0; 3], [0.5; 3]), |t| t.inner),
            views: Vec::new(),
            render: Default::default(),
            path: PathBuf::new(),
            length_unit: None,
        });
        ds.views = views;
        ds.object = Some(object);
        ds.truth = truth.map(|t| t.inner);
        if let Some(t) = &ds.truth
            && scene::Object::of(t) != object
        {
            return Err(bad(format!(
                "truth = {t:?} has another boundary or phase function than the object (eta \
                 {eta}, roughness {roughness}, g {g}); give the truth the object's"
            )));
        }
        ds.metadata.length_unit = length_unit.map(parse_unit).transpose()?;
        ds.metadata.generator = Some(format!(
            "translucent {} (Python)",
            env!("CARGO_PKG_VERSION")
        ));
        ds.warnings = mesh_warnings.iter().map(|w| w.to_string()).collect();
        Ok(PyDataset {
            inner: ds,
            mesh: Some(Arc::new(mesh)),
        })
    }

    /// Writes the dataset as a dataset.json folder (DATASET.md) at `path` and returns it as
    /// read back from there. A mesh given as arrays is written as `mesh.ply`. Existing files
    /// are replaced only with overwrite=True.
    #[pyo3(signature = (path, overwrite = false))]
    fn save(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<PyDataset> {
        let mut ds = self.inner.clone();
        let mesh = self.mesh.clone();
        py.detach(move || -> Result<scene::Dataset, scene::SceneError> {
            if let Some(m) = mesh {
                let file = path.join("mesh.ply");
                if !overwrite && file.exists() {
                    return Err(scene::SceneError::Exists { path: file });
                }
                std::fs::create_dir_all(&path).map_err(|source| scene::SceneError::Io {
                    path: path.clone(),
                    source,
                })?;
                geometry::io::save_ply(&m, &file)?;
                ds.mesh = scene::MeshSource::File(file);
            }
            ds.save(&path, overwrite)?;
            scene::Dataset::load(&path)
        })
        .map(|inner| PyDataset { inner, mesh: None })
        .map_err(errors::scene)
    }

    /// This dataset with other images (one (H, W, 3) float32 array per view), e.g. renders
    /// to recover from.
    fn with_images(&self, images: Vec<Bound<'_, PyAny>>) -> PyResult<PyDataset> {
        if images.len() != self.inner.views.len() {
            return Err(bad(format!(
                "images: {} arrays for {} views; give one per view",
                images.len(),
                self.inner.views.len()
            )));
        }
        let mut out = self.clone();
        for (i, (v, a)) in out.inner.views.iter_mut().zip(&images).enumerate() {
            let img = image_arg(a, &format!("images[{i}]"))?;
            let (w, h) = (v.camera.width, v.camera.height);
            if (img.width, img.height) != (w, h) {
                return Err(bad(format!(
                    "images[{i}] is {} × {} pixels but view {i}'s camera is {w} × {h}; array \
                     shape (height, width, 3)",
                    img.width, img.height
                )));
            }
            v.image = Some(img);
            v.image_path = None;
            v.expected_mean = None;
        }
        Ok(out)
    }

    fn __len__(&self) -> usize {
        self.inner.views.len()
    }

    /// The folder the dataset was read from (None for one made from arrays).
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.folder().map(Path::to_path_buf)
    }

    /// What one unit of the dataset's lengths is ("mm", "cm", "m"; σ_t is in 1/that unit), or
    /// None where the dataset or scene file does not say.
    #[getter]
    fn length_unit(&self) -> Option<&'static str> {
        self.inner.metadata.length_unit.map(|u| u.name())
    }

    /// Each view's camera-to-world matrix (N, 4, 4): columns x (image left), y (image up),
    /// z (view direction), position (Mitsuba 3's `to_world`).
    #[getter]
    fn to_world<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let flat: Vec<f32> = self
            .inner
            .views
            .iter()
            .flat_map(|v| v.camera.to_world_rows().into_iter().flatten())
            .collect();
        PyArray1::from_vec(py, flat).reshape([self.inner.views.len(), 4, 4])
    }

    /// Each view's intrinsics (N, 4): f_x, f_y, c_x, c_y in pixels (row 0 at the top).
    #[getter]
    fn intrinsics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat: Vec<f32> = self
            .inner
            .views
            .iter()
            .flat_map(|v| {
                let k = v.camera.intrinsics();
                [k.fx, k.fy, k.cx, k.cy]
            })
            .collect();
        PyArray1::from_vec(py, flat).reshape([self.inner.views.len(), 4])
    }

    /// Each view's film (N, 2): width, height in pixels.
    #[getter]
    fn resolution<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let flat: Vec<u32> = self
            .inner
            .views
            .iter()
            .flat_map(|v| [v.camera.width, v.camera.height])
            .collect();
        PyArray1::from_vec(py, flat).reshape([self.inner.views.len(), 2])
    }

    /// Each view's point light position (N, 3), in scene units.
    #[getter]
    fn light_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat: Vec<f32> = self
            .inner
            .views
            .iter()
            .flat_map(|v| v.light.position.to_array())
            .collect();
        PyArray1::from_vec(py, flat).reshape([self.inner.views.len(), 3])
    }

    /// Each view's point light radiant intensity (N, 3), W/sr per RGB channel.
    #[getter]
    fn light_intensities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let flat: Vec<f32> = self
            .inner
            .views
            .iter()
            .flat_map(|v| v.light.intensity)
            .collect();
        PyArray1::from_vec(py, flat).reshape([self.inner.views.len(), 3])
    }

    /// Each view's image, (H, W, 3) float32 linear radiance (None where a view has none).
    #[getter]
    fn images<'py>(&self, py: Python<'py>) -> PyResult<Vec<Option<Bound<'py, PyArray3<f32>>>>> {
        self.inner
            .views
            .iter()
            .map(|v| v.image.clone().map(|i| image_to_array(py, i)).transpose())
            .collect()
    }

    /// The object's mesh as (vertices (V, 3) float32, faces (F, 3) uint32), as loaded and
    /// checked (outward winding).
    #[getter]
    fn mesh<'py>(&self, py: Python<'py>) -> PyResult<MeshArrays<'py>> {
        let (m, _) = self.load_mesh()?;
        let nv = m.positions.len();
        let nf = m.indices.len();
        let v: Vec<f32> = m.positions.iter().flat_map(|p| p.to_array()).collect();
        let f: Vec<u32> = m.indices.iter().flatten().copied().collect();
        Ok((
            PyArray1::from_vec(py, v).reshape([nv, 3])?,
            PyArray1::from_vec(py, f).reshape([nf, 3])?,
        ))
    }

    /// What the dataset states about the object: {"eta", "roughness", "g"}, or None when it
    /// states nothing (a recovery then assumes an index-matched, isotropic object and says so).
    #[getter]
    fn object<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.inner
            .object
            .map(|o| {
                let d = PyDict::new(py);
                d.set_item("eta", short(o.eta))?;
                d.set_item("roughness", short(o.roughness))?;
                d.set_item("g", crate::medium::g_value(py, o.g)?)?;
                Ok(d)
            })
            .transpose()
    }

    /// The medium a synthetic dataset was made with (a report: never read by a recovery).
    #[getter]
    fn truth(&self) -> Option<PyMedium> {
        self.inner.truth.map(|inner| PyMedium { inner })
    }

    /// What loading found and repaired (e.g. a mesh's winding), as sentences.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings.clone()
    }

    fn __repr__(&self) -> String {
        let place = self
            .folder()
            .map_or("not saved".into(), |p| p.display().to_string());
        format!("<Dataset of {} views, {place}>", self.inner.views.len())
    }
}
