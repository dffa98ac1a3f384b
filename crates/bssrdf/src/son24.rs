//! Importer of the reference weights of Son et al. 2024 (`spock-the-wizard/shapeAdaptiveIR`).
//!
//! These weights are a yardstick for the inference path and for benchmarks, never a runtime
//! dependency: the project ships its own trained model. The folder layout is
//!
//! ```text
//! DIR/data_stats.json          dataset statistics (effAlbedo_*, g_*, mlsPolyLS3_* are used)
//! DIR/variables/NAME.bin       little-endian: int32 ndim, ndim × int32 dims, prod(dims) × f32
//! ```
//!
//! with matrices stored `[out, in]` (so `y = W x + b`) and the names
//!
//! | block | files |
//! |---|---|
//! | feature MLP | `shared_preproc_mlp_2_shapemlp_fcn_{k}_{weights,biases}` |
//! | absorption | `absorption_mlp_fcn_{k}_{weights,biases}`, then `absorption_dense_{kernel,bias}` (logit) |
//! | decoder | `scatter_decoder_fcn_fcn_{k}_{weights,biases}`, then `scatter_dense_2_{kernel,bias}` (3) |
//! | encoder | `scatter_encoder_fcn_fcn_{k}_{weights,biases}`, heads `scatter_dense_{kernel,bias}` (μ) and `scatter_dense_1_{kernel,bias}` (log σ²) |
//!
//! The number of hidden layers `k = 0, 1, …` is found from the files present. The encoder is
//! optional (absent when none of its files exist). The imported model uses the
//! `son24-compat` frame convention and the c_19 quirk.

use std::path::{Path, PathBuf};

use crate::model::{FrameConvention, ModelError, ModelInfo};
use crate::nn::{Dense, Encoder, N_POLY, Normalisation, ShapeAdaptiveModel};

/// Provenance source string of imported models.
pub const SOURCE: &str = "imported from spock-the-wizard/shapeAdaptiveIR";

const FEATURE: &str = "shared_preproc_mlp_2_shapemlp_fcn";
const ABSORPTION_HIDDEN: &str = "absorption_mlp_fcn";
const ABSORPTION_OUT: &str = "absorption_dense";
const DECODER_HIDDEN: &str = "scatter_decoder_fcn_fcn";
const DECODER_OUT: &str = "scatter_dense_2";
const ENCODER_HIDDEN: &str = "scatter_encoder_fcn_fcn";
const ENCODER_MEAN: &str = "scatter_dense";
const ENCODER_LOGVAR: &str = "scatter_dense_1";

/// Largest accepted number of dimensions / elements of one `.bin` tensor (a sanity bound that
/// turns garbage headers into errors instead of huge allocations).
const MAX_NDIM: i32 = 8;
const MAX_ELEMENTS: usize = 1 << 28;

/// Reads one `.bin` tensor: its dims and values.
pub fn read_bin(path: &Path) -> Result<(Vec<usize>, Vec<f32>), ModelError> {
    let bytes = std::fs::read(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            ModelError::Son24Missing {
                path: path.to_path_buf(),
                what: "a weight tensor".to_string(),
            }
        } else {
            ModelError::Io {
                path: path.to_path_buf(),
                action: "cannot read",
                source: e,
            }
        }
    })?;
    parse_bin(&bytes).map_err(|reason| ModelError::Son24Corrupt {
        path: path.to_path_buf(),
        reason,
    })
}

/// Parses the bytes of a `.bin` tensor.
pub fn parse_bin(bytes: &[u8]) -> Result<(Vec<usize>, Vec<f32>), String> {
    let int = |i: usize| -> Result<i32, String> {
        bytes
            .get(4 * i..4 * i + 4)
            .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .ok_or_else(|| format!("truncated header ({} bytes)", bytes.len()))
    };
    let ndim = int(0)?;
    if !(0..=MAX_NDIM).contains(&ndim) {
        return Err(format!(
            "header says {ndim} dimensions (expected 1 or 2; is this a weights file?)"
        ));
    }
    let ndim = ndim as usize;
    let mut dims = Vec::with_capacity(ndim);
    let mut n: usize = 1;
    for i in 0..ndim {
        let d = int(1 + i)?;
        if d < 0 {
            return Err(format!("dimension {i} is negative ({d})"));
        }
        dims.push(d as usize);
        n = n.saturating_mul(d as usize);
    }
    if n > MAX_ELEMENTS {
        return Err(format!("implausible size {dims:?}"));
    }
    let data = &bytes[4 * (1 + ndim)..];
    if data.len() != 4 * n {
        return Err(format!(
            "shape {dims:?} needs {} bytes of data after the header, the file has {}",
            4 * n,
            data.len()
        ));
    }
    let values: Vec<f32> = data
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(format!("non-finite value {} at flat index {i}", values[i]));
    }
    Ok((dims, values))
}

/// Imports a reference weights folder (see the module documentation) into a model.
pub fn import(dir: &Path) -> Result<ShapeAdaptiveModel, ModelError> {
    if !dir.is_dir() {
        return Err(ModelError::Son24Missing {
            path: dir.to_path_buf(),
            what: "the reference weights folder".to_string(),
        });
    }
    let vars = dir.join("variables");
    if !vars.is_dir() {
        return Err(ModelError::Son24Missing {
            path: vars,
            what: "the `variables` folder of the reference weights".to_string(),
        });
    }
    let stats_path = dir.join("data_stats.json");
    let (normalisation, n_samples) = read_stats(&stats_path)?;

    let feature = hidden_layers(&vars, FEATURE, "weights", "biases", true)?;
    let mut absorption = hidden_layers(&vars, ABSORPTION_HIDDEN, "weights", "biases", false)?;
    absorption.push(layer(&vars, ABSORPTION_OUT, "kernel", "bias")?);
    let mut decoder = hidden_layers(&vars, DECODER_HIDDEN, "weights", "biases", false)?;
    decoder.push(layer(&vars, DECODER_OUT, "kernel", "bias")?);
    let encoder_hidden = hidden_layers(&vars, ENCODER_HIDDEN, "weights", "biases", false)?;
    let encoder_heads_present = ["kernel", "bias"].iter().any(|s| {
        [ENCODER_MEAN, ENCODER_LOGVAR]
            .iter()
            .any(|h| bin_path(&vars, h, s).exists())
    });
    let encoder = if encoder_hidden.is_empty() && !encoder_heads_present {
        None
    } else {
        if encoder_hidden.is_empty() {
            return Err(ModelError::Son24Missing {
                path: bin_path(&vars, &format!("{ENCODER_HIDDEN}_0"), "weights"),
                what: "the first encoder layer (the encoder heads are present)".to_string(),
            });
        }
        let mean = layer(&vars, ENCODER_MEAN, "kernel", "bias")?;
        let logvar = layer(&vars, ENCODER_LOGVAR, "kernel", "bias")?;
        Some(Encoder::new(encoder_hidden, mean, logvar).map_err(|e| in_dir(&vars, e))?)
    };
    let mut provenance = serde_json::json!({
        "source": SOURCE,
        "directory": dir.display().to_string(),
        "stats": "data_stats.json (effAlbedo, g, mlsPolyLS3)",
    });
    if let Some(n) = n_samples {
        provenance["training_samples"] = serde_json::json!(n);
    }
    let info = ModelInfo {
        c19_quirk: true,
        frame_convention: FrameConvention::Son24Compat,
        provenance,
    };
    ShapeAdaptiveModel::new(feature, absorption, decoder, encoder, normalisation, info)
        .map_err(|e| in_dir(&vars, e))
}

/// Turns an architecture error into a "corrupt folder" error naming the folder.
fn in_dir(vars: &Path, e: ModelError) -> ModelError {
    match e {
        ModelError::Architecture(reason) => ModelError::Son24Corrupt {
            path: vars.to_path_buf(),
            reason: format!("the layer shapes do not fit together: {reason}"),
        },
        e => e,
    }
}

fn bin_path(vars: &Path, stem: &str, suffix: &str) -> PathBuf {
    vars.join(format!("{stem}_{suffix}.bin"))
}

/// Hidden layers `{prefix}_{k}_{w}/{b}` for k = 0, 1, … while the weight file exists.
fn hidden_layers(
    vars: &Path,
    prefix: &str,
    w: &str,
    b: &str,
    required: bool,
) -> Result<Vec<Dense>, ModelError> {
    let mut layers = Vec::new();
    for k in 0.. {
        let stem = format!("{prefix}_{k}");
        if !bin_path(vars, &stem, w).exists() {
            if k == 0 && required {
                return Err(ModelError::Son24Missing {
                    path: bin_path(vars, &stem, w),
                    what: "the first layer of the feature MLP".to_string(),
                });
            }
            break;
        }
        layers.push(layer(vars, &stem, w, b)?);
    }
    Ok(layers)
}

/// One dense layer from `{stem}_{w}.bin` (`[out, in]`) and `{stem}_{b}.bin` (`[out]`).
fn layer(vars: &Path, stem: &str, w: &str, b: &str) -> Result<Dense, ModelError> {
    let wp = bin_path(vars, stem, w);
    let bp = bin_path(vars, stem, b);
    let (wd, wv) = read_bin(&wp)?;
    let (bd, bv) = read_bin(&bp)?;
    if wd.len() != 2 || wd.contains(&0) {
        return Err(ModelError::Son24Corrupt {
            path: wp,
            reason: format!("a weight matrix must be 2-D [out, in], got shape {wd:?}"),
        });
    }
    if bd != [wd[0]] {
        return Err(ModelError::Son24Corrupt {
            path: bp,
            reason: format!(
                "bias has shape {bd:?}, expected [{}] to match the weights {wd:?} in {}",
                wd[0],
                wp.display()
            ),
        });
    }
    Dense::new(wd[1], wd[0], wv, bv).map_err(|e| ModelError::Son24Corrupt {
        path: wp,
        reason: e.to_string(),
    })
}

/// Reads the normalisation constants (and the number of training samples, if given).
fn read_stats(path: &Path) -> Result<(Normalisation, Option<u64>), ModelError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            ModelError::Son24Missing {
                path: path.to_path_buf(),
                what: "the dataset statistics (feature normalisation constants)".to_string(),
            }
        } else {
            ModelError::Io {
                path: path.to_path_buf(),
                action: "cannot read",
                source: e,
            }
        }
    })?;
    let corrupt = |reason: String| ModelError::Son24Corrupt {
        path: path.to_path_buf(),
        reason,
    };
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| corrupt(format!("not JSON: {e}")))?;
    let array = |key: &str, len: usize| -> Result<Vec<f32>, ModelError> {
        let a = v.get(key).and_then(|x| x.as_array()).ok_or_else(|| {
            corrupt(format!(
                "key `{key}` (an array of {len} numbers) is missing"
            ))
        })?;
        if a.len() != len {
            return Err(corrupt(format!(
                "`{key}` has {} values, expected {len}",
                a.len()
            )));
        }
        a.iter()
            .enumerate()
            .map(|(i, x)| {
                x.as_f64()
                    .map(|x| x as f32)
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| corrupt(format!("`{key}`[{i}] is not a finite number: {x}")))
            })
            .collect()
    };
    let poly = |key: &str| -> Result<[f32; N_POLY], ModelError> {
        let a = array(key, N_POLY)?;
        let mut out = [0.0; N_POLY];
        out.copy_from_slice(&a);
        Ok(out)
    };
    let normalisation = Normalisation {
        eff_albedo_mean: array("effAlbedo_mean", 1)?[0],
        eff_albedo_stdinv: array("effAlbedo_stdinv", 1)?[0],
        g_mean: array("g_mean", 1)?[0],
        g_stdinv: array("g_stdinv", 1)?[0],
        poly_mean: poly("mlsPolyLS3_mean")?,
        poly_stdinv: poly("mlsPolyLS3_stdinv")?,
    };
    let n_samples = v.get("n_samples").and_then(|x| x.as_u64());
    Ok((normalisation, n_samples))
}
