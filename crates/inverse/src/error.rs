//! The inverse core's errors.

use std::path::PathBuf;

/// Errors of the inverse loop.
#[derive(Debug, thiserror::Error)]
pub enum InverseError {
    /// Invalid settings or data.
    #[error("{0}")]
    Invalid(String),
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] bssrdf::render::RenderError),
    /// The dipole cannot render.
    #[error(transparent)]
    Dipole(#[from] dipole::DipoleError),
    /// Writing failed.
    #[error(transparent)]
    Write(#[from] scene::SceneError),
    /// A checkpoint cannot be used.
    #[error("checkpoint {}: {reason}", .path.display())]
    Checkpoint {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// NaN or Inf appeared in iteration `iteration`: in the loss or gradient of one view, or in
    /// the parameters after the Adam step. The optimiser keeps its last finite state.
    #[error(
        "iteration {iteration}{}: {what} is not finite; the run stopped with the parameters of the \
         iteration before; check the target images and the learning rates",
        .view.map_or(String::new(), |v| format!(", view {v}"))
    )]
    NonFinite {
        /// The iteration (0-based) in which it appeared.
        iteration: u32,
        /// The target view (index among the optimiser's targets), when a view's render caused it.
        view: Option<usize>,
        /// What was not finite, with its value.
        what: String,
    },
}
