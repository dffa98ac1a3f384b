//! Reading a model file: [`load`] and [`from_bytes`] parse the safetensors container and the
//! metadata document of the parent module, and validate everything before a model is built (the
//! format name and version, the architecture's consistency, every tensor's presence, dtype, shape
//! and finiteness, and no unknown tensor).

use super::*;

/// Loads and validates a model file.
///
/// Errors name the file, the tensor and what to do: missing file, not safetensors, metadata
/// missing or malformed, version mismatch, inconsistent architecture, missing or unexpected
/// tensor, wrong dtype or shape, non-finite value.
pub fn load(path: &Path) -> Result<ShapeAdaptiveModel, ModelError> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(ModelError::NotFound {
                path: path.to_path_buf(),
            });
        }
        Err(source) => {
            return Err(ModelError::Io {
                path: path.to_path_buf(),
                action: "cannot read",
                source,
            });
        }
    };
    from_bytes(path, &bytes)
}

/// Parses and validates the bytes of a model file; `path` is used in error messages.
pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<ShapeAdaptiveModel, ModelError> {
    let p = || path.to_path_buf();
    let st = SafeTensors::deserialize(bytes).map_err(|e| ModelError::NotSafetensors {
        path: p(),
        reason: e.to_string(),
    })?;
    let (_, meta) = SafeTensors::read_metadata(bytes).map_err(|e| ModelError::NotSafetensors {
        path: p(),
        reason: e.to_string(),
    })?;
    let json = meta
        .metadata()
        .as_ref()
        .and_then(|m| m.get(METADATA_KEY))
        .ok_or_else(|| ModelError::MetadataMissing { path: p() })?;
    let invalid = |reason: String| ModelError::MetadataInvalid { path: p(), reason };
    let value: serde_json::Value =
        serde_json::from_str(json).map_err(|e| invalid(format!("not JSON: {e}")))?;
    match value.get("format").and_then(|v| v.as_str()) {
        Some(FORMAT_NAME) => {}
        other => {
            return Err(invalid(format!(
                "format is {other:?}, expected \"{FORMAT_NAME}\""
            )));
        }
    }
    let version = value
        .get("version")
        .and_then(|v| v.as_u64())
        .ok_or_else(|| invalid("no integer `version`".to_string()))?;
    if version != FORMAT_VERSION {
        return Err(ModelError::VersionMismatch {
            path: p(),
            found: version,
        });
    }
    let header: Header = serde_json::from_value(value).map_err(|e| invalid(e.to_string()))?;
    let arch = &header.architecture;
    arch.check().map_err(invalid)?;

    // Every expected tensor, then no other.
    let mut expected: Vec<String> = Vec::new();
    let mut read_layer = |name: String, n_in: usize, n_out: usize| -> Result<Dense, ModelError> {
        let w = read_tensor(path, &st, &format!("{name}.weight"), &[n_out, n_in])?;
        let b = read_tensor(path, &st, &format!("{name}.bias"), &[n_out])?;
        expected.push(format!("{name}.weight"));
        expected.push(format!("{name}.bias"));
        Dense::new(n_in, n_out, w, b)
    };
    let mut read_block = |block: &str, widths: &[usize]| -> Result<Vec<Dense>, ModelError> {
        widths
            .windows(2)
            .enumerate()
            .map(|(k, w)| read_layer(format!("{block}.{k}"), w[0], w[1]))
            .collect()
    };
    let feature = read_block("feature", &arch.feature)?;
    let absorption = read_block("absorption", &arch.absorption)?;
    let decoder = read_block("decoder", &arch.decoder)?;
    let encoder_hidden = match &arch.encoder {
        Some(w) => Some(read_block("encoder", w)?),
        None => None,
    };
    let encoder = match (encoder_hidden, &arch.encoder) {
        (Some(hidden), Some(w)) => {
            let h = w[w.len() - 1];
            let mean = read_layer("encoder.mean".to_string(), h, LATENT_DIM)?;
            let logvar = read_layer("encoder.logvar".to_string(), h, LATENT_DIM)?;
            Some(Encoder::new(hidden, mean, logvar).map_err(|e| invalid(e.to_string()))?)
        }
        _ => None,
    };
    let mut names = st.names();
    names.sort_unstable();
    if let Some(extra) = names.iter().find(|n| !expected.iter().any(|e| e == *n)) {
        return Err(ModelError::UnexpectedTensor {
            path: p(),
            tensor: extra.to_string(),
        });
    }
    if let Some((name, i, v)) = header.normalisation.first_non_finite() {
        return Err(invalid(format!("normalisation {name}[{i}] is {v}")));
    }
    let info = ModelInfo {
        c19_quirk: header.c19_quirk,
        frame_convention: header.frame_convention,
        provenance: header.provenance,
    };
    ShapeAdaptiveModel::new(
        feature,
        absorption,
        decoder,
        encoder,
        header.normalisation,
        info,
    )
    .map_err(|e| invalid(e.to_string()))
}

/// Reads one F32 tensor of the given shape, checking presence, dtype, shape and finiteness.
fn read_tensor(
    path: &Path,
    st: &SafeTensors<'_>,
    name: &str,
    shape: &[usize],
) -> Result<Vec<f32>, ModelError> {
    let p = || path.to_path_buf();
    let view = st.tensor(name).map_err(|_| ModelError::MissingTensor {
        path: p(),
        tensor: name.to_string(),
    })?;
    if view.dtype() != Dtype::F32 {
        return Err(ModelError::WrongDtype {
            path: p(),
            tensor: name.to_string(),
            dtype: format!("{:?}", view.dtype()),
        });
    }
    if view.shape() != shape {
        return Err(ModelError::WrongShape {
            path: p(),
            tensor: name.to_string(),
            expected: shape.to_vec(),
            got: view.shape().to_vec(),
        });
    }
    // The data of a safetensors view need not be 4-byte aligned: decode byte by byte.
    let values: Vec<f32> = view
        .data()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(ModelError::NonFinite {
            path: p(),
            tensor: name.to_string(),
            index: i,
            value: values[i],
        });
    }
    Ok(values)
}
