//! End-to-end tests of the `translucent` binary: every command on tiny images (8×8 … 16×16, a few
//! views, a few samples per pixel), determinism of the outputs, and the error messages for bad
//! input (exit code ≠ 0, the file and field named, never a panic).
//!
//! Each test works in its own temporary folder (the binary runs with that folder as its current
//! directory, so relative paths in the messages are short and nothing leaks into the repository).

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::{Value, json};

// ---------------------------------------------------------------------------------------------
// Helpers.

/// What one run of the binary produced.
struct Run {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    args: String,
}

impl Run {
    fn describe(&self) -> String {
        format!(
            "translucent {}\nexit code: {:?}\n--- stdout ---\n{}\n--- stderr ---\n{}",
            self.args, self.code, self.stdout, self.stderr
        )
    }
}

/// Run `translucent ARGS` in `dir`. Whatever the outcome, stderr must not show a panic.
fn translucent(dir: &Path, args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_translucent"))
        .args(args)
        .current_dir(dir)
        .env_remove("TRANSLUCENT_LOG")
        .env("NO_COLOR", "1")
        .output()
        .expect("cannot start the translucent binary");
    let run = Run {
        code: out.status.code(),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        args: args.join(" "),
    };
    assert!(
        !run.stderr.contains("panicked"),
        "the binary panicked:\n{}",
        run.describe()
    );
    assert!(
        run.code.is_some(),
        "the binary was killed by a signal:\n{}",
        run.describe()
    );
    run
}

/// Run and require success (exit code 0).
fn ok(dir: &Path, args: &[&str]) -> Run {
    let run = translucent(dir, args);
    assert_eq!(run.code, Some(0), "expected success:\n{}", run.describe());
    run
}

/// Run and require failure (exit code ≠ 0, an `error:` line on stderr); returns the run.
fn fails(dir: &Path, args: &[&str]) -> Run {
    let run = translucent(dir, args);
    assert_ne!(run.code, Some(0), "expected failure:\n{}", run.describe());
    assert!(
        run.stderr.contains("error"),
        "failure without an error message:\n{}",
        run.describe()
    );
    run
}

/// Require every needle in the run's stderr.
fn assert_stderr_has(run: &Run, needles: &[&str]) {
    assert_stream_has(run, "stderr", &run.stderr, needles);
}

/// Require every needle in the run's stdout.
fn assert_stdout_has(run: &Run, needles: &[&str]) {
    assert_stream_has(run, "stdout", &run.stdout, needles);
}

fn assert_stream_has(run: &Run, name: &str, text: &str, needles: &[&str]) {
    for n in needles {
        assert!(
            text.contains(n),
            "{name} should mention {n:?}:\n{}",
            run.describe()
        );
    }
}

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("cannot create a temporary folder")
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&read(p)).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn write(p: &Path, text: impl AsRef<[u8]>) {
    std::fs::write(p, text).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
}

/// A scene file (SCENE.md) with the given geometry line(s), medium values and first view width;
/// two explicit views, 8 pixels high. `extra` is appended to the top level.
fn scene_toml(
    geometry: &str,
    sigma_t: &str,
    albedo: &str,
    eta: &str,
    width: u32,
    extra: &str,
) -> String {
    format!(
        r#"{geometry}
{extra}
[medium]
sigma_t = {sigma_t}
albedo = {albedo}
eta = {eta}

[[views]]
camera = {{ origin = [0.0, 0.3, 2.0], target = [0.0, 0.0, 0.0], up = [0.0, 1.0, 0.0], fov = 40.0, width = {width}, height = 8 }}
light = {{ position = [1.0, 1.5, 1.0], intensity = [4.0, 4.0, 4.0] }}

[[views]]
camera = {{ origin = [2.0, 0.0, 0.0], target = [0.0, 0.0, 0.0], width = 8, height = 8 }}
light = {{ position = [2.0, 0.2, 0.0], intensity = 4.0 }}
"#
    )
}

const SPHERE: &str = r#"shape = { name = "sphere", subdivisions = 2 }"#;

/// A valid two-view scene of a small sphere.
fn good_scene() -> String {
    scene_toml(
        SPHERE,
        "[50.0, 60.0, 70.0]",
        "[0.95, 0.9, 0.85]",
        "1.0",
        8,
        "",
    )
}

/// The same scene as [`good_scene`] in JSON.
fn good_scene_json() -> String {
    json!({
        "shape": { "name": "sphere", "subdivisions": 2 },
        "medium": { "sigma_t": [50.0, 60.0, 70.0], "albedo": [0.95, 0.9, 0.85], "eta": 1.0 },
        "views": [
            { "camera": { "origin": [0.0, 0.3, 2.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0], "fov": 40.0, "width": 8, "height": 8 },
              "light": { "position": [1.0, 1.5, 1.0], "intensity": [4.0, 4.0, 4.0] } },
            { "camera": { "origin": [2.0, 0.0, 0.0], "target": [0.0, 0.0, 0.0], "width": 8, "height": 8 },
              "light": { "position": [2.0, 0.2, 0.0], "intensity": 4.0 } }
        ]
    })
    .to_string()
}

/// A scene file referencing `mesh` (relative to the scene file).
fn mesh_scene(mesh: &str) -> String {
    scene_toml(&format!("mesh = \"{mesh}\""), "60.0", "0.9", "1.0", 8, "")
}

/// A closed cube of side 0.8 centred at the origin, faces counter-clockwise seen from outside,
/// as an ASCII PLY.
fn cube_ply() -> String {
    let v = [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
    ];
    let f = [
        [0, 3, 2],
        [0, 2, 1],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [3, 7, 6],
        [3, 6, 2],
        [0, 4, 7],
        [0, 7, 3],
        [1, 2, 6],
        [1, 6, 5],
    ];
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        v.len(),
        f.len()
    );
    for p in v {
        s += &format!(
            "{} {} {}\n",
            0.4 * p[0] as f32,
            0.4 * p[1] as f32,
            0.4 * p[2] as f32
        );
    }
    for t in f {
        s += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    s
}

/// A binary little-endian PLY of a tetrahedron (4 vertices, 4 faces), whole.
fn tetra_binary_ply() -> Vec<u8> {
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for p in [
        [0.0f32, 0.0, 0.0],
        [0.5, 0.0, 0.0],
        [0.0, 0.5, 0.0],
        [0.0, 0.0, 0.5],
    ] {
        for x in p {
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    for t in [[0i32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
        b.push(3);
        for i in t {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    b
}

/// `dataset` of a sphere into `dir/name` with extra arguments; returns the folder.
fn make_dataset(dir: &Path, name: &str, views: &str, res: &str, extra: &[&str]) -> PathBuf {
    let mut args = vec![
        "-q", "dataset", "--shape", "sphere", "--views", views, "--res", res, "--spp", "4",
        "--out", name,
    ];
    args.extend_from_slice(extra);
    ok(dir, &args);
    dir.join(name)
}

fn exr_names(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("view_{i:03}.exr")).collect()
}

/// The numbers of the table row of `name` printed by `compare` (9 columns: mean ratio R G B,
/// relative RMSE R G B, relMSE R G B).
fn compare_row(stdout: &str, name: &str) -> Vec<f64> {
    let line = stdout
        .lines()
        .find(|l| l.split_whitespace().next() == Some(name))
        .unwrap_or_else(|| panic!("no row {name} in:\n{stdout}"));
    let v: Vec<f64> = line
        .split_whitespace()
        .skip(1)
        .map(|x| {
            x.parse()
                .unwrap_or_else(|e| panic!("{x:?} in {line:?}: {e}"))
        })
        .collect();
    assert_eq!(v.len(), 9, "row {line:?}");
    v
}

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
    let sigma: Vec<f64> = ja["truth"]["sigma_t"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let albedo: Vec<f64> = ja["truth"]["albedo"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
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
    for n in exr_names(2) {
        assert_eq!(
            read(&a.join(&n)),
            read(&b.join(&n)),
            "{n} differs between two identical runs"
        );
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
    for n in exr_names(2) {
        assert_eq!(
            read(&one.join(&n)),
            read(&two.join(&n)),
            "{n}: --threads 1 and --threads 2 differ"
        );
    }
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
    for n in exr_names(2) {
        assert_eq!(
            read(&t.path().join("rt").join(&n)),
            read(&t.path().join("rj").join(&n)),
            "{n}: TOML and JSON scenes differ"
        );
    }
    // Existing outputs are not replaced without --overwrite.
    let r = fails(
        t.path(),
        &[
            "-q",
            "render",
            "scene.toml",
            "--out",
            "rt",
            "--spp",
            "4",
            "--seed",
            "3",
        ],
    );
    assert_stderr_has(&r, &["--overwrite", "view_000"]);
    ok(
        t.path(),
        &[
            "-q",
            "render",
            "scene.toml",
            "--out",
            "rt",
            "--spp",
            "4",
            "--seed",
            "3",
            "--overwrite",
        ],
    );
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
    for n in exr_names(2) {
        assert_eq!(
            read(&d.join(&n)),
            read(&t.path().join("r").join(&n)),
            "{n}: re-render of the dataset differs"
        );
    }
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

// ---------------------------------------------------------------------------------------------
// 3. compare

#[test]
fn compare_prints_table_and_writes_diff() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    ok(
        t.path(),
        &[
            "-q",
            "render",
            "scene.toml",
            "--out",
            "a",
            "--spp",
            "4",
            "--seed",
            "1",
        ],
    );
    ok(
        t.path(),
        &[
            "-q",
            "render",
            "scene.toml",
            "--out",
            "b",
            "--spp",
            "4",
            "--seed",
            "2",
        ],
    );

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

// ---------------------------------------------------------------------------------------------
// 4. bad input: one test per case

/// Write `scene.toml` with `text` into a new temporary folder, render it, require failure with
/// no output written; returns the run.
fn render_bad_scene(text: &str) -> Run {
    let t = tmp();
    write(&t.path().join("scene.toml"), text);
    let r = fails(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "out", "--spp", "2"],
    );
    assert!(
        !t.path().join("out/view_000.exr").exists(),
        "an image was written for a bad scene"
    );
    assert_stderr_has(&r, &["scene.toml"]);
    r
}

#[test]
fn bad_missing_scene_file() {
    let t = tmp();
    let r = fails(
        t.path(),
        &["-q", "render", "no_such_scene.toml", "--out", "out"],
    );
    assert_stderr_has(&r, &["no_such_scene.toml"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_negative_sigma_t() {
    let r = render_bad_scene(&scene_toml(
        SPHERE,
        "[60.0, -3.0, 50.0]",
        "0.9",
        "1.0",
        8,
        "",
    ));
    assert_stderr_has(&r, &["medium.sigma_t[1]", "-3", "fix:"]);
}

#[test]
fn bad_albedo_above_one() {
    let r = render_bad_scene(&scene_toml(SPHERE, "60.0", "1.5", "1.0", 8, ""));
    assert_stderr_has(&r, &["albedo", "1.5", "fix:"]);
}

#[test]
fn bad_eta_below_one() {
    let r = render_bad_scene(&scene_toml(SPHERE, "60.0", "0.9", "0.5", 8, ""));
    assert_stderr_has(&r, &["medium.eta", "0.5", "fix:"]);
}

#[test]
fn bad_zero_width() {
    let r = render_bad_scene(&scene_toml(SPHERE, "60.0", "0.9", "1.0", 0, ""));
    assert_stderr_has(&r, &["views[0].camera.width", "fix:"]);
}

#[test]
fn bad_unknown_field() {
    let r = render_bad_scene(&scene_toml(SPHERE, "60.0", "0.9", "1.0", 8, "colour = 3"));
    assert_stderr_has(&r, &["colour", "unknown field", "line 2"]);
}

#[test]
fn bad_both_mesh_and_shape() {
    let t = tmp();
    write(&t.path().join("cube.ply"), cube_ply());
    write(
        &t.path().join("scene.toml"),
        scene_toml(SPHERE, "60.0", "0.9", "1.0", 8, "mesh = \"cube.ply\""),
    );
    let r = fails(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "out", "--spp", "2"],
    );
    assert_stderr_has(&r, &["scene.toml", "mesh", "shape", "fix:"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_mesh_file_missing() {
    let r = render_bad_scene(&mesh_scene("no_such_mesh.ply"));
    assert_stderr_has(&r, &["no_such_mesh.ply", "not found", "fix:"]);
}

#[test]
fn bad_truncated_binary_ply() {
    let t = tmp();
    let whole = tetra_binary_ply();
    write(&t.path().join("whole.ply"), &whole);
    write(&t.path().join("trunc.ply"), &whole[..whole.len() - 30]);
    // The whole file renders, so the failure below is the truncation.
    write(&t.path().join("good.toml"), mesh_scene("whole.ply"));
    ok(
        t.path(),
        &["-q", "render", "good.toml", "--out", "good", "--spp", "1"],
    );
    write(&t.path().join("scene.toml"), mesh_scene("trunc.ply"));
    let r = fails(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "out", "--spp", "2"],
    );
    assert_stderr_has(&r, &["trunc.ply", "PLY"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_ply_face_index_out_of_range() {
    let t = tmp();
    let ply = cube_ply().replace("3 1 6 5\n", "3 1 6 8\n");
    assert_ne!(ply, cube_ply());
    write(&t.path().join("oob.ply"), ply);
    write(&t.path().join("scene.toml"), mesh_scene("oob.ply"));
    let r = fails(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "out", "--spp", "2"],
    );
    assert_stderr_has(&r, &["oob.ply", "face 11", "8", "out of range"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_obj_with_nan_vertex() {
    let t = tmp();
    // Faces list the vertices in file order, so vertex numbering is unambiguous.
    write(
        &t.path().join("nan.obj"),
        "v 0 0 0\nv 0.5 0 0\nv 0 nan 0\nv 0 0 0.5\nf 1 2 3\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    write(&t.path().join("scene.toml"), mesh_scene("nan.obj"));
    let r = fails(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "out", "--spp", "2"],
    );
    assert_stderr_has(&r, &["nan.obj", "NaN", "vertex"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_dataset_image_of_wrong_size() {
    let t = tmp();
    let d = make_dataset(t.path(), "ds", "2", "8", &[]);
    let big = make_dataset(t.path(), "big", "1", "16", &[]);
    std::fs::copy(big.join("view_000.exr"), d.join("view_001.exr")).unwrap();
    let r = fails(t.path(), &["-q", "render", "ds", "--out", "out"]);
    assert_stderr_has(
        &r,
        &[
            "dataset.json",
            "views[1].image",
            "view_001.exr",
            "16×16",
            "8×8",
            "fix:",
        ],
    );
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_dataset_image_with_nan_pixel() {
    let t = tmp();
    let d = make_dataset(t.path(), "ds", "2", "8", &[]);
    let p = d.join("view_001.exr");
    let mut img = scene::Image::read_exr(&p).unwrap();
    img.set(3, 5, [0.1, f32::NAN, 0.1]);
    img.write_exr(&p, true).unwrap();
    let r = fails(t.path(), &["-q", "render", "ds", "--out", "out"]);
    assert_stderr_has(&r, &["view_001.exr", "x=3", "y=5", "NaN"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_dataset_json_field() {
    let t = tmp();
    let d = make_dataset(t.path(), "ds", "2", "8", &[]);
    let mut j = read_json(&d.join("dataset.json"));
    j["truth"]["sigma_t"] = json!([60.0, -45.0, 35.0]);
    write(
        &d.join("dataset.json"),
        serde_json::to_string_pretty(&j).unwrap(),
    );
    let r = fails(t.path(), &["-q", "render", "ds", "--out", "out"]);
    assert_stderr_has(&r, &["dataset.json", "truth.sigma_t[1]", "fix:"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_dataset_camera_size_edited() {
    let t = tmp();
    let d = make_dataset(t.path(), "ds", "2", "8", &[]);
    let mut j = read_json(&d.join("dataset.json"));
    j["views"][0]["camera"]["width"] = json!(9);
    write(
        &d.join("dataset.json"),
        serde_json::to_string_pretty(&j).unwrap(),
    );
    let r = fails(t.path(), &["-q", "render", "ds", "--out", "out"]);
    assert_stderr_has(&r, &["views[0].image", "8×8", "9×8"]);
}

#[test]
fn bad_spp_zero() {
    let t = tmp();
    let r = fails(
        t.path(),
        &[
            "-q", "dataset", "--shape", "sphere", "--views", "1", "--res", "8", "--spp", "0",
            "--out", "ds",
        ],
    );
    assert_stderr_has(&r, &["--spp"]);
    assert!(!t.path().join("ds").exists());
    write(&t.path().join("scene.toml"), good_scene());
    let r = fails(
        t.path(),
        &["-q", "render", "scene.toml", "--out", "out", "--spp", "0"],
    );
    assert_stderr_has(&r, &["--spp"]);
    assert!(!t.path().join("out").exists());
}

#[test]
fn bad_projection_reach() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    for reach in ["0", "-1", "nan", "inf", "two"] {
        let r = fails(
            t.path(),
            &[
                "-q",
                "render",
                "scene.toml",
                "--method",
                "learned",
                "--out",
                "out",
                "--max-dist-scale",
                reach,
            ],
        );
        assert_stderr_has(&r, &["--max-dist-scale", "σ_n"]);
        assert!(!t.path().join("out").exists());
    }
}

#[test]
fn bad_threads_zero() {
    let t = tmp();
    let r = fails(
        t.path(),
        &[
            "-q",
            "--threads",
            "0",
            "dataset",
            "--shape",
            "sphere",
            "--views",
            "1",
            "--res",
            "8",
            "--spp",
            "1",
            "--out",
            "ds",
        ],
    );
    assert_stderr_has(&r, &["--threads"]);
    assert!(!t.path().join("ds").exists());
}

#[test]
fn bad_unknown_shape_name() {
    let t = tmp();
    let r = fails(
        t.path(),
        &[
            "-q", "dataset", "--shape", "spheer", "--views", "1", "--res", "8", "--spp", "1",
            "--out", "ds",
        ],
    );
    assert_stderr_has(
        &r,
        &["spheer", "sphere", "cone", "torus", "rounded-box", "blob"],
    );
    assert!(!t.path().join("ds").exists());
    // The same in a scene file, which also names the field.
    let r = render_bad_scene(&scene_toml(
        r#"shape = { name = "spheer" }"#,
        "60.0",
        "0.9",
        "1.0",
        8,
        "",
    ));
    assert_stderr_has(
        &r,
        &[
            "shape.name",
            "spheer",
            "sphere",
            "cone",
            "torus",
            "rounded-box",
            "blob",
        ],
    );
}

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
    let first = read(&d.join("view_000.exr"));
    // The demo may overwrite its own folder; same arguments, same images.
    ok(t.path(), &args);
    assert_eq!(read(&d.join("view_000.exr")), first);
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
        "generator": "tests/cli.rs (synthetic reference)",
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

#[test]
fn validate_mitsuba_passes_on_matching_reference() {
    let t = tmp();
    mitsuba_reference(t.path(), "ref", 1.0);
    let r = ok(
        t.path(),
        &[
            "-q",
            "validate-mitsuba",
            "ref",
            "--spp",
            "8",
            "--seed",
            "3",
            "--out",
            "ours",
        ],
    );
    assert_stdout_has(&r, &["all 2 views within tolerance"]);
    assert!(!r.stdout.contains("FAIL"), "{}", r.describe());
    for n in exr_names(2) {
        assert!(t.path().join("ours").join(&n).is_file(), "{n} missing");
    }
    // Running again needs --overwrite for the output folder.
    let r = fails(
        t.path(),
        &[
            "-q",
            "validate-mitsuba",
            "ref",
            "--spp",
            "8",
            "--seed",
            "3",
            "--out",
            "ours",
        ],
    );
    assert_stderr_has(&r, &["--overwrite"]);
    // The reference folder is also a dataset for `render`: its truth renders to the same images.
    ok(t.path(), &["-q", "render", "ref", "--out", "rr"]);
    for n in exr_names(2) {
        assert_eq!(
            read(&t.path().join("rr").join(&n)),
            read(&t.path().join("ref").join(&n)),
            "{n}"
        );
    }
}

#[test]
fn validate_mitsuba_fails_when_reference_is_twice_as_bright() {
    let t = tmp();
    mitsuba_reference(t.path(), "ref", 0.5);
    let r = fails(
        t.path(),
        &[
            "-q",
            "validate-mitsuba",
            "ref",
            "--spp",
            "8",
            "--seed",
            "3",
            "--out",
            "ours",
        ],
    );
    assert_stderr_has(&r, &["outside tolerance"]);
    assert_stdout_has(&r, &["FAIL"]);
    // Our render at half the light is half the reference: mean ratio 0.5.
    assert_stdout_has(&r, &["0.5000"]);
}

// ---------------------------------------------------------------------------------------------
// Training (issue #4): data, fit, resume, the shipped model.

#[test]
fn train_data_fit_resume_and_use_the_model() {
    let t = tmp();
    let d = t.path();
    let data_args = [
        "train",
        "data",
        "--out",
        "data",
        "--meshes",
        "1",
        "--val-meshes",
        "1",
        "--configs-per-mesh",
        "20",
        "--path-attempts",
        "64",
        "--seed",
        "1",
    ];
    let r = ok(d, &data_args);
    assert_stdout_has(&r, &["train: 320 samples"]);
    let first = read(&d.join("data/train.tlsamples"));
    // Same seed, same bytes; existing files are protected.
    let again = fails(d, &data_args);
    assert_stderr_has(&again, &["train.tlsamples", "--overwrite"]);
    let mut with_overwrite = data_args.to_vec();
    with_overwrite.push("--overwrite");
    ok(d, &with_overwrite);
    // Same records (the JSON header also holds the creation time, so compare after it:
    // magic 8 bytes, version u32, header length u32, header, records).
    let records = |b: &[u8]| {
        let n = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        b[16 + n..].to_vec()
    };
    assert_eq!(
        records(&read(&d.join("data/train.tlsamples"))),
        records(&first)
    );

    let fit = [
        "train",
        "fit",
        "--data",
        "data",
        "--out",
        "m",
        "--steps",
        "40",
        "--batch",
        "32",
        "--eval-every",
        "20",
        "--checkpoint-every",
        "20",
        "--widths",
        "F=8,8;A=4;D=8;E=8",
    ];
    ok(d, &fit);
    for f in [
        "model.safetensors",
        "checkpoint.bin",
        "history.csv",
        "loss.png",
        "train.json",
    ] {
        assert!(d.join("m").join(f).exists(), "missing {f}");
    }
    let history = String::from_utf8(read(&d.join("m/history.csv"))).unwrap();
    assert_eq!(history.lines().count(), 1 + 3, "{history}");
    // A second fit into the same folder needs --resume or --overwrite.
    let r = fails(d, &fit);
    assert_stderr_has(&r, &["--resume", "--overwrite"]);
    let mut resume: Vec<&str> = fit.to_vec();
    resume[7] = "60"; // --steps 60
    resume.push("--resume");
    let r = ok(d, &resume);
    assert_stdout_has(&r, &["trained 60 steps (20 this run)"]);
    let info = ok(d, &["model", "info", "m/model.safetensors"]);
    assert_stdout_has(&info, &["translucent train fit"]);
}

#[test]
fn train_fit_without_data_and_damaged_models_are_clear_errors() {
    let t = tmp();
    let d = t.path();
    let r = fails(d, &["train", "fit", "--data", "nothing", "--out", "m"]);
    assert_stderr_has(&r, &["nothing/train.tlsamples", "translucent train data"]);
    write(&d.join("bad.safetensors"), b"not a model at all");
    let r = fails(d, &["model", "info", "bad.safetensors"]);
    assert_stderr_has(&r, &["bad.safetensors"]);
    let r = fails(d, &["model", "info", "missing.safetensors"]);
    assert_stderr_has(&r, &["missing.safetensors", "does not exist"]);
}

#[test]
fn shipped_model_is_built_in_and_valid() {
    let t = tmp();
    let r = ok(t.path(), &["model", "info", "shipped"]);
    assert_stdout_has(&r, &["translucent train fit"]);
}

// ---------------------------------------------------------------------------------------------
// Inverse rendering (issue #5): optimize, resume, gradcheck.

#[test]
fn optimize_writes_results_resumes_and_gradcheck_runs() {
    let t = tmp();
    let d = t.path();
    ok(
        d,
        &[
            "dataset",
            "--shape",
            "sphere",
            "--views",
            "2",
            "--res",
            "12",
            "--spp",
            "4",
            "--sigma-t",
            "60",
            "--albedo",
            "0.9",
            "--out",
            "ds",
        ],
    );
    let opt = [
        "optimize",
        "--dataset",
        "ds",
        "--out",
        "o",
        "--iterations",
        "3",
        "--spp",
        "2",
        "--final-spp",
        "2",
        "--checkpoint-every",
        "2",
    ];
    let r = ok(d, &opt);
    assert_stdout_has(&r, &["truth"]);
    let res = read_json(&d.join("o/result.json"));
    for k in [
        "estimate",
        "truth",
        "iterations",
        "spp",
        "seconds_per_iteration",
        "seconds_total",
        "method",
        "seed",
    ] {
        assert!(res.get(k).is_some(), "result.json lacks {k}: {res}");
    }
    assert_eq!(res["iterations"], 3);
    assert_eq!(res["method"], "ours");
    assert_eq!(res["estimate"]["sigma_t"].as_array().unwrap().len(), 3);
    for f in [
        "iterations.csv",
        "convergence.png",
        "checkpoint.json",
        "final/view_000.png",
        "final/view_000_diff.png",
    ] {
        assert!(d.join("o").join(f).exists(), "missing {f}");
    }
    let again = fails(d, &opt);
    assert_stderr_has(&again, &["--resume", "--overwrite"]);
    let mut resume: Vec<&str> = opt.to_vec();
    resume[6] = "5"; // --iterations 5
    resume.push("--resume");
    ok(d, &resume);
    assert_eq!(read_json(&d.join("o/result.json"))["iterations"], 5);
    let bad = fails(
        d,
        &[
            "optimize",
            "--dataset",
            "ds",
            "--out",
            "o2",
            "--method",
            "magic",
        ],
    );
    assert_stderr_has(&bad, &["magic", "ours"]);

    let r = ok(
        d,
        &["gradcheck", "--dataset", "ds", "--spp", "2", "--out", "g"],
    );
    assert_stdout_has(&r, &["naive", "fd"]);
    for f in [
        "gradcheck.csv",
        "ours_d_sigma_t.png",
        "fd_d_albedo.png",
        "naive_d_sigma_t.exr",
    ] {
        assert!(d.join("g").join(f).exists(), "missing {f}");
    }
}

// ---------------------------------------------------------------------------------------------
// experiment accuracy

/// `optimize --bias-correction --bias-correction-steps 2`: each step simulates the dataset at
/// the previous medium (θ̂, then θ₁) with the dataset's own spp, recovers from it with the same
/// settings, and `result.json` reports θ₂ = θ₁ + θ̂ − θ̂₂' as `estimate` beside the optimiser's
/// own; `--resume` reuses the steps, `--overwrite` drops them.
#[test]
fn optimize_bias_correction_reports_the_iterated_correction() {
    let t = tmp();
    let d = t.path();
    make_dataset(d, "ds", "2", "12", &["--sigma-t", "60", "--albedo", "0.9"]);
    let mut args = vec![
        "-q",
        "optimize",
        "--dataset",
        "ds",
        "--out",
        "o",
        "--iterations",
        "3",
        "--spp",
        "2",
        "--final-spp",
        "2",
        "--bias-correction",
        "--bias-correction-steps",
        "2",
    ];
    let run = ok(d, &args);
    assert_stdout_has(
        &run,
        &[
            "bootstrap step 2:",
            "bias-corrected (2 steps, simulations at 4 spp)",
        ],
    );
    let r = read_json(&d.join("o/result.json"));
    let num = |v: &Value, k: &str, c: usize| v[k][c].as_f64().unwrap();
    let est = r["estimate_uncorrected"].clone();
    let steps = r["bias_correction"]["steps"].as_array().unwrap().clone();
    assert_eq!(steps.len(), 2);
    assert_eq!(r["bias_correction"]["simulation_spp"], 4);
    let mut current = est.clone();
    for (k, step) in steps.iter().enumerate() {
        let dir = d.join(format!("o/bootstrap/step-{}", k + 1));
        let sim = read_json(&dir.join("data/dataset.json"));
        let refit = read_json(&dir.join("run/result.json"))["estimate"].clone();
        for c in 0..3 {
            for key in ["sigma_t", "albedo"] {
                // Simulated at the previous medium; the step records it and its recovery.
                let (a, b) = (num(&sim["truth"], key, c), num(&current, key, c));
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs(),
                    "step {k} {key}[{c}]: {a} vs {b}"
                );
                assert_eq!(step["recovered"][key][c], refit[key][c]);
            }
            // θ_k = θ_{k−1} + θ̂ − θ̂_k in (ln σ_t, α).
            let s = (num(&current, "sigma_t", c).ln() + num(&est, "sigma_t", c).ln()
                - num(&refit, "sigma_t", c).ln())
            .exp();
            let a = (num(&current, "albedo", c) + num(&est, "albedo", c)
                - num(&refit, "albedo", c))
            .clamp(1e-4, 0.99995);
            let got = &step["corrected"];
            assert!((num(got, "sigma_t", c) - s).abs() <= 1e-9 * s, "σ_t[{c}]");
            assert!((num(got, "albedo", c) - a).abs() <= 1e-9, "α[{c}]");
        }
        current = step["corrected"].clone();
    }
    assert_eq!(r["estimate"], current);
    let rel = num(&r["errors"], "sigma_t_relative", 0);
    assert!((rel - (num(&current, "sigma_t", 0) / 60.0 - 1.0)).abs() < 1e-12);
    assert!(r["errors_uncorrected"]["sigma_t_relative"].is_array());

    // --resume reuses both steps and reports the same correction.
    args.push("--resume");
    let again = ok(d, &args);
    assert_stdout_has(
        &again,
        &[
            "bootstrap step 1: reusing",
            "run bootstrap step 2 (ours): reusing",
        ],
    );
    assert_eq!(
        read_json(&d.join("o/result.json"))["estimate"],
        r["estimate"]
    );
    // --overwrite starts again: one step now, and the second step's folder is gone.
    let one_step = [&args[..args.len() - 3], &["--overwrite"]].concat();
    assert_eq!(one_step[one_step.len() - 2], "--bias-correction");
    ok(d, &one_step);
    assert!(d.join("o/bootstrap/step-1/run/result.json").exists());
    assert!(!d.join("o/bootstrap/step-2").exists());
}

/// `experiment accuracy` on a tiny sphere case (2 views of 12², 3 iterations), quiet, into
/// `exp`, with `extra` arguments.
fn tiny_accuracy_args<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "experiment",
        "accuracy",
        "--out",
        "exp",
        "--shapes",
        "sphere",
        "--media",
        "1",
        "--views",
        "2",
        "--res",
        "12",
        "--target-spp",
        "4",
        "--iterations",
        "3",
        "--spp",
        "2",
        "-q",
    ];
    args.extend_from_slice(extra);
    args
}

/// `--bias-correction --bias-correction-steps 2`: step 1 renders at the estimate θ̂ and reports
/// 2θ̂ − θ̂₂ (`ours+bc`); step 2 renders at that correction θ₁ and reports θ₁ + θ̂ − θ̂₂'
/// (`ours+bc2`), all in (ln σ_t, α).
#[test]
fn experiment_bias_correction_refits_at_the_estimate() {
    let d = tmp();
    let args = tiny_accuracy_args(&[
        "--inits",
        "0",
        "--methods",
        "ours",
        "--bias-correction",
        "--bias-correction-steps",
        "2",
    ]);
    let run = ok(d.path(), &args);
    assert_stdout_has(
        &run,
        &[
            "| sphere-m0 | ours |",
            "| sphere-m0 | ours+bc |",
            "| sphere-m0 | ours+bc2 |",
            "bias of ours on sphere-m0",
        ],
    );
    let exp = d.path().join("exp");
    let estimate =
        |run: &str| read_json(&exp.join("runs").join(run).join("result.json"))["estimate"].clone();
    let num = |v: &Value, k: &str, c: usize| v[k][c].as_f64().unwrap();
    let csv = String::from_utf8(read(&exp.join("results.csv"))).unwrap();
    // σ_t[3], α[3] of a method's row in results.csv.
    let row = |method: &str| -> Value {
        let v: Vec<f64> = csv
            .lines()
            .find(|l| l.starts_with(&format!("sphere-m0,{method},")))
            .unwrap_or_else(|| panic!("{csv}"))
            .split(',')
            .skip(14)
            .take(6)
            .map(|v| v.parse().unwrap())
            .collect();
        serde_json::json!({ "sigma_t": v[..3], "albedo": v[3..] })
    };
    let est = estimate("sphere-m0-ours");
    let mut current = est.clone();
    for (step, (data, run, method)) in [
        ("sphere-m0-boot-ours", "sphere-m0-ours-boot", "ours+bc"),
        ("sphere-m0-boot2-ours", "sphere-m0-ours-boot2", "ours+bc2"),
    ]
    .into_iter()
    .enumerate()
    {
        // The bootstrap dataset of this step was rendered at the previous step's medium.
        let boot = read_json(&exp.join("data").join(data).join("dataset.json"));
        for c in 0..3 {
            for k in ["sigma_t", "albedo"] {
                let (a, b) = (num(&boot["truth"], k, c), num(&current, k, c));
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs(),
                    "step {step} {k}[{c}]: {a} vs {b}"
                );
            }
        }
        // θ_k = θ_{k−1} + θ̂ − θ̂_k in (ln σ_t, α).
        let refit = estimate(run);
        let got = row(method);
        for c in 0..3 {
            let s = (num(&current, "sigma_t", c).ln() + num(&est, "sigma_t", c).ln()
                - num(&refit, "sigma_t", c).ln())
            .exp();
            let a = (num(&current, "albedo", c) + num(&est, "albedo", c)
                - num(&refit, "albedo", c))
            .clamp(1e-4, 0.99995);
            let (gs, ga) = (num(&got, "sigma_t", c), num(&got, "albedo", c));
            assert!((gs - s).abs() <= 1e-4 * s, "{method} σ_t[{c}]: {gs} vs {s}");
            assert!((ga - a).abs() <= 1e-5, "{method} α[{c}]: {ga} vs {a}");
        }
        current = got;
    }
}

#[test]
fn experiment_accuracy_writes_table_and_reuses_its_runs() {
    let d = tmp();
    let args = tiny_accuracy_args(&["--inits", "2", "--methods", "ours,naive"]);
    let first = ok(d.path(), &args);
    assert_stdout_has(
        &first,
        &[
            "| sphere-m0 | ours |",
            "| sphere-m0 | naive |",
            "| random inits | 2 |",
        ],
    );
    let csv = String::from_utf8(read(&d.path().join("exp/results.csv"))).unwrap();
    assert_eq!(csv.lines().count(), 1 + 2 + 2, "{csv}");
    assert!(d.path().join("exp/inits.png").exists());
    for run in [
        "sphere-m0-ours",
        "sphere-m0-naive",
        "sphere-m0-init0",
        "sphere-m0-init1",
    ] {
        let r = read_json(&d.path().join("exp/runs").join(run).join("result.json"));
        assert_eq!(r["iterations"], 3, "{run}");
    }
    // A second run reuses the datasets and the finished runs and prints the same table.
    let second = ok(d.path(), &args);
    assert_stdout_has(&second, &["dataset sphere-m0: reusing", "reusing"]);
    let table = |s: &str| {
        s.lines()
            .filter(|l| l.starts_with('|'))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(table(&first.stdout), table(&second.stdout));
    // Runs made with another schedule are not reused (nor continued): a clear error instead.
    let mut other = args.to_vec();
    other.extend(["--albedo-warmup", "1"]);
    let bad = fails(d.path(), &other);
    assert_stderr_has(&bad, &["other settings", "sphere-m0-ours"]);
    // So are runs made with another projection reach; the header names the learned settings.
    assert_stdout_has(
        &first,
        &["son24 projection (reach 8σ_n)", "half-space exit law"],
    );
    let mut other = args.to_vec();
    other.extend(["--max-dist-scale", "3"]);
    let bad = fails(d.path(), &other);
    assert_stderr_has(&bad, &["other settings", "learned"]);
    // The random initialisations go to the case named by --inits-case, which must exist.
    let mut other = args.to_vec();
    other.extend(["--inits-case", "sphere-m7"]);
    let bad = fails(d.path(), &other);
    assert_stderr_has(&bad, &["--inits-case", "sphere-m7", "sphere-m0"]);
    // Unknown shapes and methods are refused before any work.
    let bad = fails(
        d.path(),
        &["experiment", "accuracy", "--out", "x", "--shapes", "teapot"],
    );
    assert_stderr_has(&bad, &["teapot"]);
    let bad = fails(
        d.path(),
        &["experiment", "accuracy", "--out", "x", "--methods", "magic"],
    );
    assert_stderr_has(&bad, &["magic"]);
}
