//! `experiment capture-errors --quick`: the perturbed datasets say what they perturb and carry
//! it out, every run is tabulated with a verdict, a second invocation reuses everything, and an
//! unknown perturbation is refused with the list.

use crate::helpers::*;

/// One case, four perturbations of different kinds (a camera, the light's intensity, the mesh,
/// the sensor) and the unperturbed run: five rows of three channels.
#[test]
fn experiment_capture_errors_quick_perturbs_recovers_and_tabulates() {
    let t = tmp();
    let d = t.path();
    let picked =
        "camera-rotation-0.5deg,light-intensity-x0.9,mesh-decimated-x10,sensor-noise-iso3200";
    let args = [
        "-q",
        "experiment",
        "capture-errors",
        "--quick",
        "--cases",
        "flash-5-blob",
        "--perturbations",
        picked,
        "--out",
        "ce",
    ];
    let r = ok(d, &args);
    assert_stdout_has(
        &r,
        &["Capture errors", "verdict", "Confident wrong numbers"],
    );
    let csv = testkit::CsvTable::read(d.join("ce/capture-errors.csv"));
    assert_eq!(csv.rows.len(), 5 * 3, "{}", csv.text);
    let col = |name: &str| csv.column(name);
    for f in &csv.rows {
        assert!(["holds", "flagged", "wrong"].contains(&f[col("verdict")].as_str()));
        let est: f64 = f[col("sigma_t_est")].parse().unwrap();
        assert!(est.is_finite() && est > 0.0);
        let shift: f64 = f[col("sigma_t_shift")].parse().unwrap();
        if f[col("perturbation")] == "none" {
            assert_eq!(shift, 0.0);
        }
    }
    // The perturbed datasets: the images of the unperturbed one, what the recovery is told
    // changed as named.
    let data = d.join("ce/data");
    let clean = read_json(&data.join("flash-5-blob/dataset.json"));
    let dim = read_json(&data.join("flash-5-blob-light-intensity-x0.9/dataset.json"));
    let k = |v: &serde_json::Value| v["views"][0]["light"]["intensity"][0].as_f64().unwrap();
    assert!((k(&dim) / k(&clean) - 0.9).abs() < 1e-6, "{dim}");
    assert!(dim["notes"]["capture_error"].is_string(), "{dim}");
    let turned = read_json(&data.join("flash-5-blob-camera-rotation-0.5deg/dataset.json"));
    assert_ne!(turned["views"][0]["camera"], clean["views"][0]["camera"]);
    let coarse = data.join("flash-5-blob-mesh-decimated-x10/mesh-perturbed.ply");
    let header = String::from_utf8_lossy(&read(&coarse)[..200]).to_string();
    assert!(header.contains("element face"), "{header}");
    let again = ok(d, &args);
    assert_eq!(
        again.stdout.matches("reusing").count(),
        5,
        "{}",
        again.stdout
    );
    let bad = fails(
        d,
        &[
            &args[..6],
            &["--perturbations", "camera-wobble", "--out", "ce"],
        ]
        .concat(),
    );
    assert_stderr_has(
        &bad,
        &["--perturbations", "camera-wobble", "camera-rotation-0.1deg"],
    );
}
