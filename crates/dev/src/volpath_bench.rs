//! `translucent-dev volpath`: speed of the volumetric path tracer on the reference sphere scene
//! (the Mitsuba 3 reference folder when given, otherwise the same scene rebuilt from its numbers:
//! sphere of radius 0.125, σ_t = (50, 60, 70), α = (0.95, 0.9, 0.85), 8 cameras on the reference
//! spiral at distance 0.5, fov 40°, fixed point light of 0.785 W/sr). Prints seconds per view and
//! paths per second per resolution, next to Mitsuba 3's figures measured on a machine like ours
//! (llvm_ad_rgb, 2 cores, 32 spp: 0.064 s per 64² view, 0.25 s per 128² view).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use clap::Args;
use geometry::Shape;
use glam::Vec3;
use scene::rig::{Rig, RigLight};
use scene::{Camera, Dataset, Medium, PointLight};
use volpath::{
    ChannelSampling, Lit, RenderSettings, ShadowTransmittance, VolpathSettings, render_image,
};

use inverse::views::build_accel;

#[derive(Args)]
#[command(mut_arg("spp", cmdline::groups::default("32")))]
pub struct VolpathBenchArgs {
    /// Mitsuba reference folder to take the scene from (default: the same scene rebuilt).
    #[arg(long)]
    pub reference: Option<PathBuf>,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    /// Image resolutions to time (square).
    #[arg(long, value_delimiter = ',', default_value = "64,128")]
    pub res: Vec<u32>,
    /// Repetitions (the best is reported).
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Shadow estimators to time (default: all three; `tracked` is Mitsuba 3's).
    #[arg(long, value_delimiter = ',', value_enum)]
    pub shadow: Vec<ShadowName>,
    /// Channel sampling schemes to time (default: both; `single` is Mitsuba 3's).
    #[arg(long, value_delimiter = ',', value_enum)]
    pub sampling: Vec<SamplingName>,
}

/// A shadow estimator as the bench names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ShadowName {
    /// Delta tracking with closest-hit queries (Mitsuba 3's estimator).
    Tracked,
    /// Closed-form transmittance, inside length from the light's triangle lists (our default).
    Exact,
    /// Closed-form transmittance, inside length from an all-hits BVH query.
    ExactBvh,
}

/// A channel sampling scheme as the bench names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SamplingName {
    /// Spectral MIS over the three channels (our default).
    Spectral,
    /// One channel per path with reweighting (Mitsuba 3's scheme).
    Single,
}

/// Mitsuba 3 (llvm_ad_rgb, 2 cores, 32 spp) seconds per view, as measured on the project machine (BENCHMARKS.md, "Speed against Mitsuba 3").
const MITSUBA_SECONDS: [(u32, f64); 2] = [(64, 0.064), (128, 0.25)];

/// The benchmark's scene: a Mitsuba reference folder's mesh, medium and views (`--reference`), or
/// the built-in sphere (8 views of 64² around a fixed light).
#[allow(clippy::type_complexity)]
fn bench_scene(
    a: &VolpathBenchArgs,
) -> Result<(
    geometry::Mesh,
    Vec<geometry::MeshWarning>,
    Medium,
    Vec<(Camera, PointLight)>,
)> {
    Ok(match &a.reference {
        Some(dir) => {
            let ds = Dataset::load_reference(dir)?;
            let (m, w) = ds.load_mesh()?;
            let medium = ds
                .truth
                .ok_or_else(|| anyhow::anyhow!("{}: no medium", dir.display()))?;
            let views: Vec<_> = ds
                .views
                .iter()
                .map(|v| (v.camera.clone(), v.light))
                .collect();
            (m, w, medium, views)
        }
        None => {
            let mesh = Shape::Sphere {
                radius: 0.125,
                subdivisions: 5,
            }
            .build()?;
            let medium = Medium {
                sigma_t: [50.0, 60.0, 70.0],
                albedo: [0.95, 0.9, 0.85],
                g: scene::Anisotropy::uniform(0.0),
                eta: 1.0,
                roughness: 0.0,
            };
            let light = Vec3::new(0.267_261_24, 0.400_891_86, 0.133_630_62);
            let rig = Rig {
                views: 8,
                radius: 0.5,
                target: Vec3::ZERO,
                fov_x_deg: 40.0,
                width: 64,
                height: 64,
                light: RigLight::Fixed { position: light },
                intensity: [std::f32::consts::FRAC_PI_4; 3],
                elevation_deg: (-90.0, 90.0),
            };
            let views: Vec<_> = rig
                .build()
                .into_iter()
                .map(|v| (v.camera, v.light))
                .collect();
            (mesh, Vec::new(), medium, views)
        }
    })
}

/// The best of `--repeat` timings of the views at `res`², in seconds per view. As `render` does,
/// each light position's shadow-ray lists are built once per timing (`lit`).
fn best_seconds<'a>(
    a: &VolpathBenchArgs,
    lit: impl Fn() -> Lit<'a>,
    settings: &VolpathSettings,
    views: &[(Camera, PointLight)],
    res: u32,
) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..a.repeat {
        let t0 = Instant::now();
        let lit = lit();
        for (i, (cam, light)) in views.iter().enumerate() {
            let mut cam = cam.clone();
            cam.width = res;
            cam.height = res;
            let lists = lit.lists(light);
            let scene = lit.scene(light, &lists);
            let rs = RenderSettings {
                spp: *a.spp,
                seed: *a.seed,
                view: i as u64,
            };
            std::hint::black_box(render_image(&scene, settings, &cam, &rs, None));
        }
        best = best.min(t0.elapsed().as_secs_f64() / views.len() as f64);
    }
    best
}

pub fn run(a: &VolpathBenchArgs) -> Result<()> {
    anyhow::ensure!(
        *a.spp > 0 && a.repeat > 0,
        "--spp and --repeat must be at least 1"
    );
    let (mesh, warnings, medium, views) = bench_scene(a)?;
    let tris = mesh.triangle_count();
    let accel = build_accel(mesh, &warnings, "bench scene");
    println!(
        "volpath bench: sphere ({tris} triangles), {} views, {} spp, {} thread(s), best of {}",
        views.len(),
        *a.spp,
        rayon::current_num_threads(),
        a.repeat
    );
    println!(
        "{:<8} {:<14} {:<10} {:>12} {:>14} {:>16}",
        "res", "sampling", "shadow", "s/view", "Mpaths/s", "Mitsuba s/view"
    );
    for &res in &a.res {
        anyhow::ensure!(res > 0, "--res values must be positive");
        // Exact shadows twice: through the light's triangle lists (the default) and through the
        // BVH (the reference they replace).
        let variants = [
            (ShadowTransmittance::Tracked, false),
            (ShadowTransmittance::Exact, true),
            (ShadowTransmittance::Exact, false),
        ]
        .into_iter()
        .flat_map(|sh| {
            [ChannelSampling::SpectralMis, ChannelSampling::SingleChannel].map(|c| (c, sh))
        })
        .filter(|&(sampling, (shadow, light_lists))| {
            let shadow_name = match (shadow, light_lists) {
                (ShadowTransmittance::Tracked, _) => ShadowName::Tracked,
                (ShadowTransmittance::Exact, true) => ShadowName::Exact,
                (ShadowTransmittance::Exact, false) => ShadowName::ExactBvh,
            };
            let sampling_name = match sampling {
                ChannelSampling::SpectralMis => SamplingName::Spectral,
                ChannelSampling::SingleChannel => SamplingName::Single,
            };
            (a.shadow.is_empty() || a.shadow.contains(&shadow_name))
                && (a.sampling.is_empty() || a.sampling.contains(&sampling_name))
        });
        for (sampling, (shadow, light_lists)) in variants {
            let settings = VolpathSettings {
                channel_sampling: sampling,
                shadow,
                light_lists,
                ..Default::default()
            };
            let lit = || Lit::new(&accel, medium, settings);
            let best = best_seconds(a, lit, &settings, &views, res);
            let paths = (res * res * *a.spp) as f64 / best / 1e6;
            let mitsuba = MITSUBA_SECONDS
                .iter()
                .find(|(r, _)| *r == res)
                .map(|(_, s)| format!("{s:.3}"))
                .unwrap_or_else(|| "-".into());
            let name = match sampling {
                ChannelSampling::SpectralMis => "spectral MIS",
                ChannelSampling::SingleChannel => "single channel",
            };
            let shadow = match (shadow, light_lists) {
                (ShadowTransmittance::Tracked, _) => "tracked",
                (ShadowTransmittance::Exact, true) => "exact",
                (ShadowTransmittance::Exact, false) => "exact-bvh",
            };
            println!(
                "{:<8} {:<14} {:<10} {:>12.4} {:>14.3} {:>16}",
                format!("{res}²"),
                name,
                shadow,
                best,
                paths,
                mitsuba
            );
        }
    }
    Ok(())
}
