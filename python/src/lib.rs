//! `translucent._translucent`: the Rust core of the Python package `translucent` (PyO3, abi3).
//!
//! The package's Python layer (`python/translucent/`) checks the arrays it is given and wraps
//! what this module returns; this module stands on the library crates' typed configurations
//! (`scene::Dataset`, `scene::Medium`, `inverse::forward::ModelSpec`,
//! `recovery::RecoverySettings`), never on the command line.
//!
//! | Python | Rust |
//! |---|---|
//! | `Medium` | [`medium::PyMedium`] over `scene::Medium` |
//! | `Dataset` | [`dataset::PyDataset`] over `scene::Dataset` (and a mesh given as arrays) |
//! | `render` | [`render::render`] over `inverse::views::render_with` |
//! | `optimize` | [`optimize::optimize`] over `recovery::run` |
//! | `import_colmap`, `import_nerf` | [`capture`] over `scene::capture` |
//! | `read_image`, `write_image` | `scene::Image` |
//!
//! Every call that renders or optimises releases the GIL while Rust works and runs on a thread
//! pool of the requested size (the CLI's `--threads`), so the same seed and thread count give
//! the same numbers as the CLI. Library errors become Python exceptions with the library's
//! message ([`errors`]); the settings they name are spelled as keyword arguments.

use pyo3::prelude::*;

mod arrays;
mod capture;
mod dataset;
mod errors;
mod medium;
mod optimize;
mod options;
mod render;

/// How the settings that library errors name are spelled in Python: as keyword arguments.
fn keyword_of(setting: scene::setting::Setting) -> &'static str {
    use scene::setting::Setting;
    match setting {
        Setting::Overwrite => "overwrite=True",
        Setting::Resume => "resume=True",
        Setting::FreeG => "free=[\"g\"]",
        Setting::FreeGRgb => "free=[\"g-rgb\"]",
        Setting::FreeLightScale => "free=[\"light-scale\"]",
        s => s.key(),
    }
}

/// A pool of `threads` workers (`None`: rayon's global pool, all cores, as the CLI without
/// `--threads`).
pub(crate) fn pool(threads: Option<usize>) -> PyResult<Option<rayon::ThreadPool>> {
    match threads {
        None => Ok(None),
        Some(0) => Err(pyo3::exceptions::PyValueError::new_err(
            "threads must be at least 1 (None: all cores)",
        )),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(Some)
            .map_err(|e| errors::Error::new_err(format!("threads={n}: {e}"))),
    }
}

/// Runs `f` without the GIL, on `pool` when given (else on rayon's global pool).
pub(crate) fn on_pool<T: Send>(
    py: Python<'_>,
    pool: Option<&rayon::ThreadPool>,
    f: impl FnOnce() -> T + Send,
) -> T {
    match pool {
        Some(p) => py.detach(|| p.install(f)),
        None => py.detach(f),
    }
}

#[pymodule]
fn _translucent(m: &Bound<'_, PyModule>) -> PyResult<()> {
    scene::setting::name_settings(keyword_of);
    // The library's warnings on stderr, as the CLI prints them (`TRANSLUCENT_LOG` overrides the
    // level, e.g. `info`); a host that installed its own subscriber keeps it.
    let filter = tracing_subscriber::EnvFilter::try_from_env("TRANSLUCENT_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_target(false)
        .without_time()
        .with_ansi(false)
        .with_writer(std::io::stderr)
        .try_init();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("Error", m.py().get_type::<errors::Error>())?;
    m.add_class::<medium::PyMedium>()?;
    m.add_class::<dataset::PyDataset>()?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(optimize::optimize, m)?)?;
    m.add_function(wrap_pyfunction!(optimize::default_options, m)?)?;
    m.add_function(wrap_pyfunction!(capture::import_colmap, m)?)?;
    m.add_function(wrap_pyfunction!(capture::import_nerf, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(arrays::write_image, m)?)?;
    Ok(())
}
