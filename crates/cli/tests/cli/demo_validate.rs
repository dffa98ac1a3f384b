//! `demo` and `validate-mitsuba`.

use std::path::{Path, PathBuf};

use serde_json::json;

use super::helpers::*;

// ---------------------------------------------------------------------------------------------
// 5. demo

/// A tiny demo into `out`: 2 views of 16², 2 spp, 3 iterations.
fn demo_args(out: &str) -> [&str; 12] {
    [
        "-q",
        "demo",
        "--out",
        out,
        "--res",
        "16",
        "--views",
        "2",
        "--spp",
        "2",
        "--iterations",
        "3",
    ]
}

#[test]
fn demo_writes_dataset_reruns_and_protects_other_datasets() {
    let t = tmp();
    let args = demo_args("demo");
    ok(t.path(), &args);
    let d = t.path().join("demo");
    let j = read_json(&d.join("dataset.json"));
    assert_eq!(j["format"], "translucent-dataset");
    assert_eq!(j["views"].as_array().unwrap().len(), 2);
    assert_eq!(j["views"][0]["camera"]["width"], 16);
    assert!(j["truth"]["sigma_t"].is_array());
    for f in [
        "view_000.exr",
        "view_000.png",
        "view_001.exr",
        "view_001.png",
    ] {
        assert!(d.join(f).is_file(), "{f} missing");
    }
    // By default the last half of the iterations (1 of 3) refine with the volumetric path
    // tracer, which replaces the bias correction.
    let r = read_json(&d.join("optimize/result.json"));
    assert_eq!(r["config"]["refine_iterations"], 1, "{r}");
    assert!(r.get("bias_correction").is_none(), "{r}");
    assert!(!d.join("optimize/bootstrap").exists());
    let first = read(&d.join("view_000.exr"));
    // The demo may overwrite its own folder; same arguments, same images.
    ok(t.path(), &args);
    assert_eq!(read(&d.join("view_000.exr")), first);
    // `--refine 0`: the learned model alone, corrected by one bootstrap step as `optimize`
    // does then, and the plain estimate kept.
    let mut plain = args.to_vec();
    plain.extend(["--refine", "0"]);
    ok(t.path(), &plain);
    let r = read_json(&d.join("optimize/result.json"));
    assert!(r["config"].get("refine_iterations").is_none(), "{r}");
    assert_eq!(r["bias_correction"]["steps"].as_array().unwrap().len(), 1);
    assert!(r["estimate_uncorrected"]["sigma_t"].is_array());
    assert!(
        d.join("optimize/bootstrap/step-1/data/dataset.json")
            .is_file()
    );
    // The demo's folder is a valid dataset: `render` reproduces it.
    ok(t.path(), &["-q", "render", "demo", "--out", "r"]);
    assert_eq!(read(&t.path().join("r/view_000.exr")), first);

    // A folder holding a dataset not written by the demo is left alone.
    let other = make_dataset(t.path(), "other", "1", "8", &[]);
    let json_before = read(&other.join("dataset.json"));
    let exr_before = read(&other.join("view_000.exr"));
    let r = fails(t.path(), &demo_args("other"));
    assert_stderr_has(&r, &["other", "demo"]);
    assert_eq!(read(&other.join("dataset.json")), json_before);
    assert_eq!(read(&other.join("view_000.exr")), exr_before);
    assert!(!other.join("view_001.exr").exists());
}

/// `demo --help` says "other folders are never overwritten", but a folder of `render` outputs
/// (view_XXX.exr, no dataset.json) is overwritten: demo.rs only protects folders holding a
/// dataset.json, then calls make_dataset(…, overwrite = true).
#[test]
fn demo_does_not_overwrite_render_outputs() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    ok(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "r", "--spp", "2"],
    );
    let before = read(&t.path().join("r/view_000.exr"));
    let r = translucent(t.path(), &demo_args("r"));
    assert_ne!(r.code, Some(0), "{}", r.describe());
    assert_eq!(read(&t.path().join("r/view_000.exr")), before);
}

// ---------------------------------------------------------------------------------------------
// 6. validate-mitsuba

/// A Mitsuba reference folder (DATASET.md, "Mitsuba reference-render folders") made from a
/// dataset of the cube mesh rendered by `translucent dataset` with --spp 8 --seed 3: scene.json,
/// the mesh and the dataset's EXRs. `intensity_factor` scales the light intensity recorded in
/// scene.json (1 = the intensity the images were rendered with).
fn mitsuba_reference(dir: &Path, name: &str, intensity_factor: f64) -> PathBuf {
    write(&dir.join("cube.ply"), cube_ply());
    let ds = dir.join(format!("{name}_dataset"));
    if !ds.join("dataset.json").exists() {
        ok(
            dir,
            &[
                "-q",
                "dataset",
                "--mesh",
                "cube.ply",
                "--views",
                "2",
                "--res",
                "8",
                "--spp",
                "8",
                "--seed",
                "3",
                "--out",
                &format!("{name}_dataset"),
            ],
        );
    }
    let j = read_json(&ds.join("dataset.json"));
    let mesh = j["mesh"]
        .as_str()
        .expect("a mesh dataset records its mesh file");
    assert!(
        ds.join(mesh).is_file(),
        "the dataset folder should hold its mesh ({mesh})"
    );
    assert_eq!(j["truth"]["eta"], 1.0);

    let r = dir.join(name);
    std::fs::create_dir_all(&r).unwrap();
    std::fs::copy(ds.join(mesh), r.join("mesh.ply")).unwrap();
    let views = j["views"].as_array().unwrap();
    let intensity: Vec<f64> = views[0]["light"]["intensity"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() * intensity_factor)
        .collect();
    let mut ref_views = Vec::new();
    for (i, v) in views.iter().enumerate() {
        let exr = format!("view_{i:03}.exr");
        std::fs::copy(ds.join(v["image"].as_str().unwrap()), r.join(&exr)).unwrap();
        assert_eq!(v["light"]["intensity"], views[0]["light"]["intensity"]);
        ref_views.push(json!({
            "to_world": v["camera"]["to_world"],
            "light_position": v["light"]["position"],
            "file_exr": exr,
        }));
    }
    let cam = &views[0]["camera"];
    let scene = json!({
        "generator": "tests/cli (synthetic reference)",
        "shape": { "type": "ply", "mesh_file": "mesh.ply" },
        "medium": {
            "type": "homogeneous",
            "sigma_t": j["truth"]["sigma_t"],
            "albedo": j["truth"]["albedo"],
            "phase": { "type": "isotropic" }
        },
        "boundary": { "bsdf": "null" },
        "light": { "type": "point", "intensity_rgb": intensity },
        "camera": { "fov_deg": cam["fov_x_deg"], "fov_axis": "x", "width": cam["width"], "height": cam["height"] },
        "integrator": { "type": "volpath", "max_depth": 32 },
        "render": { "spp": 8, "seed": 3 },
        "views": ref_views,
    });
    write(
        &r.join("scene.json"),
        serde_json::to_string_pretty(&scene).unwrap(),
    );
    r
}

/// `validate-mitsuba` of the folder `ref` made by [`mitsuba_reference`] into `ours`. The folder
/// was rendered by our tracer, not Mitsuba, so Mitsuba's spawn offset is not emulated.
const VALIDATE_REF: [&str; 11] = [
    "-q",
    "validate-mitsuba",
    "ref",
    "--spawn-offset",
    "robust",
    "--spp",
    "8",
    "--seed",
    "3",
    "--out",
    "ours",
];

#[test]
fn validate_mitsuba_passes_on_matching_reference() {
    let t = tmp();
    mitsuba_reference(t.path(), "ref", 1.0);
    let r = ok(t.path(), &VALIDATE_REF);
    assert_stdout_has(&r, &["all 2 views within tolerance", "spawn offset robust"]);
    assert!(!r.stdout.contains("FAIL"), "{}", r.describe());
    for n in exr_names(2) {
        assert!(t.path().join("ours").join(&n).is_file(), "{n} missing");
    }
    // Running again needs --overwrite for the output folder.
    let r = fails(t.path(), &VALIDATE_REF);
    assert_stderr_has(&r, &["--overwrite"]);
    // The reference folder is also a dataset for `render`: its truth renders to the same images.
    ok(t.path(), &["-q", "render", "ref", "--out", "rr"]);
    assert_same_images(
        &t.path().join("rr"),
        &t.path().join("ref"),
        2,
        "the reference's truth renders differently",
    );
}

#[test]
fn validate_mitsuba_fails_when_reference_is_twice_as_bright() {
    let t = tmp();
    mitsuba_reference(t.path(), "ref", 0.5);
    let r = fails(t.path(), &VALIDATE_REF);
    assert_stderr_has(&r, &["outside tolerance"]);
    assert_stdout_has(&r, &["FAIL"]);
    // Our render at half the light is half the reference: mean ratio 0.5.
    assert_stdout_has(&r, &["0.5000"]);
}

/// `--equal-time` renders in passes until the time budget is spent, reports the spp it reached,
/// and `--spp` with that number gives the same images; without a budget (the synthetic
/// scene.json records no render time) it says where to give one.
#[test]
fn validate_mitsuba_equal_time_reaches_an_spp_that_reproduces_its_images() {
    let t = tmp();
    mitsuba_reference(t.path(), "ref", 1.0);
    fn with<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        // The reference is an 8-spp render: its noise, not the tolerances, is not the point here.
        let base = [
            "-q",
            "validate-mitsuba",
            "ref",
            "--spawn-offset",
            "robust",
            "--seed",
            "3",
            "--lit-tolerance",
            "0.5",
            "--dark-tolerance",
            "0.5",
        ];
        base.into_iter().chain(extra.iter().copied()).collect()
    }
    let r = ok(
        t.path(),
        &with(&["--equal-time", "--time-per-view", "0.2", "--out", "eq"]),
    );
    assert_stdout_has(&r, &["equal time: ", "all 2 views within tolerance"]);
    // "equal time: N spp in S s/view against …"
    let number_after = |marker: &str| -> f64 {
        r.stdout
            .split(marker)
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no number after {marker:?}\n{}", r.describe()))
    };
    let spp = number_after("equal time: ") as u32;
    assert!(
        spp >= 32 && spp.is_multiple_of(32),
        "{spp} spp: passes are 32 spp"
    );
    // The seconds it reports depend on the machine's load; the stopping rule is tested with
    // synthetic timings in `validate::tests`.
    assert!(number_after(" spp in ") > 0.0);
    let spp_arg = spp.to_string();
    ok(t.path(), &with(&["--spp", &spp_arg, "--out", "fixed"]));
    assert_same_images(
        &t.path().join("eq"),
        &t.path().join("fixed"),
        2,
        "--equal-time differs from --spp at the spp it reached",
    );

    let r = fails(t.path(), &with(&["--equal-time", "--out", "x"]));
    assert_stderr_has(&r, &["records no render time", "--time-per-view"]);
    let r = fails(
        t.path(),
        &with(&["--equal-time", "--time-per-view", "0", "--out", "x"]),
    );
    assert_stderr_has(&r, &["--time-per-view must be a positive number"]);
    let r = fails(
        t.path(),
        &with(&["--equal-time", "--spp", "8", "--out", "x"]),
    );
    assert_stderr_has(&r, &["--spp"]);
}

/// Completions and man pages come from the command line itself: every user command is in them,
/// the maintainers' `bench` is not, and a second `generate man` refuses to replace the pages.
#[test]
fn generate_writes_completions_and_man_pages() {
    let t = tmp();
    let d = t.path();
    for shell in ["bash", "zsh", "fish"] {
        let r = ok(d, &["generate", "completions", shell]);
        // `--init-sigma-t` (fish writes its long options as `-l init-sigma-t`).
        assert_stdout_has(&r, &["translucent", "optimize", "init-sigma-t"]);
    }
    let r = ok(d, &["generate", "man", "--out", "man"]);
    assert_stdout_has(&r, &["man pages"]);
    for page in [
        "translucent.1",
        "translucent-optimize.1",
        "translucent-experiment-robustness.1",
    ] {
        let text = std::fs::read_to_string(d.join("man").join(page)).unwrap();
        assert!(text.contains(".TH"), "{page} is not a man page");
    }
    assert!(!d.join("man/translucent-bench.1").exists());
    assert!(!d.join("man/translucent-help.1").exists());
    assert_stderr_has(
        &fails(d, &["generate", "man", "--out", "man"]),
        &["--overwrite"],
    );
    ok(d, &["generate", "man", "--out", "man", "--overwrite"]);
    // The main help lists the user's commands and not the maintainers' diagnostics.
    let help = ok(d, &["--help"]).stdout;
    assert!(help.contains("optimize") && help.contains("generate"));
    assert!(!help.contains("bench"), "{help}");
    assert!(
        help.lines().count() <= 30,
        "the main help is longer than a screen:\n{help}"
    );
}

/// `optimize --help` puts at most ~15 options before the first "Advanced" heading.
#[test]
fn optimize_help_shows_the_user_s_options_first() {
    let t = tmp();
    let help = ok(t.path(), &["optimize", "--help"]).stdout;
    let first_advanced = help
        .find("Advanced")
        .expect("optimize --help has an Advanced heading");
    let before = help[..first_advanced]
        .lines()
        // An option's line is indented by at most 6 spaces; its possible values by more.
        .filter(|l| l.trim_start().starts_with('-') && l.len() - l.trim_start().len() <= 6)
        .count();
    assert!(
        before <= 16,
        "{before} options before the first Advanced heading:\n{}",
        &help[..first_advanced]
    );
}
