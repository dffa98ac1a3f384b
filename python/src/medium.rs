//! `translucent.Medium`: a homogeneous medium and the boundary that holds it, as the formats
//! define them (`scene::Medium`; DATASET.md): extinction σ_t per RGB channel in 1/scene unit,
//! single-scattering albedo α = σ_s/σ_t per channel, Henyey–Greenstein g, the boundary's relative
//! index of refraction η = n_inside/n_outside (1: index-matched, no surface) and its roughness as
//! the GGX α of its microfacets (Walter et al. 2007; Mitsuba 3's `roughdielectric` `alpha`;
//! 0: smooth).

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors;

/// A homogeneous medium inside its boundary.
///
/// Medium(sigma_t, albedo, g=0.0, eta=1.0, roughness=0.0)
///
/// sigma_t: extinction per RGB channel in 1/scene unit (> 0), one value or three.
/// albedo: single-scattering albedo σ_s/σ_t per channel, in [0, 1), one value or three.
/// g: Henyey–Greenstein mean cosine, (−1, 1); 0 = isotropic.
/// eta: relative index of refraction n_inside/n_outside, ≥ 1; 1 = index-matched (no surface).
/// roughness: the boundary's GGX α (Mitsuba 3's `roughdielectric` alpha), [0, 1]; 0 = smooth;
///     only a refractive boundary (eta > 1) can be rough.
///
/// Values out of range raise ValueError naming the field and the fix.
#[pyclass(name = "Medium", module = "translucent", frozen, eq, from_py_object)]
#[derive(Clone, PartialEq)]
pub struct PyMedium {
    pub inner: scene::Medium,
}

/// One value for every channel, or three.
#[derive(FromPyObject)]
pub enum Rgb {
    One(f32),
    Three([f32; 3]),
}

impl Rgb {
    pub fn rgb(&self) -> [f32; 3] {
        match self {
            Rgb::One(v) => [*v; 3],
            Rgb::Three(v) => *v,
        }
    }
}

/// A g as Python has it: a float, or a 3-tuple where the channels' g differ.
pub fn g_value(py: Python<'_>, g: scene::Anisotropy) -> PyResult<Bound<'_, PyAny>> {
    use pyo3::IntoPyObjectExt;
    match g.as_uniform() {
        Some(v) => short(v).into_bound_py_any(py),
        None => {
            let v = g.channels().map(short);
            (v[0], v[1], v[2]).into_bound_py_any(py)
        }
    }
}

impl PyMedium {
    /// `m`, checked ([`scene::Medium::validate`]) with `context` naming where it came from.
    pub fn checked(m: scene::Medium, context: &str) -> PyResult<PyMedium> {
        m.validate(context).map_err(errors::scene)?;
        Ok(PyMedium { inner: m })
    }
}

#[pymethods]
impl PyMedium {
    #[new]
    #[pyo3(signature = (sigma_t, albedo, g = Rgb::One(0.0), eta = 1.0, roughness = 0.0))]
    fn new(sigma_t: Rgb, albedo: Rgb, g: Rgb, eta: f32, roughness: f32) -> PyResult<PyMedium> {
        PyMedium::checked(
            scene::Medium {
                sigma_t: sigma_t.rgb(),
                albedo: albedo.rgb(),
                g: scene::Anisotropy(g.rgb()),
                eta,
                roughness,
            },
            "Medium",
        )
    }

    /// Extinction σ_t per RGB channel [1/scene unit].
    #[getter]
    fn sigma_t(&self) -> (f64, f64, f64) {
        let s = self.inner.sigma_t.map(short);
        (s[0], s[1], s[2])
    }

    /// Single-scattering albedo α = σ_s/σ_t per RGB channel.
    #[getter]
    fn albedo(&self) -> (f64, f64, f64) {
        let a = self.inner.albedo.map(short);
        (a[0], a[1], a[2])
    }

    /// Henyey–Greenstein g (mean cosine of the scattering angle): a number, or a 3-tuple
    /// where the channels' g differ.
    #[getter]
    fn g<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        g_value(py, self.inner.g)
    }

    /// Relative index of refraction n_inside/n_outside (1: index-matched).
    #[getter]
    fn eta(&self) -> f64 {
        short(self.inner.eta)
    }

    /// The boundary's GGX α (0: smooth).
    #[getter]
    fn roughness(&self) -> f64 {
        short(self.inner.roughness)
    }

    /// The same medium with some fields replaced: `m.replace(g=0.7)`.
    #[pyo3(signature = (*, sigma_t = None, albedo = None, g = None, eta = None, roughness = None))]
    fn replace(
        &self,
        sigma_t: Option<Rgb>,
        albedo: Option<Rgb>,
        g: Option<Rgb>,
        eta: Option<f32>,
        roughness: Option<f32>,
    ) -> PyResult<PyMedium> {
        let m = self.inner;
        PyMedium::checked(
            scene::Medium {
                sigma_t: sigma_t.map_or(m.sigma_t, |v| v.rgb()),
                albedo: albedo.map_or(m.albedo, |v| v.rgb()),
                g: g.map_or(m.g, |g| scene::Anisotropy(g.rgb())),
                eta: eta.unwrap_or(m.eta),
                roughness: roughness.unwrap_or(m.roughness),
            },
            "Medium.replace",
        )
    }

    /// A medium from a published measurement (`scene::measured`: Jensen et al. 2001's twelve
    /// materials, Narasimhan et al. 2006's media) in the given length unit ("mm", "cm", "m"),
    /// at phase function g (the reduced coefficients are converted to σ_t at that g).
    #[staticmethod]
    #[pyo3(signature = (name, unit = "mm", g = Rgb::One(0.0), eta = 1.0, roughness = 0.0))]
    fn measured(name: &str, unit: &str, g: Rgb, eta: f32, roughness: f32) -> PyResult<PyMedium> {
        use scene::measured::MeasuredMedium;
        let m = MeasuredMedium::find(name).map_err(errors::scene)?;
        let unit = parse_unit(unit)?;
        let g = scene::Anisotropy(g.rgb());
        if let Some((c, v)) = g.out_of_range() {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "Medium.measured({name:?}): {} = {v} must be in (−1, 1)",
                g.field(c)
            )));
        }
        let (sigma_t, albedo) = m.medium_rgb(g.channels().map(f64::from), unit);
        PyMedium::checked(
            scene::Medium {
                sigma_t,
                albedo,
                g,
                eta,
                roughness,
            },
            &format!("Medium.measured({name:?})"),
        )
    }

    /// The medium as the `truth` block of dataset.json writes it.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("sigma_t", self.sigma_t())?;
        d.set_item("albedo", self.albedo())?;
        d.set_item("g", self.g(py)?)?;
        d.set_item("eta", self.eta())?;
        d.set_item("roughness", self.roughness())?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let m = &self.inner;
        let f = |v: [f32; 3]| format!("({}, {}, {})", v[0], v[1], v[2]);
        format!(
            "Medium(sigma_t={}, albedo={}, g={}, eta={}, roughness={})",
            f(m.sigma_t),
            f(m.albedo),
            m.g,
            m.eta,
            m.roughness
        )
    }
}

/// A length unit by its symbol.
pub fn parse_unit(unit: &str) -> PyResult<scene::measured::LengthUnit> {
    use scene::measured::LengthUnit;
    [LengthUnit::Mm, LengthUnit::Cm, LengthUnit::M]
        .into_iter()
        .find(|u| u.name() == unit)
        .ok_or_else(|| {
            pyo3::exceptions::PyValueError::new_err(format!(
                "unit = {unit:?}: the length unit is one of \"mm\", \"cm\", \"m\""
            ))
        })
}

/// A stored f32 as the f64 with the same shortest decimal form (0.9, not 0.8999999761581421):
/// what the user gave.
pub fn short(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(f64::from(x))
}
