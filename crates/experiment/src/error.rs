//! The experiments' typed errors. Options that cannot run are [`ExperimentError::Invalid`],
//! whose message names the option and the fix ([`bail!`](crate::bail)); failures of the library
//! below keep their own types, and [`Context`] adds what the experiment was doing.

use std::fmt::Display;

/// Why an experiment stopped.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// Options (or an output folder) that cannot run; the message names them and the fix.
    #[error("{0}")]
    Invalid(String),
    /// What the experiment was doing when the error below happened (the error follows in the
    /// chain of sources, as `{:#}` of anyhow prints it).
    #[error("{context}")]
    Context {
        context: String,
        #[source]
        source: Box<ExperimentError>,
    },
    #[error(transparent)]
    Recovery(#[from] recovery::RecoveryError),
    #[error(transparent)]
    Inverse(#[from] inverse::optimize::InverseError),
    #[error(transparent)]
    Render(#[from] bssrdf::render::RenderError),
    #[error(transparent)]
    Model(#[from] bssrdf::model::ModelError),
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error(transparent)]
    Geometry(#[from] geometry::GeometryError),
    #[error(transparent)]
    Plot(#[from] plot::PlotError),
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// The experiments' result type.
pub type Result<T, E = ExperimentError> = std::result::Result<T, E>;

/// Adds what was being done to an error (or to a missing value).
pub trait Context<T> {
    fn context(self, what: impl Display) -> Result<T>;
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T>;
}

impl<T, E: Into<ExperimentError>> Context<T> for std::result::Result<T, E> {
    fn context(self, what: impl Display) -> Result<T> {
        self.with_context(|| what)
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|e| ExperimentError::Context {
            context: what().to_string(),
            source: Box::new(e.into()),
        })
    }
}

impl<T> Context<T> for Option<T> {
    fn context(self, what: impl Display) -> Result<T> {
        self.ok_or_else(|| ExperimentError::Invalid(what.to_string()))
    }
    fn with_context<D: Display>(self, what: impl FnOnce() -> D) -> Result<T> {
        self.ok_or_else(|| ExperimentError::Invalid(what().to_string()))
    }
}

/// Returns [`ExperimentError::Invalid`] with a formatted message.
#[macro_export]
macro_rules! bail {
    ($($t:tt)*) => {
        return Err($crate::ExperimentError::Invalid(format!($($t)*)))
    };
}

/// [`bail!`] unless the condition holds.
#[macro_export]
macro_rules! ensure {
    ($cond:expr, $($t:tt)*) => {
        if !$cond {
            $crate::bail!($($t)*);
        }
    };
}
