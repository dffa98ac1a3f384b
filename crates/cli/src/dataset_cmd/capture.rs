//! `dataset --as-capture`: the rendered views written as a photographed capture
//! ([`scene::capture::write_capture`]), with the lights, the truth and the command that imports
//! it.

use anyhow::{Context, Result};
use serde_json::json;

use scene::capture::{CaptureExport, photo_name, write_capture};
use scene::rig::{Rig, RigLight};
use scene::{Dataset, Medium};

use super::DatasetArgs;

/// The photos' default exposure: the 99.5th percentile of the brightest channel at 0.9.
const HEADROOM: f32 = 0.9;

pub fn write(a: &DatasetArgs, ds: &Dataset, rig: &Rig, medium: Medium) -> Result<()> {
    let images: Vec<scene::Image> = ds.views.iter().filter_map(|v| v.image.clone()).collect();
    let exposure = a
        .capture
        .photo_exposure
        .unwrap_or_else(|| HEADROOM * scene::image::auto_exposure(&images));
    anyhow::ensure!(
        exposure.is_finite() && exposure > 0.0,
        "--photo-exposure must be a positive number"
    );
    let settings = CaptureExport {
        exposure,
        quality: 95,
        mesh_noise: a.capture.mesh_noise,
        seed: *a.seed,
    };
    let (mesh, _) = ds.mesh.load()?;
    let saturated = write_capture(ds, &mesh, &a.out, &settings, *a.overwrite)?;
    let lights: String = ds
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let p = v.light.position;
            format!("{} {} {} {}\n", photo_name(i), p.x, p.y, p.z)
        })
        .collect();
    let lights_path = a.out.join("lights.txt");
    scene::fsutil::atomic_write(&lights_path, lights.as_bytes(), *a.overwrite)?;
    // The light the photos show, and the power of ten a user would state for it (an order
    // of magnitude known): the factor left to recover is their ratio.
    let seen = rig.intensity.map(|i| i * exposure);
    let stated = 10f32.powf(seen.iter().fold(0.0f32, |m, &v| m.max(v)).log10().round());
    let scale = seen.map(|s| s / stated);
    let light = match rig.light {
        // Our camera frame (x left, y up) to COLMAP's (x right, y down).
        RigLight::Attached { offset } => {
            format!("--flash={},{},{}", -offset.x, -offset.y, offset.z)
        }
        RigLight::Fixed { .. } => format!("--light-positions {}", lights_path.display()),
    };
    let truth = json!({
        "medium": {
            "sigma_t": medium.sigma_t, "albedo": medium.albedo, "g": medium.g,
            "eta": medium.eta, "roughness": medium.roughness,
        },
        "length_unit": a.medium.units.map(|u| u.name()),
        "light_intensity": rig.intensity,
        "photo_exposure": exposure,
        "stated_intensity": stated,
        "light_scale": scale,
        "light_scale_note": "the factor `optimize --free light-scale` recovers on the dataset \
                             imported with the printed command: intensity × exposure ÷ \
                             stated_intensity (per channel)",
        "mesh_noise": a.capture.mesh_noise,
        "saturated_pixels": saturated,
    });
    let truth_path = a.out.join("truth.json");
    scene::fsutil::atomic_write(
        &truth_path,
        serde_json::to_string_pretty(&truth)?.as_bytes(),
        *a.overwrite,
    )
    .with_context(|| format!("writing {}", truth_path.display()))?;
    let o = a.out.display();
    let units = a
        .medium
        .units
        .map_or(String::new(), |u| format!(" --units {}", u.name()));
    let object = if medium.eta != 1.0 || !medium.g.is_isotropic() {
        let g = medium.g.channels().map(|g| g.to_string());
        let g = if medium.g.is_uniform() {
            g[0].clone()
        } else {
            g.join(",")
        };
        format!(
            " --eta {} --roughness {} --g {g}",
            medium.eta, medium.roughness
        )
    } else {
        String::new()
    };
    println!(
        "capture: {} photos (exposure {exposure:.4}, {saturated} pixels saturated), masks, a COLMAP \
         model, the mesh{} -> {o} (the rendered dataset: {o}/rendered; the truth: {o}/truth.json)",
        ds.views.len(),
        if a.capture.mesh_noise > 0.0 {
            " with noise"
        } else {
            ""
        },
    );
    println!(
        "import it: translucent import colmap {o}/sparse --images {o}/images --masks {o}/masks \
         --mesh {o}/object.ply {light} --intensity {stated}{units}{object} --out DATASET"
    );
    println!(
        "the light's scale to recover (optimize --free light-scale): {:.4}, {:.4}, {:.4}",
        scale[0], scale[1], scale[2]
    );
    Ok(())
}
