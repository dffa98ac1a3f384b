//! The model files' errors, and the format identifiers they name.

use std::path::PathBuf;

/// Format name stored in the metadata.
pub const FORMAT_NAME: &str = "translucent-bssrdf";
/// Format version written by this build (and the only one it reads).
pub const FORMAT_VERSION: u64 = 1;
/// Key of the JSON document in the safetensors `__metadata__` map.
pub const METADATA_KEY: &str = "translucent-bssrdf";

/// What to do when no model file is at hand (part of the "not found" error).
pub const MODEL_FIX_HINT: &str = "train one with `translucent train` or use a shipped model from \
     the repository's `models/` folder (to compare against the reference weights of Son et al. \
     2024, create one with `translucent model import-son24 DIR OUT`)";

/// Errors of model construction, inference batches, model files and the SON24 importer.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The networks do not fit together (or a layer's buffers do not match its size).
    #[error("invalid model architecture: {0}")]
    Architecture(String),
    /// A batch passed to an inference method has inconsistent lengths.
    #[error("inference batch: {0}")]
    Batch(String),
    /// The model file does not exist.
    #[error("model file {} does not exist; {MODEL_FIX_HINT}", .path.display())]
    NotFound { path: PathBuf },
    /// Reading or writing failed.
    #[error("{}: {action}: {source}", .path.display())]
    Io {
        path: PathBuf,
        action: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// The file is not a safetensors file.
    #[error(
        "{} is not a safetensors model file ({reason}); pass a `.safetensors` file written by \
         `translucent` (the reference weights folder of Son et al. is imported with \
         `translucent model import-son24`)", .path.display()
    )]
    NotSafetensors { path: PathBuf, reason: String },
    /// The file has no model metadata (e.g. a safetensors file from another tool).
    #[error(
        "{} has no `{METADATA_KEY}` entry in its safetensors metadata, so it is not a \
         translucent BSSRDF model (files from other tools must be converted; the reference \
         weights are imported with `translucent model import-son24`)", .path.display()
    )]
    MetadataMissing { path: PathBuf },
    /// The metadata is malformed or contradicts itself or the tensors.
    #[error("{}: invalid model metadata: {reason}", .path.display())]
    MetadataInvalid { path: PathBuf, reason: String },
    /// The file was written in another format version.
    #[error(
        "{} is a format version {found} model, this build reads version {FORMAT_VERSION}; \
         re-create it with this build (retrain or re-import it)", .path.display()
    )]
    VersionMismatch { path: PathBuf, found: u64 },
    /// A tensor required by the architecture is absent.
    #[error(
        "{}: tensor `{tensor}` is missing (the architecture in the metadata requires it); the \
         file is incomplete, re-create it", .path.display()
    )]
    MissingTensor { path: PathBuf, tensor: String },
    /// A tensor not described by the architecture is present.
    #[error(
        "{}: tensor `{tensor}` is not part of the architecture in the metadata (the metadata \
         and the tensors disagree); re-create the file", .path.display()
    )]
    UnexpectedTensor { path: PathBuf, tensor: String },
    /// A tensor has the wrong shape.
    #[error(
        "{}: tensor `{tensor}` has shape {got:?}, expected {expected:?} from the architecture in \
         the metadata; re-create the file", .path.display()
    )]
    WrongShape {
        path: PathBuf,
        tensor: String,
        expected: Vec<usize>,
        got: Vec<usize>,
    },
    /// A tensor has a dtype other than F32.
    #[error("{}: tensor `{tensor}` has dtype {dtype}, expected F32", .path.display())]
    WrongDtype {
        path: PathBuf,
        tensor: String,
        dtype: String,
    },
    /// A weight is NaN or infinite.
    #[error(
        "{}: tensor `{tensor}` holds the non-finite value {value} at flat index {index}; the \
         model diverged or the file is damaged, retrain or restore it", .path.display()
    )]
    NonFinite {
        path: PathBuf,
        tensor: String,
        index: usize,
        value: f32,
    },
    /// A file of the SON24 reference weights folder is missing.
    #[error(
        "{} is missing: {what}; pass the folder that holds `variables/*.bin` and \
         `data_stats.json` (a copy of spock-the-wizard/shapeAdaptiveIR's weights)", .path.display()
    )]
    Son24Missing { path: PathBuf, what: String },
    /// A file of the SON24 reference weights folder is damaged.
    #[error("{}: not a valid reference weights file: {reason}", .path.display())]
    Son24Corrupt { path: PathBuf, reason: String },
}
