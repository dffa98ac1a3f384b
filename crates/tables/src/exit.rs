//! The light-side exit factor: the direction in which light leaves (by reciprocity, enters) the
//! medium at x_i, conditioned on the direction in which the camera ray entered at x_o.
//!
//! The per-sample estimator of docs/model.md §1 ends with the light-side factor
//! Sw(w_l)·max(0, n_i·w_l) = (1 − F(cos θ_l))·cos θ_l / (π(1 − 2 FM1(1/η))): the walks that
//! escape are assumed to leave with a (Fresnel-weighted) cosine distribution, whatever the
//! direction they came in with. For a real medium this is not so. In a half-space of albedo
//! α = 0.85 (η = 1, g = 0), walks entering at grazing incidence leave at grazing angles 3.9 times
//! more often than a cosine distribution says, walks entering at normal incidence leave at
//! grazing angles 10 % more often and along the normal 9 % less often. Low-order scattering
//! couples the two directions (docs/notes/light-side.md, "The exit law").
//!
//! This module replaces the cosine law by the exit-direction density of escaped walks in a
//! half-space of the same medium, conditioned on the entry direction:
//!
//!   Sw(w_l)·cos θ_l  →  f(α; μ_cam, μ_l) · μ_l / π,
//!   f(α; μ_c, μ_l) = p(μ_l | μ_c) / (2 μ_l),
//!
//! where μ_c = cos θ_cam (outside, at x_o), μ_l = cos θ_l (outside, at x_i) and p(μ | μ_c) the
//! density of the outside exit cosine of the walks that escape after entering at μ_c
//! (azimuthally averaged). A cosine law has p = 2μ, f = 1; ∫₀¹ f·2μ dμ = 1 always, so the factor
//! redistributes the light over exit directions and leaves the escaped energy, S_abs of the
//! absorption network, unchanged. The half-space is exact for a plane and scale-free (it depends on
//! α, g and η only, not on σ_t). The walks follow the physics of the training data
//! (docs/model.md §5 step 3, `learn::walk`): analog absorption, Henyey–Greenstein phase, specular
//! internal reflection with probability F and refraction otherwise, entry by refraction of the
//! camera direction (conditioned on transmission, as (1 − F(cos θ_cam)) is applied separately).
//!
//! [`ExitTable`] tabulates f on a grid of albedos (a spline in ln(1 − α) between them) and [`MU_BINS`] × [`MU_BINS`]
//! cosine bins (bin averages, from histograms of [`ExitTableSettings::walks`] walks per albedo and
//! entry bin, the entry cosine uniform within its bin). [`ExitSlice`] is the table at one albedo,
//! with ∂ln f/∂α for the α-gradient; lookups are bilinear between bin centres.

use base::fresnel::fresnel_dielectric;
use base::microfacet::RoughDielectric;
use base::phase::HenyeyGreenstein;
use base::rng::Sampler;
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use crate::table::{DEFAULT_RUNTIME_WALKS, TableError, TableFile};
use crate::table::{MediumCache, TableCheck, WalkTable, albedo_spline, for_medium, shipped};

/// The light-side exit law of the learned renderer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum ExitLaw {
    /// The exit direction of half-space walks, given the camera direction (default).
    ///
    /// f(α; μ_cam, μ_l) from half-space walks (this module).
    #[default]
    HalfSpace,
    /// The cosine law Sw·cos θ_l of Vicini et al. 2019 and Son et al. 2024.
    ///
    /// The cosine law Sw(w_l)·cos θ_l of VKJ19 and SON24 (docs/model.md §1).
    Cosine,
}

/// Cosine bins per axis.
pub const MU_BINS: usize = 16;

/// 1 − α of the albedo grid (ln-uniform interpolation; clamped outside).
pub const ONE_MINUS_ALBEDO: [f32; 16] = [
    0.95, 0.7, 0.5, 0.35, 0.25, 0.18, 0.12, 0.08, 0.05, 0.03, 0.02, 0.012, 0.007, 0.004, 0.002,
    0.001,
];

/// Scattering events after which a walk counts as absorbed (as `learn::walk::MAX_BOUNCES`).
const MAX_BOUNCES: u32 = 10_000;

/// How an [`ExitTable`] is made.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExitTableSettings {
    /// Henyey–Greenstein g of the medium.
    pub g: f32,
    /// Relative index of refraction n_inside/n_outside.
    pub eta: f32,
    /// GGX roughness α of the boundary (0 = smooth; only with η > 1). Files without the field
    /// are smooth.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub roughness: f32,
    /// Walks per (albedo, entry-cosine bin).
    pub walks: u32,
    /// Seed of the walks.
    pub seed: u64,
}

/// Serde: a smooth boundary's roughness is not written.
fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

/// f(α; μ_c, μ_l) on the grid `ONE_MINUS_ALBEDO` × `MU_BINS` × `MU_BINS` (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExitTable {
    pub settings: ExitTableSettings,
    /// `f[(a·MU_BINS + i)·MU_BINS + j]`: albedo a, entry bin i (camera), exit bin j (light).
    pub f: Vec<f32>,
    /// Escaped fraction per (albedo, entry bin) of the energy that entered: a by-product,
    /// checked against the network, and with a rough boundary the share of it that the
    /// microfacets let out ([`ExitTable::escape`]).
    pub escaped: Vec<f32>,
}

/// The outside cosine of a direction leaving the medium with inside cosine `mu` (Snell), or
/// `None` under total internal reflection.
#[inline]
fn refract_out(mu: f32, eta: f32) -> Option<f32> {
    let s2 = eta * eta * (1.0 - mu * mu);
    (s2 < 1.0).then(|| (1.0 - s2).sqrt())
}

/// The boundary of the half-space walks: smooth (Fresnel reflection with its probability,
/// Snell refraction) or rough ([`RoughDielectric`], the tracer's GGX boundary).
#[derive(Clone, Copy)]
enum Boundary {
    Smooth(f32),
    Rough(RoughDielectric),
}

impl Boundary {
    fn of(settings: &ExitTableSettings) -> Self {
        if settings.roughness > 0.0 && settings.eta > 1.0 {
            Boundary::Rough(RoughDielectric::new(settings.eta, settings.roughness))
        } else {
            Boundary::Smooth(settings.eta)
        }
    }

    /// The inside cosine of a walk that entered from outside at cosine `mu_c`, and the energy
    /// it carries: refraction (smooth: weight 1), or a transmitted sample of the rough boundary
    /// (drawn until one crosses, weighted by its flux G₁: conditioned on transmission, as
    /// the renderer applies the entry's transmittance separately). `None` when no sample
    /// crosses.
    fn enter(&self, mu_c: f32, rng: &mut Sampler) -> Option<(f32, f32)> {
        match *self {
            Boundary::Smooth(eta) => {
                let mu = (1.0 - (1.0 - mu_c * mu_c) / (eta * eta)).max(0.0).sqrt();
                Some((mu.max(1e-6), 1.0))
            }
            Boundary::Rough(b) => {
                let wi = Vec3::new((1.0 - mu_c * mu_c).max(0.0).sqrt(), 0.0, mu_c.max(1e-4));
                for _ in 0..64 {
                    let s = b.sample(wi, rng.next_f32(), rng.next_f32(), rng.next_f32());
                    if let Some(s) = s.filter(|s| s.transmitted) {
                        return Some(((-s.wo.z).max(1e-6), s.weight * b.eta * b.eta));
                    }
                }
                None
            }
        }
    }

    /// A walk reaching the boundary from inside going up with cosine `mu` > 0: `Ok(μ_out, w)`
    /// when it leaves (outside cosine, energy factor), `Err(Some((μ', w)))` when it is
    /// reflected back in (new z component μ' < 0, energy factor), `Err(None)` when the rough
    /// boundary's sample fails (the microfacet model's loss: the walk ends).
    fn meet(&self, mu: f32, rng: &mut Sampler) -> Result<(f32, f32), Option<(f32, f32)>> {
        match *self {
            Boundary::Smooth(eta) => {
                let fr = if eta == 1.0 {
                    0.0
                } else {
                    fresnel_dielectric(mu, 1.0 / eta)
                };
                let out = if fr > 0.0 && rng.next_f32() < fr {
                    None
                } else {
                    refract_out(mu, eta)
                };
                match out {
                    Some(mu_out) => Ok((mu_out, 1.0)),
                    None => Err(Some((-mu, 1.0))),
                }
            }
            Boundary::Rough(b) => {
                // Seen back along the path (the BSDF's convention): below the macro surface.
                let wi = Vec3::new(-(1.0 - mu * mu).max(0.0).sqrt(), 0.0, -mu);
                let Some(s) = b.sample(wi, rng.next_f32(), rng.next_f32(), rng.next_f32()) else {
                    return Err(None);
                };
                if s.transmitted {
                    // Flux across: the weight times η'² = 1/η² seen from inside.
                    Ok((s.wo.z, s.weight / (b.eta * b.eta)))
                } else {
                    Err(Some((s.wo.z, s.weight)))
                }
            }
        }
    }
}

/// One walk in the half-space z < 0 entering at the origin with inside direction cosine
/// `-mu_in` (downwards). Only the depth and the direction's z component matter: the phase
/// function rotates the z component as cos θ' = μ cos θ + √(1−μ²) sin θ cos φ, and an isotropic
/// boundary's reflection depends on the z component alone. Returns the outside exit cosine and
/// the energy factor of the boundary's crossings, or `None` if absorbed.
fn walk(
    mu_in: f32,
    albedo: f32,
    phase: &HenyeyGreenstein,
    boundary: &Boundary,
    rng: &mut Sampler,
) -> Option<(f32, f32)> {
    let mut mu = -mu_in; // z component of the propagation direction
    let mut z = -(-(rng.next_f32())).ln_1p() * mu; // first flight (σ_t = 1), z < 0
    let mut weight = 1.0f32;
    let mut bounces = 0;
    loop {
        bounces += 1;
        if bounces > MAX_BOUNCES || rng.next_f32() >= albedo {
            return None;
        }
        let (cos_t, u) = (phase.sample_cos(rng.next_f32()), rng.next_f32());
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let sin_m = (1.0 - mu * mu).max(0.0).sqrt();
        mu = (mu * cos_t + sin_m * sin_t * (std::f32::consts::TAU * u).cos()).clamp(-1.0, 1.0);
        loop {
            let t = -(-(rng.next_f32())).ln_1p();
            let z_new = z + t * mu;
            if z_new < 0.0 {
                z = z_new;
                break;
            }
            // Reaches the boundary going up with inside cosine mu > 0.
            match boundary.meet(mu, rng) {
                Ok((mu_out, w)) => return Some((mu_out, weight * w)),
                Err(Some((mu_back, w))) => {
                    // Internal reflection; fly on from the surface.
                    weight *= w;
                    mu = mu_back;
                    z = 0.0;
                }
                Err(None) => return None,
            }
        }
    }
}

/// Bin of a cosine in [0, 1].
#[inline]
fn bin(mu: f32) -> usize {
    ((mu * MU_BINS as f32) as usize).min(MU_BINS - 1)
}

/// Probability of bin j under the cosine law p(μ) = 2μ.
#[inline]
fn lambert_mass(j: usize) -> f32 {
    let (lo, hi) = (j as f32 / MU_BINS as f32, (j + 1) as f32 / MU_BINS as f32);
    hi * hi - lo * lo
}

impl ExitTable {
    /// Simulate the table (module docs). Deterministic for equal settings, any thread count.
    pub fn generate(settings: ExitTableSettings) -> Self {
        let rows: Vec<(Vec<f32>, f32)> = (0..ONE_MINUS_ALBEDO.len() * MU_BINS)
            .into_par_iter()
            .map(|row| Self::simulate_row(&settings, row))
            .collect();
        let mut f = Vec::with_capacity(rows.len() * MU_BINS);
        let mut escaped = Vec::with_capacity(rows.len());
        for (r, e) in rows {
            f.extend(r);
            escaped.push(e);
        }
        ExitTable {
            settings,
            f,
            escaped,
        }
    }

    /// Row `row` = a·[`MU_BINS`] + i of the table (grid albedo a, entry bin i): f over the exit
    /// bins, and the escaped share of the entered energy. Its own random stream (seed, row).
    pub fn simulate_row(settings: &ExitTableSettings, row: usize) -> (Vec<f32>, f32) {
        let phase = HenyeyGreenstein { g: settings.g };
        let boundary = Boundary::of(settings);
        let (a, i) = (row / MU_BINS, row % MU_BINS);
        let albedo = 1.0 - ONE_MINUS_ALBEDO[a];
        let mut rng = Sampler::new(settings.seed, 0xE817_7AB1, row as u64, 0);
        // Energy per exit bin, escaped and entered (each walk's entry weight; exactly the walk
        // count for a smooth boundary).
        let mut hist = [0f64; MU_BINS];
        let (mut escaped, mut entered) = (0f64, 0f64);
        for _ in 0..settings.walks {
            // Entry cosine outside, uniform in the bin; refracted into the medium.
            let mu_c = (i as f32 + rng.next_f32()) / MU_BINS as f32;
            let Some((mu_in, w_in)) = boundary.enter(mu_c, &mut rng) else {
                continue;
            };
            entered += w_in as f64;
            if let Some((mu_out, w)) = walk(mu_in, albedo, &phase, &boundary, &mut rng) {
                let e = (w_in * w) as f64;
                hist[bin(mu_out)] += e;
                escaped += e;
            }
        }
        let n = escaped.max(f64::MIN_POSITIVE);
        let f = (0..MU_BINS)
            .map(|j| (hist[j] / n) as f32 / lambert_mass(j))
            .collect();
        (f, (escaped / entered.max(f64::MIN_POSITIVE)) as f32)
    }

    /// The table shipped for the paper's media (g = 0, η = 1), made by
    /// `translucent model exit-table` with the settings it records.
    pub fn index_matched_isotropic() -> std::sync::Arc<ExitTable> {
        static TABLE: std::sync::OnceLock<std::sync::Arc<ExitTable>> = std::sync::OnceLock::new();
        shipped(&TABLE, SHIPPED_JSON, SHIPPED_NAME)
    }

    /// The table for a medium with phase g behind a boundary of index η and GGX roughness
    /// `roughness`: the shipped one for (0, 1, 0), otherwise simulated once per process
    /// ([`DEFAULT_RUNTIME_WALKS`] walks per row, fixed seed) and kept.
    pub fn for_medium(g: f32, eta: f32, roughness: f32) -> std::sync::Arc<ExitTable> {
        static CACHE: MediumCache<ExitTable> = std::sync::Mutex::new(Vec::new());
        let table = Self::index_matched_isotropic();
        for_medium(&CACHE, table, (g, eta, roughness), DEFAULT_RUNTIME_WALKS)
    }

    /// The escaped share of the entered energy per entry-cosine bin at albedo `albedo`, and its
    /// α-derivative (the spline of [`ExitTable::slice`] through [`ExitTable::escaped`]).
    pub fn escape(&self, albedo: f32) -> EscapeSlice {
        let (e, de) = albedo_spline(&self.escaped, MU_BINS, albedo);
        EscapeSlice { e, de }
    }

    /// The table at albedo `albedo`: a cubic Hermite spline in x = ln(1 − α) through the grid
    /// albedos ([`albedo_spline`]). The spline is linear in the rows, so every slice keeps the
    /// normalisation ∫ f·2μ dμ = 1.
    pub fn slice(&self, albedo: f32) -> ExitSlice {
        let (f, df) = albedo_spline(&self.f, MU_BINS * MU_BINS, albedo);
        ExitSlice { f, df }
    }
}

impl TableFile for ExitTable {
    const KIND: &'static str = "exit";

    /// `f`: albedos × [`MU_BINS`]² values, finite and ≥ 0 (a density relative to the cosine
    /// law); `escaped`: albedos × [`MU_BINS`] fractions in [0, 1].
    fn check(&self, name: &str) -> Result<(), TableError> {
        let c = TableCheck {
            name,
            table: Self::KIND,
        };
        c.settings(&self.settings)?;
        let rows = ONE_MINUS_ALBEDO.len() * MU_BINS;
        c.len("f", self.f.len(), rows * MU_BINS)?;
        c.len("escaped", self.escaped.len(), rows)?;
        c.values("f", &self.f, 0.0, f32::MAX)?;
        c.values("escaped", &self.escaped, 0.0, 1.0)
    }
}

impl WalkTable for ExitTable {
    fn settings(&self) -> &ExitTableSettings {
        &self.settings
    }
    fn simulate(settings: ExitTableSettings) -> Self {
        Self::generate(settings)
    }
}

/// The table written by `translucent model exit-table` for g = 0, η = 1.
const SHIPPED_JSON: &str = include_str!("../data/exit-g0-eta1.json");
const SHIPPED_NAME: &str = "data/exit-g0-eta1.json";

/// f(α; ·, ·) and ∂f/∂α at one albedo (see [`ExitTable::slice`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ExitSlice {
    f: Vec<f32>,
    df: Vec<f32>,
}

/// The escaped share of the entered energy over the entry cosine at one albedo
/// ([`ExitTable::escape`]).
#[derive(Clone, Debug, PartialEq)]
pub struct EscapeSlice {
    e: Vec<f32>,
    de: Vec<f32>,
}

impl EscapeSlice {
    /// (E(μ_c), ∂E/∂α), linear between bin centres.
    #[inline]
    pub fn eval(&self, mu_cam: f32) -> (f32, f32) {
        let (i, t) = centre(mu_cam);
        let at = |v: &[f32]| v[i] * (1.0 - t) + v[i + 1] * t;
        (at(&self.e), at(&self.de))
    }
}

/// Bin-centre interpolation weights of a cosine: (lower bin, weight of the upper one).
#[inline]
fn centre(mu: f32) -> (usize, f32) {
    let x = (mu.clamp(0.0, 1.0) * MU_BINS as f32 - 0.5).clamp(0.0, (MU_BINS - 1) as f32 - 1e-4);
    let i = x as usize;
    (i, x - i as f32)
}

impl ExitSlice {
    /// (f(μ_c, μ_l), ∂f/∂α), bilinear between bin centres.
    #[inline]
    pub fn eval(&self, mu_cam: f32, mu_light: f32) -> (f32, f32) {
        let ((i, ti), (j, tj)) = (centre(mu_cam), centre(mu_light));
        let at = |v: &[f32]| {
            let r = |i: usize| v[i * MU_BINS + j] * (1.0 - tj) + v[i * MU_BINS + j + 1] * tj;
            r(i) * (1.0 - ti) + r(i + 1) * ti
        };
        (at(&self.f), at(&self.df))
    }
}
