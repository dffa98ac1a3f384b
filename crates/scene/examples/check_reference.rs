//! Load a dataset folder (translucent `dataset.json` or a Mitsuba reference folder with
//! `scene.json`) and print what was read: cameras, lights, truth medium and per-view image means
//! (compared with the means recorded in the file, where there are some).
//!
//! `cargo run -p translucent-scene --example check_reference -- ../shared/reference-renders/mitsuba-sphere-rgb-64`

use std::path::PathBuf;

fn main() {
    let Some(dir) = std::env::args().nth(1).map(PathBuf::from) else {
        eprintln!("usage: check_reference <dataset folder>");
        std::process::exit(2);
    };
    let ds = match scene::Dataset::load(&dir) {
        Ok(ds) => ds,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    println!(
        "kind {:?}, mesh {}, truth {:?}",
        ds.kind,
        ds.mesh.describe(),
        ds.truth
    );
    println!("render {:?}", ds.render);
    match ds.load_mesh() {
        Ok((mesh, warnings)) => println!(
            "mesh: {} triangles, signed volume {:.6}, warnings {:?}",
            mesh.triangle_count(),
            mesh.signed_volume(),
            warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>()
        ),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    }
    let mut worst = 0.0f64;
    for (i, v) in ds.views.iter().enumerate() {
        let img = v.image.as_ref().expect("images are loaded");
        let m = img.mean();
        let rel = v.expected_mean.map(|e| {
            (0..3)
                .map(|c| ((m[c] - e[c]) / e[c]).abs())
                .fold(0.0, f64::max)
        });
        worst = worst.max(rel.unwrap_or(0.0));
        println!(
            "view {i}: origin {:?} dir {:?} fov {} {}x{} light {:?} I {:?} mean {:?} expected {:?} rel.diff {:?}",
            v.camera.origin.to_array(),
            v.camera.direction().to_array(),
            v.camera.fov_x_deg,
            v.camera.width,
            v.camera.height,
            v.light.position.to_array(),
            v.light.intensity,
            m,
            v.expected_mean,
            rel
        );
    }
    println!(
        "largest relative difference of image means: {worst:.3e}; warnings: {:?}",
        ds.warnings
    );
}
