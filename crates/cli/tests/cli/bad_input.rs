//! Bad input: one test per case, each an error naming the file and field, never a panic.

use serde_json::json;

use super::helpers::*;

// ---------------------------------------------------------------------------------------------
// 4. bad input: one test per case

/// Write `scene.toml` with `text` into a new temporary folder, render it, require failure with
/// no output written; returns the run.
fn render_bad_scene(text: &str) -> Run {
    let t = tmp();
    write(&t.path().join("scene.toml"), text);
    let r = render_fails(t.path(), &["scene.toml"]);
    assert!(
        !t.path().join("out/view_000.exr").exists(),
        "an image was written for a bad scene"
    );
    r
}

/// `render scene.toml --out out` in `dir` fails, its message has `needles`, and `out` is not
/// created.
fn render_fails(dir: &std::path::Path, needles: &[&str]) -> Run {
    let r = fails(
        dir,
        &["-q", "render", "scene.toml", "--out", "out", "--spp", "2"],
    );
    assert_stderr_has(&r, needles);
    assert!(!dir.join("out").exists(), "{}", r.describe());
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
    render_fails(t.path(), &["scene.toml", "mesh", "shape", "fix:"]);
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
    render_fails(t.path(), &["trunc.ply", "PLY"]);
}

#[test]
fn bad_ply_face_index_out_of_range() {
    let t = tmp();
    let ply = cube_ply().replace("3 1 6 5\n", "3 1 6 8\n");
    assert_ne!(ply, cube_ply());
    write(&t.path().join("oob.ply"), ply);
    write(&t.path().join("scene.toml"), mesh_scene("oob.ply"));
    render_fails(t.path(), &["oob.ply", "face 11", "8", "out of range"]);
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
    render_fails(t.path(), &["nan.obj", "NaN", "vertex"]);
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
                "--model",
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

/// Negative numbers reach a validation that names the option: a negative count says it cannot
/// be negative (not clap's "unexpected argument '-1'"), a negative medium says what is wrong.
#[test]
fn negative_numbers_are_values_with_clear_errors() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    let r = fails(t.path(), &["-q", "render", "scene.toml", "--spp", "-1"]);
    assert_stderr_has(&r, &["--spp -1", "cannot be negative", "--spp 1"]);
    let r = fails(
        t.path(),
        &[
            "-q",
            "dataset",
            "--sigma-t",
            "-5",
            "--out",
            "d",
            "--views",
            "1",
        ],
    );
    assert_stderr_has(&r, &["sigma_t", "-5", "fix"]);
    assert!(!t.path().join("d").exists());
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

/// `dataset --shape SHAPE` (one 8² view into `ds`), which must fail.
fn dataset_of_shape_fails(dir: &std::path::Path, shape: &str) -> Run {
    fails(
        dir,
        &[
            "-q", "dataset", "--shape", shape, "--views", "1", "--res", "8", "--spp", "1", "--out",
            "ds",
        ],
    )
}

#[test]
fn bad_unknown_shape_name() {
    let t = tmp();
    let r = dataset_of_shape_fails(t.path(), "spheer");
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
    // A parameter the shape does not have, in the compact NAME:KEY=VALUE form.
    let r = dataset_of_shape_fails(t.path(), "sphere:major=1");
    assert_stderr_has(
        &r,
        &["--shape", "no parameter 'major'", "radius, subdivisions"],
    );
    assert!(!t.path().join("ds").exists());
}

/// `model curvature-table` refuses an empty simulation budget before any work, naming the option.
#[test]
fn bad_curvature_table_budget() {
    let t = tmp();
    let r = fails(
        t.path(),
        &[
            "-q",
            "model",
            "curvature-table",
            "c.json",
            "--collisions",
            "0",
        ],
    );
    assert_stderr_has(&r, &["--collisions"]);
    assert!(!t.path().join("c.json").exists());
}

/// `--scale` with a mesh file is refused with the fix, not silently ignored.
#[test]
fn bad_scale_with_a_mesh_file() {
    let t = tmp();
    write(&t.path().join("cube.ply"), cube_ply());
    let r = fails(
        t.path(),
        &[
            "dataset", "--mesh", "cube.ply", "--scale", "0.5", "--views", "1", "--res", "8",
            "--out", "ds",
        ],
    );
    assert_stderr_has(&r, &["--scale", "cube.ply", "built-in shapes"]);
}

/// `render --method` is an error that names `--model`, so that `--method` means only the
/// gradient estimator of `optimize`.
#[test]
fn render_method_points_to_model() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    let r = fails(
        t.path(),
        &[
            "-q",
            "render",
            "scene.toml",
            "--method",
            "learned",
            "--out",
            "o",
        ],
    );
    assert_stderr_has(&r, &["--method learned", "--model"]);
}

/// `--model` takes a model kind: a file name or a typo is an error listing the kinds (a learned
/// model's file goes to `--model-file`); a model file given to a model without networks is
/// refused, naming both flags.
#[test]
fn model_is_a_kind_and_model_file_a_learned_model_s_weights() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    let render = |model: &[&str]| {
        let base = ["-q", "render", "scene.toml", "--out", "o"];
        fails(t.path(), &[&base[..], model].concat())
    };
    for bad in ["volpth", "models/translucent-v2.safetensors"] {
        let r = render(&["--model", bad]);
        assert_stderr_has(&r, &["--model", bad, "learned, volpath, dipole"]);
    }
    let r = render(&["--model", "volpath", "--model-file", "m.safetensors"]);
    assert_stderr_has(
        &r,
        &["--model-file m.safetensors", "--model volpath", "learned"],
    );
    let r = render(&["--model", "learned", "--model-file", "missing.safetensors"]);
    assert_stderr_has(&r, &["missing.safetensors"]);
}

#[test]
fn bad_mitsuba_scene_names_the_line() {
    let t = tmp();
    write(
        &t.path().join("scene.xml"),
        r#"<scene version="3.0.0">
    <sensor type="perspective"><float name="fov" value="40"/></sensor>
    <emitter type="point"><point name="position" x="1" y="1" z="1"/></emitter>
    <shape type="ply">
        <string name="filename" value="object.ply"/>
        <bsdf type="roughdielectric"><float name="alpha" value="0.2"/></bsdf>
        <medium type="homogeneous" name="interior"/>
    </shape>
</scene>"#,
    );
    let r = fails(
        t.path(),
        &["-q", "render", "scene.xml", "--out", "out", "--spp", "2"],
    );
    // Mitsuba's default distribution is Beckmann; the rough boundary is GGX.
    assert_stderr_has(&r, &["scene.xml:6 <bsdf>", "beckmann", "ggx"]);
    assert!(!t.path().join("out").exists());
}

/// A dataset whose every pixel is black (the cameras inside an object scaled past them) is
/// refused before any iteration, with the fix, not fitted into NaN checks.
#[test]
fn bad_all_black_dataset() {
    let t = tmp();
    make_dataset(t.path(), "ds", "2", "8", &["--scale", "10"]);
    let r = fails(
        t.path(),
        &[
            "optimize",
            "--dataset",
            "ds",
            "--out",
            "o",
            "--iterations",
            "2",
        ],
    );
    assert_stderr_has(
        &r,
        &[
            "every pixel of all 2 views is black",
            "cameras see the object",
        ],
    );
}

/// `render --guided-walks` takes the share of guided walks, between 0 and 1: outside it is an
/// error that says so; inside it renders.
#[test]
fn render_guided_walks_is_a_share() {
    let t = tmp();
    write(&t.path().join("scene.toml"), good_scene());
    let args = |share: &str| format!("-q render scene.toml --out o --spp 2 --guided-walks {share}");
    let r = fails(t.path(), &args("1.5").split(' ').collect::<Vec<_>>());
    assert_stderr_has(&r, &["--guided-walks", "between 0 and 1"]);
    let image = t.path().join("o/view_000.exr");
    assert!(!image.exists(), "{}", r.describe());
    ok(t.path(), &args("0.5").split(' ').collect::<Vec<_>>());
    assert!(image.exists());
}
