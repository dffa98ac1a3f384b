//! Rendering a list of views with any forward model, and rendering a scene into a dataset: the
//! loops behind `render`, `dataset`, the bias correction's simulations and the experiments.
//!
//! View i is rendered with the settings (spp, seed, view = i), so a list renders the same
//! images whether it is rendered whole or view by view. Every loop takes the progress bar to
//! advance (one step per image row for the tracers, per view for the dipole); pass
//! [`ProgressBar::hidden`] for none.

use std::path::Path;
use std::time::Instant;

use geometry::Accel;
use indicatif::ProgressBar;
use rayon::prelude::*;
use scene::scene_file::{RenderInfo, SceneDesc, ViewDesc};
use scene::setting::Setting;
use scene::{Dataset, Image, Medium};
use volpath::{Lit, Progressive, RenderSettings, ShadowTransmittance, VolpathSettings};

use crate::error::InverseError;
use crate::forward::{ForwardModel, ModelSpec};

/// The images of a list of views and the time each took.
pub struct RenderReport {
    pub images: Vec<Image>,
    /// Every view's derivative images (empty unless asked for): ∂I/∂σ_t, ∂I/∂α and, from a
    /// model that differentiates the phase function, ∂I/∂g.
    pub derivatives: Vec<Vec<Image>>,
    pub seconds_per_view: Vec<f64>,
}

/// One view's render: the image, and its derivative images when asked for.
type ViewRender = (Image, Option<Vec<Image>>);

/// What a render of a list of views needs whatever the model: the mesh, the medium, the views,
/// the samples per pixel and the seed (view i renders with view index i).
#[derive(Clone, Copy)]
pub struct Job<'a> {
    pub accel: &'a Accel,
    pub medium: &'a Medium,
    pub views: &'a [ViewDesc],
    pub spp: u32,
    pub seed: u64,
}

impl Job<'_> {
    /// Renders every view with `render(view, settings)` (the settings of view i: `spp`, `seed`,
    /// view index i), timing each.
    fn each(
        &self,
        mut render: impl FnMut(&ViewDesc, &RenderSettings) -> Result<ViewRender, InverseError>,
    ) -> Result<RenderReport, InverseError> {
        let mut report = RenderReport {
            images: Vec::with_capacity(self.views.len()),
            derivatives: Vec::new(),
            seconds_per_view: Vec::with_capacity(self.views.len()),
        };
        for (i, v) in self.views.iter().enumerate() {
            let rs = RenderSettings {
                spp: self.spp,
                seed: self.seed,
                view: i as u64,
            };
            let t0 = Instant::now();
            let (image, derivatives) = render(v, &rs)?;
            report.images.push(image);
            report.derivatives.extend(derivatives);
            report.seconds_per_view.push(t0.elapsed().as_secs_f64());
        }
        Ok(report)
    }
}

/// Rows of all views: the length of the tracers' progress bars.
pub fn total_rows(views: &[ViewDesc]) -> u64 {
    views.iter().map(|v| v.camera.height as u64).sum()
}

/// Every view of `job` by the model `spec` describes, prepared at the job's medium, with each
/// view's derivatives with respect to σ_t and α when `derivatives` (by the model's estimator).
/// `pb` advances by one per image row ([`total_rows`]).
pub fn render(
    spec: ModelSpec,
    job: &Job,
    derivatives: bool,
    pb: &ProgressBar,
) -> Result<RenderReport, InverseError> {
    let mut model = spec.build(job.accel);
    model.prepare(job.medium)?;
    render_with(&*model, job, derivatives, pb)
}

/// Every view of `job` by the prepared `model` ([`render`]).
pub fn render_with(
    model: &dyn ForwardModel,
    job: &Job,
    derivatives: bool,
    pb: &ProgressBar,
) -> Result<RenderReport, InverseError> {
    let at = model.at(*job.medium)?;
    job.each(|v, rs| {
        let view = at.view(&v.camera, &v.light);
        Ok(if derivatives {
            let d = view.derivatives(rs, Some(pb))?;
            let parts = [Some(d.d_sigma_t), Some(d.d_albedo), d.d_g];
            (d.value, Some(parts.into_iter().flatten().collect()))
        } else {
            (view.value(rs, Some(pb))?, None)
        })
    })
}

/// The BVH over `mesh`, with the mesh's warnings logged against `what` (the file or shape).
pub fn build_accel(mesh: geometry::Mesh, warnings: &[geometry::MeshWarning], what: &str) -> Accel {
    for w in warnings {
        tracing::warn!("{what}: {w}");
    }
    let t0 = Instant::now();
    let accel = Accel::new(mesh);
    tracing::debug!(
        "{what}: BVH over {} triangles in {:.1} ms",
        accel.mesh().triangle_count(),
        t0.elapsed().as_secs_f64() * 1e3
    );
    accel
}

/// How a dataset's images are rendered by the volumetric path tracer.
#[derive(Clone, Copy, Debug)]
pub struct RenderOpts {
    pub spp: u32,
    pub seed: u64,
    pub max_depth: u32,
    pub shadow: ShadowTransmittance,
}

/// Render the views of `desc` with the volumetric path tracer at its medium and save them as a
/// dataset in `out` (refused when `out` holds one, unless `overwrite`); returns it, with images.
/// The dataset records the spp, depth, seed and renderer. `pb` advances by one per row.
pub fn render_dataset(
    mut desc: SceneDesc,
    opts: RenderOpts,
    out: &Path,
    overwrite: bool,
    pb: &ProgressBar,
) -> Result<Dataset, InverseError> {
    let RenderOpts {
        spp,
        seed,
        max_depth,
        shadow,
    } = opts;
    if spp == 0 {
        return Err(InverseError::Invalid(format!(
            "{} must be at least 1",
            Setting::Spp
        )));
    }
    if max_depth == 0 {
        return Err(InverseError::Invalid(format!(
            "{} must be at least 1",
            Setting::MaxDepth
        )));
    }
    if !overwrite && out.join("dataset.json").exists() {
        return Err(InverseError::Invalid(format!(
            "{} already holds a dataset; pass {} to replace it",
            out.display(),
            Setting::Overwrite
        )));
    }
    desc.render = RenderInfo {
        spp: Some(spp),
        max_depth: Some(max_depth),
        seed: Some(seed),
        renderer: Some(format!(
            "translucent {} volpath (spectral MIS, {} shadow transmittance)",
            env!("CARGO_PKG_VERSION"),
            match shadow {
                ShadowTransmittance::Exact => "exact",
                ShadowTransmittance::Tracked => "tracked",
            }
        )),
    };
    desc.path = out.join("dataset.json");
    let (mesh, warnings) = desc.load_mesh()?;
    let accel = build_accel(mesh, &warnings, &desc.mesh.describe());
    let views = &desc.views;
    let settings = VolpathSettings {
        max_depth,
        shadow,
        ..Default::default()
    };
    let t0 = Instant::now();
    let job = Job {
        accel: &accel,
        medium: &desc.medium,
        views,
        spp,
        seed,
    };
    let rep = render(ModelSpec::tracer(settings), &job, false, pb)?;
    let mut ds = Dataset::from_scene(&desc);
    for (v, img) in ds.views.iter_mut().zip(rep.images) {
        v.image = Some(img);
    }
    ds.save(out, overwrite)?;
    tracing::info!(
        "rendered {} views in {:.1} s",
        views.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(ds)
}

/// σ_t ~ U[30, 100], α ~ U[0.8, 0.98] per channel (Son et al. 2024, §5), g = 0, η = 1.
pub fn random_medium(seed: u64) -> Medium {
    let mut s = base::rng::Sampler::new(seed, u64::MAX, 0, 0x6d65_6469_756d);
    let sigma_t = [0; 3].map(|_| 30.0 + 70.0 * s.next_f32());
    let albedo = [0; 3].map(|_| 0.8 + 0.18 * s.next_f32());
    Medium {
        sigma_t,
        albedo,
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    }
}

/// Renders the views of `rig` around `mesh` in `medium` with the volumetric path tracer and saves
/// them as a dataset in `out` ([`render_dataset`]), with a progress bar of one step per image row
/// from `obs`; returns it, with images.
pub fn make_dataset(
    rig: &scene::Rig,
    mesh: scene::MeshSource,
    medium: Medium,
    opts: RenderOpts,
    out: &Path,
    overwrite: bool,
    obs: &dyn crate::observer::Observer,
) -> Result<Dataset, InverseError> {
    let desc = SceneDesc {
        mesh,
        medium,
        views: rig.build(),
        render: RenderInfo::default(),
        path: out.join("dataset.json"),
        length_unit: None,
    };
    let pb = obs.progress(total_rows(&desc.views), "volpath");
    let ds = render_dataset(desc, opts, out, overwrite, &pb)?;
    pb.finish_and_clear();
    Ok(ds)
}

/// Samples per pixel of one pass of [`volpath_equal_time`].
pub const EQUAL_TIME_PASS: u32 = 32;

/// When to stop rendering passes within a time budget: after each pass, another one is started
/// only if the time so far plus the slowest pass so far stays within the budget.
#[derive(Debug, Clone, Copy)]
pub struct PassBudget {
    total: f64,
    slowest: f64,
}

impl PassBudget {
    pub fn new(total_seconds: f64) -> Self {
        Self {
            total: total_seconds,
            slowest: 0.0,
        }
    }

    /// After a pass that took `pass` seconds, with `elapsed` seconds spent in all: start another?
    pub fn another(&mut self, elapsed: f64, pass: f64) -> bool {
        self.slowest = self.slowest.max(pass);
        elapsed + self.slowest <= self.total
    }
}

/// Renders every view with the volumetric path tracer in passes of [`EQUAL_TIME_PASS`] spp until the next pass (estimated by the
/// slowest pass so far) would take the whole render past `budget` seconds per view. At least one
/// pass. Views that share a light share its shadow lists. Returns the images and their spp.
/// `pb` advances in milliseconds of the whole budget.
pub fn volpath_equal_time(
    accel: &Accel,
    medium: &Medium,
    views: &[ViewDesc],
    seed: u64,
    settings: &VolpathSettings,
    budget: f64,
    pb: &ProgressBar,
) -> (RenderReport, u32) {
    let t0 = Instant::now();
    let total = budget * views.len() as f64;
    pb.set_length((total * 1000.0).ceil() as u64);
    let lit = Lit::new(accel, *medium, *settings);
    let lists: Vec<_> = views.iter().map(|v| lit.lists(&v.light)).collect();
    let mut renders: Vec<Progressive> = views
        .iter()
        .zip(&lists)
        .enumerate()
        .map(|(i, (v, l))| {
            Progressive::new(&lit.scene(&v.light, l), settings, &v.camera, seed, i as u64)
        })
        .collect();
    let mut passes = PassBudget::new(total);
    loop {
        let tp = Instant::now();
        // All views of a pass in one parallel job, so that the threads wait for each other
        // once per pass, not once per view.
        renders
            .par_iter_mut()
            .for_each(|r| r.advance(EQUAL_TIME_PASS, None));
        pb.set_position((t0.elapsed().as_secs_f64() * 1000.0) as u64);
        if !passes.another(t0.elapsed().as_secs_f64(), tp.elapsed().as_secs_f64()) {
            break;
        }
    }
    pb.finish_and_clear();
    let per_view = t0.elapsed().as_secs_f64() / views.len() as f64;
    let report = RenderReport {
        images: renders.iter().map(Progressive::image).collect(),
        derivatives: Vec::new(),
        seconds_per_view: vec![per_view; views.len()],
    };
    (report, renders[0].spp())
}
#[cfg(test)]
mod tests {
    use super::PassBudget;

    /// Passes continue while the time so far plus the slowest pass fits the budget; a slow pass
    /// makes the estimate of the next one pessimistic; at least one pass is always rendered
    /// (the caller renders before asking).
    #[test]
    fn pass_budget_stops_before_the_slowest_pass_would_overrun() {
        let mut b = PassBudget::new(1.0);
        assert!(b.another(0.2, 0.2));
        assert!(b.another(0.4, 0.2));
        assert!(b.another(0.6, 0.2));
        assert!(b.another(0.8, 0.2));
        assert!(!b.another(1.0, 0.2));

        let mut b = PassBudget::new(1.0);
        assert!(b.another(0.1, 0.1));
        assert!(!b.another(0.6, 0.5), "0.6 s + a 0.5 s pass overruns 1 s");

        let mut b = PassBudget::new(0.1);
        assert!(
            !b.another(0.3, 0.3),
            "one pass over the whole budget: stop after it"
        );
    }
}
