//! The re-renders of a finished run: every view (at most [`RERENDER_VIEWS`], evenly spread) at
//! the estimate by the run's final model, beside its target with a false-colour difference, an
//! overview of the first four and a contact sheet of them all (`OUT/final/`); and the reported
//! medium as Mitsuba 3 XML (`OUT/mitsuba/`, [`scene::mitsuba_xml`]).

use std::path::Path;

use bssrdf::render::RenderSettings;
use scene::mitsuba_xml::MitsubaExport;
use scene::{Dataset, Image, Medium};

use super::{Observer, RecoveryConfig, RecoveryError};
use crate::report;
use inverse::optimize::Optimizer;
use inverse::params::Params;

/// Views re-rendered at the end of a run, at most: evenly spread over larger datasets.
const RERENDER_VIEWS: usize = 48;

/// Re-renders the views at the estimate next to their targets, with error images, and the
/// contact sheet of them all (`final/contact-sheet.png`).
pub(super) fn rerender(
    cfg: &RecoveryConfig,
    opt: &Optimizer,
    ds: &Dataset,
    est: &Params,
    obs: &dyn Observer,
) -> Result<(), RecoveryError> {
    let dir = cfg.out.join("final");
    std::fs::create_dir_all(&dir).map_err(|source| RecoveryError::CreateDir {
        path: dir.clone(),
        source,
    })?;
    let n = ds.views.len();
    let k = n.min(RERENDER_VIEWS);
    let chosen: Vec<usize> = (0..k).map(|i| i * n / k).collect();
    let pb = obs.progress(k as u64, "re-renders");
    let mut imgs = Vec::new();
    for &i in &chosen {
        let v = &ds.views[i];
        let rs = RenderSettings {
            spp: cfg.final_spp,
            seed: cfg.optimize.seed ^ 0xF1AA_1000,
            view: i as u64,
        };
        imgs.push(opt.render(est, &v.camera, &v.light, &rs)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let targets: Vec<&Image> = chosen
        .iter()
        .filter_map(|&i| ds.views[i].image.as_ref())
        .collect();
    let exposure = scene::image::auto_exposure(
        &targets
            .iter()
            .take(8)
            .map(|&t| t.clone())
            .collect::<Vec<_>>(),
    );
    for ((img, t), &i) in imgs.iter().zip(&targets).zip(&chosen) {
        // Named by the view's index in the dataset (the same as i without a view subset).
        let index = opt.config().view_subset.as_ref().map_or(i, |s| s[i]);
        write_view(&dir, &format!("view_{index:03}"), img, t, exposure)?;
    }
    // The first four views at a glance: targets above, re-renders below.
    let m = imgs.len().min(targets.len()).min(4);
    let overview = Image::grid(&[targets[..m].to_vec(), imgs[..m].iter().collect()], 2);
    overview.write_png(&dir.join("overview.png"), exposure, true)?;
    let renders: Vec<&Image> = imgs.iter().collect();
    report::contact_sheet(&targets, &renders, exposure)?.write_png(
        &dir.join("contact-sheet.png"),
        1.0,
        true,
    )?;
    Ok(())
}

fn write_view(
    dir: &Path,
    name: &str,
    img: &Image,
    target: &Image,
    exposure: f32,
) -> Result<(), RecoveryError> {
    img.write_exr(&dir.join(format!("{name}.exr")), true)?;
    img.write_png(&dir.join(format!("{name}.png")), exposure, true)?;
    target.write_png(&dir.join(format!("{name}_target.png")), exposure, true)?;
    Image::false_colour_diff(img, target)?.write_png(
        &dir.join(format!("{name}_diff.png")),
        1.0,
        true,
    )?;
    Ok(())
}

/// `OUT/mitsuba/`: the reported medium (`est` on the object `base`) as Mitsuba 3 XML:
/// `medium.xml` (the object's boundary and interior, to paste into a shape), the dataset's scene
/// with it (`scene.xml`, or one file per view when the views' lights differ; the lights scaled
/// where their scale was recovered) and the mesh they name (`object.ply`).
pub(super) fn mitsuba(
    cfg: &RecoveryConfig,
    ds: &Dataset,
    est: &Params,
    base: &Medium,
    obs: &dyn Observer,
) -> Result<(), RecoveryError> {
    let medium = &est.medium(base);
    let mut desc = ds.scene(*medium);
    for v in &mut desc.views {
        v.light = est.light(&v.light);
    }
    let spp = ds.render.spp.unwrap_or(64);
    let depth = ds.render.max_depth.unwrap_or(32);
    let dir = cfg.out.join("mitsuba");
    MitsubaExport::of(&desc, spp, depth)?.write(&dir, medium, true)?;
    obs.say(&format!(
        "wrote {} (the estimate as Mitsuba 3 XML: medium.xml to paste into a shape, and the \
         dataset's scene with it)",
        dir.display()
    ));
    Ok(())
}
