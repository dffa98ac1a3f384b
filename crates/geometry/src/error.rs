//! Typed errors of the geometry crate. Every message names the file (when there is one), the
//! element and the reason, and says how to fix it where a fix is obvious.

use std::path::PathBuf;

/// Errors raised while loading, validating or building geometry.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read mesh file")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file extension is not one we read.
    #[error("{path}: unsupported mesh format (expected .obj or .ply)")]
    UnsupportedFormat { path: PathBuf },
    /// The file is syntactically broken.
    #[error("{path}: malformed {format} file: {reason}")]
    Parse {
        path: PathBuf,
        format: &'static str,
        reason: String,
    },
    /// The mesh content is invalid (`element` says which vertex / face / property).
    #[error("{source_name}: {element}: {reason}")]
    Invalid {
        source_name: String,
        element: String,
        reason: String,
    },
    /// A procedural shape was given bad parameters.
    #[error("shape '{shape}': parameter '{param}' {reason}")]
    ShapeParam {
        shape: String,
        param: String,
        reason: String,
    },
}
