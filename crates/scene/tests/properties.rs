//! Property tests (proptest) of the scene crate: camera rays and projection are inverse to each
//! other; EXR images, datasets and media survive a write → read round trip; random valid scene
//! files parse to what they say.

use geometry::Vec3;
use proptest::prelude::*;
use scene::{Camera, Dataset, Image, Medium, MeshSource, PointLight, RenderInfo, SceneDesc};

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 128,
        failure_persistence: None,
        // A fixed seed: the same inputs on every run (the tests are deterministic).
        rng_seed: proptest::test_runner::RngSeed::Fixed(2),
        ..ProptestConfig::default()
    }
}

fn vec3(r: f32) -> impl Strategy<Value = Vec3> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

/// A camera 0.5–5 units from a random target, looking at it, not straight along ±Y (the up
/// vector), fov 10–120°, 1–400 pixels each way.
fn camera() -> impl Strategy<Value = Camera> {
    (
        vec3(1.0),
        vec3(1.0).prop_filter("a direction", |d| {
            d.length() > 0.1 && d.normalize().y.abs() < 0.99
        }),
        0.5f32..5.0,
        10.0f32..120.0,
        1u32..400,
        1u32..400,
    )
        .prop_map(|(target, dir, dist, fov, w, h)| {
            let origin = target + dir.normalize() * dist;
            Camera::look_at(origin, target, Vec3::Y, fov, w, h)
        })
}

fn medium() -> impl Strategy<Value = Medium> {
    (
        prop::array::uniform3(0.01f32..1000.0),
        prop::array::uniform3(0.0f32..0.999),
        prop_oneof![
            (-0.9f32..0.9).prop_map(scene::Anisotropy::uniform),
            prop::array::uniform3(-0.9f32..0.9).prop_map(scene::Anisotropy),
        ],
        1.0f32..2.0,
    )
        .prop_map(|(sigma_t, albedo, g, eta)| Medium {
            sigma_t,
            albedo,
            g,
            eta,
            roughness: 0.0,
        })
}

/// Finite pixel values across many magnitudes, zeros included.
fn pixel() -> impl Strategy<Value = [f32; 3]> {
    prop::array::uniform3(prop_oneof![
        Just(0.0f32),
        0.0f32..1.0,
        (-30i32..30, 1.0f32..2.0).prop_map(|(e, m)| m * 2f32.powi(e)),
    ])
}

fn image(max: u32) -> impl Strategy<Value = Image> {
    (1u32..max, 1u32..max).prop_flat_map(|(w, h)| {
        prop::collection::vec(pixel(), (w * h) as usize).prop_map(move |data| {
            let mut img = Image::new(w, h);
            img.data = data;
            img
        })
    })
}

proptest! {
    #![proptest_config(config())]

    /// A point on the primary ray through film position (px, py) projects back to (px, py), and
    /// the ray through a projected point passes through it.
    #[test]
    fn camera_ray_and_projection_are_inverse(
        cam in camera(),
        fx in 0.0f32..1.0,
        fy in 0.0f32..1.0,
        t in 0.1f32..10.0,
    ) {
        let (px, py) = (fx * cam.width as f32, fy * cam.height as f32);
        let (o, d) = cam.ray(px, py);
        prop_assert!((d.length() - 1.0).abs() < 1e-5);
        let p = o + d * t;
        let (qx, qy) = cam.project(p).expect("a point in front of the camera");
        let tol = 2e-3 * (1.0 + cam.width.max(cam.height) as f32 / 100.0);
        prop_assert!((qx - px).abs() < tol && (qy - py).abs() < tol, "({px}, {py}) → ({qx}, {qy})");
        let (_, d2) = cam.ray(qx, qy);
        let off = (p - o).cross(d2).length();
        prop_assert!(off < 1e-4 * (1.0 + t), "ray misses the point by {off}");
    }

    /// A point behind the camera has no projection.
    #[test]
    fn points_behind_the_camera_do_not_project(cam in camera(), fx in 0.0f32..1.0, fy in 0.0f32..1.0, t in 0.1f32..10.0) {
        let (o, d) = cam.ray(fx * cam.width as f32, fy * cam.height as f32);
        prop_assert!(cam.project(o - d * t).is_none());
    }

    /// OpenEXR: float32 RGB images are read back bit for bit.
    #[test]
    fn exr_round_trip_is_exact(img in image(24)) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("i.exr");
        img.write_exr(&path, false).unwrap();
        let back = Image::read_exr(&path).unwrap();
        prop_assert_eq!((back.width, back.height), (img.width, img.height));
        for (a, b) in back.data.iter().zip(&img.data) {
            prop_assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits));
        }
    }

    /// A dataset (built-in shape, random medium, cameras, lights, images) is read back with the
    /// same truth, render settings, cameras (to 1e-6), lights and images.
    #[test]
    fn dataset_round_trip(
        med in medium(),
        cams in prop::collection::vec((camera(), vec3(3.0), prop::array::uniform3(0.01f32..100.0)), 1..4),
        seed in any::<u64>(),
        spp in 1u32..10_000,
    ) {
        let desc = SceneDesc {
            mesh: MeshSource::Shape(geometry::Shape::from_name("sphere").unwrap()),
            medium: med,
            views: cams
                .iter()
                .map(|(c, p, i)| scene::ViewDesc {
                    camera: Camera { width: 3, height: 2, ..c.clone() },
                    light: PointLight { position: *p, intensity: *i },
                })
                .collect(),
            render: RenderInfo { spp: Some(spp), max_depth: Some(64), seed: Some(seed), renderer: Some("test".into()) },
            path: Default::default(),
            length_unit: None,
        };
        let mut ds = Dataset::from_scene(&desc);
        for (k, v) in ds.views.iter_mut().enumerate() {
            let mut img = Image::new(3, 2);
            for (j, px) in img.data.iter_mut().enumerate() {
                *px = [k as f32, j as f32 * 0.25, 1.5];
            }
            v.image = Some(img);
        }
        let dir = tempfile::tempdir().unwrap();
        ds.save(dir.path(), false).unwrap();
        let back = Dataset::load(dir.path()).unwrap();
        prop_assert_eq!(back.truth, Some(med));
        prop_assert_eq!(&back.render, &ds.render);
        prop_assert_eq!(back.views.len(), ds.views.len());
        for (a, b) in back.views.iter().zip(&ds.views) {
            prop_assert_eq!(a.light, b.light);
            prop_assert_eq!((a.camera.width, a.camera.height), (b.camera.width, b.camera.height));
            prop_assert!((a.camera.fov_x_deg - b.camera.fov_x_deg).abs() <= 1e-6 * b.camera.fov_x_deg);
            prop_assert!((a.camera.origin - b.camera.origin).length() <= 1e-6 * (1.0 + b.camera.origin.length()));
            prop_assert!((a.camera.rotation - b.camera.rotation).abs_diff_eq(geometry::Mat3::ZERO, 1e-6));
            prop_assert_eq!(&a.image.as_ref().unwrap().data, &b.image.as_ref().unwrap().data);
        }
    }

    /// The medium serialises to JSON and back unchanged.
    #[test]
    fn medium_json_round_trip(med in medium()) {
        let text = serde_json::to_string(&med).unwrap();
        let back: Medium = serde_json::from_str(&text).unwrap();
        prop_assert_eq!(back, med);
    }

    /// A random valid scene file (rig or listed views, any built-in shape, one or three numbers
    /// per RGB field), in TOML and JSON, parses to the values it states.
    #[test]
    fn random_valid_scene_files_parse(
        med in medium(),
        shape in prop::sample::select(vec!["sphere", "blob", "torus"]),
        scale in 0.1f32..3.0,
        views in 1usize..20,
        radius in 0.5f32..10.0,
        fov in 5.0f32..150.0,
        w in 1u32..2000,
        h in 1u32..2000,
        attached in any::<bool>(),
        grey in any::<bool>(),
        listed in any::<bool>(),
    ) {
        let rgb = |v: [f32; 3]| {
            if grey { format!("{:?}", v[0]) } else { format!("[{:?}, {:?}, {:?}]", v[0], v[1], v[2]) }
        };
        // One g is written as one number, a g per channel as three.
        let g = match med.g.as_uniform() {
            Some(g) => format!("{g:?}"),
            None => format!("[{:?}, {:?}, {:?}]", med.g.0[0], med.g.0[1], med.g.0[2]),
        };
        let sigma_t = if grey { [med.sigma_t[0]; 3] } else { med.sigma_t };
        let mut toml = format!(
            "shape = {{ name = \"{shape}\", scale = {scale:?} }}\n\n[medium]\nsigma_t = {}\nalbedo = {}\ng = {g}\neta = {:?}\n",
            rgb(sigma_t), rgb(med.albedo), med.eta
        );
        if listed {
            for k in 0..views {
                let a = k as f32;
                toml.push_str(&format!(
                    "\n[[views]]\ncamera = {{ origin = [{:?}, 0.5, {:?}], target = [0.0, 0.0, 0.0], fov = {fov:?}, width = {w}, height = {h} }}\nlight = {{ position = [1.0, 2.0, 3.0], intensity = 4.0 }}\n",
                    radius * a.cos(), radius * a.sin()
                ));
            }
        } else {
            toml.push_str(&format!(
                "\n[rig]\nviews = {views}\nradius = {radius:?}\nfov = {fov:?}\nwidth = {w}\nheight = {h}\nlight = \"{}\"\nintensity = 4.0\n",
                if attached { "attached" } else { "fixed" }
            ));
            if attached {
                toml.push_str("light_offset = [0.1, 0.1, 0.0]\n");
            } else {
                toml.push_str("light_position = [1.0, 1.5, 0.5]\n");
            }
        }
        let desc = SceneDesc::parse(&toml, std::path::Path::new("s.toml"))
            .map_err(|e| TestCaseError::fail(format!("{e}\n{toml}")))?;
        prop_assert_eq!(desc.medium.sigma_t, sigma_t);
        prop_assert_eq!(desc.medium.albedo, if grey { [med.albedo[0]; 3] } else { med.albedo });
        prop_assert_eq!((desc.medium.g, desc.medium.eta), (med.g, med.eta));
        prop_assert_eq!(desc.views.len(), views);
        for v in &desc.views {
            prop_assert_eq!((v.camera.width, v.camera.height), (w, h));
            prop_assert!((v.camera.fov_x_deg - fov).abs() < 1e-4 * fov);
        }
        // The same scene in JSON.
        let value: toml::Value = toml::from_str(&toml).unwrap();
        let json = serde_json::to_string(&value).unwrap();
        let from_json = SceneDesc::parse(&json, std::path::Path::new("s.json"))
            .map_err(|e| TestCaseError::fail(format!("{e}\n{json}")))?;
        prop_assert_eq!(from_json.medium, desc.medium);
        prop_assert_eq!(from_json.views.len(), desc.views.len());
    }
}
