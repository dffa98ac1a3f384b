//! The diagnostics of `translucent-dev`, run as a user runs them, on tiny datasets made with the
//! library (the volumetric tracer's targets, or the learned model's own images).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use geometry::Shape;
use glam::Vec3;
use indicatif::ProgressBar;
use inverse::views::{Job, RenderOpts, build_accel};
use scene::rig::{RigLight, house_rig};
use scene::{Dataset, Medium, MeshSource, RenderInfo, SceneDesc};

fn dev(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_translucent-dev"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("translucent-dev runs")
}

fn ok(dir: &Path, args: &[&str]) -> String {
    let out = dev(dir, args);
    assert!(
        out.status.success(),
        "translucent-dev {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn fails(dir: &Path, args: &[&str]) -> String {
    let out = dev(dir, args);
    assert!(!out.status.success(), "translucent-dev {args:?} succeeded");
    String::from_utf8(out.stderr).unwrap()
}

fn has(text: &str, needles: &[&str]) {
    for n in needles {
        assert!(text.contains(n), "{n:?} missing in:\n{text}");
    }
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// A sphere in σ_t = 60, α = 0.9, two 12² views lit from beside each camera, rendered by the
/// volumetric tracer at 4 spp into `dir/name`.
fn sphere_dataset(dir: &Path, name: &str) -> (SceneDesc, PathBuf) {
    let out = dir.join(name);
    let rig = house_rig(
        2,
        12,
        RigLight::Attached {
            offset: Vec3::new(0.8, 0.8, 0.0),
        },
        (-90.0, 90.0),
    );
    let desc = SceneDesc {
        mesh: MeshSource::Shape(Shape::from_name("sphere").unwrap()),
        medium: Medium {
            sigma_t: [60.0; 3],
            albedo: [0.9; 3],
            g: scene::Anisotropy::uniform(0.0),
            eta: 1.0,
            roughness: 0.0,
        },
        views: rig.build(),
        render: RenderInfo::default(),
        path: out.join("dataset.json"),
        length_unit: None,
    };
    let opts = RenderOpts {
        spp: 4,
        seed: 0,
        max_depth: 32,
        shadow: Default::default(),
    };
    inverse::views::render_dataset(desc.clone(), opts, &out, false, &ProgressBar::hidden())
        .unwrap();
    (desc, out)
}

/// `loss-scan --grazing-cos`: the loss per pixel class and per view, the brightness per
/// phase-angle bin; existing outputs are refused before any rendering; a bad cosine is named.
#[test]
fn loss_scan_reports_pixel_classes_views_and_phase_angles() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    sphere_dataset(d, "ds");
    let args = [
        "-q",
        "loss-scan",
        "--dataset",
        "ds",
        "--views",
        "2",
        "--spp",
        "2",
        "--scales",
        "0.9,1",
        "--grazing-cos",
        "0.3",
        "--out",
        "scan",
    ];
    has(
        &ok(d, &args),
        &["lit", "terminator", "unlit", "rim", "phase angle"],
    );
    let csv = read(&d.join("scan/loss-scan.csv"));
    let header = csv.lines().next().unwrap();
    assert!(header.ends_with(",rim_r,rim_g,rim_b"), "{header}");
    assert_eq!(csv.lines().count(), 3, "{csv}");
    let views = read(&d.join("scan/loss-scan-views.csv"));
    assert_eq!(views.lines().count(), 1 + 2 * 2, "{views}");
    for line in views.lines().skip(1) {
        let phase: f64 = line.split(',').nth(2).unwrap().parse().unwrap();
        assert!((0.0..=180.0).contains(&phase), "{line}");
    }
    has(&fails(d, &args), &["loss-scan.csv", "--overwrite"]);
    let bad = fails(d, &[&args[..11], &["1.5", "--out", "scan2"]].concat());
    has(&bad, &["--grazing-cos", "(0, 1)"]);
}

/// `loss-scan` on the learned model's own images (rendered at the truth with seed 3, 2 spp)
/// at the truth with the targets' seed renders the very same images, so the decorrelated loss is
/// exactly 0, and `--cosine-table` writes one row per (light, camera) cosine bin whose shares of
/// the image sum to 1.
#[test]
fn loss_scan_at_the_truth_of_learned_targets_and_the_cosine_table() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let (desc, _) = sphere_dataset(d, "ds");
    let (mesh, warnings) = desc.load_mesh().unwrap();
    let accel = build_accel(mesh, &warnings, "sphere");
    let job = Job {
        accel: &accel,
        medium: &desc.medium,
        views: &desc.views,
        spp: 2,
        seed: 3,
    };
    let model = bssrdf::model::shipped().unwrap();
    let settings = cmdline::arg_defaults::<cmdline::LearnedArgs>(&[]).settings();
    let spec = inverse::forward::ModelSpec::learned(&model, settings, job.seed);
    let rep = inverse::views::render(spec, &job, false, &ProgressBar::hidden()).unwrap();
    let mut ds = Dataset::from_scene(&desc);
    ds.render = RenderInfo {
        spp: Some(2),
        max_depth: Some(32),
        seed: Some(3),
        renderer: Some("learned BSSRDF".into()),
    };
    for (v, img) in ds.views.iter_mut().zip(&rep.images) {
        v.image = Some(img.clone());
    }
    ds.save(&d.join("lt"), false).unwrap();

    let scan = [
        "-q",
        "loss-scan",
        "--dataset",
        "lt",
        "--views",
        "2",
        "--spp",
        "2",
        "--scales",
        "1",
        "--seed",
        "3",
        "--cosine-table",
        "--out",
        "scan",
    ];
    has(
        &ok(d, &scan),
        &["through medium", "μ_l 0.75–1.00", "share of T"],
    );
    let csv = read(&d.join("scan/loss-scan.csv"));
    let row: Vec<f64> = csv
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(&row[1..4], &[0.0, 0.0, 0.0], "{csv}");
    let cos = read(&d.join("scan/loss-scan-cosines.csv"));
    assert_eq!(cos.lines().count(), 1 + 6 * 4, "{cos}");
    let shares: f64 = cos
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(3).unwrap().parse::<f64>().unwrap())
        .sum();
    assert!((shares - 1.0).abs() < 1e-9, "{shares}");
}

/// Every diagnostic answers `--help`, and the binary names itself.
#[test]
fn every_diagnostic_has_help() {
    let t = tempfile::tempdir().unwrap();
    let top = ok(t.path(), &["--help"]);
    for name in [
        "volpath",
        "learned-vs-volpath",
        "plane",
        "spread",
        "loss-scan",
        "noise",
    ] {
        assert!(top.contains(name), "{name} missing in:\n{top}");
        let help = ok(t.path(), &[name, "--help"]);
        assert!(
            help.contains("--seed"),
            "{name} --help has no --seed:\n{help}"
        );
    }
}

/// `noise` on a tiny scene: a volpath row and a learned row per case, and on the coloured medium
/// the ceiling row of channel sharing, every ratio finite and positive.
#[test]
fn noise_reports_the_ceiling_of_channel_sharing() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("noise");
    let printed = ok(
        t.path(),
        &[
            "-q",
            "noise",
            "--scales",
            "0.3",
            "--views",
            "1",
            "--res",
            "16",
            "--spp",
            "8",
            "--volpath-spp",
            "8",
            "--grad-seeds",
            "0",
            "--schemes",
            "stratified",
            "--out",
            out.to_str().unwrap(),
        ],
    );
    has(&printed, &["ceiling (grey)", "learned stratified"]);
    let csv = testkit::CsvTable::read(out.join("noise.csv"));
    let text = &csv.text;
    // Flash and fixed coloured cases (volpath, learned, ceiling) and the grey case (volpath,
    // learned): the grey medium has no ceiling row.
    let names: Vec<String> = csv.rows.iter().map(|r| r[..2].join("/")).collect();
    assert_eq!(csv.rows.len(), 3 + 3 + 2, "{text}");
    assert!(
        names.iter().any(|n| n == "blob0.3-flash/ceiling (grey)"),
        "{text}"
    );
    assert!(
        !names
            .iter()
            .any(|n| n == "blob0.3-flash-grey/ceiling (grey)"),
        "{text}"
    );
    let first = csv.column("volpath_vt_over_vt_r");
    for r in &csv.rows {
        for ratio in &r[first..first + 3] {
            let x: f64 = ratio.parse().unwrap();
            assert!(x.is_finite() && x > 0.0, "{text}");
        }
    }
}
