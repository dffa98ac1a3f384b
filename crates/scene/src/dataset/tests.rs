//! Tests of dataset folders: save/load round trips, overwrite refusal, validation errors of
//! `dataset.json`, the object block, and the example of DATASET.md (Mitsuba reference folders:
//! `reference_tests.rs`).

use super::*;

pub(crate) fn image(w: u32, h: u32, seed: f32) -> Image {
    let mut img = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            img.set(
                x,
                y,
                [
                    seed + x as f32 * 0.01,
                    seed * 0.5 + y as f32 * 0.02,
                    0.001 * (x + y) as f32,
                ],
            );
        }
    }
    img
}

/// A scene (2 views, mesh file in `src`) turned into a dataset with images.
pub(crate) fn sample_dataset(src: &Path) -> Dataset {
    std::fs::write(
        src.join("object.ply"),
        b"ply\nformat ascii 1.0\nend_header\n",
    )
    .unwrap();
    let text = r#"
mesh = "object.ply"
medium = { sigma_t = [50, 60, 70], albedo = [0.95, 0.9, 0.85], g = 0.1, eta = 1.0 }
rig = { views = 2, radius = 0.5, width = 12, height = 8, light = "fixed", light_position = [0.3, 0.4, 0.1], intensity = 0.785 }
render = { spp = 64, max_depth = 32, seed = 3 }
"#;
    let scene = SceneDesc::parse(text, &src.join("scene.toml")).unwrap();
    let mut ds = Dataset::from_scene(&scene);
    for (i, v) in ds.views.iter_mut().enumerate() {
        v.image = Some(image(12, 8, 0.1 * (i + 1) as f32));
    }
    ds
}

pub(super) fn assert_same_views(a: &Dataset, b: &Dataset) {
    assert_eq!(a.views.len(), b.views.len());
    for (va, vb) in a.views.iter().zip(&b.views) {
        assert!((va.camera.origin - vb.camera.origin).length() < 1e-6);
        assert!((va.camera.rotation - vb.camera.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-6));
        assert_eq!(
            (va.camera.fov_x_deg, va.camera.width, va.camera.height),
            (vb.camera.fov_x_deg, vb.camera.width, vb.camera.height)
        );
        assert_eq!(va.light, vb.light);
        assert_eq!(va.image, vb.image);
    }
}

#[test]
fn save_load_round_trip() {
    let src = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("ds");
    let ds = sample_dataset(src.path());
    ds.save(&dir, false).unwrap();
    for f in [
        "dataset.json",
        "view_000.exr",
        "view_001.exr",
        "view_000.png",
        "view_001.png",
        "object.ply",
    ] {
        assert!(dir.join(f).is_file(), "{f} written");
    }
    let back = Dataset::load(&dir).unwrap();
    assert_eq!(back.kind, DatasetKind::Native);
    assert_eq!(back.mesh, MeshSource::File(dir.join("object.ply")));
    assert_eq!(back.truth, ds.truth);
    assert_eq!(back.render, ds.render);
    assert_eq!(back.metadata.generator, ds.metadata.generator);
    assert!(back.metadata.units.as_deref().unwrap().contains("W/sr"));
    assert_eq!(back.root, dir);
    assert_same_views(&ds, &back);
    assert_eq!(
        back.views[1].image_path.as_deref(),
        Some(dir.join("view_001.exr").as_path())
    );
    // The file itself also loads, and the scene built from it has the same cameras.
    let again = Dataset::load(&dir.join("dataset.json")).unwrap();
    assert_same_views(&back, &again);
    let scene = back.scene(back.truth.unwrap());
    assert_eq!(scene.views[0], back.views[0].desc());
    // Saving the loaded dataset into its own folder keeps the mesh where it is.
    back.save(&dir, true).unwrap();
    assert_same_views(&back, &Dataset::load(&dir).unwrap());
}

#[test]
fn shape_datasets_round_trip() {
    let src = tempfile::tempdir().unwrap();
    let mut ds = sample_dataset(src.path());
    ds.mesh = MeshSource::Shape(geometry::Shape::Blob {
        radius: 0.2,
        amplitude: 0.1,
        bumps: 5,
        seed: 3,
        subdivisions: 2,
    });
    ds.truth = None;
    let out = tempfile::tempdir().unwrap();
    ds.save(out.path(), false).unwrap();
    let back = Dataset::load(out.path()).unwrap();
    assert_eq!(back.mesh, ds.mesh);
    assert_eq!(back.truth, None);
}

#[test]
fn save_refuses_to_overwrite() {
    let src = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let ds = sample_dataset(src.path());
    ds.save(out.path(), false).unwrap();
    let err = ds.save(out.path(), false).unwrap_err();
    assert!(
        matches!(err, SceneError::Exists { .. }) && err.to_string().contains("dataset.json"),
        "{err}"
    );
    ds.save(out.path(), true).unwrap();
    // A view without an image cannot be saved.
    let mut no_img = ds.clone();
    no_img.views[1].image = None;
    let msg = no_img
        .save(&out.path().join("x"), false)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("views[1].image") && msg.contains("no image"),
        "{msg}"
    );
    let mut bad = ds.clone();
    bad.views[0]
        .image
        .as_mut()
        .unwrap()
        .set(1, 1, [f32::NAN; 3]);
    let msg = bad
        .save(&out.path().join("y"), false)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("views[0].image") && msg.contains("(x=1, y=1)"),
        "{msg}"
    );
    assert!(
        !out.path().join("y").exists(),
        "nothing written for an invalid dataset"
    );
}

fn saved(dir: &Path) -> Dataset {
    let src = tempfile::tempdir().unwrap();
    let ds = sample_dataset(src.path());
    ds.save(dir, false).unwrap();
    ds
}

pub(super) fn load_err(dir: &Path) -> String {
    Dataset::load(dir)
        .expect_err("must be rejected")
        .to_string()
}

#[test]
fn wrong_image_size_missing_image_and_nan_are_rejected() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path();
    saved(dir);
    image(6, 4, 0.3)
        .write_exr(&dir.join("view_001.exr"), true)
        .unwrap();
    let msg = load_err(dir);
    assert!(
        msg.contains("views[1].image = \"view_001.exr\"")
            && msg.contains("6×4")
            && msg.contains("12×8"),
        "{msg}"
    );
    std::fs::remove_file(dir.join("view_001.exr")).unwrap();
    let msg = load_err(dir);
    assert!(
        msg.contains("views[1].image = \"view_001.exr\"") && msg.contains("not found"),
        "{msg}"
    );
    let mut nan = image(12, 8, 0.3);
    nan.set(11, 7, [0.0, 0.0, f32::NAN]);
    nan.write_exr(&dir.join("view_001.exr"), true).unwrap();
    let msg = load_err(dir);
    assert!(
        msg.contains("view_001.exr") && msg.contains("pixel (x=11, y=7) channel B"),
        "{msg}"
    );
    std::fs::remove_file(dir.join("object.ply")).unwrap();
    let msg = load_err(dir);
    assert!(
        msg.contains("dataset.json: mesh = \"object.ply\"") && msg.contains("not found"),
        "{msg}"
    );
}

pub(super) fn edit_json(dir: &Path, f: impl FnOnce(&mut Value)) {
    let p = dir.join(DATASET_FILE);
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(&p, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

#[test]
fn header_and_field_errors() {
    let empty = tempfile::tempdir().unwrap();
    let msg = load_err(empty.path());
    assert!(
        msg.contains("no dataset.json") && msg.contains("scene.json"),
        "{msg}"
    );
    let msg = load_err(&empty.path().join("nowhere"));
    assert!(msg.contains("nowhere"), "{msg}");

    let cases: Vec<(Box<dyn Fn(&mut Value)>, &[&str])> = vec![
        (
            Box::new(|v| v["format"] = "something-else".into()),
            &["format = \"something-else\"", "translucent-dataset"],
        ),
        (
            Box::new(|v| v["version"] = 2.into()),
            &["version = 2", "newer"],
        ),
        (Box::new(|v| v["version"] = 0.into()), &["version = 0"]),
        (
            Box::new(|v| v["colour"] = 1.into()),
            &["unknown field `colour`"],
        ),
        (
            Box::new(|v| v["truth"]["albedo"] = 1.5.into()),
            &["truth.albedo[0] = 1.5"],
        ),
        (
            Box::new(|v| v["views"][1]["camera"]["fov_x_deg"] = 0.into()),
            &["views[1].camera.fov_x_deg"],
        ),
        (
            Box::new(|v| v["views"][0]["camera"]["width"] = 0.into()),
            &["views[0].camera.width"],
        ),
        (
            Box::new(|v| v["views"][0]["camera"]["to_world"][0][0] = 2.0.into()),
            &["views[0].camera.to_world", "orthonormal"],
        ),
        (
            Box::new(|v| v["views"][0]["camera"]["to_world"][3][3] = 0.0.into()),
            &["views[0].camera.to_world[3]", "row-major"],
        ),
        (
            Box::new(|v| v["views"][0]["camera"]["origin"] = serde_json::json!([0, 0, 1])),
            &["views[0].camera.to_world", "not both"],
        ),
        (
            Box::new(|v| v["views"][0]["light"]["intensity"] = (-1).into()),
            &["views[0].light.intensity[0] = -1"],
        ),
        (
            Box::new(|v| v["views"] = serde_json::json!([])),
            &["views", "no views"],
        ),
        (
            Box::new(|v| v["shape"] = serde_json::json!({"name": "sphere"})),
            &["mesh, shape"],
        ),
    ];
    for (edit, wants) in cases {
        let out = tempfile::tempdir().unwrap();
        saved(out.path());
        edit_json(out.path(), edit);
        let msg = load_err(out.path());
        for w in wants {
            assert!(msg.contains(w), "{msg:?} should contain {w:?}");
        }
        assert!(msg.contains("dataset.json"), "{msg}");
    }
}

#[test]
fn look_at_cameras_load() {
    let out = tempfile::tempdir().unwrap();
    let ds = saved(out.path());
    let cam = ds.views[0].camera.clone();
    edit_json(out.path(), |v| {
        let c = &mut v["views"][0]["camera"];
        c.as_object_mut().unwrap().remove("to_world");
        c["origin"] = serde_json::json!(cam.origin.to_array());
        c["target"] = serde_json::json!([0.0, 0.0, 0.0]);
    });
    let back = Dataset::load(out.path()).unwrap();
    assert!((back.views[0].camera.rotation - cam.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-6));
    edit_json(out.path(), |v| {
        v["views"][0]["camera"]["up"] = serde_json::json!(cam.direction().to_array());
    });
    let msg = load_err(out.path());
    assert!(
        msg.contains("views[0].camera.up") && msg.contains("parallel"),
        "{msg}"
    );
}

/// A calibrated camera is written as its `intrinsics` block and read back with the same rays;
/// the block and `fov_x_deg` exclude each other, and bad values name their field.
#[test]
fn calibrated_cameras_round_trip_as_intrinsics() {
    let src = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let mut ds = sample_dataset(src.path());
    let k = crate::Intrinsics {
        fx: 14.5,
        fy: 15.25,
        cx: 6.75,
        cy: 3.5,
    };
    ds.views[1].camera = ds.views[1].camera.clone().with_intrinsics(&k);
    ds.save(out.path(), false).unwrap();
    let text = std::fs::read_to_string(out.path().join("dataset.json")).unwrap();
    let v: Value = serde_json::from_str(&text).unwrap();
    assert!(v["views"][0]["camera"]["intrinsics"].is_null());
    assert!(v["views"][1]["camera"]["fov_x_deg"].is_null());
    assert_eq!(v["views"][1]["camera"]["intrinsics"]["cx"], 6.75);
    let back = Dataset::load(out.path()).unwrap();
    let (a, b) = (&ds.views[1].camera, &back.views[1].camera);
    let kb = b.intrinsics();
    assert!(
        (kb.fx - k.fx).abs() < 1e-4 && (kb.fy - k.fy).abs() < 1e-4,
        "{kb:?}"
    );
    assert_eq!((kb.cx, kb.cy), (k.cx, k.cy));
    for (px, py) in [(0.5, 0.5), (11.0, 7.5)] {
        assert!((a.ray(px, py).1 - b.ray(px, py).1).length() < 1e-6);
    }
    assert_eq!(back.views[0].camera.pinhole, None);
    let cases: Vec<(Box<dyn Fn(&mut Value)>, &[&str])> = vec![
        (
            Box::new(|v| v["views"][1]["camera"]["fov_x_deg"] = 40.into()),
            &["views[1].camera.fov_x_deg", "not both"],
        ),
        (
            Box::new(|v| {
                v["views"][1]["camera"]
                    .as_object_mut()
                    .unwrap()
                    .remove("intrinsics");
            }),
            &["views[1].camera.fov_x_deg", "missing", "intrinsics"],
        ),
        (
            Box::new(|v| v["views"][1]["camera"]["intrinsics"]["fx"] = (-3).into()),
            &["views[1].camera.intrinsics.fx", "positive"],
        ),
        (
            Box::new(|v| v["views"][1]["camera"]["intrinsics"]["cy"] = 100.into()),
            &["views[1].camera.intrinsics.cy", "within one image size"],
        ),
        (
            Box::new(|v| v["views"][1]["camera"]["intrinsics"]["skew"] = 0.into()),
            &["unknown field `skew`"],
        ),
    ];
    for (edit, wants) in cases {
        let dir = tempfile::tempdir().unwrap();
        ds.save(dir.path(), false).unwrap();
        edit_json(dir.path(), edit);
        let msg = load_err(dir.path());
        for w in wants {
            assert!(msg.contains(w), "{msg:?} should contain {w:?}");
        }
    }
}

/// A dataset.json's object block is read, written back, and checked against its truth.
#[test]
fn dataset_object_block_round_trips_and_must_agree_with_truth() {
    let src = tempfile::tempdir().unwrap();
    let out = tempfile::tempdir().unwrap();
    let mut ds = sample_dataset(src.path());
    let object = crate::Object {
        eta: 1.33,
        roughness: 0.1,
        g: crate::Anisotropy::uniform(0.7),
    };
    ds.truth = ds.truth.map(|t| object.medium(t.sigma_t, t.albedo));
    ds.object = Some(object);
    ds.save(out.path(), false).unwrap();
    let back = Dataset::load(out.path()).unwrap();
    assert_eq!(back.object, Some(object));
    // An object without a truth is a user's capture: fine.
    edit_json(out.path(), |v| {
        v.as_object_mut().unwrap().remove("truth");
    });
    assert_eq!(Dataset::load(out.path()).unwrap().object, Some(object));
    // A truth that contradicts the object is refused, naming both.
    ds.save(out.path(), true).unwrap();
    edit_json(out.path(), |v| v["object"]["phase"]["g"] = 0.2.into());
    let msg = load_err(out.path());
    assert!(
        msg.contains("truth") && msg.contains("g 0.7") && msg.contains("g 0.2"),
        "{msg}"
    );
    edit_json(out.path(), |v| {
        v["object"]["boundary"] = serde_json::json!({"type": "glass"})
    });
    let msg = load_err(out.path());
    assert!(msg.contains("glass") && msg.contains("dielectric"), "{msg}");
}

#[test]
fn dataset_md_example_loads() {
    let md = include_str!("../../../../DATASET.md");
    let blocks = crate::scene_file::tests::code_blocks(md, "json");
    assert_eq!(blocks.len(), 1);
    let out = tempfile::tempdir().unwrap();
    let dir = out.path();
    std::fs::write(dir.join("dataset.json"), &blocks[0]).unwrap();
    std::fs::write(dir.join("bunny.ply"), b"ply\n").unwrap();
    let v: Value = serde_json::from_str(&blocks[0]).unwrap();
    for view in v["views"].as_array().unwrap() {
        let c = &view["camera"];
        let (w, h) = (
            c["width"].as_u64().unwrap() as u32,
            c["height"].as_u64().unwrap() as u32,
        );
        image(w, h, 0.1)
            .write_exr(&dir.join(view["image"].as_str().unwrap()), false)
            .unwrap();
    }
    let ds = Dataset::load(dir).unwrap();
    assert_eq!(ds.views.len(), 2);
    let (a, b) = (&ds.views[0].camera, &ds.views[1].camera);
    assert!(
        (a.direction() + a.origin.normalize()).length() < 1e-6,
        "view 0 looks at the origin"
    );
    assert!(
        (b.direction() + b.origin.normalize()).length() < 1e-6,
        "view 1 looks at the origin"
    );
    assert_eq!(b.height, 48);
    assert_eq!(
        ds.views[1].light.intensity,
        [std::f32::consts::FRAC_PI_4; 3]
    );
    assert_eq!(ds.render.max_depth, Some(32));
}
