//! Tests of dataset folders: save/load round trips, overwrite refusal, validation errors of
//! `dataset.json`, Mitsuba reference folders, and the example of DATASET.md.

use glam::Vec3;

use super::*;

fn image(w: u32, h: u32, seed: f32) -> Image {
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
fn sample_dataset(src: &Path) -> Dataset {
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

fn assert_same_views(a: &Dataset, b: &Dataset) {
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

fn load_err(dir: &Path) -> String {
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

fn edit_json(dir: &Path, f: impl FnOnce(&mut Value)) {
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

/// A Mitsuba reference folder as written by render_reference.py (the fields we read, plus
/// some we ignore).
fn reference_folder(dir: &Path) {
    std::fs::write(dir.join("mesh.ply"), b"ply\n").unwrap();
    let img0 = image(8, 6, 0.2);
    let img1 = image(8, 6, 0.4);
    img0.write_exr(&dir.join("view_000.exr"), false).unwrap();
    img1.write_exr(&dir.join("view_001.exr"), false).unwrap();
    let doc = serde_json::json!({
        "generator": "Mitsuba 3.9.1 (llvm_ad_rgb), rendered for this project as reference data",
        "software": { "variant": "llvm_ad_rgb", "mitsuba_version": "3.9.1" },
        "units": "all lengths in abstract scene units",
        "shape": { "kind": "sphere", "params": { "radius": 0.125 }, "mesh_file": "mesh.ply", "face_count": 16128 },
        "boundary": { "bsdf": "null" },
        "medium": {
            "type": "homogeneous",
            "sigma_t": [50.0, 60.0, 70.0],
            "albedo": [0.95, 0.9, 0.85],
            "phase": { "type": "isotropic", "g": 0.0 }
        },
        "light": { "type": "point", "mode": "fixed", "intensity_rgb": [0.785, 0.785, 0.785], "position": [0.26, 0.4, 0.13] },
        "integrator": { "type": "volpath", "max_depth": 32, "rr_depth": 5 },
        "camera": { "fov_deg": 40.0, "fov_axis": "x", "width": 8, "height": 6 },
        "views": [
            {
                "index": 0,
                "origin": [0.23125014452548345, 0.4375, 0.07153405242919639],
                "target": [0.0, 0.0, 0.0],
                "up": [0.0, 1.0, 0.0],
                "to_world": [
                    [-0.29552020666133955, -0.8359194279849053, -0.4625002890509669, 0.23125014452548345],
                    [0.0, 0.4841229182759271, -0.875, 0.4375],
                    [0.955336489125606, -0.2585801808286721, -0.14306810485839278, 0.07153405242919639],
                    [0.0, 0.0, 0.0, 1.0]
                ],
                "light_position": [0.2672612419124244, 0.4008918628686366, 0.1336306209562122],
                "file_exr": "view_000.exr",
                "mean_rgb": img0.mean()
            },
            {
                "index": 1,
                "origin": [-0.3528644108831139, 0.3125, 0.1668246310714128],
                "target": [0.0, 0.0, 0.0],
                "file_exr": "view_001.exr",
                "mean_rgb": [0.5, 0.5, 0.5]
            }
        ],
        "render": { "spp": 1024, "seed": 0 }
    });
    std::fs::write(
        dir.join(REFERENCE_FILE),
        serde_json::to_string_pretty(&doc).unwrap(),
    )
    .unwrap();
}

#[test]
fn mitsuba_reference_folder_loads() {
    let out = tempfile::tempdir().unwrap();
    let dir = out.path();
    reference_folder(dir);
    let ds = Dataset::load(dir).unwrap();
    assert_eq!(ds.kind, DatasetKind::MitsubaReference);
    assert_eq!(ds.mesh, MeshSource::File(dir.join("mesh.ply")));
    assert_eq!(
        ds.truth,
        Some(Medium {
            sigma_t: [50.0, 60.0, 70.0],
            albedo: [0.95, 0.9, 0.85],
            g: 0.0,
            eta: 1.0,
            roughness: 0.0,
        })
    );
    assert_eq!(ds.render.max_depth, Some(32));
    assert_eq!(ds.render.spp, Some(1024));
    assert_eq!(ds.render.renderer.as_deref(), Some("mitsuba 3.9.1 volpath"));
    assert_eq!(ds.views.len(), 2);
    let v0 = &ds.views[0];
    let look = Camera::look_at(
        Vec3::new(0.23125014452548345, 0.4375, 0.07153405242919639),
        Vec3::ZERO,
        Vec3::Y,
        40.0,
        8,
        6,
    );
    assert!((v0.camera.rotation - look.rotation).abs_diff_eq(glam::Mat3::ZERO, 1e-6));
    assert_eq!(
        v0.light.position,
        Vec3::new(0.2672612419124244, 0.4008918628686366, 0.1336306209562122)
    );
    assert_eq!(v0.light.intensity, [0.785; 3]);
    assert_eq!(v0.image.as_ref().unwrap().width, 8);
    // View 1: look-at form, light from light.position.
    assert_eq!(ds.views[1].light.position, Vec3::new(0.26, 0.4, 0.13));
    assert!(
        (ds.views[1].camera.direction() + ds.views[1].camera.origin.normalize()).length() < 1e-6
    );
    // View 1's recorded mean is wrong: a warning, not an error.
    assert_eq!(ds.warnings.len(), 1);
    assert!(ds.warnings[0].contains("views[1]") && ds.warnings[0].contains("mean_rgb"));
    assert!(Dataset::load(&dir.join("scene.json")).is_ok());
    // The reference folder saves as a translucent dataset with the same content.
    let out2 = tempfile::tempdir().unwrap();
    ds.save(out2.path(), false).unwrap();
    let back = Dataset::load(out2.path()).unwrap();
    assert_eq!(back.kind, DatasetKind::Native);
    assert_eq!(back.truth, ds.truth);
    assert_eq!(back.render, ds.render);
    assert_same_views(&ds, &back);
}

/// A rough dielectric boundary and an HG medium are read into the object (what a recovery
/// renders with) as well as the truth.
#[test]
fn mitsuba_reference_rough_boundary_and_phase_are_read() {
    let out = tempfile::tempdir().unwrap();
    reference_folder(out.path());
    let p = out.path().join(REFERENCE_FILE);
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["boundary"] = serde_json::json!({"bsdf": "roughdielectric", "int_ior": 1.4,
        "ext_ior": 1.0, "distribution": "ggx", "alpha": 0.3});
    v["medium"]["phase"] = serde_json::json!({"type": "hg", "g": 0.6});
    std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
    let ds = Dataset::load(out.path()).unwrap();
    let want = crate::Object {
        eta: 1.4,
        roughness: 0.3,
        g: 0.6,
    };
    assert_eq!(ds.object, Some(want));
    assert_eq!(ds.truth.map(|t| crate::Object::of(&t)), Some(want));
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
        g: 0.7,
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
fn mitsuba_reference_errors_name_the_field() {
    let edits: Vec<(Box<dyn Fn(&mut Value)>, &[&str])> = vec![
        (
            Box::new(|v| v["medium"]["sigma_t"] = serde_json::json!([50, -1, 70])),
            &["scene.json: medium.sigma_t[1] = -1"],
        ),
        (
            Box::new(|v| {
                v["medium"]
                    .as_object_mut()
                    .unwrap()
                    .remove("albedo")
                    .map(drop)
                    .unwrap()
            }),
            &["medium.albedo", "missing"],
        ),
        (
            Box::new(|v| v["boundary"]["bsdf"] = "diffuse".into()),
            &["boundary.bsdf = \"diffuse\""],
        ),
        (
            // Mitsuba's default distribution.
            Box::new(|v| {
                v["boundary"] = serde_json::json!({"bsdf": "roughdielectric", "int_ior": 1.4})
            }),
            &["boundary.distribution = \"beckmann\"", "GGX"],
        ),
        (
            Box::new(|v| {
                v["boundary"] = serde_json::json!({"bsdf": "roughdielectric", "int_ior": 1.4,
                    "distribution": "ggx", "alpha_u": 0.1, "alpha_v": 0.3})
            }),
            &["boundary.alpha_u", "anisotropic"],
        ),
        (
            Box::new(|v| {
                v["boundary"] = serde_json::json!({"bsdf": "roughdielectric", "int_ior": 1.4,
                    "distribution": "ggx", "alpha": 1.5})
            }),
            &["boundary.alpha = 1.5"],
        ),
        (
            Box::new(|v| {
                v["boundary"] = serde_json::json!({"bsdf": "dielectric", "int_ior": 1.4,
                    "alpha": 0.2})
            }),
            &["boundary.alpha", "roughdielectric"],
        ),
        (
            Box::new(|v| {
                v["boundary"] = serde_json::json!({"bsdf": "dielectric", "int_ior": 1.0,
                    "ext_ior": 1.33})
            }),
            &["boundary.int_ior = 1", "denser"],
        ),
        (
            Box::new(|v| v["medium"]["phase"] = serde_json::json!({"type": "rayleigh"})),
            &["medium.phase.type = \"rayleigh\""],
        ),
        (
            Box::new(|v| v["medium"]["phase"] = serde_json::json!({"type": "hg"})),
            &["medium.phase.g", "missing"],
        ),
        (
            Box::new(|v| v["medium"]["phase"] = serde_json::json!({"type": "hg", "g": 1.2})),
            &["medium.g = 1.2"],
        ),
        (
            Box::new(|v| v["camera"]["width"] = 0.into()),
            &["camera.width"],
        ),
        (
            Box::new(|v| v["camera"]["fov_deg"] = 200.into()),
            &["camera.fov_deg"],
        ),
        (
            Box::new(|v| v["views"][0]["to_world"][1] = serde_json::json!([0, 1])),
            &["views[0].to_world[1]", "4 numbers"],
        ),
        (
            Box::new(|v| v["views"][1]["file_exr"] = "gone.exr".into()),
            &["views[1].file_exr = \"gone.exr\"", "not found"],
        ),
        (
            Box::new(|v| v["shape"]["mesh_file"] = "gone.ply".into()),
            &["shape.mesh_file = \"gone.ply\"", "not found"],
        ),
        (
            Box::new(|v| v["camera"]["width"] = 16.into()),
            &["views[0].file_exr", "8×6", "16×6"],
        ),
    ];
    for (edit, wants) in edits {
        let out = tempfile::tempdir().unwrap();
        reference_folder(out.path());
        let p = out.path().join(REFERENCE_FILE);
        let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        edit(&mut v);
        std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
        let msg = load_err(out.path());
        for w in wants {
            assert!(msg.contains(w), "{msg:?} should contain {w:?}");
        }
    }
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

#[test]
fn reference_fov_axis_y_is_converted() {
    let out = tempfile::tempdir().unwrap();
    reference_folder(out.path());
    let p = out.path().join(REFERENCE_FILE);
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["camera"]["fov_axis"] = "y".into();
    std::fs::write(&p, serde_json::to_string(&v).unwrap()).unwrap();
    let ds = Dataset::load(out.path()).unwrap();
    let fx = ds.views[0].camera.fov_x_deg;
    let want = (2.0 * (20f64.to_radians().tan() * 8.0 / 6.0).atan()).to_degrees() as f32;
    assert!((fx - want).abs() < 1e-4, "{fx} vs {want}");
}
