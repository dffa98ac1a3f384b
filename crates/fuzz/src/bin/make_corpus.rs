//! Writes the seed corpus of every reader (`fuzz/corpus/<reader>/`) and the fixed companion files
//! some readers need (`fuzz/support/<reader>/`) with the project's own writers, deterministically:
//!
//! ```text
//! cargo run --release -p translucent-fuzz --bin make-corpus
//! ```
//!
//! Every file is small (a few KB; one model is the shipped one) and valid: the
//! mutation pass checks that each is accepted before it mutates them. `fuzz/README.md` lists
//! what each corpus holds.

use std::path::{Path, PathBuf};

use bssrdf::model::ModelInfo;
use bssrdf::nn::Normalisation;
use fuzz::readers::Reader;
use geometry::{Mesh, Shape};
use glam::Vec3;
use scene::{Camera, Dataset, Image, SceneDesc};

#[path = "make_corpus/captures.rs"]
mod captures;
#[path = "make_corpus/runs.rs"]
mod runs;
#[path = "make_corpus/scenes.rs"]
mod scenes;

use captures::{photos, transforms};
use runs::{optimize_checkpoints, samples_and_train_checkpoints, son24_bins};
use scenes::scenes;

type Res<T = ()> = Result<T, Box<dyn std::error::Error>>;

fn main() -> Res {
    let root = fuzz::fuzz_dir();
    let repo = root.join("..");
    // The tables' corpus is the shipped data folder; everything else is written here.
    for r in Reader::ALL.into_iter().filter(|&r| r != Reader::Tables) {
        reset(&r.corpus_dir())?;
        reset(&r.support_dir())?;
    }
    let work = std::env::temp_dir().join(format!("translucent-make-corpus-{}", std::process::id()));
    reset(&work)?;

    meshes()?;
    scenes()?;
    datasets(&work)?;
    exrs()?;
    models(&repo)?;
    optimize_checkpoints(&work)?;
    samples_and_train_checkpoints(&work)?;
    son24_bins()?;
    colmap_models()?;
    photos()?;
    transforms()?;

    std::fs::remove_dir_all(&work)?;
    for r in Reader::ALL {
        let _ = std::fs::remove_dir(r.support_dir()); // only when empty
        let n = std::fs::read_dir(r.corpus_dir())?.count();
        println!("{:20} {n} seed files", r.name());
    }
    Ok(())
}

/// An empty folder at `dir`.
fn reset(dir: &Path) -> Res {
    if dir.exists() {
        std::fs::remove_dir_all(dir)?;
    }
    std::fs::create_dir_all(dir)?;
    Ok(())
}

fn corpus(r: Reader, name: &str) -> PathBuf {
    r.corpus_dir().join(name)
}

fn support(r: Reader, name: &str) -> PathBuf {
    r.support_dir().join(name)
}

/// An icosahedron of radius 0.5 (12 vertices, 20 triangles).
fn icosahedron() -> Res<Mesh> {
    Ok(Shape::Sphere {
        radius: 0.5,
        subdivisions: 0,
    }
    .build()?)
}

fn meshes() -> Res {
    let mut ico = icosahedron()?;
    geometry::io::save_ply(&ico, &corpus(Reader::Ply, "icosahedron-binary-le.ply"))?;
    geometry::io::save_obj(&ico, &corpus(Reader::Obj, "icosahedron.obj"))?;
    ico.normals = Some(ico.compute_vertex_normals());
    geometry::io::save_ply(
        &ico,
        &corpus(Reader::Ply, "icosahedron-normals-binary-le.ply"),
    )?;
    geometry::io::save_obj(&ico, &corpus(Reader::Obj, "icosahedron-normals.obj"))?;

    // ASCII: a square pyramid (quad base, fan-triangulated), doubles, colours, an extra element.
    std::fs::write(
        corpus(Reader::Ply, "pyramid-ascii.ply"),
        "ply\nformat ascii 1.0\ncomment square pyramid, quad base\nelement vertex 5\n\
         property double x\nproperty double y\nproperty double z\nproperty uchar red\n\
         property uchar green\nproperty uchar blue\nelement face 5\n\
         property list uchar int vertex_indices\nelement edge 1\nproperty int vertex1\n\
         property int vertex2\nend_header\n\
         -0.5 0 -0.5 255 0 0\n0.5 0 -0.5 0 255 0\n0.5 0 0.5 0 0 255\n-0.5 0 0.5 9 9 9\n\
         0 1 0 1 2 3\n4 0 1 2 3\n3 0 4 1\n3 1 4 2\n3 2 4 3\n3 3 4 0\n0 4\n",
    )?;
    // Binary big endian: a tetrahedron, float positions and normals, uint indices named
    // vertex_index, as some exporters write them.
    let p = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let faces = [[0u32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\n\
                   property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
                   property float nz\nelement face 4\nproperty list uchar uint vertex_index\n\
                   end_header\n"
        .to_vec();
    for v in p {
        let n = Vec3::from(v).normalize_or_zero();
        for c in v.into_iter().chain(n.to_array()) {
            be.extend_from_slice(&c.to_be_bytes());
        }
    }
    for f in faces {
        be.push(3);
        for i in f {
            be.extend_from_slice(&i.to_be_bytes());
        }
    }
    std::fs::write(corpus(Reader::Ply, "tetrahedron-binary-be.ply"), be)?;

    // OBJ by hand: a cube of quads with texture coordinates and normals, two groups, negative
    // (relative) indices and comments.
    std::fs::write(
        corpus(Reader::Obj, "cube-quads.obj"),
        "# unit cube, quads\no cube\nv -0.5 -0.5 -0.5\nv 0.5 -0.5 -0.5\nv 0.5 0.5 -0.5\n\
         v -0.5 0.5 -0.5\nv -0.5 -0.5 0.5\nv 0.5 -0.5 0.5\nv 0.5 0.5 0.5\nv -0.5 0.5 0.5\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 -1\nvn 0 0 1\ng sides\n\
         f 1/1/1 4/4/1 3/3/1 2/2/1\nf 5/1/2 6/2/2 7/3/2 8/4/2\nf 1 2 6 5\ng top\n\
         f 2 3 7 6\nf -5 -1 -2 -6\nf 4 1 5 8\n",
    )?;
    // The companion mesh of scene files and datasets that name one.
    for r in [
        Reader::SceneToml,
        Reader::SceneJson,
        Reader::SceneXml,
        Reader::Dataset,
        Reader::Reference,
    ] {
        let ico = icosahedron()?;
        geometry::io::save_ply(&ico, &support(r, "mesh.ply"))?;
    }
    Ok(())
}

/// An image with a smooth pattern (`k` varies it): the corpus's target and view images.
fn pattern(width: u32, height: u32, k: f32) -> Image {
    let mut img = Image::new(width, height);
    for y in 0..height {
        for x in 0..width {
            let v = 0.05 + 0.1 * k + 0.01 * (x as f32) + 0.02 * (y as f32);
            img.set(x, y, [v, 0.8 * v, 0.6 * v]);
        }
    }
    img
}

fn datasets(work: &Path) -> Res {
    // A dataset of a built-in shape, 2 views of 8 × 6, written by Dataset::save.
    let toml = r#"shape = { name = "blob", scale = 0.5 }
[medium]
sigma_t = [50.0, 60.0, 70.0]
albedo = [0.95, 0.90, 0.85]
[[views]]
camera = { origin = [0.0, 0.5, 2.0], target = [0.0, 0.0, 0.0], width = 8, height = 6 }
light = { position = [1.0, 1.5, 0.5], intensity = 4.0 }
[[views]]
camera = { origin = [2.0, 0.0, 0.0], target = [0.0, 0.0, 0.0], width = 8, height = 6 }
light = { position = [2.0, 0.2, 0.0], intensity = [1.0, 2.0, 3.0] }
[render]
spp = 2
seed = 0
"#;
    let scene = SceneDesc::parse(toml, &work.join("scene.toml"))?;
    let mut ds = Dataset::from_scene(&scene);
    for (i, v) in ds.views.iter_mut().enumerate() {
        v.image = Some(pattern(8, 6, i as f32));
    }
    let dir = work.join("dataset");
    ds.save(&dir, false)?;
    let text = std::fs::read_to_string(dir.join("dataset.json"))?;
    std::fs::write(corpus(Reader::Dataset, "shape.json"), &text)?;
    for i in 0..2 {
        let name = format!("view_{i:03}.exr");
        std::fs::copy(dir.join(&name), support(Reader::Dataset, &name))?;
    }
    // The same with the mesh file and the second camera in look-at form (both forms of
    // DATASET.md).
    let mut doc: serde_json::Value = serde_json::from_str(&text)?;
    let obj = doc.as_object_mut().ok_or("dataset.json is not an object")?;
    obj.remove("shape");
    obj.insert("mesh".into(), "mesh.ply".into());
    obj.remove("truth");
    doc["views"][1]["camera"] = serde_json::json!({
        "origin": [2.0, 0.0, 0.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
        "fov_x_deg": 40.0, "width": 8, "height": 6
    });
    std::fs::write(
        corpus(Reader::Dataset, "mesh-lookat.json"),
        serde_json::to_string_pretty(&doc)?,
    )?;
    // A user's capture of a rough, forward-scattering object: an object block, no truth.
    doc["object"] = serde_json::json!({ "boundary": { "type": "dielectric", "eta": 1.4,
        "roughness": 0.2 }, "phase": { "type": "hg", "g": 0.7 } });
    let text = serde_json::to_string_pretty(&doc)?;
    std::fs::write(corpus(Reader::Dataset, "object-rough.json"), text)?;
    // A medium whose forward scattering depends on the wavelength: a g per channel.
    doc["object"]["phase"] = serde_json::json!({ "type": "hg", "g": [0.6, 0.7, 0.8] });
    let text = serde_json::to_string_pretty(&doc)?;
    std::fs::write(corpus(Reader::Dataset, "object-chromatic.json"), text)?;
    doc["object"]["phase"] = serde_json::json!({ "type": "hg", "g": 0.7 });
    // A calibrated camera (COLMAP's PINHOLE): the principal point off the centre, f_y ≠ f_x.
    doc["views"][1]["camera"] = serde_json::json!({
        "origin": [2.0, 0.0, 0.0], "target": [0.0, 0.0, 0.0],
        "intrinsics": { "fx": 10.5, "fy": 11.0, "cx": 4.75, "cy": 2.5 }, "width": 8, "height": 6
    });
    let text = serde_json::to_string_pretty(&doc)?;
    std::fs::write(corpus(Reader::Dataset, "calibrated.json"), text)?;

    // A Mitsuba reference folder as render_reference.py writes it (DATASET.md).
    let img0 = pattern(8, 6, 0.0);
    let img1 = pattern(8, 6, 1.0);
    img0.write_exr(&support(Reader::Reference, "view_000.exr"), false)?;
    img1.write_exr(&support(Reader::Reference, "view_001.exr"), false)?;
    let origin0 = Vec3::new(0.231_250_14, 0.4375, 0.071_534_05);
    let cam0 = Camera::look_at(origin0, Vec3::ZERO, Vec3::Y, 40.0, 8, 6);
    let m = cam0.to_world_rows();
    let doc = serde_json::json!({
        "generator": "Mitsuba 3 (llvm_ad_rgb), reference data",
        "software": { "variant": "llvm_ad_rgb", "mitsuba_version": "3.6.0" },
        "units": "all lengths in abstract scene units",
        "shape": { "kind": "sphere", "mesh_file": "mesh.ply" },
        "boundary": { "bsdf": "null" },
        "medium": { "type": "homogeneous", "sigma_t": [50.0, 60.0, 70.0],
                    "albedo": [0.95, 0.9, 0.85], "phase": { "type": "isotropic", "g": 0.0 } },
        "light": { "type": "point", "intensity_rgb": [0.785, 0.785, 0.785],
                   "position": [0.26, 0.4, 0.13] },
        "integrator": { "type": "volpath", "max_depth": 32, "rr_depth": 5 },
        "camera": { "fov_deg": 40.0, "fov_axis": "x", "width": 8, "height": 6 },
        "views": [
            { "index": 0, "to_world": m, "light_position": [0.27, 0.40, 0.13],
              "file_exr": "view_000.exr", "mean_rgb": img0.mean() },
            { "index": 1, "origin": [-0.35, 0.31, 0.17], "target": [0.0, 0.0, 0.0],
              "file_exr": "view_001.exr" }
        ],
        "render": { "spp": 64, "seed": 0 }
    });
    std::fs::write(
        corpus(Reader::Reference, "null-boundary.json"),
        serde_json::to_string_pretty(&doc)?,
    )?;
    let doc = serde_json::json!({
        "shape": { "mesh_file": "mesh.ply" },
        "boundary": { "bsdf": "dielectric", "int_ior": 1.5, "ext_ior": 1.0 },
        "medium": { "sigma_t": 40.0, "albedo": 0.9, "phase": { "type": "hg", "g": 0.3 } },
        "light": { "intensity": 2.0 },
        "camera": { "fov_deg": 30.0, "fov_axis": "y", "width": 8, "height": 6 },
        "views": [
            { "origin": [0.0, 0.0, 2.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
              "light_position": [1.0, 1.0, 1.0], "file_exr": "view_001.exr" }
        ]
    });
    std::fs::write(
        corpus(Reader::Reference, "dielectric-fov-y.json"),
        serde_json::to_string_pretty(&doc)?,
    )?;
    let mut doc = doc;
    doc["boundary"] = serde_json::json!({ "bsdf": "roughdielectric", "int_ior": 1.4,
        "ext_ior": 1.0, "distribution": "ggx", "alpha": 0.3 });
    doc["medium"]["phase"] = serde_json::json!({ "type": "hg", "g": 0.6 });
    let text = serde_json::to_string_pretty(&doc)?;
    std::fs::write(corpus(Reader::Reference, "rough-hg.json"), text)?;
    Ok(())
}

fn exrs() -> Res {
    use exr::prelude::*;
    pattern(4, 3, 0.0).write_exr(&corpus(Reader::Exr, "rgb-f32-zip.exr"), false)?;
    let (w, h) = (4usize, 3usize);
    let ramp = |k: f32| (0..w * h).map(move |i| 0.1 * k + 0.01 * i as f32);
    let write = |name: &str, encoding: Encoding, channels: Vec<AnyChannel<FlatSamples>>| -> Res {
        let layer = Layer::new(
            (w, h),
            LayerAttributes::named("main"),
            encoding,
            AnyChannels::sort(SmallVec::from_vec(channels)),
        );
        exr::prelude::Image::from_layer(layer)
            .write()
            .to_file(corpus(Reader::Exr, name))?;
        Ok(())
    };
    let f16s = |k: f32| FlatSamples::F16(ramp(k).map(f16::from_f32).collect());
    let f32s = |k: f32| FlatSamples::F32(ramp(k).collect());
    write(
        "rgba-f16-rle.exr",
        Encoding {
            compression: Compression::RLE,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        vec![
            AnyChannel::new("R", f16s(1.0)),
            AnyChannel::new("G", f16s(2.0)),
            AnyChannel::new("B", f16s(3.0)),
            AnyChannel::new("A", f16s(10.0)),
        ],
    )?;
    write(
        "y-f32-uncompressed.exr",
        Encoding::UNCOMPRESSED,
        vec![AnyChannel::new("Y", f32s(1.0))],
    )?;
    write(
        "rgb-f32-tiled-piz.exr",
        Encoding {
            compression: Compression::PIZ,
            blocks: Blocks::Tiles(Vec2(2, 2)),
            line_order: LineOrder::Increasing,
        },
        vec![
            AnyChannel::new("R", f32s(1.0)),
            AnyChannel::new("G", f32s(2.0)),
            AnyChannel::new("B", f32s(3.0)),
        ],
    )?;
    Ok(())
}

fn models(repo: &Path) -> Res {
    std::fs::copy(
        repo.join("models/translucent-v2.safetensors"),
        corpus(Reader::Model, "translucent-v2.safetensors"),
    )?;
    let widths = learn::cvae::Widths {
        feature: vec![4],
        absorption_hidden: vec![],
        decoder_hidden: vec![3],
        encoder_hidden: vec![2],
    };
    let model =
        learn::cvae::init_model(&widths, Normalisation::identity(), ModelInfo::default(), 1)?;
    std::fs::write(
        corpus(Reader::Model, "tiny-cvae.safetensors"),
        bssrdf::model::to_bytes(&model)?,
    )?;
    Ok(())
}

/// A COLMAP model as COLMAP writes it, text and binary: a SIMPLE_PINHOLE and a PINHOLE camera
/// (off-centre, f_y ≠ f_x) and three images (one seen from +z, one turned by 90° about y, one
/// without 2D points). Each file is a reader's seed, the other file of its format its support.
fn colmap_models() -> Res {
    let cameras = [
        (1u32, 0u32, vec![40.0f64, 32.0, 24.0]),
        (7, 1, vec![42.0, 44.5, 30.25, 26.5]),
    ];
    let h = std::f64::consts::FRAC_1_SQRT_2;
    // (id, rotation q, translation t, camera id, name, 2D points)
    type Image<'a> = (u32, [f64; 4], [f64; 3], u32, &'a str, u64);
    let images: [Image; 3] = [
        (3, [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 3.0], 1, "a.jpg", 2),
        (5, [h, 0.0, h, 0.0], [0.1, -0.2, 2.5], 7, "sub dir/b.JPG", 0),
        (9, [h, h, 0.0, 0.0], [0.0, 0.0, 2.0], 7, "c.png", 1),
    ];
    let mut ct = String::from("# Camera list with one line of data per camera:\n");
    let mut cb = (cameras.len() as u64).to_le_bytes().to_vec();
    for (id, model, params) in &cameras {
        let name = ["SIMPLE_PINHOLE", "PINHOLE"][*model as usize];
        let p: Vec<String> = params.iter().map(|v| v.to_string()).collect();
        ct.push_str(&format!("{id} {name} 64 48 {}\n", p.join(" ")));
        cb.extend(id.to_le_bytes());
        cb.extend(model.to_le_bytes());
        cb.extend(64u64.to_le_bytes());
        cb.extend(48u64.to_le_bytes());
        for v in params {
            cb.extend(v.to_le_bytes());
        }
    }
    let mut it = String::from("# Image list with two lines of data per image:\n");
    let mut ib = (images.len() as u64).to_le_bytes().to_vec();
    for (id, q, t, cam, name, points) in &images {
        it.push_str(&format!(
            "{id} {} {} {} {} {} {} {} {cam} {name}\n",
            q[0], q[1], q[2], q[3], t[0], t[1], t[2]
        ));
        let pts: Vec<String> = (0..*points)
            .map(|k| format!("{}.5 12.25 {}", k, k as i64 - 1))
            .collect();
        it.push_str(&format!("{}\n", pts.join(" ")));
        ib.extend(id.to_le_bytes());
        for v in q.iter().chain(t) {
            ib.extend(v.to_le_bytes());
        }
        ib.extend(cam.to_le_bytes());
        ib.extend(name.as_bytes());
        ib.push(0);
        ib.extend(points.to_le_bytes());
        for k in 0..*points {
            ib.extend((k as f64 + 0.5).to_le_bytes());
            ib.extend(12.25f64.to_le_bytes());
            ib.extend((k as i64 - 1).to_le_bytes());
        }
    }
    for (seed, companion, seed_bytes, support_bytes) in [
        (
            Reader::ColmapCamerasTxt,
            "images.txt",
            ct.as_bytes(),
            it.as_bytes(),
        ),
        (
            Reader::ColmapImagesTxt,
            "cameras.txt",
            it.as_bytes(),
            ct.as_bytes(),
        ),
        (Reader::ColmapCamerasBin, "images.bin", &cb[..], &ib[..]),
        (Reader::ColmapImagesBin, "cameras.bin", &ib[..], &cb[..]),
    ] {
        std::fs::write(corpus(seed, "two-cameras"), seed_bytes)?;
        std::fs::write(support(seed, companion), support_bytes)?;
    }
    Ok(())
}
