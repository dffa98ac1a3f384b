//! Typed errors of the scene crate; every message names the file, the field and the fix.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: cannot read or write this file")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A field has an invalid value. `location` is "file: field.path".
    #[error("{}", join_location(location, reason))]
    Invalid { location: String, reason: String },
    /// The file does not parse.
    #[error("{path}: {reason}")]
    Parse { path: PathBuf, reason: String },
    /// Refused to overwrite a file the user made.
    #[error(
        "{path} already exists; pass {} to replace it",
        crate::setting::Setting::Overwrite
    )]
    Exists { path: PathBuf },
    /// Another run holds the output folder ([`crate::fsutil::lock_folder`]).
    #[error(
        "{dir} is in use by another translucent run (process {owner}); wait for it to finish, or \
         choose another output folder"
    )]
    Busy { dir: PathBuf, owner: String },
    #[error(transparent)]
    Geometry(#[from] geometry::GeometryError),
}

/// "file: field = value: reason" when the reason starts with the value ("= …"), else
/// "file: field: reason".
fn join_location(location: &str, reason: &str) -> String {
    if reason.starts_with("= ") {
        format!("{location} {reason}")
    } else {
        format!("{location}: {reason}")
    }
}
