//! Helpers of the end-to-end tests: running the binary, reading its outputs, tiny scenes,
//! meshes and datasets.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::{Value, json};

/// What one run of the binary produced.
pub struct Run {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    pub args: String,
}

impl Run {
    pub fn describe(&self) -> String {
        format!(
            "translucent {}\nexit code: {:?}\n--- stdout ---\n{}\n--- stderr ---\n{}",
            self.args, self.code, self.stdout, self.stderr
        )
    }
}

/// Run `translucent ARGS` in `dir`. Whatever the outcome, stderr must not show a panic.
pub fn translucent(dir: &Path, args: &[&str]) -> Run {
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
pub fn ok(dir: &Path, args: &[&str]) -> Run {
    let run = translucent(dir, args);
    assert_eq!(run.code, Some(0), "expected success:\n{}", run.describe());
    run
}

/// Run and require failure (exit code ≠ 0, an `error:` line on stderr); returns the run.
pub fn fails(dir: &Path, args: &[&str]) -> Run {
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
pub fn assert_stderr_has(run: &Run, needles: &[&str]) {
    assert_stream_has(run, "stderr", &run.stderr, needles);
}

/// Require every needle in the run's stdout.
pub fn assert_stdout_has(run: &Run, needles: &[&str]) {
    assert_stream_has(run, "stdout", &run.stdout, needles);
}

pub fn assert_stream_has(run: &Run, name: &str, text: &str, needles: &[&str]) {
    for n in needles {
        assert!(
            text.contains(n),
            "{name} should mention {n:?}:\n{}",
            run.describe()
        );
    }
}

pub fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().expect("cannot create a temporary folder")
}

pub fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

pub fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&read(p)).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

pub fn write(p: &Path, text: impl AsRef<[u8]>) {
    std::fs::write(p, text).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
}

/// A scene file (SCENE.md) with the given geometry line(s), medium values and first view width;
/// two explicit views, 8 pixels high. `extra` is appended to the top level.
pub fn scene_toml(
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

pub const SPHERE: &str = r#"shape = { name = "sphere", subdivisions = 2 }"#;

/// A valid two-view scene of a small sphere.
pub fn good_scene() -> String {
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
pub fn good_scene_json() -> String {
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
pub fn mesh_scene(mesh: &str) -> String {
    scene_toml(&format!("mesh = \"{mesh}\""), "60.0", "0.9", "1.0", 8, "")
}

/// A closed cube of side 0.8 centred at the origin, faces counter-clockwise seen from outside,
/// as an ASCII PLY.
pub fn cube_ply() -> String {
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
pub fn tetra_binary_ply() -> Vec<u8> {
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
pub fn make_dataset(dir: &Path, name: &str, views: &str, res: &str, extra: &[&str]) -> PathBuf {
    let mut args = vec![
        "-q", "dataset", "--shape", "sphere", "--views", views, "--res", res, "--spp", "4",
        "--out", name,
    ];
    args.extend_from_slice(extra);
    ok(dir, &args);
    dir.join(name)
}

/// `view_000.exr` … of two folders are byte-identical (`what` names the comparison).
pub fn assert_same_images(a: &Path, b: &Path, views: usize, what: &str) {
    for n in exr_names(views) {
        assert_eq!(read(&a.join(&n)), read(&b.join(&n)), "{n}: {what}");
    }
}

pub fn exr_names(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("view_{i:03}.exr")).collect()
}

/// The numbers of the table row of `name` printed by `compare` (9 columns: mean ratio R G B,
/// relative RMSE R G B, relMSE R G B).
pub fn compare_row(stdout: &str, name: &str) -> Vec<f64> {
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
