//! Tests of the COLMAP reader: our cameras written as a COLMAP model (text and binary, by the
//! format's definition) read back to the same rays; distortion, fisheye models and damaged files
//! refused with the file, the place and the fix.

use std::fmt::Write as _;

use glam::{DMat3, DQuat, Vec3};

use super::*;
use crate::Dataset;

/// Our cameras: a plain one, a calibrated one (off-centre, f_y ≠ f_x), a third sharing the
/// second's intrinsics.
fn cameras() -> Vec<Camera> {
    let a = Camera::look_at(Vec3::new(0.3, 0.8, 2.5), Vec3::ZERO, Vec3::Y, 40.0, 64, 48);
    let k = Intrinsics {
        fx: 70.0,
        fy: 74.5,
        cx: 36.25,
        cy: 21.5,
    };
    let b = Camera::look_at(
        Vec3::new(-2.0, 0.4, 0.3),
        Vec3::new(0.1, 0.0, 0.0),
        Vec3::Y,
        40.0,
        64,
        48,
    )
    .with_intrinsics(&k);
    let c = Camera::look_at(
        Vec3::new(0.2, -1.5, -1.8),
        Vec3::ZERO,
        Vec3::Y,
        40.0,
        64,
        48,
    )
    .with_intrinsics(&k);
    vec![a, b, c]
}

/// COLMAP's pose of our camera: R's rows are the camera's (−x, −y, z) axes, t = −R·origin.
fn pose(c: &Camera) -> ([f64; 4], [f64; 3]) {
    let m = c.rotation.as_dmat3();
    let r = DMat3::from_cols(-m.x_axis, -m.y_axis, m.z_axis).transpose();
    let q = DQuat::from_mat3(&r);
    let t = -(r * c.origin.as_dvec3());
    ([q.w, q.x, q.y, q.z], t.to_array())
}

/// The model as COLMAP writes it: cameras 1 (SIMPLE_PINHOLE) and 7 (PINHOLE), images 3, 5, 9.
fn model_text(cams: &[Camera]) -> (String, String) {
    let mut c = String::from("# Camera list with one line of data per camera:\n");
    let k0 = cams[0].intrinsics();
    let k1 = cams[1].intrinsics();
    let _ = writeln!(c, "1 SIMPLE_PINHOLE 64 48 {} {} {}", k0.fx, k0.cx, k0.cy);
    let _ = writeln!(c, "7 PINHOLE 64 48 {} {} {} {}", k1.fx, k1.fy, k1.cx, k1.cy);
    let mut i = String::from("# Image list with two lines of data per image:\n");
    for (id, cam_id, cam, name) in [
        (3, 1, &cams[0], "a.jpg"),
        (5, 7, &cams[1], "sub dir/b.jpg"),
        (9, 7, &cams[2], "c.png"),
    ] {
        let (q, t) = pose(cam);
        let _ = writeln!(
            i,
            "{id} {} {} {} {} {} {} {} {cam_id} {name}",
            q[0], q[1], q[2], q[3], t[0], t[1], t[2]
        );
        // Image 5 has no 2D points: its second line is empty.
        let points = if id == 5 {
            ""
        } else {
            "12.5 3.25 -1 40.0 20.0 17"
        };
        let _ = writeln!(i, "{points}");
    }
    (c, i)
}

/// The same model in the binary format.
fn model_binary(cams: &[Camera]) -> (Vec<u8>, Vec<u8>) {
    let mut c = 2u64.to_le_bytes().to_vec();
    let k0 = cams[0].intrinsics();
    let k1 = cams[1].intrinsics();
    for (id, model, params) in [
        (1u32, 0u32, vec![k0.fx, k0.cx, k0.cy]),
        (7, 1, vec![k1.fx, k1.fy, k1.cx, k1.cy]),
    ] {
        c.extend(id.to_le_bytes());
        c.extend(model.to_le_bytes());
        c.extend(64u64.to_le_bytes());
        c.extend(48u64.to_le_bytes());
        for p in params {
            c.extend((p as f64).to_le_bytes());
        }
    }
    let mut i = 3u64.to_le_bytes().to_vec();
    for (id, cam_id, cam, name, points) in [
        (3u32, 1u32, &cams[0], "a.jpg", 2u64),
        (5, 7, &cams[1], "sub dir/b.jpg", 0),
        (9, 7, &cams[2], "c.png", 1),
    ] {
        let (q, t) = pose(cam);
        i.extend(id.to_le_bytes());
        for v in q.iter().chain(&t) {
            i.extend(v.to_le_bytes());
        }
        i.extend(cam_id.to_le_bytes());
        i.extend(name.as_bytes());
        i.push(0);
        i.extend(points.to_le_bytes());
        for k in 0..points {
            i.extend((k as f64).to_le_bytes());
            i.extend(2.5f64.to_le_bytes());
            i.extend((-1i64).to_le_bytes());
        }
    }
    (c, i)
}

pub(crate) fn assert_same_rays(a: &Camera, b: &Camera) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    assert!(
        (a.origin - b.origin).length() < 1e-5,
        "{} {}",
        a.origin,
        b.origin
    );
    for (px, py) in [(0.5, 0.5), (20.25, 40.0), (63.0, 1.0), (36.25, 21.5)] {
        let (da, db) = (a.ray(px, py).1, b.ray(px, py).1);
        assert!((da - db).length() < 1e-5, "({px}, {py}): {da} {db}");
    }
}

/// Both formats read back to our cameras, in the file's order, with their names.
#[test]
fn a_model_reads_back_to_the_cameras_it_was_written_from() {
    let cams = cameras();
    let text = tempfile::tempdir().unwrap();
    let (c, i) = model_text(&cams);
    std::fs::write(text.path().join("cameras.txt"), c).unwrap();
    std::fs::write(text.path().join("images.txt"), i).unwrap();
    let bin = tempfile::tempdir().unwrap();
    let (c, i) = model_binary(&cams);
    std::fs::write(bin.path().join("cameras.bin"), c).unwrap();
    std::fs::write(bin.path().join("images.bin"), i).unwrap();
    for dir in [text.path(), bin.path()] {
        let m = ColmapModel::read(dir).unwrap();
        let names: Vec<&str> = m.images.iter().map(|im| im.name.as_str()).collect();
        assert_eq!(names, ["a.jpg", "sub dir/b.jpg", "c.png"]);
        for (im, want) in m.images.iter().zip(&cams) {
            let got = m.camera(im).unwrap();
            assert_same_rays(&got, want);
        }
        assert_eq!(m.camera(&m.images[0]).unwrap().pinhole, None);
        assert!(m.camera(&m.images[1]).unwrap().pinhole.is_some());
    }
}

/// `SIMPLE_RADIAL`/`OPENCV` with zero distortion are pinholes; with distortion, or a fisheye
/// model, the camera is refused with the undistorter as the fix.
#[test]
fn only_pinholes_are_read() {
    let cam = |model: &str, params: Vec<f64>| ColmapCamera {
        model: model.into(),
        width: 64,
        height: 48,
        params,
    };
    let k = cam("OPENCV", vec![70.0, 72.0, 31.0, 25.0, 0.0, 0.0, 0.0, 0.0])
        .intrinsics("c")
        .unwrap();
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (70.0, 72.0, 31.0, 25.0));
    assert!(
        cam("SIMPLE_RADIAL", vec![70.0, 31.0, 25.0, 0.0])
            .intrinsics("c")
            .is_ok()
    );
    for (model, params, want) in [
        (
            "SIMPLE_RADIAL",
            vec![70.0, 31.0, 25.0, -0.02],
            "distortion coefficient 0 is -0.02",
        ),
        (
            "OPENCV",
            vec![70.0, 72.0, 31.0, 25.0, 0.0, 0.0, 0.001, 0.0],
            "coefficient 2",
        ),
        (
            "OPENCV_FISHEYE",
            vec![70.0, 72.0, 31.0, 25.0, 0.0, 0.0, 0.0, 0.0],
            "fisheye",
        ),
        ("PINHOLE", vec![-70.0, 72.0, 31.0, 25.0], "must be positive"),
    ] {
        let e = cam(model, params)
            .intrinsics("cam 4")
            .unwrap_err()
            .to_string();
        assert!(e.contains("cam 4") && e.contains(want), "{e}");
        if !want.contains("positive") {
            assert!(e.contains("image_undistorter"), "{e}");
        }
    }
}

/// Damaged or inconsistent files name the file, the line or byte, and what is wrong.
#[test]
fn damaged_models_are_refused_with_the_place() {
    let cams = cameras();
    let (c, i) = model_text(&cams);
    let read_text = |c: &str, i: &str| {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("cameras.txt"), c).unwrap();
        std::fs::write(d.path().join("images.txt"), i).unwrap();
        ColmapModel::read(d.path()).and_then(|m| {
            m.images
                .iter()
                .map(|im| m.camera(im))
                .collect::<Result<Vec<_>, _>>()
        })
    };
    for (c2, i2, want) in [
        (
            c.replace("PINHOLE 64", "PINHOLE 0"),
            i.clone(),
            "cameras.txt:2",
        ),
        (
            c.replace("SIMPLE_PINHOLE", "PINHOL"),
            i.clone(),
            "not one of COLMAP's",
        ),
        (
            c.replace("PINHOLE 64 48 70", "PINHOLE 64 48"),
            i.clone(),
            "has 4 parameters",
        ),
        (
            c.clone(),
            i.replace(" 7 c.png", " 8 c.png"),
            "names camera 8",
        ),
        (c.clone(), i.replace(" 1 a.jpg", " 1"), "NAME is missing"),
        (c.clone(), i.replacen("3 ", "x ", 1), "IMAGE_ID \"x\""),
    ] {
        let e = read_text(&c2, &i2).unwrap_err().to_string();
        assert!(e.contains(want), "{want:?} not in {e}");
    }
    let d = tempfile::tempdir().unwrap();
    let e = ColmapModel::read(d.path()).unwrap_err().to_string();
    assert!(
        e.contains("no COLMAP model here") && e.contains("sparse/0"),
        "{e}"
    );
    // A binary model cut short, and one whose count runs past the end.
    let (cb, ib) = model_binary(&cams);
    for (cut, want) in [(ib.len() - 30, "truncated"), (8, "does not fit")] {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("cameras.bin"), &cb).unwrap();
        let mut ib2 = ib[..cut].to_vec();
        if cut == 8 {
            ib2 = 1000u64.to_le_bytes().to_vec();
        }
        std::fs::write(d.path().join("images.bin"), ib2).unwrap();
        let e = ColmapModel::read(d.path()).unwrap_err().to_string();
        assert!(e.contains("images.bin (byte") && e.contains(want), "{e}");
    }
}

/// A COLMAP capture of three images (`a.exr`, `sub dir/b.exr`, `c.exr`, 64 × 48) in a
/// temporary folder, with a flash: the folder, the model, the capture and the cameras.
fn capture_fixture() -> (tempfile::TempDir, ColmapModel, Capture, Vec<Camera>) {
    let cams = cameras();
    let d = tempfile::tempdir().unwrap();
    let (c, i) = model_text(&cams);
    std::fs::write(d.path().join("cameras.txt"), c).unwrap();
    std::fs::write(d.path().join("images.txt"), i).unwrap();
    let images = d.path().join("images");
    std::fs::create_dir_all(images.join("sub dir")).unwrap();
    for name in ["a.exr", "sub dir/b.exr", "c.exr"] {
        crate::dataset::tests::image(64, 48, 0.2)
            .write_exr(&images.join(name), false)
            .unwrap();
    }
    let mesh = geometry::Shape::Sphere {
        radius: 0.5,
        subdivisions: 2,
    }
    .build()
    .unwrap();
    geometry::io::save_ply(&mesh, &d.path().join("mesh.ply")).unwrap();
    let model = ColmapModel::read(d.path()).unwrap();
    let capture = Capture {
        images: images.clone(),
        mesh: d.path().join("mesh.ply"),
        light: CaptureLight::Flash {
            offset: Vec3::new(0.1, -0.05, 0.0),
        },
        intensity: [2.0; 3],
        object: None,
        length_unit: None,
        masks: None,
        photo: Default::default(),
    };
    (d, model, capture, cams)
}

/// A capture (the model, an EXR per image, a mesh, a flash beside the lens) becomes a dataset
/// that saves and loads with the same cameras; the flash sits at its offset in COLMAP's camera
/// frame; photos, missing lights and images of another size are refused with the fix.
#[test]
fn a_capture_is_a_dataset() {
    let (d, model, mut capture, cams) = capture_fixture();
    let ds = model.dataset(&capture).unwrap();
    assert_eq!(ds.views.len(), 3);
    for (v, cam) in ds.views.iter().zip(&cams) {
        // 0.1 to the image's right (our −x) and 0.05 up (our +y).
        let want = cam.origin - 0.1 * cam.rotation.x_axis + 0.05 * cam.rotation.y_axis;
        assert!(
            (v.light.position - want).length() < 1e-5,
            "{}",
            v.light.position
        );
    }
    let out = tempfile::tempdir().unwrap();
    ds.save(out.path(), false).unwrap();
    let back = Dataset::load(out.path()).unwrap();
    for (v, cam) in back.views.iter().zip(&cams) {
        assert_same_rays(&v.camera, cam);
    }
    // Light positions per image, one missing.
    let lights = d.path().join("lights.txt");
    std::fs::write(&lights, "# name x y z\na.jpg 1 2 3\nsub dir/b.jpg 0 1 0\n").unwrap();
    capture.light = CaptureLight::read_positions(&lights).unwrap();
    let e = model.dataset(&capture).unwrap_err().to_string();
    assert!(
        e.contains("\"c.png\"") && e.contains("has no light position"),
        "{e}"
    );
    std::fs::write(&lights, "a.jpg 1 2\n").unwrap();
    let e = CaptureLight::read_positions(&lights)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("lights.txt:1") && e.contains("NAME X Y Z"),
        "{e}"
    );
}

/// Photos (an sRGB PNG with a saturated pixel) in place of EXRs, with masks in COLMAP's naming
/// and the plain one: the left-out pixels are zero and out of the cameras' measurement, and the
/// masks round-trip through a saved dataset; a missing mask and a photo of another size are
/// refused.
#[test]
fn a_capture_takes_photos_and_masks() {
    let (d, model, mut capture, _) = capture_fixture();
    let images = d.path().join("images");
    // The photo itself (8-bit sRGB, with a saturated pixel) instead of an EXR, with masks in
    // COLMAP's naming (`c.png.png`) and the plain one (`a.png`).
    std::fs::remove_file(images.join("c.exr")).unwrap();
    let mut photo = image::RgbImage::from_pixel(64, 48, image::Rgb([188, 188, 188]));
    photo.put_pixel(3, 2, image::Rgb([255, 10, 10]));
    photo.save(images.join("c.png")).unwrap();
    let masks = d.path().join("masks");
    std::fs::create_dir_all(masks.join("sub dir")).unwrap();
    let mut m = image::GrayImage::from_pixel(64, 48, image::Luma([255]));
    m.put_pixel(10, 20, image::Luma([0]));
    m.save(masks.join("c.png.png")).unwrap();
    m.save(masks.join("a.png")).unwrap();
    m.save(masks.join("sub dir/b.png")).unwrap();
    capture.masks = Some(masks.clone());
    let ds = model.dataset(&capture).unwrap();
    let c = &ds.views[2];
    let mask = c.camera.mask.as_ref().unwrap();
    assert_eq!(mask.count(), 64 * 48 - 2);
    assert!(!c.camera.measures(3, 2) && !c.camera.measures(10, 20) && c.camera.measures(0, 0));
    // sRGB 188/255 is 0.5029 linear; the left-out pixels are zero.
    let v = c.image.as_ref().unwrap();
    assert!(
        (v.get(0, 0)[1] - 0.502886).abs() < 1e-4,
        "{:?}",
        v.get(0, 0)
    );
    assert_eq!((v.get(3, 2), v.get(10, 20)), ([0.0; 3], [0.0; 3]));
    // Masks round-trip through a saved dataset.
    let out = tempfile::tempdir().unwrap();
    ds.save(out.path(), false).unwrap();
    let back = Dataset::load(out.path()).unwrap();
    assert_eq!(back.views[2].camera.mask, c.camera.mask);
    assert_eq!(back.views[2].image, c.image);
    // A missing mask, and an image of another size.
    std::fs::remove_file(masks.join("a.png")).unwrap();
    let e = model.dataset(&capture).unwrap_err().to_string();
    assert!(
        e.contains("a.jpg.png") && e.contains("leave the masks out"),
        "{e}"
    );
    capture.masks = None;
    image::RgbImage::new(32, 48)
        .save(images.join("c.png"))
        .unwrap();
    let e = model.dataset(&capture).unwrap_err().to_string();
    assert!(e.contains("32×48 pixels") && e.contains("64×48"), "{e}");
    std::fs::remove_file(images.join("c.png")).unwrap();
    let e = model.dataset(&capture).unwrap_err().to_string();
    assert!(
        e.contains("c.png") && e.contains("c.exr") && e.contains("missing"),
        "{e}"
    );
}

/// A model written by [`super::write_text`] reads back to the same cameras and names.
#[test]
fn a_written_model_reads_back() {
    let cams = cameras();
    let views: Vec<crate::capture::CapturedView> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| crate::capture::CapturedView {
            name: format!("IMG_{i}.jpg"),
            camera: c.clone(),
        })
        .collect();
    let d = tempfile::tempdir().unwrap();
    super::write_text(d.path(), &views, false).unwrap();
    assert!(super::write_text(d.path(), &views, false).is_err());
    let m = ColmapModel::read(d.path()).unwrap();
    assert_eq!(m.images.len(), 3);
    for (im, v) in m.images.iter().zip(&views) {
        assert_eq!(im.name, v.name);
        assert_same_rays(&m.camera(im).unwrap(), &v.camera);
    }
}
