//! Tests of the Mitsuba reference-folder reader: a folder as `render_reference.py` writes it,
//! its rough dielectric boundary and phase function, each error naming the field, and the
//! field of view's axis.

use glam::Vec3;

use super::tests::{assert_same_views, image, load_err};
use super::*;

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
            g: crate::Anisotropy::uniform(0.0),
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
        g: crate::Anisotropy::uniform(0.6),
    };
    assert_eq!(ds.object, Some(want));
    assert_eq!(ds.truth.map(|t| crate::Object::of(&t)), Some(want));
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
