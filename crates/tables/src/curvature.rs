//! The light side on convex surfaces: the half-space light factors against exact walks in a
//! sphere.
//!
//! The estimator's light term at the entry point x_i, S_abs·f(α; μ_c, μ_l)·μ_l/π·A/N
//! ([`crate::exit`], [`crate::incidence`]), is built from half-space walks: exact for a plane lit
//! by a distant light. On a convex surface the learned images fall off towards the terminator
//! faster than the volumetric path tracer's, and are too bright where the camera grazes the lit
//! surface, by amounts that grow with the curvature in mean free paths (docs/notes/light-side.md,
//! "The light side on convex surfaces"). This module measures the gap where it can be computed
//! exactly: a ball of radius R (in mean free paths, σ_t = 1) lit by a distant light.
//!
//! * **Exact**: walks enter at the camera point x_o (the ball's north pole, outward normal +z)
//!   along the camera direction (cosine μ_c, forward direction +x; η = 1, so unrefracted) and
//!   scatter with albedo α (isotropically for the paper's media). At every collision,
//!   next-event estimation toward the light: α·(1/4π)·e^{−t}, t the distance to the sphere along
//!   the light direction. Their mean is
//!   the radiance leaving x_o toward the camera per unit irradiance of the light (reciprocity).
//! * **Model**: the same walks' exits x_i stand for the decoder's proposals and their escape
//!   fraction for S_abs; each contributes f(α; μ_c, μ_l(x_i))/π·μ_l(x_i)·A/N, with the light
//!   cosine μ_l(x_i) at the exit point (0 where the light is behind the surface), exactly as the
//!   renderer evaluates it ([`crate::render`]).
//!
//! In a half-space the two agree to 1–2 % where the light and the camera look the same way along
//! the surface; with the light opposite the camera (φ = π) and a grazing camera the model is up
//! to 18 % too bright. On balls the model is too dark near the terminator (exact/model 1.04–1.10
//! at μ_l ≤ 0.07, R = 21) and too bright where the camera grazes the lit surface (0.95 at R = 21,
//! 0.83 at R = 10.5).
//!
//! # The correction
//!
//! [`CurvatureTable`] holds C = exact/model on nodes of the albedo grid of [`crate::exit`]
//! (the same C¹ spline in ln(1 − α), so ∂C/∂α is available) × [`MU_C`] camera cosines ×
//! [`KAPPA`] curvatures (1/R in inverse mean free paths) × [`MU_L`] light cosines at the camera
//! point × [`PHI`] azimuths, multilinear between nodes. With `LightCurvature::Ball` the renderer
//! multiplies the light term of every sample by C at its camera point: μ_c and the camera's
//! forward direction, the light's cosine and forward direction there, and the mean curvature of
//! the sample's fitted cubic in units of 1/σ_t (concave points use the half-space row κ = 0;
//! beyond the last node the last row holds). Its σ_t-dependence (through κ/σ_t) enters the offset
//! samples of `ours`, its α-derivative ∂I/∂α. The table is exact for index-matched balls. For
//! the paper's media (g = 0) it is shipped (`data/curvature-g0-eta1.json`, `translucent model
//! curvature-table`); for a medium of another g the exact walks scatter by its Henyey–Greenstein
//! phase function (next-event estimation α·p(θ)·e^{−t}, the model side the exit and incidence
//! tables of that g) and the table is simulated at run time with fewer collisions
//! ([`CurvatureTable::for_medium`], [`RUNTIME_COLLISIONS`]). Forward scattering makes it matter
//! far more: light that travels around a convex surface escapes more often than on a plane, but
//! along the surface, away from a light in front of it. The balls have no dielectric boundary;
//! the renderer uses the same correction behind a rough one (an approximation) and none behind a
//! smooth one, whose total internal reflection keeps that light inside
//! (docs/notes/learned-real-media.md).

use base::phase::HenyeyGreenstein;
use base::rng::Sampler;
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::exit::{ExitSlice, ExitTable, ONE_MINUS_ALBEDO};
use crate::incidence::{IncidenceSlice, IncidenceTable, fast_acos};
use crate::table::{MediumCache, TableCheck, TableError, TableFile, albedo_spline, shipped};

/// Camera-cosine nodes.
pub const MU_C: [f32; 7] = [0.05, 0.15, 0.3, 0.5, 0.7, 0.9, 1.0];
/// Curvature nodes: 1/R in inverse mean free paths (0: the half-space).
pub const KAPPA: [f32; 5] = [0.0, 0.0125, 0.025, 0.05, 0.1];
/// Light-cosine nodes at the camera point (negative: the light is below its horizon).
pub const MU_L: [f32; 11] = [-0.2, -0.1, -0.05, 0.0, 0.05, 0.1, 0.2, 0.35, 0.55, 0.8, 1.0];
/// Nodes of the angle φ between the camera's and the light's forward directions.
pub const PHI: [f32; 5] = [
    0.0,
    std::f32::consts::FRAC_PI_4,
    std::f32::consts::FRAC_PI_2,
    3.0 * std::f32::consts::FRAC_PI_4,
    std::f32::consts::PI,
];
/// Values per albedo.
const PER_ALBEDO: usize = MU_C.len() * KAPPA.len() * MU_L.len() * PHI.len();
/// Where both responses are below this fraction of the batch's brightest, C tends to 1.
const REGULARISE: f64 = 1e-3;
/// C is kept in [1/C_MAX, C_MAX].
const C_MAX: f32 = 10.0;

/// A distant light seen from the camera point: its cosine μ_l with the normal there (negative:
/// below the horizon) and the angle φ between the camera's and the light's forward directions
/// along the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightDir {
    pub mu_l: f32,
    pub phi: f32,
}

impl LightDir {
    /// Unit direction toward the light: its tangential part points against the light's forward
    /// direction (cos φ, sin φ, 0).
    pub fn direction(self) -> Vec3 {
        let s = (1.0 - self.mu_l * self.mu_l).max(0.0).sqrt();
        Vec3::new(-s * self.phi.cos(), -s * self.phi.sin(), self.mu_l)
    }
}

/// The surface the walks run in: a ball of radius `radius` (mean free paths) whose north pole is
/// the origin, or the half-space z < 0 (`radius` infinite).
#[derive(Clone, Copy, Debug)]
struct Ball {
    radius: f32,
}

impl Ball {
    fn centre(self) -> Vec3 {
        Vec3::new(0.0, 0.0, -self.radius)
    }

    /// Distance from `p` (inside) along the unit `d` to the boundary (infinite when it never
    /// leaves the half-space).
    fn exit_distance(self, p: Vec3, d: Vec3) -> f32 {
        if self.radius.is_infinite() {
            return if d.z > 0.0 { -p.z / d.z } else { f32::INFINITY };
        }
        let c = p - self.centre();
        let b = c.dot(d);
        let cc = c.length_squared() - self.radius * self.radius;
        -b + (b * b - cc).max(0.0).sqrt()
    }

    fn normal(self, x: Vec3) -> Vec3 {
        if self.radius.is_infinite() {
            Vec3::Z
        } else {
            (x - self.centre()) / self.radius
        }
    }
}

fn isotropic(rng: &mut Sampler) -> Vec3 {
    let z = 2.0 * rng.next_f32() - 1.0;
    let phi = std::f32::consts::TAU * rng.next_f32();
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Exact and model radiance per unit irradiance at the camera point for every light of `lights`
/// ([`module docs`](self)), from walks of albedo `albedo` and Henyey–Greenstein phase `g`
/// entering at camera cosine `mu_c` into a ball of radius `radius` mean free paths (infinite:
/// half-space). Walks are started until they have made `collisions` collisions together (at
/// least one walk); returns (exact, model, walks).
#[allow(clippy::too_many_arguments)]
pub fn ball_response(
    (albedo, g): (f32, f32),
    mu_c: f32,
    radius: f32,
    lights: &[LightDir],
    exit: &ExitSlice,
    incidence: &IncidenceSlice,
    collisions: u64,
    seed: u64,
) -> (Vec<f64>, Vec<f64>, u64) {
    let ball = Ball { radius };
    let dirs: Vec<Vec3> = lights.iter().map(|l| l.direction()).collect();
    let (mut exact, mut model) = (vec![0.0f64; lights.len()], vec![0.0f64; lights.len()]);
    let d0 = Vec3::new((1.0 - mu_c * mu_c).max(0.0).sqrt(), 0.0, -mu_c);
    let phase = HenyeyGreenstein { g };
    // NEE: α·p(θ)·e^{−t}, with p = 1/(4π) for isotropic scattering.
    let nee = albedo as f64 / (4.0 * std::f64::consts::PI);
    let (mut made, mut walks) = (0u64, 0u64);
    while walks == 0 || made < collisions {
        let mut rng = Sampler::new(seed, 0xC0DE, walks, 0);
        walks += 1;
        let (mut p, mut d) = (Vec3::ZERO, d0);
        for _ in 0..MAX_COLLISIONS {
            let t = -(1.0 - rng.next_f32()).ln();
            let tb = ball.exit_distance(p, d);
            if t >= tb {
                let x_i = p + tb * d;
                let n_i = ball.normal(x_i);
                for (k, w_l) in dirs.iter().enumerate() {
                    let cos_l = n_i.dot(*w_l);
                    if cos_l <= 0.0 {
                        continue;
                    }
                    let (f, _) = exit.eval(mu_c, cos_l);
                    let (a, _) = incidence.at_points(
                        (x_i, n_i, *w_l, cos_l),
                        (Vec3::ZERO, mu_c, Vec3::X),
                        1.0,
                    );
                    model[k] += (f * std::f32::consts::FRAC_1_PI * cos_l * a) as f64;
                }
                break;
            }
            p += t * d;
            made += 1;
            for (k, w_l) in dirs.iter().enumerate() {
                let tl = ball.exit_distance(p, *w_l);
                if tl.is_finite() {
                    let p_phase = if g == 0.0 {
                        nee
                    } else {
                        albedo as f64 * phase.eval(d, *w_l) as f64
                    };
                    exact[k] += p_phase * (-tl as f64).exp();
                }
            }
            if rng.next_f32() >= albedo {
                break;
            }
            d = if g == 0.0 {
                isotropic(&mut rng)
            } else {
                phase.sample(d, rng.next_f32(), rng.next_f32())
            };
        }
    }
    let n = walks as f64;
    exact
        .iter_mut()
        .chain(model.iter_mut())
        .for_each(|v| *v /= n);
    (exact, model, walks)
}

/// Collisions per batch of a table simulated at run time (the shipped one has 10⁶).
pub const RUNTIME_COLLISIONS: u64 = 100_000;

/// Collisions after which a walk counts as absorbed.
const MAX_COLLISIONS: u32 = 100_000;

/// The lights of one batch, in table order (μ_l major, φ minor).
fn batch_lights() -> Vec<LightDir> {
    MU_L.iter()
        .flat_map(|&mu_l| PHI.iter().map(move |&phi| LightDir { mu_l, phi }))
        .collect()
}

/// How a [`CurvatureTable`] is made.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurvatureSettings {
    /// Henyey–Greenstein g of the medium (files without the field: 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub g: f32,
    /// Collisions per batch (albedo, camera cosine, curvature).
    pub collisions: u64,
    pub seed: u64,
}

/// Serde: an isotropic medium's g is not written.
fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

/// C = exact/model on the nodes ([`module docs`](self)), `c[a·PER_ALBEDO + …]` for grid albedo a,
/// then camera cosine, curvature, light cosine and φ.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurvatureTable {
    pub settings: CurvatureSettings,
    pub c: Vec<f32>,
}

/// The table written by `translucent model curvature-table` for g = 0, η = 1.
const SHIPPED_JSON: &str = include_str!("../data/curvature-g0-eta1.json");
const SHIPPED_NAME: &str = "data/curvature-g0-eta1.json";

impl CurvatureTable {
    /// Simulates the table for the medium's g (η = 1) against the renderer's exit and
    /// incidence tables of that medium (the model side must be the renderer's: the shipped
    /// ones at g = 0).
    pub fn generate(settings: CurvatureSettings) -> Self {
        let exit = ExitTable::for_medium(settings.g, 1.0, 0.0);
        let inc = IncidenceTable::for_medium(settings.g, 1.0);
        let lights = batch_lights();
        let batches = ONE_MINUS_ALBEDO.len() * MU_C.len() * KAPPA.len();
        let rows: Vec<Vec<f32>> = (0..batches)
            .into_par_iter()
            .map(|b| {
                let a = b / (MU_C.len() * KAPPA.len());
                let (m, k) = ((b / KAPPA.len()) % MU_C.len(), b % KAPPA.len());
                let albedo = 1.0 - ONE_MINUS_ALBEDO[a];
                let radius = if KAPPA[k] > 0.0 {
                    1.0 / KAPPA[k]
                } else {
                    f32::INFINITY
                };
                let (e, mo, _) = ball_response(
                    (albedo, settings.g),
                    MU_C[m],
                    radius,
                    &lights,
                    &exit.slice(albedo),
                    &inc.slice(albedo),
                    settings.collisions,
                    settings.seed ^ (b as u64) << 20,
                );
                let eps = REGULARISE * e.iter().chain(&mo).cloned().fold(0.0, f64::max);
                e.iter()
                    .zip(&mo)
                    .map(|(&e, &m)| {
                        let r = if eps > 0.0 {
                            (e + eps) / (m + eps)
                        } else {
                            1.0
                        };
                        (r as f32).clamp(1.0 / C_MAX, C_MAX)
                    })
                    .collect()
            })
            .collect();
        CurvatureTable {
            settings,
            c: rows.concat(),
        }
    }

    /// Values rounded to `digits` decimals (a smaller shipped file).
    pub fn rounded(mut self, digits: i32) -> Self {
        let s = 10f32.powi(digits);
        self.c.iter_mut().for_each(|v| *v = (*v * s).round() / s);
        self
    }

    /// The table shipped for the paper's media (g = 0, η = 1).
    pub fn index_matched_isotropic() -> std::sync::Arc<CurvatureTable> {
        static TABLE: std::sync::OnceLock<std::sync::Arc<CurvatureTable>> =
            std::sync::OnceLock::new();
        shipped(&TABLE, SHIPPED_JSON, SHIPPED_NAME)
    }

    /// The table for an index-matched medium of phase g: the shipped one at g = 0, otherwise
    /// simulated once per process ([`RUNTIME_COLLISIONS`] collisions per batch, seed 0) and
    /// kept (and on disk for the next process, [`crate::disk`]).
    pub fn for_medium(g: f32) -> std::sync::Arc<CurvatureTable> {
        static CACHE: MediumCache<CurvatureTable> = std::sync::Mutex::new(Vec::new());
        let shipped = Self::index_matched_isotropic();
        if shipped.settings.g == g {
            return shipped;
        }
        let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(t) = cache.iter().find(|t| t.settings.g == g) {
            return t.clone();
        }
        let settings = CurvatureSettings {
            g,
            collisions: RUNTIME_COLLISIONS,
            seed: 0,
        };
        let t = std::sync::Arc::new(crate::disk::load_or_simulate::<CurvatureTable>(
            crate::disk::folder().as_deref(),
            settings,
        ));
        cache.push(t.clone());
        t
    }

    /// The table at albedo `albedo`, with ∂C/∂α.
    pub fn slice(&self, albedo: f32) -> CurvatureSlice {
        let (c, dc) = albedo_spline(&self.c, PER_ALBEDO, albedo);
        CurvatureSlice { c, dc }
    }
}

impl TableFile for CurvatureTable {
    const KIND: &'static str = "curvature";

    /// `c`: albedos × camera cosines × curvatures × light cosines × φ values, finite and in
    /// (0, C_MAX] (the generator clamps C to [1/C_MAX, C_MAX]).
    fn check(&self, name: &str) -> Result<(), TableError> {
        let c = TableCheck {
            name,
            table: Self::KIND,
        };
        c.len("c", self.c.len(), ONE_MINUS_ALBEDO.len() * PER_ALBEDO)?;
        c.values("c", &self.c, f32::MIN_POSITIVE, C_MAX)
    }
}

/// C and ∂C/∂α at one albedo.
#[derive(Clone, Debug, PartialEq)]
pub struct CurvatureSlice {
    c: Vec<f32>,
    dc: Vec<f32>,
}

/// The node interval of `x` in `nodes` (ascending) and the weight of its upper end (clamped at
/// the ends). The interval is the number of interior nodes at or below `x` (a branch-free count;
/// 0 for NaN).
#[inline]
fn locate(nodes: &[f32], x: f32) -> (usize, f32) {
    let last = nodes.len() - 2;
    let i = nodes[1..=last].iter().filter(|&&n| x >= n).count();
    let t = (x - nodes[i]) / (nodes[i + 1] - nodes[i]);
    (i, t.clamp(0.0, 1.0))
}

/// Node counts of the four table axes (μ_c, κ, μ_l, φ) and the index strides of a slice.
const SIZES: [usize; 4] = [MU_C.len(), KAPPA.len(), MU_L.len(), PHI.len()];
const STRIDES: [usize; 4] = [
    SIZES[1] * SIZES[2] * SIZES[3],
    SIZES[2] * SIZES[3],
    SIZES[3],
    1,
];

/// The coordinates of a lookup other than the curvature: camera cosine μ_c, light cosine μ_l
/// and azimuth φ, each located on its nodes (interval, upper weight). They depend only on the
/// camera point and the light, so one camera sample computes them once for all its light
/// evaluations (the σ_t offset pair included; only κ/σ_t differs between those).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurvatureCoords {
    mu_c: (u32, f32),
    mu_l: (u32, f32),
    phi: (u32, f32),
}

impl CurvatureCoords {
    /// At camera cosine `mu_c`, light cosine `mu_l` at the camera point and cos φ.
    #[inline]
    pub fn from_cosines(mu_c: f32, mu_l: f32, cos_phi: f32) -> Self {
        let at = |(i, t): (usize, f32)| (i as u32, t);
        CurvatureCoords {
            mu_c: at(locate(&MU_C, mu_c)),
            mu_l: at(locate(&MU_L, mu_l)),
            phi: at(locate(&PHI, fast_acos(cos_phi.clamp(-1.0, 1.0)))),
        }
    }

    /// For the camera point `x_o` (shading normal `n_o`, camera cosine `mu_c`, camera forward
    /// direction `cam_fwd`) and the light at `light`.
    #[inline]
    pub fn at_point((x_o, n_o, mu_c, cam_fwd): (Vec3, Vec3, f32, Vec3), light: Vec3) -> Self {
        let w = (light - x_o).normalize_or_zero();
        let mu_l = n_o.dot(w);
        let fwd = (n_o * mu_l - w).normalize_or_zero();
        // Without a forward direction on either side the azimuth does not matter: φ = π/2.
        let cos_phi = cam_fwd.dot(fwd);
        Self::from_cosines(mu_c, mu_l, cos_phi)
    }
}

impl CurvatureSlice {
    /// (C, ∂C/∂α) at camera cosine `mu_c`, curvature `kappa` (1/mean free paths; concave values
    /// use the half-space row), light cosine `mu_l` at the camera point and cos φ.
    #[inline]
    pub fn eval(&self, mu_c: f32, kappa: f32, mu_l: f32, cos_phi: f32) -> (f32, f32) {
        self.eval_coords(&CurvatureCoords::from_cosines(mu_c, mu_l, cos_phi), kappa)
    }

    /// (C, ∂C/∂α) at the located coordinates `at` and curvature `kappa` (1/mean free paths):
    /// quadrilinear between the nodes (16 corners, the μ_c axis varying fastest).
    #[inline]
    pub fn eval_coords(&self, at: &CurvatureCoords, kappa: f32) -> (f32, f32) {
        let kappa = locate(&KAPPA, kappa.max(0.0));
        let dims = [
            (at.mu_c.0 as usize, at.mu_c.1),
            kappa,
            (at.mu_l.0 as usize, at.mu_l.1),
            (at.phi.0 as usize, at.phi.1),
        ];
        let w = dims.map(|(_, t)| [1.0 - t, t]);
        let base: usize = (0..4).map(|d| dims[d].0 * STRIDES[d]).sum();
        let (c, dc) = (&self.c[base..], &self.dc[base..]);
        let (mut acc, mut dacc) = (0.0, 0.0);
        for u3 in 0..2 {
            for u2 in 0..2 {
                for u1 in 0..2 {
                    for u0 in 0..2 {
                        let wc = w[0][u0] * w[1][u1] * w[2][u2] * w[3][u3];
                        let k = u0 * STRIDES[0] + u1 * STRIDES[1] + u2 * STRIDES[2] + u3;
                        acc += wc * c[k];
                        dacc += wc * dc[k];
                    }
                }
            }
        }
        (acc, dacc)
    }

    /// (C, ∂C/∂α) for the camera point `x_o` (shading normal `n_o`, camera cosine `mu_c`,
    /// camera forward direction `cam_fwd`), the light at `light`, the mean curvature `kappa`
    /// there (inverse scene units) and extinction `sigma_t`.
    #[inline]
    pub fn at_point(
        &self,
        point: (Vec3, Vec3, f32, Vec3),
        light: Vec3,
        kappa: f32,
        sigma_t: f32,
    ) -> (f32, f32) {
        self.eval_coords(&CurvatureCoords::at_point(point, light), kappa / sigma_t)
    }
}

#[cfg(test)]
mod tests;
