//! The binary samples file (training data of docs/model.md §5–§6).
//!
//! Layout (all integers little-endian):
//!
//! | offset | size | content |
//! |---|---|---|
//! | 0 | 8 | magic bytes `TLSAMPLE` |
//! | 8 | 4 | `u32` format version ([`FORMAT_VERSION`] = 1) |
//! | 12 | 4 | `u32` header length `H` in bytes |
//! | 16 | H | UTF-8 JSON header ([`SampleFileHeader`]) |
//! | 16 + H | N · 196 | N records, each a [`Sample`] as little-endian `f32`/`u32` words |
//!
//! The JSON header holds: `format` ("translucent-samples"), `version`, `sample_count` N,
//! `record_size` (196), `byte_order` ("little"), `fields` (name, byte offset, dtype, count of each
//! record field, in order: `poly_ls` f32×20 @0, `out_ls` f32×3 @80, `albedo` @92, `sigma_t` @96,
//! `g` @100, `eta` @104, `absorption_prob` @108, `sigma_n` @112, `in_pos` f32×3 @116, `in_dir` @128,
//! `in_normal` @140, `out_pos` @152, `out_normal` @164, `out_dir` @176, `bounces` u32 @188,
//! `config` u32 @192), `seed`, `config` (the generating [`crate::datagen::DataConfig`] as JSON),
//! `parameter_ranges`, `summary` (optional [`crate::datagen::DataSummary`]), `generator` and
//! `created_unix_s`. See [`Sample`] for the meaning of each field.
//!
//! Writing is atomic (temporary file in the same directory, `fsync`, rename) and refuses to
//! replace an existing file unless `overwrite` is set. Reading checks the magic, the version, the
//! header JSON, the record size and field layout, `sample_count` against the file length and that
//! every `f32` field is finite; each error names the file.

use std::io::Write;
use std::mem::offset_of;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::sample::{SAMPLE_BYTES, Sample};

/// Magic bytes at the start of the file.
pub const MAGIC: &[u8; 8] = b"TLSAMPLE";
/// Current format version.
pub const FORMAT_VERSION: u32 = 1;
/// Value of the header's `format` field.
pub const FORMAT_NAME: &str = "translucent-samples";
/// Number of leading `f32` words of a record (the rest are the `u32` fields).
const F32_WORDS: usize = offset_of!(Sample, bounces) / 4;

/// One field of the record layout.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FieldLayout {
    pub name: String,
    /// Byte offset inside the record.
    pub offset: usize,
    /// "f32" or "u32".
    pub dtype: String,
    /// Number of elements.
    pub count: usize,
}

/// The record layout of [`Sample`].
pub fn record_layout() -> Vec<FieldLayout> {
    macro_rules! f {
        ($name:ident, $dtype:expr, $count:expr) => {
            FieldLayout {
                name: stringify!($name).to_string(),
                offset: offset_of!(Sample, $name),
                dtype: $dtype.to_string(),
                count: $count,
            }
        };
    }
    vec![
        f!(poly_ls, "f32", bssrdf::nn::N_POLY),
        f!(out_ls, "f32", 3),
        f!(albedo, "f32", 1),
        f!(sigma_t, "f32", 1),
        f!(g, "f32", 1),
        f!(eta, "f32", 1),
        f!(absorption_prob, "f32", 1),
        f!(sigma_n, "f32", 1),
        f!(in_pos, "f32", 3),
        f!(in_dir, "f32", 3),
        f!(in_normal, "f32", 3),
        f!(out_pos, "f32", 3),
        f!(out_normal, "f32", 3),
        f!(out_dir, "f32", 3),
        f!(bounces, "u32", 1),
        f!(config, "u32", 1),
    ]
}

/// The JSON header (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleFileHeader {
    pub format: String,
    pub version: u32,
    pub sample_count: u64,
    pub record_size: usize,
    pub byte_order: String,
    pub fields: Vec<FieldLayout>,
    pub seed: u64,
    pub config: serde_json::Value,
    pub parameter_ranges: serde_json::Value,
    #[serde(default)]
    pub summary: serde_json::Value,
    pub generator: String,
    pub created_unix_s: u64,
}

impl SampleFileHeader {
    /// Header for data generated with `cfg` (`sample_count` is set by [`write_samples`]).
    pub fn new(
        cfg: &crate::datagen::DataConfig,
        summary: Option<&crate::datagen::DataSummary>,
    ) -> Self {
        SampleFileHeader {
            format: FORMAT_NAME.to_string(),
            version: FORMAT_VERSION,
            sample_count: 0,
            record_size: SAMPLE_BYTES,
            byte_order: "little".to_string(),
            fields: record_layout(),
            seed: cfg.seed,
            config: serde_json::to_value(cfg).unwrap_or_default(),
            parameter_ranges: serde_json::to_value(&cfg.ranges).unwrap_or_default(),
            summary: summary
                .and_then(|s| serde_json::to_value(s).ok())
                .unwrap_or_default(),
            generator: crate::datagen::GENERATOR_VERSION.to_string(),
            created_unix_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0),
        }
    }
}

/// Errors of reading or writing a samples file; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum SampleFileError {
    #[error("{path}: I/O error")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: file exists (pass overwrite to replace it)")]
    Exists { path: PathBuf },
    #[error("{path}: not a samples file (bad magic bytes)")]
    BadMagic { path: PathBuf },
    #[error("{path}: unsupported format version {found} (this build reads {FORMAT_VERSION})")]
    Version { path: PathBuf, found: u32 },
    #[error("{path}: truncated file ({len} bytes, the header needs {needed})")]
    Truncated {
        path: PathBuf,
        len: u64,
        needed: u64,
    },
    #[error("{path}: invalid JSON header")]
    Header {
        path: PathBuf,
        #[source]
        source: serde_json::Error,
    },
    #[error("{path}: record size {found} bytes, this build uses {SAMPLE_BYTES}")]
    RecordSize { path: PathBuf, found: usize },
    #[error("{path}: record field layout differs from this build's Sample")]
    Layout { path: PathBuf },
    #[error(
        "{path}: header says {count} records ({expected} bytes of data) but the file has {found}"
    )]
    Length {
        path: PathBuf,
        count: u64,
        expected: u64,
        found: u64,
    },
    #[error("{path}: record {record} has a non-finite value in field `{field}`")]
    NonFinite {
        path: PathBuf,
        record: usize,
        field: String,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SampleFileError + '_ {
    move |source| SampleFileError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Write `samples` with `header` (its count, record size, layout and format fields are set here)
/// atomically to `path`; fails with [`SampleFileError::Exists`] unless `overwrite`.
pub fn write_samples(
    path: &Path,
    header: &SampleFileHeader,
    samples: &[Sample],
    overwrite: bool,
) -> Result<(), SampleFileError> {
    if !overwrite && path.exists() {
        return Err(SampleFileError::Exists {
            path: path.to_path_buf(),
        });
    }
    let mut header = header.clone();
    header.format = FORMAT_NAME.to_string();
    header.version = FORMAT_VERSION;
    header.sample_count = samples.len() as u64;
    header.record_size = SAMPLE_BYTES;
    header.byte_order = "little".to_string();
    header.fields = record_layout();
    let json = serde_json::to_vec(&header).map_err(|source| SampleFileError::Header {
        path: path.to_path_buf(),
        source,
    })?;
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| -> std::io::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
        w.write_all(MAGIC)?;
        w.write_all(&FORMAT_VERSION.to_le_bytes())?;
        w.write_all(&(json.len() as u32).to_le_bytes())?;
        w.write_all(&json)?;
        let words: &[u32] = bytemuck::cast_slice(samples);
        if cfg!(target_endian = "little") {
            w.write_all(bytemuck::cast_slice(words))?;
        } else {
            for word in words {
                w.write_all(&word.to_le_bytes())?;
            }
        }
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(io_err(path)(e));
    }
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io_err(path)(e)
    })
}

/// Read and validate a samples file (module docs).
pub fn read_samples(path: &Path) -> Result<(SampleFileHeader, Vec<Sample>), SampleFileError> {
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    let p = || path.to_path_buf();
    let len = bytes.len() as u64;
    if bytes.len() < 8 || &bytes[..8] != MAGIC {
        return Err(SampleFileError::BadMagic { path: p() });
    }
    if bytes.len() < 16 {
        return Err(SampleFileError::Truncated {
            path: p(),
            len,
            needed: 16,
        });
    }
    let word = |o: usize| u32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    let version = word(8);
    if version != FORMAT_VERSION {
        return Err(SampleFileError::Version {
            path: p(),
            found: version,
        });
    }
    let hlen = word(12) as u64;
    if len < 16 + hlen {
        return Err(SampleFileError::Truncated {
            path: p(),
            len,
            needed: 16 + hlen,
        });
    }
    let data_start = 16 + hlen as usize;
    let header: SampleFileHeader = serde_json::from_slice(&bytes[16..data_start])
        .map_err(|source| SampleFileError::Header { path: p(), source })?;
    if header.version != FORMAT_VERSION {
        return Err(SampleFileError::Version {
            path: p(),
            found: header.version,
        });
    }
    if header.record_size != SAMPLE_BYTES {
        return Err(SampleFileError::RecordSize {
            path: p(),
            found: header.record_size,
        });
    }
    if header.fields != record_layout() || header.byte_order != "little" {
        return Err(SampleFileError::Layout { path: p() });
    }
    let data = &bytes[data_start..];
    let expected = header.sample_count.checked_mul(SAMPLE_BYTES as u64);
    if expected != Some(data.len() as u64) {
        return Err(SampleFileError::Length {
            path: p(),
            count: header.sample_count,
            expected: expected.unwrap_or(u64::MAX),
            found: data.len() as u64,
        });
    }
    let n = header.sample_count as usize;
    let mut samples = vec![Sample::default(); n];
    {
        let words: &mut [u32] = bytemuck::cast_slice_mut(&mut samples);
        for (w, chunk) in words.iter_mut().zip(data.chunks_exact(4)) {
            *w = u32::from_le_bytes(chunk.try_into().expect("4 bytes"));
        }
    }
    let layout = record_layout();
    for (i, s) in samples.iter().enumerate() {
        let floats: &[f32] =
            &bytemuck::cast_slice::<Sample, f32>(std::slice::from_ref(s))[..F32_WORDS];
        if let Some(k) = floats.iter().position(|v| !v.is_finite()) {
            let field = layout
                .iter()
                .rev()
                .find(|f| f.offset <= 4 * k)
                .map(|f| f.name.clone())
                .unwrap_or_default();
            return Err(SampleFileError::NonFinite {
                path: p(),
                record: i,
                field,
            });
        }
    }
    Ok((header, samples))
}
