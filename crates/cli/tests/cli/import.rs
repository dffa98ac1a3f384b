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
    let back = read_json(&d.join("imported/dataset.json"));
    for (i, (v, w)) in ds["views"]
        .as_array()
        .unwrap()
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
    assert!(
        back["truth"].is_null() && back["object"].is_null(),
        "{back}"
    );
    // Nothing is overwritten without permission; the light is required; photos are refused.
    let again = import(&[]);
    assert_stderr_has(&again, &["already exists", "--overwrite"]);
    let no_light = fails(
        d,
        &[
            "import", "colmap", "model", "--images", "photos", "--mesh", "cube.ply", "--out", "x",
        ],
    );
    assert_stderr_has(&no_light, &["--flash", "--light-positions"]);
    std::fs::rename(d.join("photos/IMG_002.exr"), d.join("photos/IMG_002.JPG")).unwrap();
    let photo = import(&["--overwrite", "--eta", "1.4"]);
    assert_stderr_has(&photo, &["IMG_002.exr", "is a photo", "linear EXR"]);
}
