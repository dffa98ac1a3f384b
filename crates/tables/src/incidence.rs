//! The light-side incidence factor: where, around the point x_i at which light enters, it leaves
//! the medium again, depending on the DIRECTION it came from.
//!
//! The learned model proposes x_i around the camera point x_o from the camera side alone: the
//! decoder is conditioned on the camera ray (by reciprocity, the "incident" ray of the training
//! walks), and the light side enters the estimator only through its cosine ([`crate::exit`]).
//! That treats the light's entry as isotropic in azimuth. It is not: light entering obliquely
//! keeps its tangential direction for about one mean free path before it scatters, so it leaves
//! the medium mostly AHEAD of its entry point. In a half-space of albedo 0.86 (η = 1, g = 0),
//! 82 % of the walks entering at 60° leave ahead of the entry point (mean shift 0.64 mean free
//! paths against a mean exit distance of 1.2), 90 % at 78°. On a curved object this is what
//! carries light over the terminator into the dark side; without it the learned images fall off
//! towards the terminator much faster than the volumetric path tracer's
//! (docs/notes/light-side.md, "The light's direction of incidence"). The directional dipole of
//! Frisvad, Hachisuka and Kjeldsen (ACM TOG 34(1), 2014) addresses the same shortcoming of the
//! classical dipole.
//!
//! # The factor
//!
//! For light entering at x_i along −w_l (w_l the unit direction from x_i to the light, outside
//! cosine μ_l = n_i·w_l) and leaving at x_o, let Δ = x_o − x_i, ρ = |Δ|·σ_t (mean free paths),
//! t = the unit tangential part of −w_l at x_i (the light's forward direction along the surface)
//! and ψ ∈ [0, π] the angle between t and the tangential part of Δ. The half-space walks give the
//! joint density of the exit point; the factor is its azimuthal density relative to uniform:
//!
//!   A(α; μ_l, ρ, ψ) = p(ψ | μ_l, ρ) / (1/π),     ∫₀^π A dψ/π = 1 for every (μ_l, ρ),
//!
//! The decoder's proposals are already anisotropic about the camera's direction, so the two
//! factors are combined as a product of experts, p(Δ | w_cam, w_l) ∝ p(Δ | w_cam)·A(Δ | w_l),
//! normalised so that the escaped energy stays that of the model:
//!
//!   N(α; μ_c, μ_l, φ) = E[A(α; μ_l, ρ, ψ)]  over half-space walks entering at the camera's
//!                       cosine μ_c, φ the angle between the camera's and the light's forward
//!                       directions along the surface,
//!
//! and the estimator's light term f(α; μ_cam, μ_l)·μ_l/π ([`crate::exit`]) becomes
//! (A/N)·f·μ_l/π. In a half-space with isotropic scattering the reflected energy does not
//! depend on φ (Chandrasekhar's H-function solution), and with N it does not either: the factor
//! moves light around the entry point, towards where the light was heading, without changing
//! how much escapes (S_abs of the absorption network) or its dependence on the two cosines (the
//! exit law). At normal incidence A = 1.
//!
//! [`IncidenceTable`] tabulates A on the albedo grid of [`crate::exit`] (the same C¹ spline in
//! ln(1 − α) between rows, so ∂A/∂α is available for the α-gradient) × [`MU_BINS`] light
//! cosines × [`RHO_BINS`] distances (uniform in ln(1 + ρ/ρ₀)) × [`PSI_BINS`] angles;
//! [`IncidenceSlice`] is the table at one albedo with trilinear interpolation between bin
//! centres; N on the albedo grid × [`MU_BINS`] camera cosines × [`MU_BINS`] light cosines ×
//! [`PHI_BINS`] angles, from a second set of walks and the table of A at the grid albedos. The
//! walks follow the physics of [`crate::exit`] (analog absorption, HG phase, Fresnel reflection
//! at the boundary), in three dimensions.

use base::fresnel::fresnel_dielectric;
use base::phase::HenyeyGreenstein;
use base::rng::Sampler;
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::exit::{MU_BINS, ONE_MINUS_ALBEDO};
use crate::table::{
    MediumCache, TableCheck, TableError, TableFile, WalkTable, albedo_spline, for_medium, shipped,
};

/// Distance bins (uniform in ln(1 + ρ/ρ₀), ρ in mean free paths; the last is open).
pub const RHO_BINS: usize = 12;
/// ρ₀ of the distance bins (mean free paths).
pub const RHO_0: f32 = 0.25;
/// Largest tabulated distance (mean free paths); beyond it the last bin's values hold.
pub const RHO_MAX: f32 = 16.0;
/// Angle bins over [0, π].
pub const PSI_BINS: usize = 12;
/// Values per albedo: light cosine × distance × angle.
const PER_ALBEDO: usize = MU_BINS * RHO_BINS * PSI_BINS;
/// Bins of the angle φ between the camera's and the light's forward directions, over [0, π].
pub const PHI_BINS: usize = 8;
/// Values of N per albedo: camera cosine × light cosine × φ.
const NORM_PER_ALBEDO: usize = MU_BINS * MU_BINS * PHI_BINS;
/// The walks for N are this fraction of [`IncidenceSettings::walks`].
const NORM_WALKS_DIVISOR: u32 = 8;
/// Escaped walks a (cosine, distance) cell needs before its angular histogram is used; below,
/// A = 1 (no information is better than noise).
pub const MIN_CELL: u64 = 200;
/// Scattering events after which a walk counts as absorbed (as `learn::walk::MAX_BOUNCES`).
const MAX_BOUNCES: u32 = 10_000;

/// How an [`IncidenceTable`] is made: the settings of the exit law's walks (g, η, walks per
/// albedo and cosine bin, seed).
pub type IncidenceSettings = crate::exit::ExitTableSettings;

/// A(α; μ_l, ρ, ψ) on the grid (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IncidenceTable {
    pub settings: IncidenceSettings,
    /// `a[((alb·MU_BINS + i)·RHO_BINS + r)·PSI_BINS + k]`: light cosine bin i, distance r,
    /// angle ψ bin k.
    pub a: Vec<f32>,
    /// Escaped walks per (albedo, light cosine, distance) cell of `a` (its histogram is
    /// `a·cells/PSI_BINS`; cells with fewer than [`MIN_CELL`] walks hold A = 1).
    pub cells: Vec<u32>,
    /// `norm[((alb·MU_BINS + i)·MU_BINS + j)·PHI_BINS + k]`: N for camera cosine bin i, light
    /// cosine bin j, angle φ bin k.
    pub norm: Vec<f32>,
}

/// N and the statistics of its walks ([`IncidenceTable::normalisation`]).
#[derive(Clone, Debug, PartialEq)]
pub struct NormStats {
    /// N per (albedo, camera cosine, light cosine, φ), as [`IncidenceTable::norm`].
    pub mean: Vec<f32>,
    /// Escaped walks per (albedo, camera cosine) row: the sample size of each mean.
    pub escaped: Vec<u64>,
}

/// ln(1 + ρ/ρ₀) scaled to bin units.
#[inline]
fn rho_coord(rho: f32) -> f32 {
    let top = (1.0 + RHO_MAX / RHO_0).ln();
    (1.0 + rho.max(0.0) / RHO_0).ln() / top * RHO_BINS as f32
}

/// An orthonormal basis (b1, b2) completing the unit vector n (Duff et al. 2017).
#[inline]
fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// One walk in the half-space z < 0 (σ_t = 1) entering at the origin with inside direction
/// (sin θ, 0, −cos θ), `mu_in` = cos θ: the exit point (x, y) on z = 0, or `None` if absorbed.
/// Analog absorption, HG phase, Fresnel reflection at the boundary (the physics of
/// `learn::walk`, which the tests compare it with).
pub fn walk(
    mu_in: f32,
    albedo: f32,
    phase: &HenyeyGreenstein,
    eta: f32,
    rng: &mut Sampler,
) -> Option<(f32, f32)> {
    let mut d = Vec3::new((1.0 - mu_in * mu_in).max(0.0).sqrt(), 0.0, -mu_in);
    let mut p = d * -(-(rng.next_f32())).ln_1p();
    let mut bounces = 0;
    loop {
        bounces += 1;
        if bounces > MAX_BOUNCES || rng.next_f32() >= albedo {
            return None;
        }
        let (cos_t, u) = (phase.sample_cos(rng.next_f32()), rng.next_f32());
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let (b1, b2) = basis(d);
        let (s, c) = (std::f32::consts::TAU * u).sin_cos();
        d = (d * cos_t + (b1 * c + b2 * s) * sin_t).normalize();
        loop {
            let t = -(-(rng.next_f32())).ln_1p();
            let q = p + d * t;
            if q.z < 0.0 {
                p = q;
                break;
            }
            // Reaches the boundary going up.
            let at = p + d * (-p.z / d.z.max(1e-12));
            let fr = if eta == 1.0 {
                0.0
            } else {
                fresnel_dielectric(d.z, 1.0 / eta)
            };
            let tir = eta * eta * (1.0 - d.z * d.z) >= 1.0;
            if tir || (fr > 0.0 && rng.next_f32() < fr) {
                // Specular internal reflection; fly on from the surface.
                d.z = -d.z;
                p = Vec3::new(at.x, at.y, 0.0);
            } else {
                return Some((at.x, at.y));
            }
        }
    }
}

impl IncidenceTable {
    /// Simulate the table (module docs). Deterministic for equal settings, any thread count.
    pub fn generate(settings: IncidenceSettings) -> Self {
        let phase = HenyeyGreenstein { g: settings.g };
        let eta = settings.eta;
        let rows: Vec<(Vec<f32>, Vec<u32>)> = (0..ONE_MINUS_ALBEDO.len() * MU_BINS)
            .into_par_iter()
            .map(|row| {
                let (alb, i) = (row / MU_BINS, row % MU_BINS);
                let albedo = 1.0 - ONE_MINUS_ALBEDO[alb];
                let mut rng = Sampler::new(settings.seed, 0x1AC1_DE2C, row as u64, 0);
                let mut hist = vec![0u64; RHO_BINS * PSI_BINS];
                for _ in 0..settings.walks {
                    // Light cosine outside, uniform in the bin; refracted into the medium.
                    let mu_l = (i as f32 + rng.next_f32()) / MU_BINS as f32;
                    let mu_in = (1.0 - (1.0 - mu_l * mu_l) / (eta * eta)).max(0.0).sqrt();
                    if let Some((x, y)) = walk(mu_in.max(1e-6), albedo, &phase, eta, &mut rng) {
                        let r = (rho_coord(x.hypot(y)) as usize).min(RHO_BINS - 1);
                        let psi = y.abs().atan2(x);
                        let k = ((psi / std::f32::consts::PI * PSI_BINS as f32) as usize)
                            .min(PSI_BINS - 1);
                        hist[r * PSI_BINS + k] += 1;
                    }
                }
                let mut a = vec![1.0f32; RHO_BINS * PSI_BINS];
                let mut cells = vec![0u32; RHO_BINS];
                for r in 0..RHO_BINS {
                    let cell = &hist[r * PSI_BINS..(r + 1) * PSI_BINS];
                    let n: u64 = cell.iter().sum();
                    cells[r] = n.min(u32::MAX as u64) as u32;
                    if n >= MIN_CELL {
                        for k in 0..PSI_BINS {
                            a[r * PSI_BINS + k] = cell[k] as f32 / n as f32 * PSI_BINS as f32;
                        }
                    }
                }
                (a, cells)
            })
            .collect();
        let (a, cells): (Vec<Vec<f32>>, Vec<Vec<u32>>) = rows.into_iter().unzip();
        let a = a.concat();
        let norm = Self::normalisation(&settings, &a).mean;
        IncidenceTable {
            settings,
            a,
            cells: cells.concat(),
            norm,
        }
    }

    /// N(α; μ_c, μ_l, φ) at the grid albedos: the mean of the table `a` of A over walks
    /// entering at the camera cosine (module docs; `settings.walks`/8 walks per row), with A
    /// taken at the bin centres of the light cosine.
    pub fn normalisation(settings: &IncidenceSettings, a: &[f32]) -> NormStats {
        let phase = HenyeyGreenstein { g: settings.g };
        let eta = settings.eta;
        let walks = (settings.walks / NORM_WALKS_DIVISOR).max(1);
        // Light's forward direction relative to the camera's for each φ bin centre.
        let dirs: [(f32, f32); PHI_BINS] = std::array::from_fn(|k| {
            let phi = (k as f32 + 0.5) / PHI_BINS as f32 * std::f32::consts::PI;
            (phi.cos(), phi.sin())
        });
        let rows: Vec<(Vec<f32>, u64)> = (0..ONE_MINUS_ALBEDO.len() * MU_BINS)
            .into_par_iter()
            .map(|row| {
                let (alb, i) = (row / MU_BINS, row % MU_BINS);
                let albedo = 1.0 - ONE_MINUS_ALBEDO[alb];
                let table = &a[alb * PER_ALBEDO..(alb + 1) * PER_ALBEDO];
                let mut rng = Sampler::new(settings.seed, 0x90A3_11CE, row as u64, 0);
                let mut sum = vec![0.0f64; MU_BINS * PHI_BINS];
                let mut escaped = 0u64;
                for _ in 0..walks {
                    let mu_c = (i as f32 + rng.next_f32()) / MU_BINS as f32;
                    let mu_in = (1.0 - (1.0 - mu_c * mu_c) / (eta * eta)).max(0.0).sqrt();
                    let Some((x, y)) = walk(mu_in.max(1e-6), albedo, &phase, eta, &mut rng) else {
                        continue;
                    };
                    escaped += 1;
                    // The light enters at the exit point e = (x, y) and leaves at the origin:
                    // Δ = −e. (The walks are symmetric in y, so φ ∈ [0, π] covers both signs.)
                    let rho = x.hypot(y);
                    let (r, tr) = centre(rho_coord(rho), RHO_BINS);
                    let inv = if rho > 0.0 { 1.0 / rho } else { 0.0 };
                    for (k, &(c, s)) in dirs.iter().enumerate() {
                        let cos_psi = -(x * c + y * s) * inv;
                        let (q, tq) = psi_coord(cos_psi);
                        for j in 0..MU_BINS {
                            let v = &table[j * RHO_BINS * PSI_BINS..(j + 1) * RHO_BINS * PSI_BINS];
                            sum[j * PHI_BINS + k] += bilinear(v, (r, tr), (q, tq)) as f64;
                        }
                    }
                }
                if escaped == 0 {
                    return (vec![1.0; sum.len()], 0);
                }
                let n = escaped as f64;
                (sum.iter().map(|&v| (v / n) as f32).collect(), escaped)
            })
            .collect();
        let (mean, escaped): (Vec<Vec<f32>>, Vec<u64>) = rows.into_iter().unzip();
        NormStats {
            mean: mean.concat(),
            escaped,
        }
    }

    /// The table with every value rounded to `digits` significant digits (for a compact file;
    /// the rounding, ≤ 5·10⁻⁵ relative at 4 digits, is far below the walks' noise).
    pub fn rounded(mut self, digits: i32) -> Self {
        let round = |v: &mut f32| {
            if *v != 0.0 && v.is_finite() {
                let e = 10f64.powi(digits - 1 - (v.abs() as f64).log10().floor() as i32);
                *v = ((*v as f64 * e).round() / e) as f32;
            }
        };
        self.a.iter_mut().for_each(round);
        self.norm.iter_mut().for_each(round);
        self
    }

    /// The table shipped for the paper's media (g = 0, η = 1), made by
    /// `translucent model incidence-table` with the settings it records.
    pub fn index_matched_isotropic() -> std::sync::Arc<IncidenceTable> {
        static TABLE: std::sync::OnceLock<std::sync::Arc<IncidenceTable>> =
            std::sync::OnceLock::new();
        shipped(&TABLE, SHIPPED_JSON, SHIPPED_NAME)
    }

    /// The table for a medium with phase g and index η: the shipped one for (0, 1), otherwise
    /// simulated once per process ([`DEFAULT_RUNTIME_WALKS`] walks per row, fixed seed) and kept.
    pub fn for_medium(g: f32, eta: f32) -> std::sync::Arc<IncidenceTable> {
        static CACHE: MediumCache<IncidenceTable> = std::sync::Mutex::new(Vec::new());
        let table = Self::index_matched_isotropic();
        for_medium(&CACHE, table, (g, eta, 0.0), DEFAULT_RUNTIME_WALKS)
    }

    /// The table at albedo `albedo` ([`crate::exit`]'s spline in ln(1 − α)); every slice keeps
    /// the normalisation ∫ A dψ/π = 1.
    pub fn slice(&self, albedo: f32) -> IncidenceSlice {
        let (a, da) = albedo_spline(&self.a, PER_ALBEDO, albedo);
        let (norm, dnorm) = albedo_spline(&self.norm, NORM_PER_ALBEDO, albedo);
        IncidenceSlice { a, da, norm, dnorm }
    }
}

impl TableFile for IncidenceTable {
    const KIND: &'static str = "incidence";

    /// `a`: albedos × [`MU_BINS`] × [`RHO_BINS`] × [`PSI_BINS`] values, finite and ≥ 0;
    /// `cells`: one count per (albedo, cosine, distance); `norm`: albedos × [`MU_BINS`]² ×
    /// [`PHI_BINS`] values, finite and ≥ 0.
    fn check(&self, name: &str) -> Result<(), TableError> {
        let c = TableCheck {
            name,
            table: Self::KIND,
        };
        c.settings(&self.settings)?;
        let albedos = ONE_MINUS_ALBEDO.len();
        c.len("a", self.a.len(), albedos * PER_ALBEDO)?;
        c.len("cells", self.cells.len(), albedos * MU_BINS * RHO_BINS)?;
        c.len("norm", self.norm.len(), albedos * NORM_PER_ALBEDO)?;
        c.values("a", &self.a, 0.0, f32::MAX)?;
        c.values("norm", &self.norm, 0.0, f32::MAX)
    }
}

impl WalkTable for IncidenceTable {
    fn settings(&self) -> &IncidenceSettings {
        &self.settings
    }
    fn simulate(settings: IncidenceSettings) -> Self {
        Self::generate(settings)
    }
}

/// Walks per row of a table simulated at run time (the shipped one has more).
pub const DEFAULT_RUNTIME_WALKS: u32 = 100_000;

/// The table written by `translucent model incidence-table` for g = 0, η = 1.
const SHIPPED_JSON: &str = include_str!("../data/incidence-g0-eta1.json");
const SHIPPED_NAME: &str = "data/incidence-g0-eta1.json";

/// A(α; ·, ·, ·) and ∂A/∂α at one albedo (see [`IncidenceTable::slice`]).
#[derive(Clone, Debug, PartialEq)]
pub struct IncidenceSlice {
    a: Vec<f32>,
    da: Vec<f32>,
    norm: Vec<f32>,
    dnorm: Vec<f32>,
}

/// Interpolation between bin centres of a coordinate in bin units: (lower bin, upper weight).
#[inline]
fn centre(x: f32, bins: usize) -> (usize, f32) {
    let x = (x - 0.5).clamp(0.0, (bins - 1) as f32 - 1e-4);
    let i = x as usize;
    (i, x - i as f32)
}

/// arccos with an absolute error below 7·10⁻⁵ rad (Abramowitz & Stegun 4.4.45:
/// acos x ≈ √(1 − x)·(a₀ + a₁x + a₂x² + a₃x³) for x ∈ [0, 1], π − acos(−x) below): a table
/// coordinate, where `f32::acos` cost a tenth of the light evaluation.
#[inline]
pub fn fast_acos(x: f32) -> f32 {
    let a = x.abs().min(1.0);
    let r =
        (1.0 - a).sqrt() * (1.570_728_8 + a * (-0.212_114_4 + a * (0.074_261_0 - a * 0.018_729_3)));
    if x < 0.0 { std::f32::consts::PI - r } else { r }
}

/// ψ (from its cosine) in bin units, as (lower bin, upper weight) between bin centres.
#[inline]
fn psi_coord(cos_psi: f32) -> (usize, f32) {
    centre(
        fast_acos(cos_psi) / std::f32::consts::PI * PSI_BINS as f32,
        PSI_BINS,
    )
}

/// Weight of the normal-incidence limit (A = N = 1) for a cosine above the last bin centre:
/// 0 at the centre, 1 at μ = 1.
#[inline]
fn to_normal(mu: f32) -> f32 {
    let last = (MU_BINS as f32 - 0.5) / MU_BINS as f32;
    ((mu - last) / (1.0 - last)).clamp(0.0, 1.0)
}

/// Bilinear interpolation in a distance × angle block of A.
#[inline]
fn bilinear(v: &[f32], (r, tr): (usize, f32), (k, tk): (usize, f32)) -> f32 {
    let row = |r: usize| v[r * PSI_BINS + k] * (1.0 - tk) + v[r * PSI_BINS + k + 1] * tk;
    row(r) * (1.0 - tr) + row(r + 1) * tr
}

impl IncidenceSlice {
    /// (A, ∂A/∂α) for light cosine `mu_l`, distance `rho` (mean free paths) and angle cosine
    /// `cos_psi`, trilinear between bin centres; above the last cosine bin centre it goes
    /// linearly to exactly 1 at normal incidence (where the light has no direction along the
    /// surface).
    #[inline]
    pub fn eval(&self, mu_l: f32, rho: f32, cos_psi: f32) -> (f32, f32) {
        let (i, ti) = centre(mu_l.clamp(0.0, 1.0) * MU_BINS as f32, MU_BINS);
        let rr = centre(rho_coord(rho), RHO_BINS);
        let kk = psi_coord(cos_psi);
        let block = RHO_BINS * PSI_BINS;
        let at = |v: &[f32]| {
            bilinear(&v[i * block..(i + 1) * block], rr, kk) * (1.0 - ti)
                + bilinear(&v[(i + 1) * block..(i + 2) * block], rr, kk) * ti
        };
        let w = to_normal(mu_l);
        (at(&self.a) * (1.0 - w) + w, at(&self.da) * (1.0 - w))
    }

    /// (N, ∂N/∂α) for camera cosine `mu_c`, light cosine `mu_l` and angle cosine `cos_phi`
    /// between the forward directions, trilinear between bin centres; like A, it goes to 1 at
    /// normal incidence of either (isotropic camera walks average A to 1; A = 1 for normal light).
    #[inline]
    pub fn normalisation(&self, mu_c: f32, mu_l: f32, cos_phi: f32) -> (f32, f32) {
        let (i, ti) = centre(mu_c.clamp(0.0, 1.0) * MU_BINS as f32, MU_BINS);
        let (j, tj) = centre(mu_l.clamp(0.0, 1.0) * MU_BINS as f32, MU_BINS);
        let phi = fast_acos(cos_phi);
        let (k, tk) = centre(phi / std::f32::consts::PI * PHI_BINS as f32, PHI_BINS);
        let at = |v: &[f32]| {
            let mut acc = 0.0;
            for (di, wi) in [(0, 1.0 - ti), (1, ti)] {
                for (dj, wj) in [(0, 1.0 - tj), (1, tj)] {
                    let base = ((i + di) * MU_BINS + j + dj) * PHI_BINS + k;
                    acc += wi * wj * (v[base] * (1.0 - tk) + v[base + 1] * tk);
                }
            }
            acc
        };
        let keep = (1.0 - to_normal(mu_c)) * (1.0 - to_normal(mu_l));
        (at(&self.norm) * keep + (1.0 - keep), at(&self.dnorm) * keep)
    }

    /// The normalised factor A/N at a pair of surface points (module docs): light entering at
    /// `x_i` (shading normal `n_i`) from the unit direction `w_l` towards the light (cosine
    /// `mu_l` = n_i·w_l > 0) and leaving at `x_o`, where the camera ray arrived with cosine
    /// `mu_c` and unit forward direction `cam_fwd` along the surface (zero at normal
    /// incidence), in a medium of extinction `sigma_t`. Returns (A/N, ∂(A/N)/∂α).
    #[inline]
    pub fn at_points(
        &self,
        (x_i, n_i, w_l, mu_l): (Vec3, Vec3, Vec3, f32),
        (x_o, mu_c, cam_fwd): (Vec3, f32, Vec3),
        sigma_t: f32,
    ) -> (f32, f32) {
        let delta = x_o - x_i;
        let fwd = -w_l + n_i * mu_l;
        let fwd_len = fwd.length();
        if fwd_len.is_nan() || fwd_len <= 1e-6 {
            // Normal incidence: no preferred azimuth.
            return (1.0, 0.0);
        }
        let fwd = fwd / fwd_len;
        let tangential = delta - n_i * n_i.dot(delta);
        let t_len = tangential.length();
        let (a, da) = if t_len > 0.0 {
            self.eval(mu_l, delta.length() * sigma_t, fwd.dot(tangential) / t_len)
        } else {
            // x_o straight above x_i: the ring's average.
            (1.0, 0.0)
        };
        let (n, dn) = self.normalisation(mu_c, mu_l, cam_fwd.dot(fwd));
        if n.is_nan() || n <= 1e-6 {
            return (1.0, 0.0);
        }
        (a / n, (da * n - a * dn) / (n * n))
    }
}
