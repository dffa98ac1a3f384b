//! `optimize`'s keyword arguments: each sets one field of the library's
//! [`recovery::RecoverySettings`], whose [`Default`] is the product's recovery (the CLI's
//! `optimize` defaults come from the same definition). An unknown keyword is a `TypeError`
//! listing the known ones; a value of the wrong type or range a `ValueError` naming it.

use std::path::PathBuf;

use inverse::params::OneOrRgb;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use recovery::RecoverySettings;

/// Every keyword `optimize` takes besides the dataset, the output folder, the callback, the
/// thread count and `verbose`, with what it sets (the CLI's flag of the same name).
pub const OPTIONS: &[(&str, &str)] = &[
    (
        "iterations",
        "Adam iterations in all (the learned fit, then the tracer's refinement)",
    ),
    ("spp", "samples per pixel of each iteration's renders"),
    ("views_per_iter", "views rendered per iteration"),
    (
        "crop",
        "render a random square crop of this many pixels per view (None: whole views)",
    ),
    (
        "view_subset",
        "the dataset's views to recover from, by index (None: all)",
    ),
    ("seed", "seed of every random stream"),
    (
        "model",
        "forward model: \"learned\" (default), \"volpath\" or \"dipole\"",
    ),
    (
        "estimator",
        "the model's gradient estimator (None: its default)",
    ),
    (
        "model_file",
        "a learned model's weights instead of the shipped ones",
    ),
    ("init_sigma_t", "starting σ_t, one value or three"),
    ("init_albedo", "starting albedo, one value or three"),
    (
        "init_g",
        "starting g of a recovery that frees it, one value or three",
    ),
    (
        "init_light_scale",
        "starting light scale of a recovery that frees it",
    ),
    (
        "free",
        "more unknowns: any of \"g\", \"g-rgb\", \"light-scale\", \"light-scale-rgb\"",
    ),
    ("fix_sigma_t", "hold σ_t at its start"),
    ("fix_albedo", "hold the albedo at its start"),
    ("monochrome", "one σ_t and one albedo for all channels"),
    ("lr_sigma_t", "learning rate of ln σ_t"),
    ("lr_albedo", "learning rate of the albedo"),
    ("lr_g", "learning rate of g"),
    ("lr_light_scale", "learning rate of ln k"),
    (
        "refine",
        "the last this many iterations refine with the tracer (None: the default share)",
    ),
    (
        "refine_spp",
        "samples per pixel of the refinement (None: spp)",
    ),
    (
        "max_depth",
        "the tracer's maximum path depth (None: the dataset's own, else 32)",
    ),
    ("checkpoint_every", "iterations between checkpoints"),
    (
        "final_spp",
        "samples per pixel of the re-renders in OUT/final",
    ),
    ("uncertainty_views", "views of the 95 % intervals (0: none)"),
    (
        "uncertainty_spp",
        "samples per pixel of the intervals' renders",
    ),
    (
        "mesh_error",
        "the mesh's stated RMS error as a fraction of its diagonal (None: exact)",
    ),
    (
        "consistency_views",
        "views re-rendered by the tracer at the estimate (0: no check)",
    ),
    ("starts", "initialisations tried first (1: none)"),
    (
        "resume",
        "continue the run in the output folder from its checkpoint",
    ),
    ("overwrite", "replace a run in the output folder"),
];

fn value_error(key: &str, v: &Bound<'_, PyAny>, what: &str) -> PyErr {
    let shown = v
        .repr()
        .map(|r| r.to_string())
        .unwrap_or_else(|_| "?".into());
    PyValueError::new_err(format!("{key} = {shown}: {what}"))
}

fn get<'a, 'py, T: FromPyObject<'a, 'py>>(
    key: &str,
    v: &'a Bound<'py, PyAny>,
    what: &str,
) -> PyResult<T> {
    v.extract::<T>().map_err(|_| value_error(key, v, what))
}

/// A count ≥ 1.
fn count(key: &str, v: &Bound<'_, PyAny>) -> PyResult<u32> {
    let n: i64 = get(key, v, "give a whole number")?;
    u32::try_from(n)
        .ok()
        .filter(|&n| n >= 1)
        .ok_or_else(|| value_error(key, v, "give a whole number of at least 1"))
}

/// A count ≥ 0.
fn count0(key: &str, v: &Bound<'_, PyAny>) -> PyResult<u32> {
    let n: i64 = get(key, v, "give a whole number")?;
    u32::try_from(n).map_err(|_| value_error(key, v, "give a whole number of at least 0"))
}

/// A positive, finite number.
fn positive(key: &str, v: &Bound<'_, PyAny>) -> PyResult<f64> {
    let x: f64 = get(key, v, "give a number")?;
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(value_error(key, v, "give a positive, finite number"))
    }
}

/// One number for every channel, or three.
fn rgb(key: &str, v: &Bound<'_, PyAny>) -> PyResult<[f64; 3]> {
    if let Ok(x) = v.extract::<f64>() {
        return Ok([x; 3]);
    }
    get(key, v, "give one number or three (R, G, B)")
}

/// `None` or `f(value)`.
fn optional<T>(
    v: &Bound<'_, PyAny>,
    f: impl FnOnce(&Bound<'_, PyAny>) -> PyResult<T>,
) -> PyResult<Option<T>> {
    if v.is_none() {
        Ok(None)
    } else {
        f(v).map(Some)
    }
}

/// Sets the option `key` of `s` to `v`.
pub fn apply(s: &mut RecoverySettings, key: &str, v: &Bound<'_, PyAny>) -> PyResult<()> {
    let flag = |what| get::<bool>(key, v, what);
    match key {
        "iterations" => s.schedule.iterations = count(key, v)?,
        "spp" => s.schedule.spp = count(key, v)?,
        "views_per_iter" => s.schedule.views_per_iter = count(key, v)? as usize,
        "crop" => s.schedule.crop = optional(v, |v| count(key, v))?,
        "view_subset" => {
            s.schedule.view_subset = optional(v, |v| get(key, v, "give a list of view indices"))?
        }
        "seed" => s.schedule.seed = get(key, v, "give a whole number ≥ 0")?,
        "model" => {
            let name: String = get(key, v, "give \"learned\", \"volpath\" or \"dipole\"")?;
            s.model.kind = name.parse().map_err(|e: String| value_error(key, v, &e))?;
        }
        "estimator" => s.model.estimator = optional(v, |v| get(key, v, "give a name"))?,
        "model_file" => s.model.file = optional(v, |v| get::<PathBuf>(key, v, "give a file path"))?,
        "init_sigma_t" => {
            s.start.init.sigma_t = rgb(key, v)?;
            s.start.sigma_t_from_units = false;
        }
        "init_albedo" => s.start.init.albedo = rgb(key, v)?,
        "init_g" => {
            s.start.init.g = optional(v, |v| {
                if let Ok(x) = v.extract::<f64>() {
                    return Ok(OneOrRgb::One(x));
                }
                let g: [f64; 3] = get(key, v, "give a number in (−1, 1), or three (R, G, B)")?;
                Ok(OneOrRgb::Rgb(g))
            })?
        }
        "init_light_scale" => {
            s.start.init.light_scale = optional(v, |v| positive(key, v))?.map(OneOrRgb::One)
        }
        "free" => {
            let names: Vec<String> = if let Ok(one) = v.extract::<String>() {
                vec![one]
            } else {
                get(
                    key,
                    v,
                    "give a list of \"g\", \"g-rgb\", \"light-scale\", \"light-scale-rgb\"",
                )?
            };
            let p = &mut s.schedule.params;
            for n in names {
                match n.as_str() {
                    "g" => p.free_g = true,
                    "g-rgb" | "g_rgb" => {
                        p.free_g = true;
                        p.g_per_channel = true;
                    }
                    "light-scale" | "light_scale" => p.free_light_scale = true,
                    "light-scale-rgb" | "light_scale_rgb" => {
                        p.free_light_scale = true;
                        p.light_scale_per_channel = true;
                    }
                    _ => {
                        return Err(value_error(
                            key,
                            v,
                            "the unknowns that can be freed are \"g\", \"g-rgb\", \
                             \"light-scale\" and \"light-scale-rgb\"",
                        ));
                    }
                }
            }
        }
        "fix_sigma_t" => s.schedule.params.fix_sigma_t = flag("give True or False")?,
        "fix_albedo" => s.schedule.params.fix_albedo = flag("give True or False")?,
        "monochrome" => s.schedule.params.monochrome = flag("give True or False")?,
        "lr_sigma_t" => s.schedule.lr_sigma_t = positive(key, v)? as f32,
        "lr_albedo" => s.schedule.lr_albedo = positive(key, v)? as f32,
        "lr_g" => s.schedule.lr_g = positive(key, v)? as f32,
        "lr_light_scale" => s.schedule.lr_light_scale = positive(key, v)? as f32,
        "refine" => s.tracer.refine = optional(v, |v| count0(key, v))?,
        "refine_spp" => s.tracer.refine_spp = optional(v, |v| count(key, v))?,
        "max_depth" => s.tracer.max_depth = optional(v, |v| count(key, v))?,
        "checkpoint_every" => s.checks.checkpoint_every = count(key, v)?,
        "final_spp" => s.checks.final_spp = count(key, v)?,
        "uncertainty_views" => s.checks.uncertainty.views = count0(key, v)? as usize,
        "uncertainty_spp" => s.checks.uncertainty.spp = count(key, v)?,
        "mesh_error" => s.checks.uncertainty.mesh_error = optional(v, |v| positive(key, v))?,
        "consistency_views" => s.checks.consistency_views = count0(key, v)? as usize,
        "starts" => s.start.starts = count(key, v)?,
        "resume" => s.resume = flag("give True or False")?,
        "overwrite" => s.overwrite = flag("give True or False")?,
        _ => {
            let known: Vec<&str> = OPTIONS.iter().map(|(k, _)| *k).collect();
            return Err(PyTypeError::new_err(format!(
                "optimize() got an unexpected keyword argument {key:?}; the options are: {}",
                known.join(", ")
            )));
        }
    }
    Ok(())
}

/// The settings `options` make of the product's defaults.
pub fn settings(options: Option<&Bound<'_, PyDict>>) -> PyResult<RecoverySettings> {
    let mut s = RecoverySettings::default();
    if let Some(o) = options {
        for (k, v) in o.iter() {
            let key: String = k.extract()?;
            apply(&mut s, &key, &v)?;
        }
    }
    Ok(s)
}

/// The product's default of the option `key` ([`OPTIONS`]) as a Python value.
pub fn default_of<'py>(py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    let s = RecoverySettings::default();
    use pyo3::IntoPyObjectExt;
    let rgb = |v: [f64; 3]| (v[0], v[1], v[2]).into_bound_py_any(py);
    macro_rules! py {
        ($v:expr) => {
            $v.into_bound_py_any(py)
        };
    }
    let free: Vec<&str> = [
        (
            s.schedule.params.free_g && !s.schedule.params.g_per_channel,
            "g",
        ),
        (s.schedule.params.g_per_channel, "g-rgb"),
        (
            s.schedule.params.free_light_scale && !s.schedule.params.light_scale_per_channel,
            "light-scale",
        ),
        (s.schedule.params.light_scale_per_channel, "light-scale-rgb"),
    ]
    .into_iter()
    .filter_map(|(on, n)| on.then_some(n))
    .collect();
    match key {
        "iterations" => py!(s.schedule.iterations),
        "spp" => py!(s.schedule.spp),
        "views_per_iter" => py!(s.schedule.views_per_iter),
        "crop" => py!(s.schedule.crop),
        "view_subset" => py!(s.schedule.view_subset),
        "seed" => py!(s.schedule.seed),
        "model" => py!(s.model.kind.name()),
        "estimator" => py!(s.model.estimator),
        "model_file" => py!(s.model.file),
        "init_sigma_t" => rgb(s.start.init.sigma_t),
        "init_albedo" => rgb(s.start.init.albedo),
        "init_g" => py!(None::<f64>),
        "init_light_scale" => py!(None::<f64>),
        "free" => py!(free),
        "fix_sigma_t" => py!(s.schedule.params.fix_sigma_t),
        "fix_albedo" => py!(s.schedule.params.fix_albedo),
        "monochrome" => py!(s.schedule.params.monochrome),
        "lr_sigma_t" => py!(s.schedule.lr_sigma_t),
        "lr_albedo" => py!(s.schedule.lr_albedo),
        "lr_g" => py!(s.schedule.lr_g),
        "lr_light_scale" => py!(s.schedule.lr_light_scale),
        "refine" => py!(s.tracer.refine),
        "refine_spp" => py!(s.tracer.refine_spp),
        "max_depth" => py!(s.tracer.max_depth),
        "checkpoint_every" => py!(s.checks.checkpoint_every),
        "final_spp" => py!(s.checks.final_spp),
        "uncertainty_views" => py!(s.checks.uncertainty.views),
        "uncertainty_spp" => py!(s.checks.uncertainty.spp),
        "mesh_error" => py!(s.checks.uncertainty.mesh_error),
        "consistency_views" => py!(s.checks.consistency_views),
        "starts" => py!(s.start.starts),
        "resume" => py!(s.resume),
        "overwrite" => py!(s.overwrite),
        _ => Err(PyTypeError::new_err(format!("no option {key:?}"))),
    }
}
