//! Model files: save/load round trip, one test per validation error (missing file, not
//! safetensors, metadata missing / malformed / inconsistent, version mismatch, missing,
//! unexpected, wrongly shaped, wrongly typed and non-finite tensors), atomic saving; and the
//! SON24 importer on a synthetic reference-weights folder written in a temporary directory
//! (values, conventions, and its errors for missing or damaged files).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use bssrdf::model::{self, FORMAT_NAME, FrameConvention, METADATA_KEY, ModelError, ModelInfo};
use bssrdf::nn::{
    Dense, Encoder, INPUT_DIM, LATENT_DIM, Normalisation, POSITION_DIM, ShapeAdaptiveModel,
    Workspace,
};
use bssrdf::son24;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};

/// Random models, raw safetensors rewriting, synthetic SON24 folders.
mod support {
    use super::*;

    pub fn layer(rng: &mut Pcg32, n_in: usize, n_out: usize) -> Dense {
        let s = (6.0 / n_in as f32).sqrt();
        let w = (0..n_in * n_out).map(|_| rng.random_range(-s..s)).collect();
        let b = (0..n_out).map(|_| rng.random_range(-0.3..0.3)).collect();
        Dense::new(n_in, n_out, w, b).unwrap()
    }

    /// A small random model: feature 23 → 8 → 6, absorption 6 → 5 → 1, decoder 10 → 7 → 3,
    /// encoder 9 → 7 (+ heads) if `encoder`.
    pub fn small_model(seed: u64, encoder: bool) -> ShapeAdaptiveModel {
        let mut r = Pcg32::seed_from_u64(seed);
        let feature = vec![layer(&mut r, INPUT_DIM, 8), layer(&mut r, 8, 6)];
        let absorption = vec![layer(&mut r, 6, 5), layer(&mut r, 5, 1)];
        let decoder = vec![
            layer(&mut r, LATENT_DIM + 6, 7),
            layer(&mut r, 7, POSITION_DIM),
        ];
        let enc = encoder.then(|| {
            Encoder::new(
                vec![layer(&mut r, POSITION_DIM + 6, 7)],
                layer(&mut r, 7, LATENT_DIM),
                layer(&mut r, 7, LATENT_DIM),
            )
            .unwrap()
        });
        let mut norm = Normalisation::identity();
        norm.eff_albedo_mean = 0.5773536;
        norm.eff_albedo_stdinv = 2.337987;
        norm.g_mean = 0.4757318;
        norm.g_stdinv = 2.391793;
        for k in 0..20 {
            norm.poly_mean[k] = 0.01 * k as f32 - 0.05;
            norm.poly_stdinv[k] = 1.0 + 0.1 * k as f32;
        }
        let info = ModelInfo {
            c19_quirk: false,
            frame_convention: FrameConvention::Vkj19,
            provenance: serde_json::json!({
                "data": "unit test", "seed": seed, "steps": 12345,
                "metrics": { "loss": 0.25 }
            }),
        };
        ShapeAdaptiveModel::new(feature, absorption, decoder, enc, norm, info).unwrap()
    }

    /// A raw tensor: name, dtype, shape, bytes.
    pub type Raw = (String, Dtype, Vec<usize>, Vec<u8>);

    /// Tensors and metadata of a safetensors buffer.
    pub fn parts(bytes: &[u8]) -> (Vec<Raw>, Option<HashMap<String, String>>) {
        let st = SafeTensors::deserialize(bytes).unwrap();
        let (_, meta) = SafeTensors::read_metadata(bytes).unwrap();
        let t = st
            .tensors()
            .into_iter()
            .map(|(n, v)| (n, v.dtype(), v.shape().to_vec(), v.data().to_vec()))
            .collect();
        (t, meta.metadata().clone())
    }

    /// Writes tensors and metadata as a safetensors file.
    pub fn write(path: &Path, tensors: &[Raw], meta: Option<HashMap<String, String>>) {
        let views: Vec<(&str, TensorView<'_>)> = tensors
            .iter()
            .map(|(n, d, s, b)| (n.as_str(), TensorView::new(*d, s.clone(), b).unwrap()))
            .collect();
        std::fs::write(path, safetensors::serialize(views, meta).unwrap()).unwrap();
    }

    /// Saves `model` into `dir/name`, lets `edit` change its tensors and metadata JSON, and
    /// returns the path.
    pub fn edited(
        dir: &Path,
        name: &str,
        model: &ShapeAdaptiveModel,
        edit: impl FnOnce(&mut Vec<Raw>, &mut serde_json::Value),
    ) -> PathBuf {
        let path = dir.join(name);
        let (mut tensors, meta) = parts(&model::to_bytes(model).unwrap());
        let mut json: serde_json::Value =
            serde_json::from_str(&meta.unwrap()[METADATA_KEY]).unwrap();
        edit(&mut tensors, &mut json);
        let meta = HashMap::from([(METADATA_KEY.to_string(), json.to_string())]);
        write(&path, &tensors, Some(meta));
        path
    }

    pub fn f32_bytes(v: &[f32]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    /// Writes a SON24-style `.bin` tensor.
    pub fn write_bin(path: &Path, dims: &[usize], data: &[f32]) {
        let mut b = (dims.len() as i32).to_le_bytes().to_vec();
        for &d in dims {
            b.extend((d as i32).to_le_bytes());
        }
        b.extend(f32_bytes(data));
        std::fs::write(path, b).unwrap();
    }

    /// Writes a synthetic reference-weights folder for `model` (which must have an encoder) in
    /// the SON24 layout, with a `data_stats.json` holding its normalisation (plus unrelated keys,
    /// as the real file has).
    pub fn write_son24(dir: &Path, m: &ShapeAdaptiveModel) {
        let vars = dir.join("variables");
        std::fs::create_dir_all(&vars).unwrap();
        let put = |stem: &str, w: &str, b: &str, l: &Dense| {
            write_bin(
                &vars.join(format!("{stem}_{w}.bin")),
                &[l.n_out(), l.n_in()],
                l.weights(),
            );
            write_bin(
                &vars.join(format!("{stem}_{b}.bin")),
                &[l.n_out()],
                l.bias(),
            );
        };
        for (k, l) in m.feature_mlp().layers().iter().enumerate() {
            put(
                &format!("shared_preproc_mlp_2_shapemlp_fcn_{k}"),
                "weights",
                "biases",
                l,
            );
        }
        let blocks = [
            (m.absorption_mlp(), "absorption_mlp_fcn", "absorption_dense"),
            (m.decoder(), "scatter_decoder_fcn_fcn", "scatter_dense_2"),
        ];
        for (mlp, hidden, out) in blocks {
            let n = mlp.layers().len();
            for (k, l) in mlp.layers()[..n - 1].iter().enumerate() {
                put(&format!("{hidden}_{k}"), "weights", "biases", l);
            }
            put(out, "kernel", "bias", &mlp.layers()[n - 1]);
        }
        let e = m.encoder().unwrap();
        for (k, l) in e.hidden().layers().iter().enumerate() {
            put(
                &format!("scatter_encoder_fcn_fcn_{k}"),
                "weights",
                "biases",
                l,
            );
        }
        put("scatter_dense", "kernel", "bias", e.mean());
        put("scatter_dense_1", "kernel", "bias", e.logvar());
        let n = m.normalisation();
        let stats = serde_json::json!({
            "inPos_mean": [0.0, 0.0, 0.0],
            "effAlbedo_mean": [n.eff_albedo_mean], "effAlbedo_stdinv": [n.eff_albedo_stdinv],
            "g_mean": [n.g_mean], "g_stdinv": [n.g_stdinv],
            "mlsPolyLS3_mean": n.poly_mean, "mlsPolyLS3_stdinv": n.poly_stdinv,
            "mlsPoly3_mean": vec![0.0; 20],
            "n_samples": 1234,
        });
        std::fs::write(dir.join("data_stats.json"), stats.to_string()).unwrap();
    }
}

use support::*;

fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// Evaluates features, Absorb and the decoder of a model on fixed inputs.
fn outputs(m: &ShapeAdaptiveModel) -> (Vec<f32>, Vec<f32>, Vec<[f32; 3]>) {
    let mut rng = Pcg32::seed_from_u64(99);
    let x: Vec<[f32; INPUT_DIM]> = (0..50)
        .map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
        .collect();
    let mut ws = Workspace::new();
    let mut f = vec![0.0; 50 * m.feature_dim()];
    m.features_with(&x, &mut f, &mut ws).unwrap();
    let mut a = vec![0.0; 50];
    m.absorb_with(&f, &mut a, &mut ws).unwrap();
    let z: Vec<[f32; 4]> = (0..200)
        .map(|_| std::array::from_fn(|_| rng.random_range(-2.0..2.0)))
        .collect();
    let idx: Vec<u32> = (0..200).map(|i| i % 50).collect();
    let mut y = vec![[0.0; 3]; 200];
    m.decode_with(&f, &z, &idx, &mut y, &mut ws).unwrap();
    (f, a, y)
}

#[test]
fn round_trip_with_and_without_encoder() {
    let dir = tempdir();
    for encoder in [true, false] {
        let m = small_model(1, encoder);
        let path = dir.path().join(format!("m{encoder}.safetensors"));
        m.save(&path).unwrap();
        let back = ShapeAdaptiveModel::load(&path).unwrap();
        assert_eq!(back, m);
        assert_eq!(outputs(&back), outputs(&m));
        assert_eq!(back.info().provenance["metrics"]["loss"], 0.25);
        // Overwriting an existing file works and leaves no temporary file behind.
        m.save(&path).unwrap();
    }
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
    // The metadata is a readable JSON document with the documented fields.
    let bytes = std::fs::read(dir.path().join("mtrue.safetensors")).unwrap();
    let (tensors, meta) = parts(&bytes);
    let json: serde_json::Value = serde_json::from_str(&meta.unwrap()[METADATA_KEY]).unwrap();
    assert_eq!(json["format"], FORMAT_NAME);
    assert_eq!(json["version"], 1);
    assert_eq!(
        json["architecture"]["feature"],
        serde_json::json!([23, 8, 6])
    );
    assert_eq!(
        json["architecture"]["decoder"],
        serde_json::json!([10, 7, 3])
    );
    assert_eq!(json["architecture"]["encoder"], serde_json::json!([9, 7]));
    assert_eq!(json["architecture"]["latent_dim"], 4);
    assert_eq!(json["frame_convention"], "vkj19");
    assert_eq!(json["c19_quirk"], false);
    let mut names: Vec<&str> = tensors.iter().map(|t| t.0.as_str()).collect();
    names.sort_unstable();
    assert_eq!(
        names,
        [
            "absorption.0.bias",
            "absorption.0.weight",
            "absorption.1.bias",
            "absorption.1.weight",
            "decoder.0.bias",
            "decoder.0.weight",
            "decoder.1.bias",
            "decoder.1.weight",
            "encoder.0.bias",
            "encoder.0.weight",
            "encoder.logvar.bias",
            "encoder.logvar.weight",
            "encoder.mean.bias",
            "encoder.mean.weight",
            "feature.0.bias",
            "feature.0.weight",
            "feature.1.bias",
            "feature.1.weight",
        ]
    );
    let w = tensors.iter().find(|t| t.0 == "feature.0.weight").unwrap();
    assert_eq!(w.2, [8, 23]);
}

#[test]
fn missing_file_says_how_to_get_one() {
    let dir = tempdir();
    let path = dir.path().join("nope.safetensors");
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::NotFound { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(
        msg.contains("nope.safetensors") && msg.contains("does not exist"),
        "{msg}"
    );
    assert!(
        msg.contains("translucent train") && msg.contains("models/"),
        "{msg}"
    );
}

#[test]
fn not_safetensors() {
    let dir = tempdir();
    let path = dir.path().join("junk.safetensors");
    std::fs::write(&path, b"this is not a model").unwrap();
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::NotSafetensors { .. }), "{e:?}");
    assert!(e.to_string().contains("junk.safetensors"), "{e}");
    // A truncated model is not a safetensors file either.
    let bytes = model::to_bytes(&small_model(2, true)).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 10]).unwrap();
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::NotSafetensors { .. }), "{e:?}");
}

#[test]
fn metadata_missing() {
    let dir = tempdir();
    let m = small_model(3, false);
    let (tensors, _) = parts(&model::to_bytes(&m).unwrap());
    let path = dir.path().join("nometa.safetensors");
    write(&path, &tensors, None);
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::MetadataMissing { .. }), "{e:?}");
    // Metadata without our key is the same error.
    let meta = HashMap::from([("format".to_string(), "pt".to_string())]);
    write(&path, &tensors, Some(meta));
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::MetadataMissing { .. }), "{e:?}");
}

#[test]
fn metadata_malformed_or_foreign() {
    let dir = tempdir();
    let m = small_model(4, false);
    let (tensors, _) = parts(&model::to_bytes(&m).unwrap());
    let path = dir.path().join("bad.safetensors");
    let meta = HashMap::from([(METADATA_KEY.to_string(), "{not json".to_string())]);
    write(&path, &tensors, Some(meta));
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::MetadataInvalid { .. }), "{e:?}");
    assert!(e.to_string().contains("not JSON"), "{e}");

    let path = edited(dir.path(), "fmt.safetensors", &m, |_, j| {
        j["format"] = "something-else".into()
    });
    let e = model::load(&path).unwrap_err();
    assert!(e.to_string().contains("something-else"), "{e}");

    let path = edited(dir.path(), "nonorm.safetensors", &m, |_, j| {
        j.as_object_mut().unwrap().remove("normalisation");
    });
    let e = model::load(&path).unwrap_err();
    assert!(e.to_string().contains("normalisation"), "{e}");

    let path = edited(dir.path(), "frame.safetensors", &m, |_, j| {
        j["frame_convention"] = "sideways".into()
    });
    let e = model::load(&path).unwrap_err();
    assert!(e.to_string().contains("sideways"), "{e}");
}

#[test]
fn version_mismatch() {
    let dir = tempdir();
    let path = edited(
        dir.path(),
        "v2.safetensors",
        &small_model(5, true),
        |_, j| j["version"] = 2.into(),
    );
    let e = model::load(&path).unwrap_err();
    assert!(
        matches!(e, ModelError::VersionMismatch { found: 2, .. }),
        "{e:?}"
    );
    assert!(e.to_string().contains("version 2"), "{e}");
}

#[test]
fn missing_tensor_is_named() {
    let dir = tempdir();
    let path = edited(
        dir.path(),
        "m.safetensors",
        &small_model(6, true),
        |t, _| t.retain(|x| x.0 != "decoder.1.weight"),
    );
    let e = model::load(&path).unwrap_err();
    match &e {
        ModelError::MissingTensor { tensor, .. } => assert_eq!(tensor, "decoder.1.weight"),
        _ => panic!("{e:?}"),
    }
    assert!(e.to_string().contains("`decoder.1.weight`"), "{e}");
    // A missing encoder head, too.
    let path = edited(
        dir.path(),
        "h.safetensors",
        &small_model(6, true),
        |t, _| t.retain(|x| x.0 != "encoder.logvar.bias"),
    );
    let e = model::load(&path).unwrap_err();
    assert!(e.to_string().contains("`encoder.logvar.bias`"), "{e}");
}

#[test]
fn wrong_shape_names_tensor_and_shapes() {
    let dir = tempdir();
    let path = edited(
        dir.path(),
        "s.safetensors",
        &small_model(7, false),
        |t, _| {
            // Same number of values, transposed shape ([in, out] instead of [out, in]).
            let x = t.iter_mut().find(|x| x.0 == "feature.1.weight").unwrap();
            x.2 = vec![8, 6];
        },
    );
    let e = model::load(&path).unwrap_err();
    match &e {
        ModelError::WrongShape {
            tensor,
            expected,
            got,
            ..
        } => {
            assert_eq!(tensor, "feature.1.weight");
            assert_eq!(expected, &[6, 8]);
            assert_eq!(got, &[8, 6]);
        }
        _ => panic!("{e:?}"),
    }
    let msg = e.to_string();
    assert!(msg.contains("[8, 6]") && msg.contains("[6, 8]"), "{msg}");
}

#[test]
fn wrong_dtype() {
    let dir = tempdir();
    let path = edited(
        dir.path(),
        "d.safetensors",
        &small_model(8, false),
        |t, _| {
            let x = t.iter_mut().find(|x| x.0 == "absorption.1.bias").unwrap();
            x.1 = Dtype::I32;
        },
    );
    let e = model::load(&path).unwrap_err();
    assert!(
        matches!(&e, ModelError::WrongDtype { tensor, .. } if tensor == "absorption.1.bias"),
        "{e:?}"
    );
}

#[test]
fn non_finite_weight_names_tensor_and_index() {
    let dir = tempdir();
    let path = edited(
        dir.path(),
        "nan.safetensors",
        &small_model(9, true),
        |t, _| {
            let x = t.iter_mut().find(|x| x.0 == "decoder.0.weight").unwrap();
            x.3[4 * 17..4 * 18].copy_from_slice(&f32::NAN.to_le_bytes());
        },
    );
    let e = model::load(&path).unwrap_err();
    match &e {
        ModelError::NonFinite { tensor, index, .. } => {
            assert_eq!(tensor, "decoder.0.weight");
            assert_eq!(*index, 17);
        }
        _ => panic!("{e:?}"),
    }
    assert!(e.to_string().contains("index 17"), "{e}");
    // Infinity in a bias too.
    let path = edited(
        dir.path(),
        "inf.safetensors",
        &small_model(9, true),
        |t, _| {
            let x = t.iter_mut().find(|x| x.0 == "encoder.mean.bias").unwrap();
            x.3[..4].copy_from_slice(&f32::INFINITY.to_le_bytes());
        },
    );
    let e = model::load(&path).unwrap_err();
    assert!(
        matches!(&e, ModelError::NonFinite { tensor, index: 0, .. } if tensor == "encoder.mean.bias"),
        "{e:?}"
    );
    // Saving refuses non-finite weights.
    let mut m = small_model(9, false);
    m.networks_mut().2.layers_mut()[1].weights_mut()[2] = f32::NAN;
    let e = m.save(&dir.path().join("never.safetensors")).unwrap_err();
    assert!(
        matches!(&e, ModelError::NonFinite { tensor, index: 2, .. } if tensor == "decoder.1.weight"),
        "{e:?}"
    );
    assert!(!dir.path().join("never.safetensors").exists());
}

#[test]
fn metadata_inconsistent_with_tensors() {
    let dir = tempdir();
    let m = small_model(10, true);
    // The architecture claims a third feature layer the file does not have.
    let path = edited(dir.path(), "a.safetensors", &m, |_, j| {
        j["architecture"]["feature"] = serde_json::json!([23, 8, 6, 6]);
    });
    let e = model::load(&path).unwrap_err();
    assert!(
        matches!(&e, ModelError::MissingTensor { tensor, .. } if tensor == "feature.2.weight"),
        "{e:?}"
    );
    // A tensor the architecture does not describe.
    let path = edited(dir.path(), "b.safetensors", &m, |t, _| {
        t.push((
            "decoder.2.weight".to_string(),
            Dtype::F32,
            vec![1],
            f32_bytes(&[1.0]),
        ))
    });
    let e = model::load(&path).unwrap_err();
    assert!(
        matches!(&e, ModelError::UnexpectedTensor { tensor, .. } if tensor == "decoder.2.weight"),
        "{e:?}"
    );
    // An encoder in the file but not in the architecture.
    let path = edited(dir.path(), "c.safetensors", &m, |_, j| {
        j["architecture"]["encoder"] = serde_json::Value::Null;
    });
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::UnexpectedTensor { .. }), "{e:?}");
    // Blocks that do not fit together (feature width vs decoder input).
    let path = edited(dir.path(), "d.safetensors", &m, |_, j| {
        j["architecture"]["feature_dim"] = 7.into();
    });
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::MetadataInvalid { .. }), "{e:?}");
    assert!(e.to_string().contains("expected 7"), "{e}");
    // Unsupported latent size.
    let path = edited(dir.path(), "e.safetensors", &m, |_, j| {
        j["architecture"]["latent_dim"] = 8.into();
    });
    let e = model::load(&path).unwrap_err();
    assert!(e.to_string().contains("latent_dim is 8"), "{e}");
    // Non-finite normalisation constant (JSON has no NaN: a huge value overflows f32 to inf).
    let path = edited(dir.path(), "f.safetensors", &m, |_, j| {
        j["normalisation"]["g_stdinv"] = serde_json::json!(1e300);
    });
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::MetadataInvalid { .. }), "{e:?}");
    // A feature width of 2⁶⁴ − 1 (found by the mutation pass of `crates/fuzz` in the test
    // profile: the expected decoder input 4 + F overflowed while checking the architecture).
    let path = edited(dir.path(), "g.safetensors", &m, |_, j| {
        j["architecture"]["feature_dim"] = u64::MAX.into();
    });
    let e = model::load(&path).unwrap_err();
    assert!(matches!(e, ModelError::MetadataInvalid { .. }), "{e:?}");
    assert!(e.to_string().contains("g.safetensors"), "{e}");
}

#[test]
fn son24_import_reads_weights_and_stats() {
    let dir = tempdir();
    let m = small_model(11, true);
    write_son24(dir.path(), &m);
    let imported = son24::import(dir.path()).unwrap();
    assert_eq!(imported.feature_mlp(), m.feature_mlp());
    assert_eq!(imported.absorption_mlp(), m.absorption_mlp());
    assert_eq!(imported.decoder(), m.decoder());
    assert_eq!(imported.encoder(), m.encoder());
    assert_eq!(imported.normalisation(), m.normalisation());
    let info = imported.info();
    assert_eq!(info.frame_convention, FrameConvention::Son24Compat);
    assert!(info.c19_quirk);
    assert_eq!(info.provenance["source"], son24::SOURCE);
    assert_eq!(info.provenance["training_samples"], 1234);
    assert_eq!(outputs(&imported), outputs(&m));
    // And it survives our format.
    let path = dir.path().join("imported.safetensors");
    imported.save(&path).unwrap();
    assert_eq!(model::load(&path).unwrap(), imported);

    // Without any encoder file the encoder is absent.
    for f in std::fs::read_dir(dir.path().join("variables")).unwrap() {
        let p = f.unwrap().path();
        let n = p.file_name().unwrap().to_str().unwrap().to_string();
        if n.starts_with("scatter_encoder")
            || n.starts_with("scatter_dense_kernel")
            || n.starts_with("scatter_dense_bias")
            || n.starts_with("scatter_dense_1")
        {
            std::fs::remove_file(p).unwrap();
        }
    }
    let imported = son24::import(dir.path()).unwrap();
    assert!(imported.encoder().is_none());
}

#[test]
fn son24_import_errors() {
    let err = |dir: &Path| son24::import(dir).unwrap_err();
    let fresh = || {
        let d = tempdir();
        write_son24(d.path(), &small_model(12, true));
        d
    };
    // Missing folder, missing variables/, missing stats.
    let d = tempdir();
    let e = err(&d.path().join("absent"));
    assert!(matches!(e, ModelError::Son24Missing { .. }), "{e:?}");
    assert!(e.to_string().contains("variables/*.bin"), "{e}");
    let e = err(d.path());
    assert!(e.to_string().contains("variables"), "{e}");
    let d = fresh();
    std::fs::remove_file(d.path().join("data_stats.json")).unwrap();
    let e = err(d.path());
    assert!(
        matches!(&e, ModelError::Son24Missing { path, .. } if path.ends_with("data_stats.json")),
        "{e:?}"
    );
    // A stats key missing or of the wrong length.
    let d = fresh();
    let p = d.path().join("data_stats.json");
    let mut j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    j.as_object_mut().unwrap().remove("effAlbedo_stdinv");
    std::fs::write(&p, j.to_string()).unwrap();
    let e = err(d.path());
    assert!(
        matches!(e, ModelError::Son24Corrupt { .. }) && e.to_string().contains("effAlbedo_stdinv"),
        "{e}"
    );
    j["effAlbedo_stdinv"] = serde_json::json!([1.0]);
    j["mlsPolyLS3_mean"] = serde_json::json!(vec![0.0; 19]);
    std::fs::write(&p, j.to_string()).unwrap();
    let e = err(d.path());
    assert!(
        e.to_string().contains("`mlsPolyLS3_mean` has 19 values"),
        "{e}"
    );
    // Missing weight files: the first feature layer, a bias, the decoder output.
    for name in [
        "shared_preproc_mlp_2_shapemlp_fcn_0_weights.bin",
        "absorption_mlp_fcn_0_biases.bin",
        "scatter_dense_2_kernel.bin",
        "scatter_dense_1_bias.bin",
    ] {
        let d = fresh();
        std::fs::remove_file(d.path().join("variables").join(name)).unwrap();
        let e = err(d.path());
        assert!(
            matches!(&e, ModelError::Son24Missing { path, .. } if path.ends_with(name)),
            "{name}: {e:?}"
        );
    }
    // Truncated and garbage files.
    let d = fresh();
    let p = d
        .path()
        .join("variables/scatter_decoder_fcn_fcn_0_weights.bin");
    let b = std::fs::read(&p).unwrap();
    std::fs::write(&p, &b[..b.len() - 3]).unwrap();
    let e = err(d.path());
    assert!(
        matches!(&e, ModelError::Son24Corrupt { path, .. } if path == &p),
        "{e:?}"
    );
    assert!(e.to_string().contains("bytes of data"), "{e}");
    std::fs::write(&p, b"\xff\xff\xff\x7f").unwrap();
    let e = err(d.path());
    assert!(e.to_string().contains("dimensions"), "{e}");
    // Bias that does not match its weights.
    let d = fresh();
    write_bin(
        &d.path().join("variables/absorption_dense_bias.bin"),
        &[2],
        &[0.0, 0.0],
    );
    let e = err(d.path());
    assert!(e.to_string().contains("bias has shape [2]"), "{e}");
    // Layers that do not chain (decoder output layer with the wrong input width).
    let d = fresh();
    write_bin(
        &d.path().join("variables/scatter_dense_2_kernel.bin"),
        &[3, 5],
        &[0.0; 15],
    );
    let e = err(d.path());
    assert!(
        matches!(e, ModelError::Son24Corrupt { .. }) && e.to_string().contains("do not fit"),
        "{e}"
    );
    // Non-finite weight.
    let d = fresh();
    write_bin(
        &d.path().join("variables/scatter_dense_2_bias.bin"),
        &[3],
        &[0.0, f32::NAN, 0.0],
    );
    let e = err(d.path());
    assert!(e.to_string().contains("index 1"), "{e}");
}
