use std::path::Path;

use glam::{Mat4, Vec3};

use super::*;
use crate::scene_file::MeshSource;

/// A folder with `object.ply` (a small sphere) and `scene.xml` holding `xml`.
fn folder(xml: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let mesh = geometry::Shape::Sphere {
        radius: 0.5,
        subdivisions: 2,
    }
    .build()
    .unwrap();
    geometry::io::save_ply(&mesh, &dir.path().join("object.ply")).unwrap();
    let p = dir.path().join("scene.xml");
    std::fs::write(&p, xml).unwrap();
    (dir, p)
}

const SCENE: &str = r#"<scene version="3.0.0">
    <default name="spp" value="128"/>
    <default name="res" value="64"/>
    <integrator type="volpath"><integer name="max_depth" value="48"/></integrator>
    <bsdf type="roughdielectric" id="skin">
        <string name="distribution" value="ggx"/>
        <float name="alpha" value="0.2"/>
        <string name="int_ior" value="water"/>
    </bsdf>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/><integer name="height" value="32"/>
            <rfilter type="gaussian"/>
        </film>
    </sensor>
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <string name="fov_axis" value="y"/>
        <float name="principal_point_offset_x" value="0.125"/>
        <float name="principal_point_offset_y" value="-0.0625"/>
        <transform name="to_world"><lookat origin="4, 0, 0" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="32"/></film>
    </sensor>
    <emitter type="point">
        <point name="position" x="1" y="2" z="3"/>
        <rgb name="intensity" value="5, 6, 7"/>
    </emitter>
    <shape type="ply">
        <string name="filename" value="object.ply"/>
        <transform name="to_world"><scale value="2"/><translate x="1"/></transform>
        <ref id="skin"/>
        <medium type="homogeneous" name="interior">
            <rgb name="sigma_t" value="0.5, 0.6, 0.7"/>
            <float name="scale" value="100"/>
            <rgb name="albedo" value="0.9, 0.8, 0.7"/>
            <phase type="hg"><float name="g" value="0.7"/></phase>
        </medium>
    </shape>
</scene>"#;

#[test]
fn a_mitsuba_scene_reads_as_written() {
    let (_d, p) = folder(SCENE);
    let s = SceneDesc::load(&p).unwrap();
    let m = s.medium;
    assert_eq!(m.sigma_t, [50.0, 60.0, 70.0]);
    assert_eq!(m.albedo, [0.9, 0.8, 0.7]);
    assert_eq!((m.g, m.roughness), (crate::Anisotropy::uniform(0.7), 0.2));
    // water (1.3330) in air (Mitsuba's default ext_ior, 1.000277).
    assert!((m.eta as f64 - 1.3330 / 1.000277).abs() < 1e-6, "{}", m.eta);
    assert_eq!((s.render.spp, s.render.max_depth), (Some(128), Some(48)));
    assert_eq!(s.views.len(), 2);
    let c0 = &s.views[0].camera;
    let want = Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y, 40.0, 64, 32);
    assert!(c0.rotation.abs_diff_eq(want.rotation, 1e-6) && c0.origin == want.origin);
    assert_eq!((c0.fov_x_deg, c0.width, c0.height), (40.0, 64, 32));
    // fov 30° along y of a 64 × 32 film: tan(fov_x/2) = tan(15°)·2.
    let c1 = &s.views[1].camera;
    let tan_x = (c1.fov_x_deg.to_radians() / 2.0).tan();
    assert!((tan_x - 15f32.to_radians().tan() * 2.0).abs() < 1e-5);
    // Its principal point: the optical axis meets the film at ½ − offset of its size.
    let k = c1.intrinsics();
    assert_eq!((k.cx, k.cy), (24.0, 18.0));
    assert!((k.fy / k.fx - 1.0).abs() < 1e-6 && c0.pinhole.is_none());
    assert_eq!(s.views[1].light.position, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(s.views[0].light.intensity, [5.0, 6.0, 7.0]);
    // The shape's to_world: scale by 2, then translate by x = 1.
    let MeshSource::Placed { to_world, .. } = &s.mesh else {
        panic!("{:?}", s.mesh)
    };
    let q = to_world.transform_point3(Vec3::new(0.5, 0.0, 0.0));
    assert!((q - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6, "{q}");
    let (mesh, _) = s.load_mesh().unwrap();
    let (lo, hi) = mesh.bounds();
    assert!(
        (lo.x - 0.0).abs() < 1e-3 && (hi.x - 2.0).abs() < 1e-3,
        "{lo} {hi}"
    );
}

/// `SCENE` with `from` replaced by `to`; the error message of reading it.
fn error_of(from: &str, to: &str) -> String {
    assert!(SCENE.contains(from), "{from}");
    let (_d, p) = folder(&SCENE.replace(from, to));
    SceneDesc::load(&p).unwrap_err().to_string()
}

#[test]
fn what_cannot_be_honoured_is_refused_with_the_line_and_the_fix() {
    let cases = [
        (
            r#"value="ggx""#,
            r#"value="beckmann""#,
            "distribution \"beckmann\"",
        ),
        (
            "</shape>",
            "</shape>\n<shape type=\"rectangle\"><bsdf type=\"diffuse\"/></shape>",
            "a shape without an interior medium",
        ),
        (
            "</shape>",
            "</shape>\n<emitter type=\"constant\"/>",
            "emitter type \"constant\"",
        ),
        (
            r#"<rgb name="intensity" value="5, 6, 7"/>
    </emitter>"#,
            r#"<rgb name="intensity" value="5, 6, 7"/>
    </emitter><emitter type="point"/>"#,
            "2 point emitters",
        ),
        (
            r#"<float name="scale" value="100"/>"#,
            r#"<float name="scale" value="100"/><float name="density" value="2"/>"#,
            "the property 'density' of <medium type=\"homogeneous\"> is not modelled",
        ),
        (r#"value="$spp""#, r#"value="$samples""#, "$samples"),
        (r#"version="3.0.0""#, r#"version="0.6.0""#, "version"),
        (r#"<ref id="skin"/>"#, r#"<ref id="wax"/>"#, "id=\"wax\""),
        (
            r#"<string name="int_ior" value="water"/>"#,
            r#"<string name="int_ior" value="jade"/>"#,
            "\"jade\" is not an index of refraction",
        ),
        (
            r#"<float name="fov" value="40"/>"#,
            r#"<float name="fov" value="40"/><float name="principal_point_offset_x" value="3"/>"#,
            "the principal point must lie within one image size",
        ),
        (
            r#"<rgb name="albedo" value="0.9, 0.8, 0.7"/>"#,
            r#"<rgb name="albedo" value="1.2, 0.8, 0.7"/>"#,
            "albedo[0] = 1.2",
        ),
        ("</scene>", "", "not well-formed XML"),
    ];
    for (from, to, want) in cases {
        let e = error_of(from, to);
        assert!(e.contains(want), "{want:?} not in: {e}");
        assert!(e.contains("scene.xml"), "{e}");
    }
    // The line of the offending element.
    let e = error_of(r#"value="ggx""#, r#"value="beckmann""#);
    assert!(e.contains("scene.xml:5 <bsdf"), "{e}");
}

#[test]
fn an_exported_scene_reads_back_as_the_same_scene() {
    let (_d, p) = folder(SCENE);
    let s = SceneDesc::load(&p).unwrap();
    let out = tempfile::tempdir().unwrap();
    let export = MitsubaExport::of(&s, 64, 32).unwrap();
    let written = export.write(out.path(), &s.medium, false).unwrap();
    assert_eq!(written.len(), 3, "{written:?}");
    let back = SceneDesc::load(&out.path().join("scene.xml")).unwrap();
    let (a, b) = (s.medium, back.medium);
    for c in 0..3 {
        assert!((a.sigma_t[c] / b.sigma_t[c] - 1.0).abs() < 1e-6);
        assert_eq!(a.albedo[c], b.albedo[c]);
    }
    assert_eq!((a.g, a.eta, a.roughness), (b.g, b.eta, b.roughness));
    assert_eq!(back.render.spp, Some(64));
    for (v, w) in s.views.iter().zip(&back.views) {
        assert!(v.camera.rotation.abs_diff_eq(w.camera.rotation, 1e-6));
        assert_eq!(v.camera.origin, w.camera.origin);
        assert!((v.camera.fov_x_deg - w.camera.fov_x_deg).abs() < 1e-4);
        let (kv, kw) = (v.camera.intrinsics(), w.camera.intrinsics());
        assert!((kv.cx - kw.cx).abs() < 1e-4 && (kv.cy - kw.cy).abs() < 1e-4);
        assert_eq!(v.light, w.light);
    }
    // Non-square pixels have no Mitsuba sensor.
    let mut stretched = s.clone();
    let k = stretched.views[0].camera.intrinsics();
    stretched.views[0].camera =
        (stretched.views[0].camera.clone()).with_intrinsics(&crate::Intrinsics {
            fy: 1.1 * k.fx,
            ..k
        });
    let e = MitsubaExport::of(&stretched, 64, 32)
        .unwrap_err()
        .to_string();
    assert!(e.contains("view 0") && e.contains("square pixels"), "{e}");
    let (m0, _) = s.load_mesh().unwrap();
    let (m1, _) = back.load_mesh().unwrap();
    assert_eq!(m0.bounds(), m1.bounds());
    // Nothing is overwritten without permission; a view per light when the lights differ.
    assert!(export.write(out.path(), &s.medium, false).is_err());
    let mut moved = s.clone();
    moved.views[1].light.position = Vec3::new(-1.0, 0.0, 0.0);
    let e = MitsubaExport::of(&moved, 64, 32).unwrap();
    let names: Vec<&str> = e.files.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["view_000.xml", "view_001.xml"]);
    // A g per channel: a scene per channel, each at its channel's g, and the snippet says the
    // mean is written.
    let mut chromatic = s.clone();
    chromatic.medium.g = crate::Anisotropy([0.3, 0.5, 0.7]);
    let e = MitsubaExport::of(&chromatic, 64, 32).unwrap();
    let names: Vec<&str> = e.files.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["scene_r.xml", "scene_g.xml", "scene_b.xml"]);
    let out = tempfile::tempdir().unwrap();
    e.write(out.path(), &chromatic.medium, false).unwrap();
    for (name, g) in [("scene_r.xml", 0.3), ("scene_b.xml", 0.7)] {
        let back = SceneDesc::load(&out.path().join(name)).unwrap();
        assert_eq!(back.medium.g, crate::Anisotropy::uniform(g), "{name}");
    }
    let snippet = std::fs::read_to_string(out.path().join("medium.xml")).unwrap();
    assert!(
        snippet.contains("(0.3, 0.5, 0.7)") && snippet.contains("mean"),
        "{snippet}"
    );
}

#[test]
fn the_snippet_states_the_boundary_and_the_medium() {
    let m = Medium {
        sigma_t: [50.0, 100.0, 25.0],
        albedo: [0.9, 0.95, 0.99],
        g: crate::Anisotropy::uniform(0.5),
        eta: 1.4,
        roughness: 0.3,
    };
    let s = medium_snippet(&m);
    for want in [
        "roughdielectric",
        r#"value="ggx""#,
        r#"<float name="alpha" value="0.3"/>"#,
        r#"<rgb name="sigma_t" value="0.5, 1, 0.25"/>"#,
        r#"<float name="scale" value="100"/>"#,
        r#"<float name="g" value="0.5"/>"#,
    ] {
        assert!(s.contains(want), "{want} not in\n{s}");
    }
    let null = medium_snippet(&Medium {
        eta: 1.0,
        roughness: 0.0,
        ..m
    });
    assert!(null.starts_with("<bsdf type=\"null\"/>"));
    let _ = (Mat4::IDENTITY, Path::new("."));
}

#[test]
fn a_scene_folder_with_an_image_per_sensor_is_a_dataset() {
    let (d, _) = folder(SCENE);
    let img = |w, h| {
        let mut i = crate::Image::new(w, h);
        i.set(1, 1, [0.5, 0.25, 0.125]);
        i
    };
    img(64, 32)
        .write_exr(&d.path().join("view_000.exr"), false)
        .unwrap();
    // The second sensor's image is missing: the error names it and the sensor.
    let e = crate::Dataset::load(d.path()).unwrap_err().to_string();
    assert!(e.contains("sensor 1") && e.contains("view_001.exr"), "{e}");
    img(64, 32)
        .write_exr(&d.path().join("view_001.exr"), false)
        .unwrap();
    let ds = crate::Dataset::load(d.path()).unwrap();
    assert_eq!(ds.kind, crate::DatasetKind::MitsubaScene);
    assert_eq!(ds.views.len(), 2);
    assert!(ds.views.iter().all(|v| v.image.is_some()));
    // The boundary and the phase function are stated; σ_t and α are what the images are for.
    assert!(ds.truth.is_none());
    let o = ds.object.unwrap();
    assert_eq!((o.g, o.roughness), (crate::Anisotropy::uniform(0.7), 0.2));
    assert!((o.eta - 1.3330 / 1.000277).abs() < 1e-6);
    // A folder's scene.xml named directly reads the same.
    let again = crate::Dataset::load(&d.path().join("scene.xml")).unwrap();
    assert_eq!(again.views.len(), 2);
    // Saved as our own dataset, the placed mesh is written in world coordinates.
    let out = tempfile::tempdir().unwrap();
    ds.save(out.path(), false).unwrap();
    let saved = crate::Dataset::load(out.path()).unwrap();
    assert_eq!(saved.mesh, MeshSource::File(out.path().join("object.ply")));
    assert_eq!(
        saved.load_mesh().unwrap().0.bounds(),
        ds.load_mesh().unwrap().0.bounds()
    );
    assert_eq!(saved.object, Some(o));
}
