//! Tests of the camera: crops, calibrated pinholes, projections, validation.

use super::*;

fn cam(w: u32, h: u32) -> Camera {
    Camera::look_at(
        Vec3::new(0.3, 0.8, 2.5),
        Vec3::new(0.1, -0.2, 0.0),
        Vec3::Y,
        40.0,
        w,
        h,
    )
}

fn calibrated(w: u32, h: u32) -> Camera {
    cam(w, h).with_intrinsics(&Intrinsics {
        fx: 61.5,
        fy: 66.0,
        cx: 0.5 * w as f32 + 7.25,
        cy: 0.5 * h as f32 - 4.5,
    })
}

/// A calibrated camera's rays and projections are inverse (a crop's too), and its
/// intrinsics read back as given.
#[test]
fn a_calibrated_camera_projects_its_rays_back_to_their_pixels() {
    let c = calibrated(64, 48);
    let k = c.intrinsics();
    assert!(
        (k.fx - 61.5).abs() < 1e-3 && (k.fy - 66.0).abs() < 1e-3,
        "{k:?}"
    );
    assert_eq!((k.cx, k.cy), (39.25, 19.5));
    for cam in [c.clone(), c.cropped(6, 3, 40, 30).unwrap()] {
        for (px, py) in [(0.0, 0.0), (3.5, 2.25), (21.0, 17.5), (39.9, 29.9)] {
            let (o, d) = cam.ray(px, py);
            let (qx, qy) = cam.project(o + 2.5 * d).unwrap();
            assert!(
                (qx - px).abs() < 2e-3 && (qy - py).abs() < 2e-3,
                "{px},{py}: {qx},{qy}"
            );
        }
    }
    // The ray through the principal point is the view direction.
    let (_, d) = c.ray(k.cx, k.cy);
    assert!((d - c.direction()).length() < 1e-6, "{d:?}");
    let back: Camera = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
    assert_eq!(back, c);
}

/// The centred, square-pixel intrinsics are the plain camera (no pinhole, the same rays);
/// a principal point moved by whole pixels moves the image by as many pixels.
#[test]
fn the_centred_intrinsics_are_the_plain_camera() {
    let plain = cam(64, 48);
    let same = plain.clone().with_intrinsics(&plain.intrinsics());
    assert_eq!(same.pinhole, None);
    assert!((same.fov_x_deg - plain.fov_x_deg).abs() < 1e-4);
    let k = plain.intrinsics();
    let shifted = plain.clone().with_intrinsics(&Intrinsics {
        cx: k.cx + 3.0,
        cy: k.cy - 2.0,
        ..k
    });
    for (px, py) in [(0.5, 0.5), (10.25, 30.75), (40.0, 20.0)] {
        let (_, a) = plain.ray(px, py);
        let (_, b) = shifted.ray(px + 3.0, py - 2.0);
        assert!((a - b).length() < 1e-6, "{px},{py}: {a:?} {b:?}");
    }
    let e = plain
        .clone()
        .with_intrinsics(&Intrinsics { cx: 500.0, ..k })
        .validate("test")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("test.cx") && e.contains("within one image size"),
        "{e}"
    );
}

/// A crop sees exactly what the full camera sees at the shifted pixels, crops compose, and
/// projection returns crop-local coordinates.
#[test]
fn crops_are_windows_of_the_full_film() {
    let full = cam(64, 48);
    let c = full.cropped(10, 7, 20, 16).unwrap();
    assert_eq!((c.width, c.height), (20, 16));
    for (px, py) in [(0.0, 0.0), (3.5, 2.25), (19.9, 15.9)] {
        assert_eq!(c.ray(px, py), full.ray(px + 10.0, py + 7.0));
    }
    let cc = c.cropped(4, 5, 8, 8).unwrap();
    assert_eq!(cc.ray(1.5, 2.5), full.ray(15.5, 14.5));
    let p = full.ray(33.25, 20.5).1 * 2.0 + full.origin;
    let (fx, fy) = full.project(p).unwrap();
    let (cx, cy) = c.project(p).unwrap();
    assert!((cx + 10.0 - fx).abs() < 1e-3 && (cy + 7.0 - fy).abs() < 1e-3);
    // Survives serialization (datasets and checkpoints store cameras).
    let back: Camera = serde_json::from_str(&serde_json::to_string(&cc).unwrap()).unwrap();
    assert_eq!(back, cc);
    for (x0, y0, w, h) in [
        (60, 0, 5, 5),
        (0, 40, 4, 9),
        (0, 0, 0, 4),
        (u32::MAX, 0, 2, 2),
    ] {
        let e = full.cropped(x0, y0, w, h).unwrap_err().to_string();
        assert!(e.contains("does not fit in the 64×48 image"), "{e}");
    }
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

#[test]
fn centre_pixel_ray_is_the_view_direction() {
    for (w, h) in [(64, 64), (65, 33), (100, 40)] {
        let c = cam(w, h);
        let (o, d) = c.ray(w as f32 / 2.0, h as f32 / 2.0);
        assert_eq!(o, c.origin);
        let z = (Vec3::new(0.1, -0.2, 0.0) - c.origin).normalize();
        assert!(close(d, z, 1e-6), "{d} vs {z}");
    }
}

#[test]
fn px_zero_is_image_left_and_py_zero_is_up() {
    let c = cam(80, 60);
    let (x, y, z) = (c.rotation.x_axis, c.rotation.y_axis, c.rotation.z_axis);
    // x = normalize(cross(up, z)) is image LEFT: column 0 looks towards +x.
    assert!(close(x, Vec3::Y.cross(z).normalize(), 1e-6));
    let (_, left) = c.ray(0.0, 30.0);
    let (_, right) = c.ray(80.0, 30.0);
    assert!(left.dot(x) > 0.0 && right.dot(x) < 0.0);
    assert!(left.dot(y).abs() < 1e-6);
    // Row 0 looks up (+y), the last row down.
    let (_, top) = c.ray(40.0, 0.0);
    let (_, bottom) = c.ray(40.0, 60.0);
    assert!(top.dot(y) > 0.0 && bottom.dot(y) < 0.0);
    // fov along x: the left edge is at angle fov/2 from the axis; the top edge at
    // atan(tan(fov/2)·H/W).
    let t = 20f32.to_radians().tan();
    assert!((left.dot(x) / left.dot(z) - t).abs() < 1e-5);
    assert!((top.dot(y) / top.dot(z) - t * 60.0 / 80.0).abs() < 1e-5);
    // World up (+Y) appears at the top of the image for this camera.
    assert!(y.dot(Vec3::Y) > 0.0);
}

#[test]
fn project_round_trips_ray() {
    let c = cam(97, 41);
    for &(px, py) in &[
        (0.0, 0.0),
        (0.5, 0.5),
        (96.5, 40.5),
        (48.5, 20.5),
        (10.25, 33.75),
        (97.0, 41.0),
    ] {
        let (o, d) = c.ray(px, py);
        for t in [0.5f32, 2.0, 7.0] {
            let (qx, qy) = c.project(o + t * d).expect("in front of the camera");
            assert!(
                (qx - px).abs() < 2e-3 && (qy - py).abs() < 2e-3,
                "({px},{py}) -> ({qx},{qy})"
            );
        }
    }
    assert!(c.project(c.origin - c.direction()).is_none());
}

#[test]
fn camera_from_to_world_equals_look_at() {
    // View 0 of the Mitsuba reference render (numbers copied from its scene.json).
    let rows = [
        [
            -0.29552020666133955,
            -0.8359194279849053,
            -0.4625002890509669,
            0.23125014452548345,
        ],
        [0.0, 0.4841229182759271, -0.875, 0.4375],
        [
            0.955336489125606,
            -0.2585801808286721,
            -0.14306810485839278,
            0.07153405242919639,
        ],
        [0.0, 0.0, 0.0, 1.0],
    ]
    .map(|r: [f64; 4]| r.map(|v| v as f32));
    let a = Camera::from_to_world(rows, 40.0, 64, 64);
    let b = Camera::look_at(
        Vec3::new(0.23125014452548345, 0.4375, 0.07153405242919639),
        Vec3::ZERO,
        Vec3::Y,
        40.0,
        64,
        64,
    );
    assert!(close(a.origin, b.origin, 1e-7));
    for i in 0..3 {
        assert!(
            close(a.rotation.col(i), b.rotation.col(i), 1e-6),
            "column {i}"
        );
    }
    for &(px, py) in &[(0.0, 0.0), (32.0, 32.0), (16.0, 44.8)] {
        assert!(close(a.ray(px, py).1, b.ray(px, py).1, 1e-6));
    }
    // And back to rows.
    let back = b.to_world_rows();
    for r in 0..4 {
        for c in 0..4 {
            assert!((back[r][c] - rows[r][c]).abs() < 1e-6);
        }
    }
    a.validate("test").unwrap();
}

#[test]
fn validate_names_the_field() {
    let mut c = cam(8, 8);
    c.width = 0;
    assert!(c.validate("x").unwrap_err().to_string().contains("x.width"));
    let mut c = cam(8, 8);
    c.fov_x_deg = 180.0;
    assert!(c.validate("x").unwrap_err().to_string().contains("x.fov"));
    let mut c = cam(8, 8);
    c.rotation *= 2.0;
    assert!(
        c.validate("x")
            .unwrap_err()
            .to_string()
            .contains("orthonormal")
    );
    let mut c = cam(8, 8);
    c.rotation.x_axis = -c.rotation.x_axis;
    assert!(
        c.validate("x")
            .unwrap_err()
            .to_string()
            .contains("reflection")
    );
}
