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
use base::phase::HenyeyGreenstein;
use base::rng::Sampler;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

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
    /// Walks per (albedo, entry-cosine bin).
    pub walks: u32,
    /// Seed of the walks.
    pub seed: u64,
}

/// f(α; μ_c, μ_l) on the grid `ONE_MINUS_ALBEDO` × `MU_BINS` × `MU_BINS` (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExitTable {
    pub settings: ExitTableSettings,
    /// `f[(a·MU_BINS + i)·MU_BINS + j]`: albedo a, entry bin i (camera), exit bin j (light).
    pub f: Vec<f32>,
    /// Escaped fraction per (albedo, entry bin): a by-product, checked against the network.
    pub escaped: Vec<f32>,
}

/// The outside cosine of a direction leaving the medium with inside cosine `mu` (Snell), or
/// `None` under total internal reflection.
#[inline]
fn refract_out(mu: f32, eta: f32) -> Option<f32> {
    let s2 = eta * eta * (1.0 - mu * mu);
    (s2 < 1.0).then(|| (1.0 - s2).sqrt())
}

/// One walk in the half-space z < 0 entering at the origin with inside direction cosine
/// `-mu_in` (downwards). Only the depth and the direction's z component matter: the phase
/// function rotates the z component as cos θ' = μ cos θ + √(1−μ²) sin θ cos φ. Returns the
/// outside exit cosine, or `None` if absorbed.
fn walk(
    mu_in: f32,
    albedo: f32,
    phase: &HenyeyGreenstein,
    eta: f32,
    rng: &mut Sampler,
) -> Option<f32> {
    let mut mu = -mu_in; // z component of the propagation direction
    let mut z = -(-(rng.next_f32())).ln_1p() * mu; // first flight (σ_t = 1), z < 0
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
                Some(mu_out) => return Some(mu_out),
                None => {
                    // Specular internal reflection; fly on from the surface.
                    mu = -mu;
                    z = 0.0;
                }
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
        let phase = HenyeyGreenstein { g: settings.g };
        let eta = settings.eta;
        let rows: Vec<(Vec<f32>, f32)> = (0..ONE_MINUS_ALBEDO.len() * MU_BINS)
            .into_par_iter()
            .map(|row| {
                let (a, i) = (row / MU_BINS, row % MU_BINS);
                let albedo = 1.0 - ONE_MINUS_ALBEDO[a];
                let mut rng = Sampler::new(settings.seed, 0xE817_7AB1, row as u64, 0);
                let mut hist = [0u64; MU_BINS];
                let mut escaped = 0u64;
                for _ in 0..settings.walks {
                    // Entry cosine outside, uniform in the bin; refracted into the medium.
                    let mu_c = (i as f32 + rng.next_f32()) / MU_BINS as f32;
                    let mu_in = (1.0 - (1.0 - mu_c * mu_c) / (eta * eta)).max(0.0).sqrt();
                    if let Some(mu_out) = walk(mu_in.max(1e-6), albedo, &phase, eta, &mut rng) {
                        hist[bin(mu_out)] += 1;
                        escaped += 1;
                    }
                }
                let n = escaped.max(1) as f32;
                let f = (0..MU_BINS)
                    .map(|j| hist[j] as f32 / n / lambert_mass(j))
                    .collect();
                (f, escaped as f32 / settings.walks.max(1) as f32)
            })
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

    /// The table shipped for the paper's media (g = 0, η = 1), made by
    /// `translucent model exit-table` with the settings it records.
    pub fn index_matched_isotropic() -> std::sync::Arc<ExitTable> {
        static TABLE: std::sync::OnceLock<std::sync::Arc<ExitTable>> = std::sync::OnceLock::new();
        shipped(&TABLE, SHIPPED_JSON, SHIPPED_NAME)
    }

    /// The table for a medium with phase g and index η: the shipped one for (0, 1), otherwise
    /// simulated once per process ([`DEFAULT_RUNTIME_WALKS`] walks per row, fixed seed) and kept.
    pub fn for_medium(g: f32, eta: f32) -> std::sync::Arc<ExitTable> {
        static CACHE: MediumCache<ExitTable> = std::sync::Mutex::new(Vec::new());
        let table = Self::index_matched_isotropic();
        for_medium(&CACHE, table, (g, eta), DEFAULT_RUNTIME_WALKS)
    }

    /// The table at albedo `albedo`: a cubic Hermite spline in x = ln(1 − α) through the grid
    /// albedos ([`albedo_spline`]). The spline is linear in the rows, so every slice keeps the
    /// normalisation ∫ f·2μ dμ = 1.
    pub fn slice(&self, albedo: f32) -> ExitSlice {
        let (f, df) = albedo_spline(&self.f, MU_BINS * MU_BINS, albedo);
        ExitSlice { f, df }
    }
}

/// The tables simulated at run time for media other than the shipped one, per process.
pub(crate) type MediumCache<T> = std::sync::Mutex<Vec<std::sync::Arc<T>>>;

/// Errors of reading a table ([`TableFile::from_json`]); each names the file and the field.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The text is not the JSON of this kind of table.
    #[error(
        "{name}: not a valid {table} table ({reason}); fix: regenerate it with `translucent model {table}-table`"
    )]
    Parse {
        /// The file.
        name: String,
        /// The kind of table (`exit`, `incidence`, `curvature`).
        table: &'static str,
        /// What the JSON parser said.
        reason: String,
    },
    /// A field has the wrong length or an impossible value.
    #[error(
        "{name}: {table} table field `{field}` {reason}; fix: regenerate it with `translucent model {table}-table`"
    )]
    Invalid {
        /// The file.
        name: String,
        /// The kind of table.
        table: &'static str,
        /// The field (`settings.g`, `a`, `a[17]`, …).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

/// A table stored as JSON (the shipped `data/*.json` files, written by `translucent model
/// …-table`): parsed, then checked against the grid of this build, so that a damaged or
/// mismatched file is an error naming the field and never an out-of-bounds lookup later.
pub trait TableFile: serde::de::DeserializeOwned {
    /// The kind of table, as in the command that writes it (`exit`, `incidence`, `curvature`).
    const KIND: &'static str;

    /// Checks lengths and values; `name` is the file, for the error.
    fn check(&self, name: &str) -> Result<(), TableError>;

    /// Parses and checks the JSON text of a table; `name` is the file, for errors.
    fn from_json(text: &str, name: &str) -> Result<Self, TableError> {
        let table: Self = serde_json::from_str(text).map_err(|e| TableError::Parse {
            name: name.to_string(),
            table: Self::KIND,
            reason: e.to_string(),
        })?;
        table.check(name)?;
        Ok(table)
    }
}

/// Checks shared by the table files: lengths against the grid, values finite and in range.
pub(crate) struct TableCheck<'a> {
    pub(crate) name: &'a str,
    pub(crate) table: &'static str,
}

impl TableCheck<'_> {
    pub(crate) fn err(&self, field: impl Into<String>, reason: impl Into<String>) -> TableError {
        TableError::Invalid {
            name: self.name.to_string(),
            table: self.table,
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// `len == expected`.
    pub(crate) fn len(&self, field: &str, len: usize, expected: usize) -> Result<(), TableError> {
        if len != expected {
            return Err(self.err(
                field,
                format!("holds {len} values, this build's grid needs {expected}"),
            ));
        }
        Ok(())
    }

    /// Every value finite and within `[lo, hi]`.
    pub(crate) fn values(
        &self,
        field: &str,
        v: &[f32],
        lo: f32,
        hi: f32,
    ) -> Result<(), TableError> {
        if let Some(i) = v
            .iter()
            .position(|x| !(x.is_finite() && (lo..=hi).contains(x)))
        {
            return Err(self.err(
                format!("{field}[{i}]"),
                format!("= {} is outside [{lo}, {hi}]", v[i]),
            ));
        }
        Ok(())
    }

    /// The medium of a walk table: |g| < 1, η finite and positive.
    pub(crate) fn settings(&self, s: &ExitTableSettings) -> Result<(), TableError> {
        if !(s.g.is_finite() && s.g.abs() < 1.0) {
            return Err(self.err("settings.g", format!("= {} is outside (-1, 1)", s.g)));
        }
        if !(s.eta.is_finite() && s.eta > 0.0) {
            return Err(self.err("settings.eta", format!("= {} is not positive", s.eta)));
        }
        Ok(())
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

/// A shipped table (JSON built into the binary, `name` its file under `data/`), parsed and
/// checked once.
pub(crate) fn shipped<T: TableFile>(
    cell: &std::sync::OnceLock<std::sync::Arc<T>>,
    json: &str,
    name: &str,
) -> std::sync::Arc<T> {
    cell.get_or_init(|| {
        std::sync::Arc::new(
            T::from_json(json, name)
                .unwrap_or_else(|e| panic!("a shipped table reads (checked by its tests): {e}")),
        )
    })
    .clone()
}

/// A table simulated by half-space walks with [`ExitTableSettings`] (the exit and incidence
/// tables), so that [`for_medium`] can make and look up the table of any medium.
pub(crate) trait WalkTable: Sized {
    /// The settings the table was made with.
    fn settings(&self) -> &ExitTableSettings;
    /// Simulate the table.
    fn simulate(settings: ExitTableSettings) -> Self;
}

impl WalkTable for ExitTable {
    fn settings(&self) -> &ExitTableSettings {
        &self.settings
    }
    fn simulate(settings: ExitTableSettings) -> Self {
        Self::generate(settings)
    }
}

/// The table of a medium `(g, η)`: `shipped` when its own (g, η) match, else one simulated with
/// `walks` walks per row (seed 0) once per process and kept in `cache`.
pub(crate) fn for_medium<T: WalkTable>(
    cache: &MediumCache<T>,
    shipped: std::sync::Arc<T>,
    (g, eta): (f32, f32),
    walks: u32,
) -> std::sync::Arc<T> {
    let key = |t: &T| (t.settings().g, t.settings().eta);
    if key(&shipped) == (g, eta) {
        return shipped;
    }
    let mut cache = cache.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(t) = cache.iter().find(|t| key(t) == (g, eta)) {
        return t.clone();
    }
    let t = std::sync::Arc::new(T::simulate(ExitTableSettings {
        g,
        eta,
        walks,
        seed: 0,
    }));
    cache.push(t.clone());
    t
}

/// A table of rows over the albedo grid [`ONE_MINUS_ALBEDO`] (`rows[a·n..(a + 1)·n]` for grid
/// albedo a) at albedo `albedo`, with its α-derivative: a cubic Hermite spline in
/// x = ln(1 − α) through the grid albedos (tangents by central differences, one-sided at the
/// ends; C¹, so the derivative is continuous), constant outside the grid (derivative 0). The
/// spline is a linear combination of rows, so any linear normalisation of the rows holds for
/// every albedo.
pub(crate) fn albedo_spline(rows: &[f32], n: usize, albedo: f32) -> (Vec<f32>, Vec<f32>) {
    let xs: Vec<f32> = ONE_MINUS_ALBEDO.iter().map(|x| x.ln()).collect();
    let x = (1.0 - albedo).clamp(1e-6, 1.0).ln();
    let last = xs.len() - 1;
    let row = |a: usize| &rows[a * n..(a + 1) * n];
    // Outside the grid (xs decreases with a): the end row, no α-dependence.
    let end = if x >= xs[0] {
        Some(0)
    } else if x <= xs[last] {
        Some(last)
    } else {
        None
    };
    if let Some(a) = end {
        return (row(a).to_vec(), vec![0.0; n]);
    }
    let a = (0..last)
        .find(|&a| x <= xs[a] && x >= xs[a + 1])
        .unwrap_or(0);
    let h = xs[a + 1] - xs[a]; // < 0
    let t = (x - xs[a]) / h;
    // Tangent dF/dx at node k for cell value index `i`.
    let tangent = |k: usize, i: usize| {
        let (lo, hi) = (k.saturating_sub(1), (k + 1).min(last));
        (row(hi)[i] - row(lo)[i]) / (xs[hi] - xs[lo])
    };
    let (t2, t3) = (t * t, t * t * t);
    let (h00, h10, h01, h11) = (
        2.0 * t3 - 3.0 * t2 + 1.0,
        t3 - 2.0 * t2 + t,
        -2.0 * t3 + 3.0 * t2,
        t3 - t2,
    );
    let (d00, d10, d01, d11) = (
        6.0 * t2 - 6.0 * t,
        3.0 * t2 - 4.0 * t + 1.0,
        -6.0 * t2 + 6.0 * t,
        3.0 * t2 - 2.0 * t,
    );
    // dx/dα = −1/(1 − α); dt/dx = 1/h.
    let dt_da = -1.0 / ((1.0 - albedo).max(1e-6) * h);
    let (r0, r1) = (row(a), row(a + 1));
    let mut f = Vec::with_capacity(n);
    let mut df = Vec::with_capacity(n);
    for i in 0..n {
        let (m0, m1) = (tangent(a, i) * h, tangent(a + 1, i) * h);
        f.push(h00 * r0[i] + h10 * m0 + h01 * r1[i] + h11 * m1);
        df.push((d00 * r0[i] + d10 * m0 + d01 * r1[i] + d11 * m1) * dt_da);
    }
    (f, df)
}

/// Walks per row of a table simulated at run time (the shipped one has more).
pub const DEFAULT_RUNTIME_WALKS: u32 = 40_000;

/// The table written by `translucent model exit-table` for g = 0, η = 1.
const SHIPPED_JSON: &str = include_str!("../data/exit-g0-eta1.json");
const SHIPPED_NAME: &str = "data/exit-g0-eta1.json";

/// f(α; ·, ·) and ∂f/∂α at one albedo (see [`ExitTable::slice`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ExitSlice {
    f: Vec<f32>,
    df: Vec<f32>,
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
