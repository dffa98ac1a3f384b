//! Typed errors of the scene crate; every message names the file, the field and the fix.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A field has an invalid value. `location` is "file: field.path".
    #[error("{location}: {reason}")]
    Invalid { location: String, reason: String },
    /// The file does not parse.
    #[error("{path}: {reason}")]
    Parse { path: PathBuf, reason: String },
    /// Refused to overwrite a file the user made.
    #[error("{path} already exists; pass --overwrite to replace it")]
    Exists { path: PathBuf },
    #[error(transparent)]
    Geometry(#[from] geometry::GeometryError),
}
