//! Tests of `transforms.json`: the same rig as our own dataset.json gives the same dataset view
//! by view (cameras ray by ray, lights, images); calibrated intrinsics against a ray computed by
//! hand; the errors.

use glam::Vec3;
use serde_json::{Value, json};

use super::*;
use crate::capture::Capture;
use crate::colmap::tests::assert_same_rays;
use crate::dataset::Dataset;
use crate::image::PhotoSettings;

/// A camera's OpenGL camera-to-world rows: columns (−x, y, −z) of ours, then its position.
fn gl_matrix(c: &Camera) -> Value {
    let r = c.rotation;
    let cols = [-r.x_axis, r.y_axis, -r.z_axis, c.origin];
    json!(
        (0..3)
            .map(|i| cols.iter().map(|v| v[i] as f64).collect::<Vec<_>>())
            .chain([vec![0.0, 0.0, 0.0, 1.0]])
            .collect::<Vec<_>>()
    )
}

fn capture(images: &Path, light: CaptureLight) -> Capture {
    Capture {
        images: images.to_path_buf(),
        masks: None,
        photo: PhotoSettings::default(),
        mesh: images.join("object.ply"),
        light,
        intensity: [0.785; 3],
        object: None,
        length_unit: None,
    }
}

#[test]
fn a_transforms_file_gives_the_dataset_of_the_same_rig() {
    let d = tempfile::tempdir().unwrap();
    let ds = crate::dataset::tests::sample_dataset(d.path());
    ds.save(&d.path().join("ds"), false).unwrap();
    let ds = Dataset::load(&d.path().join("ds")).unwrap();
    let c0 = &ds.views[0].camera;
    // Blender's layout: one field of view for all, names without extensions, a light per frame.
    let frames: Vec<Value> = ds
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            json!({
                "file_path": format!("./view_{i:03}"),
                "transform_matrix": gl_matrix(&v.camera),
                "light_position": v.light.position.to_array(),
            })
        })
        .collect();
    let file = d.path().join("ds/transforms.json");
    let doc = json!({
        "camera_angle_x": (c0.fov_x_deg as f64).to_radians(),
        "w": c0.width, "h": c0.height, "aabb_scale": 4,
        "frames": frames,
    });
    std::fs::write(&file, doc.to_string()).unwrap();
    let t = NerfTransforms::read(&file).unwrap();
    let light = t.lights().unwrap().unwrap();
    let views = t
        .views(|_| unreachable!("the file states the size"))
        .unwrap();
    let back = capture(&t.dir(), light)
        .dataset(&views, "units".into(), "test", "fix")
        .unwrap();
    assert_eq!(back.views.len(), ds.views.len());
    for (a, b) in ds.views.iter().zip(&back.views) {
        assert_same_rays(&a.camera, &b.camera);
        assert!(b.camera.pinhole.is_none());
        assert!((a.light.position - b.light.position).length() < 1e-6);
        assert_eq!(a.image, b.image);
    }
    // Without w and h, the size comes from the image.
    let mut doc = doc;
    doc.as_object_mut().unwrap().remove("w");
    doc.as_object_mut().unwrap().remove("h");
    std::fs::write(&file, doc.to_string()).unwrap();
    let t = NerfTransforms::read(&file).unwrap();
    let views = t
        .views(|name| Ok((if name.ends_with('0') { 12 } else { 99 }, 8)))
        .unwrap();
    assert_eq!((views[0].camera.width, views[1].camera.width), (12, 99));
}

/// fl_x, fl_y, cx, cy (a frame's own f_y over the file's): the ray through a pixel is the one
/// computed by hand, d ∝ R·((c_x − p_x)/f_x, (c_y − p_y)/f_y, 1) in our axes.
#[test]
fn calibrated_intrinsics_give_the_rays_computed_by_hand() {
    let d = tempfile::tempdir().unwrap();
    let file = d.path().join("transforms.json");
    // Camera at (0, 0, 3) looking down −z (OpenGL identity rotation).
    let pose = json!([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]);
    let doc = json!({
        "fl_x": 100.0, "fl_y": 100.0, "cx": 30.0, "cy": 20.0, "w": 64, "h": 48,
        "k1": 0.0, "camera_model": "OPENCV",
        "frames": [
            {"file_path": "a.png", "transform_matrix": pose},
            {"file_path": "b.png", "transform_matrix": pose, "fl_y": 120.0,
             "light_transform": [[1, 0, 0, 0.5], [0, 1, 0, 1.5], [0, 0, 1, 2.5], [0, 0, 0, 1]]},
        ]
    });
    std::fs::write(&file, doc.to_string()).unwrap();
    let t = NerfTransforms::read(&file).unwrap();
    let e = t.lights().unwrap_err().to_string();
    assert!(
        e.contains("frames[0]") && e.contains("states no light"),
        "{e}"
    );
    assert_eq!(t.frames[1].light, Some(Vec3::new(0.5, 1.5, 2.5)));
    let views = t.views(|_| unreachable!()).unwrap();
    for (v, fy) in views.iter().zip([100.0f32, 120.0]) {
        let c = &v.camera;
        assert_eq!(c.origin, Vec3::new(0.0, 0.0, 3.0));
        let (px, py) = (10.5f32, 40.25f32);
        // OpenGL: x right, y up, looking along −z; pixel y grows downwards.
        let want = Vec3::new((px - 30.0) / 100.0, -(py - 20.0) / fy, -1.0).normalize();
        let got = c.ray(px, py).1;
        assert!((got - want).length() < 1e-5, "{got} {want}");
    }
}

#[test]
fn damaged_transforms_are_refused_with_the_field() {
    let d = tempfile::tempdir().unwrap();
    let file = d.path().join("transforms.json");
    let pose = json!([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]);
    let frame = |extra: Value| {
        let mut f = json!({"file_path": "a.png", "transform_matrix": pose});
        for (k, v) in extra.as_object().unwrap() {
            f[k] = v.clone();
        }
        f
    };
    let err = |doc: Value| {
        std::fs::write(&file, doc.to_string()).unwrap();
        match NerfTransforms::read(&file) {
            Err(e) => e.to_string(),
            Ok(t) => t
                .views(|_| Ok((64, 48)))
                .and_then(|_| t.lights())
                .map(|_| String::from("accepted"))
                .unwrap_or_else(|e| e.to_string()),
        }
    };
    let base = |f: Value| json!({"camera_angle_x": 0.7, "frames": [f]});
    for (doc, want) in [
        (
            json!({"camera_angle_x": 0.7}),
            "frames: must be a non-empty array",
        ),
        (json!([1, 2]), "must be a JSON object"),
        (
            base(json!({"transform_matrix": pose})),
            "frames[0].file_path",
        ),
        (
            base(frame(
                json!({"transform_matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}),
            )),
            "frames[0].transform_matrix: must be 4 rows",
        ),
        (
            base(frame(
                json!({"transform_matrix": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [0, 0, 0, 1]]}),
            )),
            "not orthonormal",
        ),
        (
            base(frame(
                json!({"transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 3], [1, 0, 0, 1]]}),
            )),
            "last row must be [0, 0, 0, 1]",
        ),
        (base(frame(json!({"k1": 0.01}))), "frames[0]: k1"),
        (
            base(frame(json!({"camera_model": "OPENCV_FISHEYE"}))),
            "is not a pinhole",
        ),
        (base(frame(json!({"w": 64.5, "h": 48}))), "frames[0]: w"),
        (base(frame(json!({"camera_angle_x": 4.0}))), "(0, π)"),
        (
            base(frame(json!({"fl_x": "wide"}))),
            "fl_x: must be a finite number",
        ),
        (base(frame(json!({"fl_x": -5.0}))), "must be positive"),
        (
            json!({"frames": [frame(json!({}))]}),
            "states no focal length",
        ),
        (
            base(frame(json!({"light_position": [1, 2]}))),
            "light_position: must be [x, y, z]",
        ),
    ] {
        let e = err(doc.clone());
        assert!(
            e.contains(want) && (e.contains("transforms.json") || e.contains("frames")),
            "{doc}: {e}"
        );
    }
}
