//! Our model file format: one `.safetensors` file with JSON metadata, and its validation.
//!
//! # Format (version 1)
//!
//! Tensors (all `F32`, little-endian; weights `[out, in]` so that `y = W x + b`):
//!
//! | name | shape | block |
//! |---|---|---|
//! | `feature.{k}.weight`, `feature.{k}.bias` | `[out, in]`, `[out]` | feature MLP, layer k (ReLU on every layer) |
//! | `absorption.{k}.weight`, `.bias` | | absorption MLP (ReLU on hidden layers; the last output is a logit, Absorb = sigmoid) |
//! | `decoder.{k}.weight`, `.bias` | | decoder, input `[z(4) ⊕ f]` (ReLU on hidden layers, last layer linear) |
//! | `encoder.{k}.weight`, `.bias` | | encoder hidden layers, input `[x(3) ⊕ f]` (optional block) |
//! | `encoder.mean.weight`, `.bias` / `encoder.logvar.weight`, `.bias` | `[4, H]`, `[4]` | encoder heads |
//!
//! The safetensors `__metadata__` map holds one key, [`METADATA_KEY`], whose value is a JSON
//! document:
//!
//! ```json
//! { "format": "translucent-bssrdf", "version": 1,
//!   "architecture": { "input_dim": 23, "latent_dim": 4, "position_dim": 3, "feature_dim": 32,
//!                     "activation": "relu", "absorption_output": "sigmoid",
//!                     "feature": [23, 32, 32], "absorption": [32, 16, 1],
//!                     "decoder": [36, 32, 32, 3], "encoder": [35, 32, 32] },
//!   "normalisation": { "eff_albedo_mean": …, "eff_albedo_stdinv": …, "g_mean": …, "g_stdinv": …,
//!                      "poly_mean": [20 values], "poly_stdinv": [20 values] },
//!   "c19_quirk": true, "frame_convention": "vkj19" | "son24-compat",
//!   "provenance": { free-form: data, seed, steps, time, metrics, source … } }
//! ```
//!
//! Widths list `[n_in, hidden…, n_out]` of each block (`encoder`: its hidden layers only, or
//! `null`; each head is `[latent_dim, last width]`). [`load`] checks everything: the file, the
//! format name and version, the architecture's consistency, every tensor's presence, dtype,
//! shape and finiteness, and that no unknown tensor is present.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use serde::{Deserialize, Serialize};

pub(crate) mod error;
mod read;

pub use error::{FORMAT_NAME, FORMAT_VERSION, METADATA_KEY, MODEL_FIX_HINT, ModelError};
pub use read::{from_bytes, load};

use crate::nn::{
    Dense, Encoder, INPUT_DIM, LATENT_DIM, Mlp, Normalisation, POSITION_DIM, ShapeAdaptiveModel,
};

/// Frame convention the model's inputs and outputs are meant for (docs/model.md §10 A4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum FrameConvention {
    /// Vicini et al. 2019's frames.
    ///
    /// VKJ19: refracted, polynomial-aligned incident direction; light-space frame (+e1, +e2,
    /// −d_in) for both features and output.
    #[serde(rename = "vkj19")]
    Vkj19,
    /// Son et al. 2024's released code's frames.
    ///
    /// SON24's choices: features in (−e1, −e2, wi) built from the unrefracted wi, output in
    /// the shading-normal frame.
    #[serde(rename = "son24-compat")]
    Son24Compat,
}

impl FrameConvention {
    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vkj19 => "vkj19",
            Self::Son24Compat => "son24-compat",
        }
    }
}

/// Conventions and provenance of a model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    /// Whether the training data dropped the z³ coefficient of the world-space fit (c_19 = 0,
    /// docs/model.md §3.2 item 7); the renderer must then do the same.
    pub c19_quirk: bool,
    /// Frame convention of the inputs and outputs.
    pub frame_convention: FrameConvention,
    /// Free-form training provenance (data, seed, steps, time, metrics, source…).
    pub provenance: serde_json::Value,
}

impl Default for ModelInfo {
    fn default() -> Self {
        Self {
            c19_quirk: true,
            frame_convention: FrameConvention::Vkj19,
            provenance: serde_json::Value::Object(Default::default()),
        }
    }
}

/// Layer widths of every block, as stored in the metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Architecture {
    /// Number of network inputs (23).
    pub input_dim: usize,
    /// Latent dimension (4).
    pub latent_dim: usize,
    /// Position dimension (3).
    pub position_dim: usize,
    /// Feature width F.
    pub feature_dim: usize,
    /// Hidden activation (`"relu"`).
    pub activation: String,
    /// Output activation of the absorption block (`"sigmoid"`).
    pub absorption_output: String,
    /// `[23, hidden…, F]`.
    pub feature: Vec<usize>,
    /// `[F, hidden…, 1]`.
    pub absorption: Vec<usize>,
    /// `[4 + F, hidden…, 3]`.
    pub decoder: Vec<usize>,
    /// `[3 + F, hidden…]` (then two heads of `latent_dim`), or `None`.
    pub encoder: Option<Vec<usize>>,
}

impl Architecture {
    /// The architecture of a model.
    pub fn of(model: &ShapeAdaptiveModel) -> Self {
        Self {
            input_dim: INPUT_DIM,
            latent_dim: LATENT_DIM,
            position_dim: POSITION_DIM,
            feature_dim: model.feature_dim(),
            activation: "relu".to_string(),
            absorption_output: "sigmoid".to_string(),
            feature: model.feature_mlp().widths(),
            absorption: model.absorption_mlp().widths(),
            decoder: model.decoder().widths(),
            encoder: model.encoder().map(|e| e.hidden().widths()),
        }
    }

    /// Checks the fixed dimensions and that the blocks fit together.
    fn check(&self) -> Result<(), String> {
        let mut p = Vec::new();
        let fixed = [
            ("input_dim", self.input_dim, INPUT_DIM),
            ("latent_dim", self.latent_dim, LATENT_DIM),
            ("position_dim", self.position_dim, POSITION_DIM),
        ];
        for (name, got, want) in fixed {
            if got != want {
                p.push(format!("{name} is {got}, this build supports only {want}"));
            }
        }
        if self.activation != "relu" {
            p.push(format!(
                "activation `{}` is not supported (only `relu`)",
                self.activation
            ));
        }
        if self.absorption_output != "sigmoid" {
            p.push(format!(
                "absorption_output `{}` is not supported (only `sigmoid`)",
                self.absorption_output
            ));
        }
        let f = self.feature_dim;
        let blocks: [(&str, &Vec<usize>, usize, Option<usize>); 3] = [
            ("feature", &self.feature, INPUT_DIM, Some(f)),
            ("absorption", &self.absorption, f, Some(1)),
            // Saturating: F comes from the file (an impossible width is reported below).
            (
                "decoder",
                &self.decoder,
                LATENT_DIM.saturating_add(f),
                Some(POSITION_DIM),
            ),
        ];
        let enc = self
            .encoder
            .as_ref()
            .map(|w| ("encoder", w, POSITION_DIM.saturating_add(f), None));
        for (name, w, first, last) in blocks.into_iter().chain(enc) {
            if w.len() < 2 {
                p.push(format!(
                    "{name} widths {w:?} need at least an input and an output"
                ));
                continue;
            }
            if w.contains(&0) {
                p.push(format!("{name} widths {w:?} contain a zero"));
            }
            if w[0] != first {
                p.push(format!("{name} takes {} inputs, expected {first}", w[0]));
            }
            if let Some(last) = last
                && w[w.len() - 1] != last
            {
                p.push(format!(
                    "{name} has {} outputs, expected {last}",
                    w[w.len() - 1]
                ));
            }
        }
        if p.is_empty() {
            Ok(())
        } else {
            Err(p.join("; "))
        }
    }
}

/// The metadata document.
#[derive(Serialize, Deserialize)]
struct Header {
    format: String,
    version: u64,
    architecture: Architecture,
    normalisation: Normalisation,
    c19_quirk: bool,
    frame_convention: FrameConvention,
    provenance: serde_json::Value,
}

/// Named tensors of a model, in file order: (name, shape, values).
pub fn tensors_of(model: &ShapeAdaptiveModel) -> Vec<(String, Vec<usize>, &[f32])> {
    let mut t = Vec::new();
    fn add<'a>(t: &mut Vec<(String, Vec<usize>, &'a [f32])>, name: &str, l: &'a Dense) {
        t.push((
            format!("{name}.weight"),
            vec![l.n_out(), l.n_in()],
            l.weights(),
        ));
        t.push((format!("{name}.bias"), vec![l.n_out()], l.bias()));
    }
    for (block, mlp) in [
        ("feature", model.feature_mlp()),
        ("absorption", model.absorption_mlp()),
        ("decoder", model.decoder()),
    ] {
        for (k, l) in mlp.layers().iter().enumerate() {
            add(&mut t, &format!("{block}.{k}"), l);
        }
    }
    if let Some(e) = model.encoder() {
        for (k, l) in e.hidden().layers().iter().enumerate() {
            add(&mut t, &format!("encoder.{k}"), l);
        }
        add(&mut t, "encoder.mean", e.mean());
        add(&mut t, "encoder.logvar", e.logvar());
    }
    t
}

/// Serialises a model into the bytes of a safetensors file.
pub fn to_bytes(model: &ShapeAdaptiveModel) -> Result<Vec<u8>, ModelError> {
    let header = Header {
        format: FORMAT_NAME.to_string(),
        version: FORMAT_VERSION,
        architecture: Architecture::of(model),
        normalisation: model.normalisation().clone(),
        c19_quirk: model.info().c19_quirk,
        frame_convention: model.info().frame_convention,
        provenance: model.info().provenance.clone(),
    };
    let json = serde_json::to_string(&header)
        .map_err(|e| ModelError::Architecture(format!("cannot encode the metadata: {e}")))?;
    let tensors = tensors_of(model);
    let bytes: Vec<(String, Vec<usize>, Vec<u8>)> = tensors
        .into_iter()
        .map(|(n, s, v)| (n, s, v.iter().flat_map(|x| x.to_le_bytes()).collect()))
        .collect();
    let views = bytes
        .iter()
        .map(|(n, s, b)| {
            TensorView::new(Dtype::F32, s.clone(), b)
                .map(|v| (n.as_str(), v))
                .map_err(|e| ModelError::Architecture(format!("tensor `{n}`: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let meta = HashMap::from([(METADATA_KEY.to_string(), json)]);
    safetensors::serialize(views, Some(meta))
        .map_err(|e| ModelError::Architecture(format!("cannot serialise the model: {e}")))
}

impl ShapeAdaptiveModel {
    /// Saves the model to `path` atomically (written to a temporary file in the same folder,
    /// then renamed). Refuses non-finite weights.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        for (name, _, v) in tensors_of(self) {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(ModelError::NonFinite {
                    path: path.to_path_buf(),
                    tensor: name,
                    index: i,
                    value: v[i],
                });
            }
        }
        let bytes = to_bytes(self)?;
        write_atomic(path, &bytes)
    }

    /// Loads and validates a model file (see [`load`]).
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        load(path)
    }
}

/// Name of the shipped model (`models/translucent-v2.safetensors`, see `models/MODEL_CARD.md`).
pub const SHIPPED_NAME: &str = "models/translucent-v2.safetensors";
static SHIPPED: &[u8] = include_bytes!("../../../models/translucent-v2.safetensors");

/// The shipped model, built into the library and validated like a file.
pub fn shipped() -> Result<ShapeAdaptiveModel, ModelError> {
    from_bytes(Path::new(SHIPPED_NAME), SHIPPED)
}

/// Writes `bytes` to `path` through a temporary sibling file and a rename.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ModelError> {
    let io = |action: &'static str| {
        move |source| ModelError::Io {
            path: path.to_path_buf(),
            action,
            source,
        }
    };
    let file_name = path.file_name().ok_or_else(|| ModelError::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
    })?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp = parent.join(format!(
        ".{}.tmp-{}",
        file_name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp).map_err(io("cannot create a temporary file"))?;
        f.write_all(bytes).map_err(io("cannot write"))?;
        f.sync_all().map_err(io("cannot write"))?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(io("cannot move the temporary file into place"))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Parameter counts per block: (feature, absorption, decoder, encoder or 0).
pub fn parameter_counts(model: &ShapeAdaptiveModel) -> [(&'static str, usize); 4] {
    [
        ("feature", model.feature_mlp().n_params()),
        ("absorption", model.absorption_mlp().n_params()),
        ("decoder", model.decoder().n_params()),
        ("encoder", model.encoder().map_or(0, Encoder::n_params)),
    ]
}

/// Convenience: an [`Mlp`]'s widths as a string like `23 -> 32 -> 32`.
pub fn widths_string(mlp: &Mlp) -> String {
    mlp.widths()
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(" -> ")
}
