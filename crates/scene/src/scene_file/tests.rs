//! Tests of scene files: TOML/JSON equivalence, shapes and rigs, validation errors naming the
//! field, unknown fields with line and column, mesh loading, and the examples of SCENE.md.
//! [`code_blocks`] is shared with the dataset tests.

use glam::Vec3;

use super::*;
use crate::{Camera, Medium, PointLight};

const FULL_TOML: &str = r#"
mesh = "meshes/object.ply"

[medium]
sigma_t = [50, 60.5, 70]
albedo = 0.9
g = 0.2
eta = 1.3

[[views]]
camera = { origin = [0, 0, 3], target = [0, 0, 0], up = [0, 1, 0], fov = 35, width = 64, height = 48 }
light = { position = [1, 2, 3], intensity = [1, 2, 3] }

[[views]]
camera = { origin = [3, 1, 0], target = [0, 0.1, 0], width = 32, height = 32 }
light = { position = [0, 5, 0], intensity = 2.5 }

[render]
spp = 128
max_depth = 32
seed = 7
renderer = "volpath"
"#;

const FULL_JSON: &str = r#"{
  "mesh": "meshes/object.ply",
  "medium": { "sigma_t": [50, 60.5, 70], "albedo": 0.9, "g": 0.2, "eta": 1.3 },
  "views": [
    { "camera": { "origin": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 35, "width": 64, "height": 48 },
      "light": { "position": [1, 2, 3], "intensity": [1, 2, 3] } },
    { "camera": { "origin": [3, 1, 0], "target": [0, 0.1, 0], "width": 32, "height": 32 },
      "light": { "position": [0, 5, 0], "intensity": 2.5 } }
  ],
  "render": { "spp": 128, "max_depth": 32, "seed": 7, "renderer": "volpath" }
}"#;

/// A temp folder with an (empty) mesh file at meshes/object.ply.
fn folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::write(dir.path().join("meshes/object.ply"), b"ply\n").unwrap();
    dir
}

fn parse_toml(text: &str) -> Result<SceneDesc, SceneError> {
    let dir = folder();
    SceneDesc::parse(text, &dir.path().join("scene.toml"))
}

fn err_toml(text: &str) -> String {
    parse_toml(text).expect_err("must be rejected").to_string()
}

#[test]
fn full_example_parses_the_same_in_toml_and_json() {
    let dir = folder();
    let st = dir.path().join("scene.toml");
    let sj = dir.path().join("scene.json");
    std::fs::write(&st, FULL_TOML).unwrap();
    std::fs::write(&sj, FULL_JSON).unwrap();
    let a = SceneDesc::load(&st).unwrap();
    let b = SceneDesc::load(&sj).unwrap();
    assert_eq!(
        a.mesh,
        MeshSource::File(dir.path().join("meshes/object.ply"))
    );
    assert_eq!(a.mesh, b.mesh);
    assert_eq!(
        a.medium,
        Medium {
            sigma_t: [50.0, 60.5, 70.0],
            albedo: [0.9; 3],
            g: crate::Anisotropy::uniform(0.2),
            eta: 1.3,
            roughness: 0.0,
        }
    );
    assert_eq!(a.medium, b.medium);
    assert_eq!(a.views, b.views);
    assert_eq!(a.render, b.render);
    assert_eq!(
        a.render,
        RenderInfo {
            spp: Some(128),
            max_depth: Some(32),
            seed: Some(7),
            renderer: Some("volpath".into())
        }
    );
    assert_eq!(a.views.len(), 2);
    let v0 = &a.views[0];
    assert_eq!(
        v0.camera,
        Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y, 35.0, 64, 48)
    );
    assert_eq!(
        v0.light,
        PointLight {
            position: Vec3::new(1.0, 2.0, 3.0),
            intensity: [1.0, 2.0, 3.0]
        }
    );
    let v1 = &a.views[1];
    assert_eq!(v1.camera.fov_x_deg, 40.0, "default fov");
    assert_eq!(
        v1.camera,
        Camera::look_at(
            Vec3::new(3.0, 1.0, 0.0),
            Vec3::new(0.0, 0.1, 0.0),
            Vec3::Y,
            40.0,
            32,
            32
        )
    );
    assert_eq!(
        v1.light.intensity, [2.5; 3],
        "scalar intensity is broadcast"
    );
    assert_eq!(a.path, st);
}

#[test]
fn example_scene_with_shape_and_rig_parses() {
    let s = parse_toml(EXAMPLE_SCENE_TOML).unwrap();
    assert_eq!(s.views.len(), 8);
    let MeshSource::Shape(shape) = &s.mesh else {
        panic!("shape expected")
    };
    assert_eq!(shape.name(), "blob");
    let default = geometry::Shape::from_name("blob").unwrap().scaled(0.5);
    assert_eq!(*shape, default);
    for v in &s.views {
        assert!((v.camera.origin.length() - 2.0).abs() < 1e-5);
        assert_eq!(v.light.position, Vec3::new(1.0, 1.5, 0.5));
        assert_eq!(v.light.intensity, [4.0; 3]);
        assert_eq!((v.camera.width, v.camera.height), (128, 128));
    }
    assert_eq!(s.render.spp, Some(256));
}

#[test]
fn shape_parameters_override_defaults_then_scale() {
    let s = parse_toml(
        r#"shape = { name = "sphere", radius = 0.125, subdivisions = 3, scale = 2 }
               medium = { sigma_t = 1, albedo = 0.5 }
               rig = { views = 2, radius = 1, width = 4, height = 4, light = "attached", intensity = 1 }"#,
    )
    .unwrap();
    assert_eq!(
        s.mesh,
        MeshSource::Shape(geometry::Shape::Sphere {
            radius: 0.25,
            subdivisions: 3
        })
    );
    assert_eq!(s.medium.g, crate::Anisotropy::ISOTROPIC);
    assert_eq!(s.medium.eta, 1.0);
    // Attached light without an offset sits at the camera.
    assert_eq!(s.views[1].light.position, s.views[1].camera.origin);
    let spec = ShapeSpec::from_shape(&geometry::Shape::Torus {
        major: 1.0,
        minor: 0.25,
        segments: 9,
    });
    assert_eq!(
        spec.to_shape("x").unwrap(),
        geometry::Shape::Torus {
            major: 1.0,
            minor: 0.25,
            segments: 9
        }
    );
    let msg = err_toml(
        r#"shape = { name = "sphere", major = 1 }
               medium = { sigma_t = 1, albedo = 0.5 }
               rig = { views = 2, radius = 1, width = 4, height = 4, light = "attached", intensity = 1 }"#,
    );
    assert!(
        msg.contains("shape.major") && msg.contains("radius, subdivisions"),
        "{msg}"
    );
    let msg = err_toml(
        r#"shape = { name = "teapot" }
               medium = { sigma_t = 1, albedo = 0.5 }
               rig = { views = 2, radius = 1, width = 4, height = 4, light = "attached", intensity = 1 }"#,
    );
    assert!(
        msg.contains("shape.name = \"teapot\"") && msg.contains("sphere"),
        "{msg}"
    );
}

/// A valid scene with one view, with `replace` substituted into it.
#[test]
fn compact_shape_specs_parse_and_errors_name_the_option() {
    let spec = ShapeSpec::parse_compact("blob:amplitude=0.05:bumps=6", "--shapes").unwrap();
    let geometry::Shape::Blob {
        amplitude, bumps, ..
    } = spec.to_shape("--shapes").unwrap()
    else {
        panic!("not a blob: {spec:?}");
    };
    assert_eq!((amplitude, bumps), (0.05, 6));
    // The bare name is the built-in default shape.
    let plain = ShapeSpec::parse_compact("torus", "--shapes").unwrap();
    assert_eq!(
        plain.to_shape("--shapes").unwrap(),
        geometry::Shape::from_name("torus").unwrap()
    );
    for (text, wanted) in [
        ("", "names no shape"),
        ("blob:amplitude", "not KEY=VALUE"),
        ("blob:ampl itude=1", "not a parameter name"),
        ("blob:colour=1", "colour"),
        ("blob:amplitude=x", "--shapes \"blob:amplitude=x\""),
    ] {
        let msg = ShapeSpec::parse_compact(text, "--shapes")
            .unwrap_err()
            .to_string();
        assert!(msg.contains(wanted), "{text:?}: {msg}");
    }
    // A parameter the shape does not have is caught when the shape is built.
    let msg = ShapeSpec::parse_compact("sphere:major=1", "--shapes")
        .unwrap()
        .to_shape("--shapes")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("no parameter 'major'"), "{msg}");
}

fn one_view(replace: &[(&str, &str)]) -> String {
    let mut s = r#"
mesh = "meshes/object.ply"
[medium]
sigma_t = [50, 60, 70]
albedo = [0.9, 0.9, 0.9]
g = 0
eta = 1
[[views]]
camera = { origin = [0, 0, 3], target = [0, 0, 0], up = [0, 1, 0], fov = 40, width = 16, height = 16 }
light = { position = [1, 1, 1], intensity = 1 }
"#
    .to_string();
    for (a, b) in replace {
        assert!(s.contains(a), "{a}");
        s = s.replace(a, b);
    }
    s
}

#[test]
fn one_view_base_is_valid() {
    parse_toml(&one_view(&[])).unwrap();
}

#[test]
fn validation_errors_name_the_field() {
    let cases: &[(&[(&str, &str)], &[&str])] = &[
        (
            &[("sigma_t = [50, 60, 70]", "sigma_t = [50, 0, 70]")],
            &[
                "scene.toml: medium.sigma_t[1] = 0",
                "extinction must be > 0",
            ],
        ),
        (
            &[("sigma_t = [50, 60, 70]", "sigma_t = -3")],
            &["medium.sigma_t[0] = -3"],
        ),
        (
            &[("albedo = [0.9, 0.9, 0.9]", "albedo = [0.9, 1.0, 0.9]")],
            &["medium.albedo[1] = 1", "[0, 1)"],
        ),
        (
            &[("albedo = [0.9, 0.9, 0.9]", "albedo = -0.5")],
            &["medium.albedo[0] = -0.5"],
        ),
        (&[("g = 0", "g = 1")], &["medium.g = 1"]),
        (&[("g = 0", "g = -1.2")], &["medium.g = -1.2"]),
        (&[("eta = 1", "eta = 0.8")], &["medium.eta = 0.8"]),
        (
            &[("width = 16", "width = 0")],
            &["views[0].camera.width", "resolution"],
        ),
        (
            &[("height = 16", "height = 0")],
            &["views[0].camera.height"],
        ),
        (
            &[("fov = 40", "fov = 0")],
            &["views[0].camera.fov", "(0, 180)"],
        ),
        (&[("fov = 40", "fov = 180")], &["views[0].camera.fov"]),
        (
            &[
                ("up = [0, 1, 0]", "up = [0, 2, 0]"),
                ("origin = [0, 0, 3]", "origin = [0, 3, 0]"),
            ],
            &["views[0].camera.up", "parallel"],
        ),
        (
            &[("origin = [0, 0, 3]", "origin = [0, 0, 0]")],
            &["views[0].camera.target", "sits at its target"],
        ),
        (
            &[("intensity = 1", "intensity = [1, -1, 1]")],
            &["views[0].light.intensity[1] = -1"],
        ),
        (
            &[("intensity = 1", "intensity = nan")],
            &["views[0].light.intensity[0] = NaN"],
        ),
        (
            &[("position = [1, 1, 1]", "position = [1, inf, 1]")],
            &["views[0].light.position"],
        ),
        (
            &[(
                "mesh = \"meshes/object.ply\"",
                "mesh = \"meshes/object.ply\"\nshape = { name = \"sphere\" }",
            )],
            &["mesh, shape", "exactly one"],
        ),
        (
            &[("mesh = \"meshes/object.ply\"", "")],
            &["scene.toml: mesh", "no geometry"],
        ),
        (
            &[("mesh = \"meshes/object.ply\"", "mesh = \"nope.obj\"")],
            &["mesh = \"nope.obj\"", "not found", "relative"],
        ),
    ];
    for (repl, wants) in cases {
        let msg = err_toml(&one_view(repl));
        for w in *wants {
            assert!(msg.contains(w), "{repl:?}: {msg:?} should contain {w:?}");
        }
        assert!(msg.contains("scene.toml"), "{msg}");
    }
}

#[test]
fn unknown_fields_are_errors_with_line_and_column() {
    let msg = err_toml(&one_view(&[("g = 0", "g = 0\nsigma_s = 3")]));
    assert!(
        msg.contains("sigma_s") && msg.contains("line 7") && msg.contains("column"),
        "{msg}"
    );
    let msg = err_toml(&one_view(&[("fov = 40", "fov_y = 40")]));
    assert!(
        msg.contains("fov_y") && msg.contains("line 9, column 68"),
        "{msg}"
    );
    let msg = err_toml(&one_view(&[("mesh = ", "mesh_file = ")]));
    assert!(msg.contains("mesh_file"), "{msg}");
    // JSON too (line/column from serde_json).
    let dir = folder();
    let msg = SceneDesc::parse(
        &FULL_JSON.replace("\"g\": 0.2", "\"gg\": 0.2"),
        &dir.path().join("s.json"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        msg.contains("unknown field `gg`") && msg.contains("line 3"),
        "{msg}"
    );
    // Wrong type and unknown extension.
    let msg = err_toml(&one_view(&[("width = 16", "width = -16")]));
    assert!(msg.contains("line 9") && msg.contains("width"), "{msg}");
    let msg = SceneDesc::parse("", &dir.path().join("scene.yaml"))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("scene.yaml") && msg.contains(".toml"), "{msg}");
}

#[test]
fn views_and_rig_are_exclusive_and_rig_lights_checked() {
    let rig = r#"
[rig]
views = 3
radius = 2
width = 8
height = 8
light = "fixed"
light_position = [0, 3, 0]
intensity = [1, 1, 1]
"#;
    let msg = err_toml(&(one_view(&[]) + rig));
    assert!(msg.contains("views, rig"), "{msg}");
    let no_views = |extra: &str| {
        let base = one_view(&[]);
        let cut = base.find("[[views]]").unwrap();
        format!("{}{extra}", &base[..cut])
    };
    let s = parse_toml(&no_views(rig)).unwrap();
    assert_eq!(s.views.len(), 3);
    let msg = err_toml(&no_views(&rig.replace("light_position = [0, 3, 0]\n", "")));
    assert!(
        msg.contains("rig.light_position") && msg.contains("missing"),
        "{msg}"
    );
    let msg = err_toml(&no_views(&rig.replace("\"fixed\"", "\"attached\"")));
    assert!(
        msg.contains("rig.light_position") && msg.contains("attached"),
        "{msg}"
    );
    let msg = err_toml(&no_views(&rig.replace("\"fixed\"", "\"orbiting\"")));
    assert!(
        msg.contains("orbiting") && msg.contains("fixed") && msg.contains("line"),
        "{msg}"
    );
    let msg = err_toml(&no_views(&rig.replace("views = 3", "views = 0")));
    assert!(msg.contains("rig.views"), "{msg}");
    let msg = err_toml(&no_views(&rig.replace("width = 8", "width = 0")));
    assert!(msg.contains("rig.width"), "{msg}");
    let msg = err_toml(&no_views(""));
    assert!(msg.contains("no cameras"), "{msg}");
    let msg = err_toml(&format!("views = []\n{}", no_views("")));
    assert!(msg.contains("empty"), "{msg}");
    let msg = err_toml(&(one_view(&[]) + "[render]\nspp = 0\n"));
    assert!(msg.contains("render.spp"), "{msg}");
}

#[test]
fn load_mesh_builds_shapes_and_reads_files() {
    let dir = tempfile::tempdir().unwrap();
    let rig = r#"rig = { views = 1, radius = 3, width = 4, height = 4, light = "attached", intensity = 1 }
medium = { sigma_t = 1, albedo = 0.5 }
"#;
    let s = SceneDesc::parse(
        &format!("shape = {{ name = \"sphere\", subdivisions = 1 }}\n{rig}"),
        &dir.path().join("a.toml"),
    )
    .unwrap();
    let (mesh, warnings) = s.load_mesh().unwrap();
    assert_eq!(mesh.triangle_count(), 80);
    assert!(warnings.is_empty());
    // A tetrahedron with inward-facing triangles: loads, flipped, with a warning.
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n";
    let inward = {
        // Orient every face outward, then reverse them all.
        let p = [
            [0.0f32, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ]
        .map(Vec3::from_array);
        let centre = (p[0] + p[1] + p[2] + p[3]) / 4.0;
        let mut text: String = obj
            .lines()
            .filter(|l| l.starts_with('v'))
            .map(|l| format!("{l}\n"))
            .collect();
        for f in [[0usize, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]] {
            let n = (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]);
            let out = n.dot(p[f[0]] - centre) > 0.0;
            let f = if out { [f[0], f[2], f[1]] } else { f };
            text.push_str(&format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1));
        }
        text
    };
    std::fs::write(dir.path().join("tet.obj"), inward).unwrap();
    let s = SceneDesc::parse(
        &format!("mesh = \"tet.obj\"\n{rig}"),
        &dir.path().join("b.toml"),
    )
    .unwrap();
    let (mesh, warnings) = s.load_mesh().unwrap();
    assert_eq!(mesh.triangle_count(), 4);
    assert!(mesh.signed_volume() > 0.0);
    assert!(
        warnings
            .iter()
            .any(|w| matches!(w, geometry::MeshWarning::Flipped { .. })),
        "{warnings:?}"
    );
}

/// The fenced blocks of a markdown file with the given language tag.
pub(crate) fn code_blocks(md: &str, lang: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur: Option<String> = None;
    for line in md.lines() {
        match &mut cur {
            None if line.trim_start() == format!("```{lang}") => cur = Some(String::new()),
            Some(block) if line.trim_start() == "```" => {
                out.push(std::mem::take(block));
                cur = None;
            }
            Some(block) => {
                block.push_str(line);
                block.push('\n');
            }
            None => {}
        }
    }
    out
}

#[test]
fn scene_md_examples_parse() {
    let md = include_str!("../../../../SCENE.md");
    assert!(
        md.contains(EXAMPLE_SCENE_TOML),
        "SCENE.md must show EXAMPLE_SCENE_TOML verbatim"
    );
    let dir = folder();
    std::fs::write(dir.path().join("bunny.ply"), b"ply\n").unwrap();
    let tomls = code_blocks(md, "toml");
    let jsons = code_blocks(md, "json");
    assert_eq!((tomls.len(), jsons.len()), (3, 1));
    let a = SceneDesc::parse(&tomls[1], &dir.path().join("s.toml")).unwrap();
    let b = SceneDesc::parse(&jsons[0], &dir.path().join("s.json")).unwrap();
    assert_eq!(
        (&a.mesh, &a.medium, &a.views),
        (&b.mesh, &b.medium, &b.views)
    );
    assert_eq!(a.medium.sigma_t, [60.0; 3]);
    SceneDesc::parse(&tomls[0], &dir.path().join("e.toml")).unwrap();
    // The measured medium's fragment, with a view added.
    let marble = format!(
        "{}\n[[views]]\ncamera = {{ origin = [0, 0, 60], target = [0, 0, 0], width = 8, height = 8 }}\nlight = {{ position = [0, 0, 60], intensity = 1 }}\n",
        tomls[2]
    );
    let m = SceneDesc::parse(&marble, &dir.path().join("m.toml")).unwrap();
    assert_eq!(m.length_unit, Some(crate::measured::LengthUnit::Mm));
    assert!(m.medium.sigma_t.iter().all(|s| (1.0..10.0).contains(s)));
}

#[test]
fn rgb_accepts_scalar_or_three_numbers_only() {
    let msg = err_toml(&one_view(&[(
        "sigma_t = [50, 60, 70]",
        "sigma_t = [50, 60]",
    )]));
    assert!(msg.contains("array of 3 numbers"), "{msg}");
    let msg = err_toml(&one_view(&[(
        "sigma_t = [50, 60, 70]",
        "sigma_t = [50, 60, 70, 80]",
    )]));
    assert!(msg.contains("array of 3 numbers"), "{msg}");
    let s = parse_toml(&one_view(&[("sigma_t = [50, 60, 70]", "sigma_t = 42")])).unwrap();
    assert_eq!(s.medium.sigma_t, [42.0; 3]);
}
