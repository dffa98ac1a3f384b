//! Run, resume or reuse a recovery's folder: the step of multi-run commands (the experiments,
//! the bias correction's own recoveries, the starts) that makes an interrupted command continue
//! where it stopped. A folder is reused only when its run was made with the same settings.

use std::path::Path;

use scene::setting::Setting;

use super::{Observer, RecoveryConfig, RecoveryError};
use inverse::params::Params;

/// What a finished run reports (from its `result.json`).
#[derive(Clone, Copy, Debug)]
pub struct RunResult {
    pub estimate: Params,
    pub seconds_per_iteration: f64,
}

/// Run the recovery `cfg` into `cfg.out`, or resume it from its checkpoint, or reuse it when it
/// has already finished its iterations; then read its result. A folder whose run (finished or
/// not) was made with other settings than `cfg.optimize` (the iteration count aside) is an
/// error naming the differing settings. `label` names the run in the report.
pub fn run_or_reuse(
    cfg: &RecoveryConfig,
    obs: &dyn Observer,
    label: &str,
) -> Result<RunResult, RecoveryError> {
    let run_dir = &cfg.out;
    let result = run_dir.join("result.json");
    let expected = serde_json::to_value(&cfg.optimize)?;
    let differing = |c: &serde_json::Value| -> Vec<String> {
        differing_settings(&expected, c)
            .into_iter()
            .map(|d| d.key)
            .collect()
    };
    let checkpoint = run_dir.join("checkpoint.json");
    for file in [&result, &checkpoint] {
        if let Ok(v) = read_json(file) {
            let keys = differing(&v["config"]);
            if !keys.is_empty() {
                return Err(RecoveryError::Invalid(format!(
                    "{} holds a run made with other settings than this command's (differing: \
                     {}); use another {} or remove that folder",
                    run_dir.display(),
                    keys.join(", "),
                    Setting::Out
                )));
            }
        }
    }
    let iterations = cfg.optimize.iterations;
    if is_finished(&result, iterations) {
        obs.say(&format!(
            "run {label} ({}): reusing {}",
            cfg.estimator(),
            run_dir.display()
        ));
    } else {
        obs.say(&format!(
            "run {label} ({}): {iterations} iterations",
            cfg.estimator()
        ));
        let mut c = cfg.clone();
        c.resume = checkpoint.exists();
        c.overwrite = false;
        super::run(&c, obs)?;
    }
    let v = read_json(&result)?;
    Ok(RunResult {
        estimate: params_of(&v["estimate"]).ok_or_else(|| {
            RecoveryError::Invalid(format!("{}: no estimate.sigma_t/albedo", result.display()))
        })?,
        seconds_per_iteration: v["seconds_per_iteration"].as_f64().unwrap_or(f64::NAN),
    })
}

/// Whether `result` (a `result.json`) records a complete run of `iterations` iterations.
fn is_finished(result: &Path, iterations: u32) -> bool {
    read_json(result).ok().is_some_and(|v| {
        v["iterations"].as_u64() == Some(iterations as u64)
            && v["complete"].as_bool() != Some(false)
    })
}

/// The result of the run in `cfg.out` if it has finished with the settings of `cfg` (its
/// iterations included); `None` while it is absent, unfinished or made with other settings.
/// Runs nothing: what a table assembled from finished runs reads.
pub fn finished(cfg: &RecoveryConfig) -> Option<RunResult> {
    let result = cfg.out.join("result.json");
    let v = read_json(&result).ok()?;
    let expected = serde_json::to_value(&cfg.optimize).ok()?;
    if !differing_settings(&expected, &v["config"]).is_empty()
        || !is_finished(&result, cfg.optimize.iterations)
    {
        return None;
    }
    Some(RunResult {
        estimate: params_of(&v["estimate"])?,
        seconds_per_iteration: v["seconds_per_iteration"].as_f64().unwrap_or(f64::NAN),
    })
}

/// One setting in which a run's recorded configuration differs from a command's.
pub struct SettingDifference {
    /// The configuration's key ("the format" when only the sets of keys differ).
    pub key: String,
    /// The command's value.
    pub expected: serde_json::Value,
    /// The run's value.
    pub recorded: serde_json::Value,
}

/// The top-level settings in which a run's recorded configuration `recorded` differs from
/// `expected` (both the JSON form of an [`inverse::optimize::OptimizeConfig`]), the iteration
/// count aside: a run may be extended. Numbers compare at f32 precision, as the files write them
/// either way.
pub fn differing_settings(
    expected: &serde_json::Value,
    recorded: &serde_json::Value,
) -> Vec<SettingDifference> {
    let Some(m) = expected.as_object() else {
        return vec![SettingDifference {
            key: "the format".into(),
            expected: expected.clone(),
            recorded: recorded.clone(),
        }];
    };
    let null = serde_json::Value::Null;
    let mut out: Vec<SettingDifference> = m
        .iter()
        .filter(|(k, e)| {
            *k != "iterations" && !recorded.get(k.as_str()).is_some_and(|v| json_close(v, e))
        })
        .map(|(k, e)| SettingDifference {
            key: k.clone(),
            expected: e.clone(),
            recorded: recorded.get(k.as_str()).unwrap_or(&null).clone(),
        })
        .collect();
    if out.is_empty() && recorded.as_object().map_or(0, |c| c.len()) != m.len() {
        out.push(SettingDifference {
            key: "the format".into(),
            expected: expected.clone(),
            recorded: recorded.clone(),
        });
    }
    out
}

/// `{"sigma_t": [3], "albedo": [3]}` (and `"g"`, `"light_scale"` where the run recovered
/// them) as parameters.
pub fn params_of(v: &serde_json::Value) -> Option<Params> {
    let rgb = |field: &str| -> Option<[f64; 3]> {
        let a = v[field].as_array().filter(|a| a.len() == 3)?;
        let out: [Option<f64>; 3] = std::array::from_fn(|c| a[c].as_f64());
        Some([out[0]?, out[1]?, out[2]?])
    };
    Some(Params {
        sigma_t: rgb("sigma_t")?,
        albedo: rgb("albedo")?,
        g: serde_json::from_value(v["g"].clone()).ok(),
        light_scale: serde_json::from_value(v["light_scale"].clone()).ok(),
    })
}

/// Equal JSON values, numbers equal to f32 precision (relative 1e-6).
fn json_close(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (
                x.as_f64().unwrap_or(f64::NAN),
                y.as_f64().unwrap_or(f64::NAN),
            );
            x == y || (x - y).abs() <= 1e-6 * x.abs().max(y.abs())
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| json_close(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| json_close(v, w)))
        }
        _ => a == b,
    }
}

/// A JSON file, with its path in the errors.
pub fn read_json(path: &Path) -> Result<serde_json::Value, RecoveryError> {
    let text = std::fs::read_to_string(path).map_err(|source| RecoveryError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|source| RecoveryError::Json {
        path: Some(path.to_path_buf()),
        source,
    })
}
