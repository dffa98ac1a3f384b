//! `translucent import colmap`: a dataset's cameras and lights written as a COLMAP model (by the
//! format's definition: world-to-camera poses, x right, y down) with its images renamed as a
//! camera names them, imported back into a dataset that renders the same images.

use std::fmt::Write as _;

use glam::{DMat3, DQuat, DVec3};

use crate::helpers::*;

#[test]
fn a_colmap_capture_imports_as_the_dataset_it_came_from() {
    let dir = tmp();
    let d = dir.path();
    write(&d.join("cube.ply"), cube_ply());
    ok(
        d,
        &[
            "-q", "dataset", "--mesh", "cube.ply", "--views", "3", "--res", "12", "--spp", "4",
            "--out", "ds",
        ],
    );
    let ds = read_json(&d.join("ds/dataset.json"));
    std::fs::create_dir_all(d.join("model")).unwrap();
    std::fs::create_dir_all(d.join("photos")).unwrap();
    let (mut cameras, mut images, mut lights) = (String::new(), String::new(), String::new());
    for (i, v) in ds["views"].as_array().unwrap().iter().enumerate() {
        let c = &v["camera"];
        let m = |r: usize, k: usize| c["to_world"][r][k].as_f64().unwrap();
        let axis = |k: usize| DVec3::new(m(0, k), m(1, k), m(2, k));
        let r = DMat3::from_cols(-axis(0), -axis(1), axis(2)).transpose();
        let q = DQuat::from_mat3(&r);
        let t = -(r * axis(3));
        let (w, fov) = (
            c["width"].as_f64().unwrap(),
            c["fov_x_deg"].as_f64().unwrap(),
        );
        let f = 0.5 * w / (0.5 * fov.to_radians()).tan();
        let _ = writeln!(cameras, "{} SIMPLE_PINHOLE 12 12 {f} 6 6", i + 1);
        let _ = writeln!(
            images,
            "{} {} {} {} {} {} {} {} {} IMG_{i:03}.JPG\n",
            10 + i,
            q.w,
            q.x,
            q.y,
            q.z,
            t.x,
            t.y,
            t.z,
            i + 1
        );
        let p = &v["light"]["position"];
        let _ = writeln!(lights, "IMG_{i:03}.JPG {} {} {}", p[0], p[1], p[2]);
        std::fs::copy(
            d.join("ds").join(format!("view_{i:03}.exr")),
            d.join("photos").join(format!("IMG_{i:03}.exr")),
        )
        .unwrap();
    }
    write(&d.join("model/cameras.txt"), cameras);
    write(&d.join("model/images.txt"), images);
    write(&d.join("lights.txt"), lights);
    let intensity = ds["views"][0]["light"]["intensity"][0].to_string();
    let import = |extra: &[&str]| {
        let mut args = vec![
            "import",
            "colmap",
            "model",
            "--images",
            "photos",
            "--mesh",
            "cube.ply",
            "--light-positions",
            "lights.txt",
            "--intensity",
            &intensity,
            "--out",
            "imported",
        ];
        args.extend_from_slice(extra);
        translucent(d, &args)
    };
    let run = import(&[]);
    assert_eq!(run.code, Some(0), "{}", run.describe());
    assert_stdout_has(
        &run,
        &[
            "3 views from model (3 cameras)",
            "nothing stated",
            "model's own units",
        ],
    );
    // The imported dataset holds the cameras, lights and images of the one it came from.
    let back = assert_imported_as(d, &ds);
    assert!(
        back["truth"].is_null() && back["object"].is_null(),
        "{back}"
    );
    // Nothing is overwritten without permission; the light is required.
    let again = import(&[]);
    assert_stderr_has(&again, &["already exists", "--overwrite"]);
    let no_light = fails(
        d,
        &[
            "import", "colmap", "model", "--images", "photos", "--mesh", "cube.ply", "--out", "x",
        ],
    );
    assert_stderr_has(&no_light, &["--flash", "--light-positions"]);
    // A photo in place of an EXR (a JPEG, sRGB-decoded, one pixel saturated) and masks in
    // COLMAP's naming: the pixels they leave out are zero in the dataset, which keeps the masks.
    std::fs::remove_file(d.join("photos/IMG_002.exr")).unwrap();
    let mut jpeg = image::RgbImage::from_pixel(12, 12, image::Rgb([90, 90, 90]));
    // In another 8 × 8 block than the pixel checked below (the JPEG rings within a block).
    jpeg.put_pixel(1, 10, image::Rgb([255, 255, 255]));
    jpeg.save_with_format(d.join("photos/IMG_002.JPG"), image::ImageFormat::Jpeg)
        .unwrap();
    std::fs::create_dir_all(d.join("masks")).unwrap();
    for i in 0..3 {
        image::GrayImage::from_fn(12, 12, |x, _| image::Luma([if x < 6 { 255 } else { 0 }]))
            .save(d.join(format!("masks/IMG_{i:03}.JPG.png")))
            .unwrap();
    }
    let photo = import(&["--overwrite", "--eta", "1.4", "--masks", "masks"]);
    assert_eq!(photo.code, Some(0), "{}", photo.describe());
    // 3 views × 72 pixels inside the masks, less the saturated one.
    assert_stdout_has(&photo, &["pixels in the fit: 215 of 432 (49.8 %"]);
    let back = read_json(&d.join("imported/dataset.json"));
    assert_eq!(back["views"][2]["mask"], "mask_002.png");
    let img = scene::Image::read_exr(&d.join("imported/view_002.exr")).unwrap();
    // sRGB 90 is 0.1022 linear (the JPEG's rounding within 5 %).
    let want = scene::image::srgb_to_linear(90.0 / 255.0);
    assert!(img.get(7, 3) == [0.0; 3] && img.get(1, 10) == [0.0; 3]);
    assert!(
        (img.get(3, 3)[0] - want).abs() < 0.05 * want,
        "{:?}",
        img.get(3, 3)
    );
    let half = import(&["--overwrite", "--masks", "masks", "--exposure", "0.5"]);
    assert_eq!(half.code, Some(0), "{}", half.describe());
    let img = scene::Image::read_exr(&d.join("imported/view_002.exr")).unwrap();
    assert!(
        (img.get(3, 3)[0] - 0.5 * want).abs() < 0.025 * want,
        "{:?}",
        img.get(3, 3)
    );
}

/// A dataset's views written as a NeRF `transforms.json` (OpenGL camera-to-world, x right, y up,
/// looking along −z; the field of view as `camera_angle_x`; a light per frame), imported back
/// into the same cameras, lights and images.
#[test]
fn a_transforms_json_imports_as_the_dataset_it_came_from() {
    let dir = tmp();
    let d = dir.path();
    write(&d.join("cube.ply"), cube_ply());
    ok(
        d,
        &[
            "-q", "dataset", "--mesh", "cube.ply", "--views", "2", "--res", "10", "--spp", "4",
            "--out", "ds",
        ],
    );
    let ds = read_json(&d.join("ds/dataset.json"));
    let views = ds["views"].as_array().unwrap();
    let frames: Vec<serde_json::Value> = views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let m = &v["camera"]["to_world"];
            let e = |r: usize, k: usize| m[r][k].as_f64().unwrap();
            let rows: Vec<Vec<f64>> = (0..3)
                .map(|r| vec![-e(r, 0), e(r, 1), -e(r, 2), e(r, 3)])
                .chain([vec![0.0, 0.0, 0.0, 1.0]])
                .collect();
            serde_json::json!({
                "file_path": format!("view_{i:03}"),
                "transform_matrix": rows,
                "light_position": v["light"]["position"],
            })
        })
        .collect();
    let fov = views[0]["camera"]["fov_x_deg"].as_f64().unwrap();
    let doc = serde_json::json!({
        "camera_angle_x": fov.to_radians(),
        "frames": frames,
    });
    write(&d.join("ds/transforms.json"), doc.to_string());
    let intensity = views[0]["light"]["intensity"][0].to_string();
    let run = translucent(
        d,
        &[
            "import",
            "nerf",
            "ds/transforms.json",
            "--mesh",
            "cube.ply",
            "--intensity",
            &intensity,
            "--out",
            "imported",
        ],
    );
    assert_eq!(run.code, Some(0), "{}", run.describe());
    assert_stdout_has(&run, &["2 views from ds/transforms.json", "100.0 %"]);
    assert_imported_as(d, &ds);
    // Without a light in the file or on the command line: refused, with the fix.
    let mut bare = doc.clone();
    for f in bare["frames"].as_array_mut().unwrap() {
        f.as_object_mut().unwrap().remove("light_position");
    }
    write(&d.join("ds/transforms.json"), bare.to_string());
    let e = fails(
        d,
        &[
            "import",
            "nerf",
            "ds/transforms.json",
            "--mesh",
            "cube.ply",
            "--out",
            "x",
        ],
    );
    assert_stderr_has(&e, &["no frame states a light", "--flash"]);
}

/// `dataset --as-capture` writes the render as a photographed capture (COLMAP model, sRGB JPEGs,
/// silhouette masks, the mesh, the lights, the truth), and the command it prints imports it back:
/// the same cameras, and the photos' linear values those of the render times the exposure
/// within the JPEG's rounding.
#[test]
fn a_capture_written_by_dataset_imports_back() {
    let dir = tmp();
    let d = dir.path();
    let r = ok(
        d,
        &[
            "dataset",
            "--shape",
            "sphere",
            "--views",
            "2",
            "--res",
            "16",
            "--spp",
            "16",
            "--light",
            "attached",
            "--units",
            "cm",
            "--as-capture",
            "--out",
            "cap",
        ],
    );
    assert_stdout_has(
        &r,
        &["capture: 2 photos", "import it: translucent import colmap"],
    );
    let line = r
        .stdout
        .lines()
        .find(|l| l.starts_with("import it: "))
        .unwrap();
    let cmd: Vec<&str> = line["import it: translucent ".len()..]
        .split(' ')
        .map(|w| if w == "DATASET" { "imported" } else { w })
        .collect();
    assert!(
        cmd.contains(&"--flash=-0.8,-0.8,0") && cmd.contains(&"cm"),
        "{line}"
    );
    let run = translucent(d, &cmd);
    assert_eq!(run.code, Some(0), "{}", run.describe());
    let truth = read_json(&d.join("cap/truth.json"));
    let exposure = truth["photo_exposure"].as_f64().unwrap() as f32;
    let rendered = scene::Dataset::load(&d.join("cap/rendered")).unwrap();
    let back = scene::Dataset::load(&d.join("imported")).unwrap();
    assert_eq!(
        back.metadata.length_unit,
        Some(scene::measured::LengthUnit::Cm)
    );
    for (a, b) in rendered.views.iter().zip(&back.views) {
        assert!((a.camera.origin - b.camera.origin).length() < 1e-4);
        assert!((a.light.position - b.light.position).length() < 1e-4);
        let mask = b
            .camera
            .mask
            .as_ref()
            .expect("the silhouette leaves the background out");
        assert!(mask.count() > 40 && mask.count() < 256, "{}", mask.count());
        let (ia, ib) = (a.image.as_ref().unwrap(), b.image.as_ref().unwrap());
        let (mut sum_a, mut sum_b) = (0.0, 0.0);
        for (i, (pa, pb)) in ia.data.iter().zip(&ib.data).enumerate() {
            if mask.bits[i] {
                sum_a += (pa[1] * exposure).min(1.0) as f64;
                sum_b += pb[1] as f64;
            } else {
                assert_eq!(*pb, [0.0; 3]);
            }
        }
        assert!((sum_b / sum_a - 1.0).abs() < 0.03, "{sum_b} {sum_a}");
    }
}

/// The dataset `d/imported` has the cameras (a centred camera with no intrinsics block), lights
/// and images of `ds` (the dataset.json of `d/ds`); returns the imported dataset.json.
fn assert_imported_as(d: &std::path::Path, ds: &serde_json::Value) -> serde_json::Value {
    let back = read_json(&d.join("imported/dataset.json"));
    let views = ds["views"].as_array().unwrap();
    for (i, (v, w)) in views
        .iter()
        .zip(back["views"].as_array().unwrap())
        .enumerate()
    {
        let num = |x: &serde_json::Value| x.as_f64().unwrap();
        for r in 0..3 {
            for k in 0..4 {
                let (a, b) = (
                    num(&v["camera"]["to_world"][r][k]),
                    num(&w["camera"]["to_world"][r][k]),
                );
                assert!((a - b).abs() < 1e-5, "view {i} to_world[{r}][{k}]: {a} {b}");
            }
        }
        let (a, b) = (
            num(&v["camera"]["fov_x_deg"]),
            num(&w["camera"]["fov_x_deg"]),
        );
        assert!((a - b).abs() < 1e-4, "view {i} fov: {a} {b}");
        assert!(
            w["camera"]["intrinsics"].is_null(),
            "a centred camera has no intrinsics block"
        );
        assert_eq!(v["light"], w["light"], "view {i}");
        let name = format!("view_{i:03}.exr");
        assert_eq!(
            read(&d.join("ds").join(&name)),
            read(&d.join("imported").join(&name))
        );
    }
    back
}
