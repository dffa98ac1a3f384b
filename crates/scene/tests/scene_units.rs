//! A scene file's `length_unit` and a measured medium named in it: the medium in the scene's
//! unit, the unit carried into the dataset made from the scene and back, and the errors that
//! name the field and the fix.

use scene::measured::{LengthUnit, MeasuredMedium};
use scene::{Dataset, SceneDesc, SceneError};

fn scene(top: &str, medium: &str) -> String {
    format!(
        r#"{top}
shape = {{ name = "sphere", radius = 15 }}
[medium]
{medium}
[[views]]
camera = {{ origin = [0, 0, 60], target = [0, 0, 0], fov = 40, width = 8, height = 8 }}
light = {{ position = [10, 10, 60], intensity = 1000 }}
"#
    )
}

fn parse(text: &str) -> Result<SceneDesc, SceneError> {
    let dir = tempfile::tempdir().unwrap();
    SceneDesc::parse(text, &dir.path().join("scene.toml"))
}

fn err(text: &str) -> String {
    parse(text).expect_err("must be rejected").to_string()
}

/// `measured = "marble"` in a scene in millimetres is Jensen et al.'s marble in 1/mm at the
/// stated g, with the stated boundary; in centimetres σ_t is ten times larger.
#[test]
fn a_measured_medium_is_read_in_the_scene_s_unit() {
    let mm = parse(&scene(
        r#"length_unit = "mm""#,
        r#"measured = "marble"
g = 0.3
eta = 1.5
roughness = 0.1"#,
    ))
    .unwrap();
    let (sigma_t, albedo) = MeasuredMedium::find("marble")
        .unwrap()
        .medium(0.3f32 as f64, LengthUnit::Mm);
    assert_eq!(mm.length_unit, Some(LengthUnit::Mm));
    assert_eq!(mm.medium.sigma_t, sigma_t);
    assert_eq!(mm.medium.albedo, albedo);
    assert_eq!(
        (mm.medium.g, mm.medium.eta, mm.medium.roughness),
        (scene::Anisotropy::uniform(0.3), 1.5, 0.1)
    );
    let cm = parse(&scene(
        r#"length_unit = "cm""#,
        r#"measured = "marble"
g = 0.3"#,
    ))
    .unwrap();
    for c in 0..3 {
        let r = cm.medium.sigma_t[c] / mm.medium.sigma_t[c];
        assert!((r - 10.0).abs() < 1e-4, "channel {c}: {r}");
    }
}

/// The unit goes into the dataset made from the scene, its saved `dataset.json` and back; a
/// scene without one states none.
#[test]
fn the_unit_travels_with_the_dataset() {
    let desc = parse(&scene(
        r#"length_unit = "cm""#,
        "sigma_t = 2.0\nalbedo = 0.9",
    ))
    .unwrap();
    let mut ds = Dataset::from_scene(&desc);
    assert_eq!(ds.metadata.length_unit, Some(LengthUnit::Cm));
    for v in &mut ds.views {
        v.image = Some(scene::Image::new(8, 8));
    }
    let dir = tempfile::tempdir().unwrap();
    ds.save(dir.path(), false).unwrap();
    let text = std::fs::read_to_string(dir.path().join("dataset.json")).unwrap();
    assert!(text.contains("\"length_unit\": \"cm\""), "{text}");
    assert!(text.contains("sigma_t in 1/cm"), "{text}");
    let back = Dataset::load(dir.path()).unwrap();
    assert_eq!(back.metadata.length_unit, Some(LengthUnit::Cm));
    assert_eq!(back.scene(desc.medium).length_unit, Some(LengthUnit::Cm));
    let plain = parse(&scene("", "sigma_t = 2.0\nalbedo = 0.9")).unwrap();
    assert_eq!(plain.length_unit, None);
    assert_eq!(Dataset::from_scene(&plain).metadata.length_unit, None);
}

/// Every mistake is named with its field and its fix.
#[test]
fn units_and_measured_media_errors_name_the_field_and_the_fix() {
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "",
            r#"measured = "marble""#,
            &["scene.toml: length_unit", "missing", "length_unit = \"mm\""],
        ),
        (
            r#"length_unit = "mm""#,
            "measured = \"marble\"\nsigma_t = 2",
            &["medium.measured", "remove sigma_t and albedo"],
        ),
        (
            r#"length_unit = "mm""#,
            r#"measured = "unobtainium""#,
            &[
                "medium.measured = \"unobtainium\"",
                "no such measured medium",
                "marble",
            ],
        ),
        (
            r#"length_unit = "mm""#,
            "measured = \"marble\"\ng = 1",
            &["medium.g", "(−1, 1)"],
        ),
        (
            "",
            "albedo = 0.9",
            &["medium.sigma_t", "missing", "measured"],
        ),
        ("", "sigma_t = 3", &["medium.albedo", "missing"]),
        (
            r#"length_unit = "furlong""#,
            "sigma_t = 3\nalbedo = 0.9",
            &["length_unit", "furlong"],
        ),
    ];
    for (top, medium, want) in cases {
        let e = err(&scene(top, medium));
        for w in *want {
            assert!(e.contains(w), "{top} / {medium}: {e:?} lacks {w:?}");
        }
    }
}
