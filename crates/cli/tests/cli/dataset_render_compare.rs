//! `dataset`, `render` and `compare`: outputs, determinism, overwrite protection.

use serde_json::json;

use super::helpers::*;

// ---------------------------------------------------------------------------------------------
// 1. dataset

#[test]
fn dataset_writes_folder_and_needs_overwrite_to_replace_it() {
    let t = tmp();
    let d = make_dataset(t.path(), "ds", "3", "12", &[]);
    for f in [
        "dataset.json",
        "view_000.exr",
        "view_000.png",
        "view_001.exr",
        "view_002.exr",
        "view_002.png",
    ] {
        assert!(d.join(f).is_file(), "{f} missing");
    }
    assert!(!d.join("view_003.exr").exists());
    let j = read_json(&d.join("dataset.json"));
    assert_eq!(j["format"], "translucent-dataset");
    assert_eq!(j["version"], 1);
    assert_eq!(j["shape"]["name"], "sphere");
    assert_eq!(j["views"].as_array().unwrap().len(), 3);
    assert_eq!(j["views"][0]["camera"]["width"], 12);
    assert_eq!(j["views"][0]["camera"]["height"], 12);
    assert_eq!(j["views"][2]["image"], "view_002.exr");
    assert_eq!(j["render"]["spp"], 4);
    assert_eq!(j["truth"]["sigma_t"], json!([60.0, 45.0, 35.0]));
    // The PNG preview is a PNG.
    assert_eq!(&read(&d.join("view_000.png"))[..8], b"\x89PNG\r\n\x1a\n");
    // Images are 12×12 with finite, non-zero radiance.
    let img = scene::Image::read_exr(&d.join("view_000.exr")).unwrap();
    assert_eq!((img.width, img.height), (12, 12));
    assert!(
        img.mean().iter().all(|m| m.is_finite() && *m > 0.0),
        "mean {:?}",
        img.mean()
    );

    // Again without --overwrite: refused, nothing changed.
    let before = read(&d.join("view_000.exr"));
    let json_before = read(&d.join("dataset.json"));
    let r = fails(
        t.path(),
        &[
            "-q", "dataset", "--shape", "sphere", "--views", "3", "--res", "12", "--spp", "4",
            "--seed", "9", "--out", "ds",
        ],
    );
    assert_stderr_has(&r, &["--overwrite", "ds"]);
    assert_eq!(read(&d.join("view_000.exr")), before);
    assert_eq!(read(&d.join("dataset.json")), json_before);

    // With --overwrite: replaced (another seed gives other images).
    ok(
        t.path(),
        &[
            "-q",
            "dataset",
            "--shape",
            "sphere",
            "--views",
            "3",
            "--res",
            "12",
            "--spp",
            "4",
            "--seed",
            "9",
            "--out",
            "ds",
            "--overwrite",
        ],
    );
    assert_ne!(read(&d.join("view_000.exr")), before);
    assert_eq!(read_json(&d.join("dataset.json"))["render"]["seed"], 9);
}

#[test]
fn dataset_random_medium_is_deterministic() {
    let t = tmp();
    let a = make_dataset(t.path(), "a", "2", "8", &["--random-medium", "--seed", "5"]);
    let b = make_dataset(t.path(), "b", "2", "8", &["--random-medium", "--seed", "5"]);
    let c = make_dataset(t.path(), "c", "2", "8", &["--random-medium", "--seed", "6"]);
    let (ja, jb, jc) = (
        read_json(&a.join("dataset.json")),
        read_json(&b.join("dataset.json")),
        read_json(&c.join("dataset.json")),
    );
    assert_eq!(ja["truth"], jb["truth"]);
    assert_eq!(ja["views"], jb["views"]);
    // Drawn from the paper's ranges, not the default medium, and depending on the seed.
    let truth = |key: &str| -> Vec<f64> {
        let values = ja["truth"][key].as_array().unwrap();
        values.iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let (sigma, albedo) = (truth("sigma_t"), truth("albedo"));
    assert!(
        sigma.iter().all(|s| (30.0..=100.0).contains(s)),
        "sigma_t {sigma:?}"
    );
    assert!(
        albedo.iter().all(|a| (0.8..=0.98).contains(a)),
        "albedo {albedo:?}"
    );
    assert_ne!(ja["truth"]["sigma_t"], json!([60.0, 45.0, 35.0]));
    assert_ne!(
        ja["truth"], jc["truth"],
        "another seed must give another medium"
    );
    assert_same_images(&a, &b, 2, "differs between two identical runs");
    for n in exr_names(2) {
        assert_ne!(
            read(&a.join(&n)),
            read(&c.join(&n)),
            "{n}: seeds 5 and 6 gave the same image"
        );
    }
}

#[test]
fn dataset_images_do_not_depend_on_thread_count() {
    let t = tmp();
    let one = make_dataset(t.path(), "t1", "2", "12", &["--threads", "1"]);
    let two = make_dataset(t.path(), "t2", "2", "12", &["--threads", "2"]);
    assert_same_images(&one, &two, 2, "--threads 1 and --threads 2 differ");
}

// ---------------------------------------------------------------------------------------------
// 2. render

#[test]
fn render_scene_file_toml_and_json_agree() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    write(&t.path().join("sphere.json"), good_scene_json());
    let r = ok(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "rt", "--spp", "4"],
    );
    assert_stdout_has(&r, &["rendered 2 view(s) at 4 spp"]);
    for f in [
        "view_000.exr",
        "view_000.png",
        "view_001.exr",
        "view_001.png",
    ] {
        assert!(t.path().join("rt").join(f).is_file(), "{f} missing");
    }
    for n in exr_names(2) {
        let img = scene::Image::read_exr(&t.path().join("rt").join(&n)).unwrap();
        assert_eq!((img.width, img.height), (8, 8));
        assert!(
            img.mean().iter().all(|m| m.is_finite() && *m > 0.0),
            "{n}: mean {:?}",
            img.mean()
        );
    }
    // The same scene written in JSON renders to the same bytes.
    ok(
        t.path(),
        &["-q", "render", "sphere.json", "--out", "rj", "--spp", "4"],
    );
    assert_same_images(
        &t.path().join("rt"),
        &t.path().join("rj"),
        2,
        "TOML and JSON scenes differ",
    );
    // Existing outputs are not replaced without --overwrite.
    let seed3 = [
        "-q",
        "render",
        "scene.toml",
        "--out",
        "rt",
        "--spp",
        "4",
        "--seed",
        "3",
    ];
    let r = fails(t.path(), &seed3);
    assert_stderr_has(&r, &["--overwrite", "view_000"]);
    ok(t.path(), &[&seed3[..], &["--overwrite"]].concat());
    assert_ne!(
        read(&t.path().join("rt/view_000.exr")),
        read(&t.path().join("rj/view_000.exr")),
        "--seed 3 --overwrite did not replace the image"
    );
}

/// SCENE.md: a scene file is TOML or JSON "chosen by the file extension", but `render` treats any
/// file named `scene.json` as the description of a Mitsuba reference folder
/// (crates/cli/src/render_cmd.rs, `run`: `n == "scene.json"` → `Dataset::load`), so a JSON scene
/// file with that natural name fails with "shape.mesh_file: missing".
#[test]
fn render_json_scene_file_named_scene_json() {
    let t = tmp();
    write(&t.path().join("scene.json"), good_scene_json());
    ok(
        t.path(),
        &["-q", "render", "scene.json", "--out", "r", "--spp", "2"],
    );
    assert!(t.path().join("r/view_001.exr").is_file());
}

#[test]
fn render_dataset_folder_reproduces_its_images() {
    let t = tmp();
    let d = make_dataset(t.path(), "ds", "2", "12", &["--seed", "4"]);
    // Default spp/seed/max_depth come from the dataset's render info: the same images result.
    let r = ok(t.path(), &["-q", "render", "ds", "--out", "r"]);
    assert_stdout_has(&r, &["rendered 2 view(s) at 4 spp"]);
    assert_same_images(
        &d,
        &t.path().join("r"),
        2,
        "re-render of the dataset differs",
    );
    // dataset.json itself is accepted too, and another seed changes the images.
    ok(
        t.path(),
        &[
            "-q",
            "render",
            "ds/dataset.json",
            "--out",
            "r2",
            "--seed",
            "5",
        ],
    );
    assert_ne!(
        read(&d.join("view_000.exr")),
        read(&t.path().join("r2/view_000.exr"))
    );
}

/// `render --derivatives`: the images are the plain render's, bit for bit; each view gets its
/// derivative images (EXR and PNG: σ_t, α and, from the tracer, g), finite, with ∂I/∂α ≥ 0
/// (more albedo, more light); a
/// second run into the same folder needs `--overwrite`; the learned model and the planar dipole
/// render them too (the dipole's ∂I/∂α ≥ 0 as well).
#[test]
fn render_derivatives_writes_the_plain_images_and_the_derivatives_of_each_view() {
    let t = tmp();
    make_dataset(t.path(), "ds", "2", "12", &["--seed", "4"]);
    ok(t.path(), &["-q", "render", "ds", "--out", "plain"]);
    let args = ["-q", "render", "ds", "--out", "d", "--derivatives"];
    ok(t.path(), &args);
    assert_same_images(
        &t.path().join("plain"),
        &t.path().join("d"),
        2,
        "the render with derivatives changed the image",
    );
    for v in 0..2 {
        for what in ["d_sigma_t", "d_albedo", "d_g"] {
            let stem = t.path().join(format!("d/view_{v:03}_{what}"));
            assert!(
                stem.with_extension("png").is_file(),
                "{what} PNG of view {v}"
            );
            let img = scene::Image::read_exr(&stem.with_extension("exr")).unwrap();
            assert!(img.data.iter().flatten().all(|x| x.is_finite()));
            assert!(
                img.data.iter().flatten().any(|x| *x != 0.0),
                "{what} of view {v} is 0"
            );
            if what == "d_albedo" {
                assert!(img.data.iter().flatten().all(|x| *x >= 0.0));
            }
        }
    }
    let again = fails(t.path(), &args);
    assert_stderr_has(&again, &["--overwrite"]);
    ok(
        t.path(),
        &[
            "-q",
            "render",
            "ds",
            "--out",
            "l",
            "--derivatives",
            "--model",
            "learned",
            "--spp",
            "2",
        ],
    );
    assert!(t.path().join("l/view_001_d_sigma_t.exr").is_file());
    // The learned model does not differentiate the phase function.
    assert!(!t.path().join("l/view_001_d_g.exr").exists());
    let args = [
        "-q",
        "render",
        "ds",
        "--out",
        "p",
        "--derivatives",
        "--model",
        "dipole",
    ];
    ok(t.path(), &args);
    let img = scene::Image::read_exr(&t.path().join("p/view_001_d_albedo.exr")).unwrap();
    assert!(
        img.data
            .iter()
            .flatten()
            .all(|x| x.is_finite() && *x >= 0.0)
    );
    assert!(img.data.iter().flatten().any(|x| *x > 0.0));
}

// ---------------------------------------------------------------------------------------------
// 3. compare

#[test]
fn compare_prints_table_and_writes_diff() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    for (out, seed) in [("a", "1"), ("b", "2")] {
        let args = [
            "-q",
            "render",
            "scene.toml",
            "--out",
            out,
            "--spp",
            "4",
            "--seed",
            seed,
        ];
        ok(t.path(), &args);
    }

    // Folders, matched by name.
    let r = ok(t.path(), &["-q", "compare", "a", "b"]);
    assert_stdout_has(&r, &["mean ratio"]);
    for name in ["view_000", "view_001"] {
        let row = compare_row(&r.stdout, name);
        assert!(
            row[..3].iter().all(|x| *x > 0.5 && *x < 2.0),
            "{name}: mean ratios {row:?}"
        );
        assert!(
            row[3..6].iter().all(|x| *x > 0.0),
            "{name}: two seeds cannot give RMSE 0: {row:?}"
        );
    }

    // An image against itself: ratio 1, error 0.
    let r = ok(
        t.path(),
        &["-q", "compare", "a/view_000.exr", "a/view_000.exr"],
    );
    assert_eq!(
        compare_row(&r.stdout, "view_000"),
        [1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    );

    // An image twice as bright: ratio 2.
    let mut img = scene::Image::read_exr(&t.path().join("a/view_000.exr")).unwrap();
    img.scale(2.0);
    img.write_exr(&t.path().join("double.exr"), false).unwrap();
    let r = ok(t.path(), &["-q", "compare", "double.exr", "a/view_000.exr"]);
    let row = compare_row(&r.stdout, "double");
    assert!(row[..3].iter().all(|x| (x - 2.0).abs() < 1e-3), "{row:?}");

    // --diff writes one PNG per pair.
    ok(t.path(), &["-q", "compare", "a", "b", "--diff", "d"]);
    for name in ["view_000_diff.png", "view_001_diff.png"] {
        let png = read(&t.path().join("d").join(name));
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{name} is not a PNG");
    }
}

#[test]
fn compare_refuses_images_of_different_sizes() {
    let t = tmp();
    make_dataset(t.path(), "small", "1", "8", &[]);
    make_dataset(t.path(), "large", "1", "16", &[]);
    let r = fails(
        t.path(),
        &[
            "-q",
            "compare",
            "small/view_000.exr",
            "large/view_000.exr",
            "--diff",
            "d",
        ],
    );
    assert_stderr_has(&r, &["8×8", "16×16", "small/view_000.exr"]);
    assert!(!t.path().join("d/view_000_diff.png").exists());
}

#[test]
fn compare_missing_input_fails() {
    let t = tmp();
    make_dataset(t.path(), "a", "1", "8", &[]);
    let r = fails(
        t.path(),
        &["-q", "compare", "a/view_000.exr", "nothing_here.exr"],
    );
    assert_stderr_has(&r, &["nothing_here.exr"]);
}
