//! Training data generation (docs/model.md §5; VKJ19 `datapipeline.py`, `sss_particle_tracer.cpp`).
//!
//! **Meshes.** Mesh `i` (global index `first_mesh + i`, seeded by `hash(seed, i)`) is a random base
//! shape — one of our procedural families ([`Shape`]) with random parameters, or one of
//! `DataConfig::base_meshes` — normalised to max bbox extent 1 and centred, uniformly randomly
//! rotated (Shoemake's quaternion), scaled ×20 and then per axis by `U[0.25, 3]`. One constraint
//! cloud per mesh with density `2/ε₀` per unit area, `ε₀ = ε(σ_t = 1, α = 0.5, g = 0) ≈ 0.1791`
//! (at least 1024 points).
//!
//! **Medium** (MixedMediumParamGenerator3): `α' = (1 − e^{−8u})/(1 − e^{−8})`, `u ~ U[0,1]`,
//! clamped ≥ 0.05 (uniform in effective albedo); with probability `p_g_zero` `g = 0` (then `α = α'`,
//! `σ_t = 1`), else `g ~ U[0, 0.95]`, `σ_s = α'/(1 − g)`, `σ_a = 1 − α'`, `σ_t = σ_s + σ_a`,
//! `α = σ_s/σ_t`, then w.p. ½ `σ_t ← 1` (α kept) and w.p. ½ `g ← 0.95 α''` (α'' another
//! effective-albedo-uniform draw; α not recomputed). `η = 1` with probability `p_eta_one`, else
//! `η ~ U[1, 1.5]`. The `p_g_zero`/`p_eta_one` masses are our addition so that the paper's setting
//! (g = 0, η = 1, SON24 §5) is well covered; set both to 0 for the VKJ19 distribution.
//!
//! **Configuration.** Entry point uniform by area; incoming direction cosine-distributed around the
//! mesh shading normal, rejected w.p. `F_η(cos θ)`, refracted (Snell); the polynomial is fitted at
//! the entry point with this medium's `ε = σ_n²` (world axes, [`ConstraintCloud::fit_at`]); the
//! direction is aligned to the polynomial normal (§3.5); LS coefficients `poly.to_light_space(d_in)`.
//! Up to `incident_attempts` tries. Walks ([`crate::walk`]) run until `≥ samples_per_config`
//! exits AND `≥ path_attempts` finished (exited or absorbed) paths; `absorption_prob` = absorbed
//! among the first `path_attempts` attempts / `path_attempts`. More than `max_invalid` invalid or
//! `max_absorbed` absorbed paths restart the configuration with fresh draws (at most
//! `max_restarts` times, then it is skipped).
//!
//! **Determinism.** Meshes are built one after the other; configurations run in parallel (rayon),
//! each with its own stream `Sampler(seed, mesh, config, restart)`, collected in order: the output
//! is identical for any thread count. `Sample::config = mesh · configs_per_mesh + c` with the global
//! mesh index, so `config / configs_per_mesh` is the mesh; [`DataSummary::meshes`] gives each mesh's
//! sample range. Disjoint `first_mesh` ranges give disjoint train/validation meshes.

use base::fresnel::{fresnel_dielectric, refract};
use base::rng::{Sampler, hash_key};
use bssrdf::fit::{ConstraintCloud, FitError};
use bssrdf::medium::{effective_albedo_inverse, kernel_epsilon, sigma_n};
use geometry::{AreaSampler, Frame, GeometryError, Mesh, Shape};
use glam::{Mat4, Quat, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::sample::Sample;
use crate::walk::{WalkMedium, WalkOutcome, WalkSurface, random_walk};

/// Version string of this generator (stored in the samples file header).
pub const GENERATOR_VERSION: &str =
    concat!("translucent-learn datagen ", env!("CARGO_PKG_VERSION"));

const PURPOSE_MESH: u64 = 1;
const PURPOSE_CLOUD: u64 = 2;

/// Distribution parameters of meshes and media (docs/model.md §5).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamRanges {
    /// Lower clamp of the reduced albedo α' (0.05).
    pub albedo_red_min: f64,
    /// Range of g when it is drawn uniformly ([0, 0.95]).
    pub g: [f64; 2],
    /// Range of η when it is drawn uniformly ([1, 1.5]).
    pub eta: [f64; 2],
    /// Fraction of configurations with g = 0 exactly (0.5; 0 = VKJ19).
    pub p_g_zero: f64,
    /// Fraction of configurations with η = 1 exactly (0.5; 0 = VKJ19).
    pub p_eta_one: f64,
    /// Probability of the `σ_t ← 1` replacement (0.5).
    pub p_sigma_t_one: f64,
    /// Probability of the `g ← 0.95 α''` replacement (0.5).
    pub p_g_replace: f64,
    /// Uniform scale after normalisation to extent 1 (20).
    pub mesh_scale: f32,
    /// Range of the per-axis anisotropic scale ([0.25, 3]).
    pub axis_scale: [f32; 2],
}

impl Default for ParamRanges {
    fn default() -> Self {
        ParamRanges {
            albedo_red_min: 0.05,
            g: [0.0, 0.95],
            eta: [1.0, 1.5],
            p_g_zero: 0.5,
            p_eta_one: 0.5,
            p_sigma_t_one: 0.5,
            p_g_replace: 0.5,
            mesh_scale: 20.0,
            axis_scale: [0.25, 3.0],
        }
    }
}

/// Everything that determines a data set.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DataConfig {
    /// Number of random meshes.
    pub meshes: usize,
    /// Global index of the first mesh (seeding and `Sample::config`); use disjoint ranges for
    /// train and validation.
    pub first_mesh: u64,
    /// Configurations per mesh (VKJ19: 6,250).
    pub configs_per_mesh: usize,
    /// Recorded exits per configuration (16).
    pub samples_per_config: usize,
    /// Path attempts for the absorption probability (1024).
    pub path_attempts: usize,
    /// Master seed.
    pub seed: u64,
    /// Drop the fitted z³ coefficient (docs/model.md §3.2 quirk; true for comparability).
    pub quirk_c19: bool,
    /// Whether the procedural families are in the base-shape pool.
    pub procedural: bool,
    /// Extra base shapes (e.g. loaded mesh files); transformed like the procedural ones.
    #[serde(skip)]
    pub base_meshes: Vec<Mesh>,
    /// Names of the extra base shapes (for the header).
    pub base_mesh_names: Vec<String>,
    /// Parameter distributions.
    pub ranges: ParamRanges,
    /// Incident point/direction attempts per configuration (10).
    pub incident_attempts: u32,
    /// Restart when more invalid paths than this (2048).
    pub max_invalid: u64,
    /// Restart when more absorbed paths than this (102,400).
    pub max_absorbed: u64,
    /// Restarts before a configuration is skipped (8).
    pub max_restarts: u32,
}

impl Default for DataConfig {
    fn default() -> Self {
        DataConfig {
            meshes: 20,
            first_mesh: 0,
            configs_per_mesh: 6250,
            samples_per_config: 16,
            path_attempts: 1024,
            seed: 1,
            quirk_c19: true,
            procedural: true,
            base_meshes: Vec::new(),
            base_mesh_names: Vec::new(),
            ranges: ParamRanges::default(),
            incident_attempts: 10,
            max_invalid: 2048,
            max_absorbed: 102_400,
            max_restarts: 8,
        }
    }
}

/// Errors of data generation.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A configuration value is out of range.
    #[error("invalid data configuration: {0}")]
    Config(String),
    /// Building a mesh failed.
    #[error("mesh {mesh}: cannot build the shape")]
    Mesh {
        mesh: u64,
        #[source]
        source: GeometryError,
    },
    /// The constraint cloud could not be built.
    #[error("mesh {mesh}: cannot build the constraint cloud")]
    Cloud {
        mesh: u64,
        #[source]
        source: FitError,
    },
}

/// Per-mesh statistics.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct MeshSummary {
    /// Global mesh index.
    pub index: u64,
    /// Base shape name.
    pub base: String,
    /// Per-axis scale applied after rotation (×20 included).
    pub scale: [f32; 3],
    pub triangles: usize,
    pub area: f64,
    pub cloud_points: usize,
    /// Index of this mesh's first sample in the output.
    pub first_sample: usize,
    pub samples: usize,
    pub configs_skipped: usize,
}

/// Statistics of a run.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct DataSummary {
    pub meshes: Vec<MeshSummary>,
    pub configs: usize,
    pub configs_skipped: usize,
    pub restarts: u64,
    pub incident_failures: u64,
    pub paths: u64,
    pub exited: u64,
    pub absorbed: u64,
    pub invalid: u64,
    pub samples: usize,
}

impl DataConfig {
    fn validate(&self) -> Result<(), DataError> {
        let bad = |m: &str| Err(DataError::Config(m.to_string()));
        let r = &self.ranges;
        let prob = |p: f64| (0.0..=1.0).contains(&p);
        if self.samples_per_config == 0 || self.path_attempts == 0 {
            return bad("samples_per_config and path_attempts must be ≥ 1");
        }
        if !self.procedural && self.base_meshes.is_empty() && self.meshes > 0 {
            return bad("no base shapes: enable procedural shapes or give base meshes");
        }
        let total = (self.first_mesh as u128 + self.meshes as u128) * self.configs_per_mesh as u128;
        if total > u32::MAX as u128 {
            return bad("mesh × configuration index does not fit in u32");
        }
        if ![r.p_g_zero, r.p_eta_one, r.p_sigma_t_one, r.p_g_replace]
            .into_iter()
            .all(prob)
        {
            return bad("probabilities must lie in [0, 1]");
        }
        if !(r.g[0] >= 0.0 && r.g[0] <= r.g[1] && r.g[1] < 1.0) {
            return bad("g range must satisfy 0 ≤ g_min ≤ g_max < 1");
        }
        if !(r.eta[0] >= 1.0 && r.eta[0] <= r.eta[1] && r.eta[1].is_finite()) {
            return bad("eta range must satisfy 1 ≤ eta_min ≤ eta_max");
        }
        if !(r.albedo_red_min > 0.0 && r.albedo_red_min < 1.0) {
            return bad("albedo_red_min must lie in (0, 1)");
        }
        if !(r.mesh_scale > 0.0 && r.axis_scale[0] > 0.0 && r.axis_scale[0] <= r.axis_scale[1]) {
            return bad("mesh scales must be > 0 with axis_scale[0] ≤ axis_scale[1]");
        }
        Ok(())
    }
}

/// `ε₀ = ε(σ_t = 1, α = 0.5, g = 0)` ≈ 0.1791, the kernel of the constraint-cloud density.
pub fn cloud_epsilon() -> f64 {
    kernel_epsilon(1.0, 0.5, 0.0, 1.0)
}

fn uniform(rng: &mut Sampler, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.next_f32() as f64
}

/// A random base shape of the procedural families, with random parameters.
fn random_shape(rng: &mut Sampler) -> Shape {
    let u = |rng: &mut Sampler, a: f32, b: f32| a + (b - a) * rng.next_f32();
    let shape = match rng.next_below(5) {
        0 => Shape::Sphere {
            radius: 0.5,
            subdivisions: 4,
        },
        1 => {
            let radius = u(rng, 0.2, 0.5);
            Shape::Cone {
                height: 1.0,
                radius,
                tip_radius: radius * u(rng, 0.1, 0.4),
                segments: 64,
            }
        }
        2 => {
            let major = u(rng, 0.25, 0.4);
            Shape::Torus {
                major,
                minor: major * u(rng, 0.25, 0.7),
                segments: 64,
            }
        }
        3 => {
            let size = [u(rng, 0.3, 1.0), u(rng, 0.3, 1.0), u(rng, 0.3, 1.0)];
            let m = size[0].min(size[1]).min(size[2]);
            Shape::RoundedBox {
                size,
                radius: m * u(rng, 0.05, 0.45),
                segments: 16,
            }
        }
        _ => Shape::Blob {
            radius: 0.5,
            amplitude: u(rng, 0.05, 0.3),
            bumps: 4 + rng.next_below(21),
            seed: rng.next_below(u32::MAX) as u64,
            subdivisions: 4,
        },
    };
    if shape.check().is_ok() {
        shape
    } else {
        Shape::from_name(shape.name()).unwrap_or(Shape::Sphere {
            radius: 0.5,
            subdivisions: 4,
        })
    }
}

/// Random mesh `index` (docs/model.md §5 "Meshes").
fn build_mesh(cfg: &DataConfig, index: u64) -> Result<(Mesh, MeshSummary), DataError> {
    let mut rng = Sampler::new(cfg.seed, index, 0, PURPOSE_MESH);
    let n_proc = if cfg.procedural { 5 } else { 0 };
    let pick = rng.next_below(n_proc + cfg.base_meshes.len() as u32);
    let (mut mesh, base) = if pick < n_proc {
        let shape = random_shape(&mut rng);
        let mesh = shape.build().map_err(|source| DataError::Mesh {
            mesh: index,
            source,
        })?;
        (mesh, shape.name().to_string())
    } else {
        let k = (pick - n_proc) as usize;
        let name = cfg
            .base_mesh_names
            .get(k)
            .cloned()
            .unwrap_or_else(|| format!("base-{k}"));
        (cfg.base_meshes[k].clone(), name)
    };
    let (lo, hi) = mesh.bounds();
    let extent = (hi - lo).max_element().max(1e-12);
    let normalise =
        Mat4::from_scale(Vec3::splat(1.0 / extent)) * Mat4::from_translation(-(lo + hi) * 0.5);
    // Uniform random rotation (Shoemake 1992).
    let (u1, u2, u3) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
    let tau = std::f32::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let q = Quat::from_xyzw(
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
        b * (tau * u3).cos(),
    )
    .normalize();
    let r = &cfg.ranges;
    let scale: [f32; 3] = std::array::from_fn(|_| {
        r.mesh_scale * (r.axis_scale[0] + (r.axis_scale[1] - r.axis_scale[0]) * rng.next_f32())
    });
    mesh.transform(Mat4::from_scale(Vec3::from(scale)) * Mat4::from_quat(q) * normalise);
    let summary = MeshSummary {
        index,
        base,
        scale,
        triangles: mesh.triangle_count(),
        area: mesh.area(),
        ..Default::default()
    };
    Ok((mesh, summary))
}

/// Medium of one configuration (module docs); returns (σ_t, α, g, η).
fn sample_medium(r: &ParamRanges, rng: &mut Sampler) -> WalkMedium {
    let eff_uniform = |rng: &mut Sampler| effective_albedo_inverse(rng.next_f32() as f64);
    let albedo_red = eff_uniform(rng).clamp(r.albedo_red_min, 1.0);
    let g_zero = (rng.next_f32() as f64) < r.p_g_zero;
    let eta = if (rng.next_f32() as f64) < r.p_eta_one {
        1.0
    } else {
        uniform(rng, r.eta[0], r.eta[1])
    };
    if g_zero {
        return WalkMedium {
            sigma_t: 1.0,
            albedo: albedo_red,
            g: 0.0,
            eta,
        };
    }
    let mut g = uniform(rng, r.g[0], r.g[1]);
    let sigma_s = albedo_red / (1.0 - g);
    let sigma_a = 1.0 - albedo_red;
    let mut sigma_t = sigma_s + sigma_a;
    let albedo = sigma_s / sigma_t;
    if (rng.next_f32() as f64) < r.p_sigma_t_one {
        sigma_t = 1.0;
    }
    if (rng.next_f32() as f64) < r.p_g_replace {
        g = 0.95 * eff_uniform(rng).clamp(r.albedo_red_min, 1.0);
    }
    WalkMedium {
        sigma_t,
        albedo,
        g,
        eta,
    }
}

/// Outcome counters of one configuration.
#[derive(Default)]
struct ConfigResult {
    samples: Vec<Sample>,
    paths: u64,
    exited: u64,
    absorbed: u64,
    invalid: u64,
    restarts: u64,
    incident_failures: u64,
    skipped: bool,
}

/// Everything a configuration needs from its mesh.
struct MeshCtx<'a> {
    mesh: &'a Mesh,
    sampler: &'a AreaSampler,
    cloud: &'a ConstraintCloud,
    index: u64,
}

/// One configuration: draws, fit, walks (module docs). Deterministic in (seed, mesh, config).
fn run_config(cfg: &DataConfig, ctx: &MeshCtx, config: u32) -> ConfigResult {
    let mut res = ConfigResult::default();
    'restart: for restart in 0..=cfg.max_restarts as u64 {
        if restart > 0 {
            res.restarts += 1;
        }
        let mut rng = Sampler::new(cfg.seed, ctx.index, config as u64, 16 + restart);
        let medium = sample_medium(&cfg.ranges, &mut rng);
        let sn = sigma_n(medium.sigma_t, medium.albedo, medium.g);
        let eps = sn * sn;
        // Incident point and direction.
        let mut incident = None;
        for _ in 0..cfg.incident_attempts {
            let s = ctx
                .sampler
                .sample(ctx.mesh, [rng.next_f32(), rng.next_f32(), rng.next_f32()]);
            let (u1, u2) = (rng.next_f32(), rng.next_f32());
            let (rr, phi) = (u1.sqrt(), std::f32::consts::TAU * u2);
            let cos = (1.0 - u1).max(0.0).sqrt();
            let w =
                Frame::from_normal(s.ns).to_world(Vec3::new(rr * phi.cos(), rr * phi.sin(), cos));
            if rng.next_f32() < fresnel_dielectric(cos, medium.eta as f32) {
                continue;
            }
            let Some(d) = refract(-w, s.ns, medium.eta as f32) else {
                continue;
            };
            let Ok(poly) = ctx.cloud.fit_at(s.p, eps, cfg.quirk_c19) else {
                continue;
            };
            let Some(n_poly) = poly.normal() else {
                continue;
            };
            let d_in = bssrdf::polynomial::align_direction(d, s.ns, n_poly).normalize();
            if d_in.dot(n_poly) >= 0.0 || !d_in.is_finite() {
                continue;
            }
            incident = Some((s.p, d_in, n_poly, poly));
            break;
        }
        let Some((in_pos, in_dir, in_normal, poly)) = incident else {
            res.incident_failures += 1;
            continue 'restart;
        };
        let surface = WalkSurface::new(&poly, sn);
        let poly_ls = poly.to_light_space(in_dir);
        let frame = bssrdf::polynomial::light_space_frame(in_dir);
        let (fs, ft, fnn) = (frame.s.as_dvec3(), frame.t.as_dvec3(), frame.n.as_dvec3());
        let want = cfg.samples_per_config;
        let attempts = cfg.path_attempts as u64;
        let (mut attempt, mut exited, mut finished, mut absorbed, mut invalid) =
            (0u64, 0usize, 0u64, 0u64, 0u64);
        let mut absorbed_first = 0u64;
        res.samples.clear();
        while exited < want || finished < attempts {
            attempt += 1;
            res.paths += 1;
            match random_walk(&surface, &medium, in_dir, &mut rng) {
                WalkOutcome::Exited(e) => {
                    exited += 1;
                    finished += 1;
                    res.exited += 1;
                    if res.samples.len() < want {
                        let r = e.position / sn;
                        res.samples.push(Sample {
                            poly_ls: poly_ls.0,
                            out_ls: [r.dot(fs) as f32, r.dot(ft) as f32, r.dot(fnn) as f32],
                            albedo: medium.albedo as f32,
                            sigma_t: medium.sigma_t as f32,
                            g: medium.g as f32,
                            eta: medium.eta as f32,
                            absorption_prob: 0.0,
                            sigma_n: sn as f32,
                            in_pos: in_pos.to_array(),
                            in_dir: in_dir.to_array(),
                            in_normal: in_normal.to_array(),
                            out_pos: (in_pos.as_dvec3() + e.position).as_vec3().to_array(),
                            out_normal: e.normal.to_array(),
                            out_dir: e.direction.to_array(),
                            bounces: e.bounces,
                            config: ctx.index as u32 * cfg.configs_per_mesh as u32 + config,
                        });
                    }
                }
                WalkOutcome::Absorbed { .. } => {
                    absorbed += 1;
                    finished += 1;
                    res.absorbed += 1;
                    if attempt <= attempts {
                        absorbed_first += 1;
                    }
                }
                WalkOutcome::Invalid(_) => {
                    invalid += 1;
                    res.invalid += 1;
                }
            }
            if invalid > cfg.max_invalid || absorbed > cfg.max_absorbed {
                continue 'restart;
            }
        }
        let prob = (absorbed_first as f64 / attempts as f64) as f32;
        for s in &mut res.samples {
            s.absorption_prob = prob;
        }
        return res;
    }
    res.samples.clear();
    res.skipped = true;
    res
}

/// Generate the data set of `cfg` (module docs). `progress` is advanced by one per configuration
/// (its length is set to the total).
pub fn generate(
    cfg: &DataConfig,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<(Vec<Sample>, DataSummary), DataError> {
    cfg.validate()?;
    if let Some(pb) = progress {
        pb.set_length((cfg.meshes * cfg.configs_per_mesh) as u64);
    }
    let mut samples =
        Vec::with_capacity(cfg.meshes * cfg.configs_per_mesh * cfg.samples_per_config);
    let mut summary = DataSummary::default();
    let eps0 = cloud_epsilon();
    for i in 0..cfg.meshes as u64 {
        let index = cfg.first_mesh + i;
        let (mesh, mut ms) = build_mesh(cfg, index)?;
        let cloud =
            ConstraintCloud::from_mesh(&mesh, eps0, hash_key(&[cfg.seed, index, PURPOSE_CLOUD]))
                .map_err(|source| DataError::Cloud {
                    mesh: index,
                    source,
                })?;
        let sampler = AreaSampler::new(&mesh);
        let ctx = MeshCtx {
            mesh: &mesh,
            sampler: &sampler,
            cloud: &cloud,
            index,
        };
        let results: Vec<ConfigResult> = (0..cfg.configs_per_mesh as u32)
            .into_par_iter()
            .map(|c| {
                let r = run_config(cfg, &ctx, c);
                if let Some(pb) = progress {
                    pb.inc(1);
                }
                r
            })
            .collect();
        ms.cloud_points = cloud.len();
        ms.first_sample = samples.len();
        for r in results {
            summary.configs += 1;
            summary.configs_skipped += r.skipped as usize;
            ms.configs_skipped += r.skipped as usize;
            summary.restarts += r.restarts;
            summary.incident_failures += r.incident_failures;
            summary.paths += r.paths;
            summary.exited += r.exited;
            summary.absorbed += r.absorbed;
            summary.invalid += r.invalid;
            samples.extend_from_slice(&r.samples);
        }
        ms.samples = samples.len() - ms.first_sample;
        summary.meshes.push(ms);
    }
    summary.samples = samples.len();
    Ok((samples, summary))
}

/// Mesh index (global) of a sample: `config / configs_per_mesh`.
pub fn mesh_of(sample: &Sample, configs_per_mesh: usize) -> u64 {
    sample.config as u64 / configs_per_mesh.max(1) as u64
}
