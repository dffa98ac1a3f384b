//! The surface constraint point cloud and the weighted least-squares cubic fit
//! (docs/model.md §3.2, §3.4; VKJ19 `polynomials.cpp` fitPolynomialsImpl, `vaehelper.cpp`).
//!
//! **Cloud.** `N = max(⌊2·A/ε⌋, 1024)` points sampled uniformly by area on the mesh (A = total
//! area, ε = kernel variance of the medium channel, [`crate::medium::kernel_epsilon`]) with their
//! unit shading normals (interpolated vertex normals where the mesh has them, as Mitsuba's
//! `samplePosition`), stored in a k-d tree. The first 32 points form the "global" constraint set.
//! Sampling is counter-based (point `i` uses uniforms hashed from `(seed, i)`), hence
//! deterministic and independent of the thread count.
//!
//! **Fit** at a reference point p with kernel ε, `σ_n = sqrt(ε)`, `s = 1/σ_n`:
//! 1. local set: cloud points with `|q − p|² < 9ε`; global set: the first 32 cloud points (a point
//!    can be in both, it then counts twice); `N_tot` = size of both sets together;
//! 2. row weights `w = sqrt(exp(−|q − p|²/(2ε))) / sqrt(N_tot)` (local) and
//!    `w = 0.01 · sqrt(1/32)` (global);
//! 3. scaled world-axis coordinates `r = (q − p)·s`;
//! 4. unknowns `c_1..c_19` (`c_0 = 0`, hard surface constraint); per point one value row
//!    `w·m_k(r) = 0` and three gradient rows `w·∂m_k/∂r_a(r) = w·n_a` (the gradient with respect to
//!    the SCALED coordinates is fitted to the unit normal);
//! 5. normal equations `(AᵀA + λ·diag(0,0,0,1,…,1)) c = Aᵀb`, λ = 1e-4 (the three linear terms are
//!    not regularised), assembled in `f64` directly (rank-1 updates, exploiting that each gradient
//!    row has only 10 non-zeros), solved with a static 19×19 Cholesky, SVD as fallback;
//! 6. `quirk_c19` (docs/model.md §3.2 step 7, §10 A3): VKJ19 copies only the first 18 of the 19
//!    solved values into the 20-vector, so `c_19` (z³) is left 0. Set it to reproduce the data the
//!    released networks were trained on.

use geometry::{AreaSampler, Mesh};
use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::polynomial::{DERIV, N_COEFFS, Poly3, monomials_f64};

/// Size of the global constraint set (VKJ19 ConstraintKdTree: first 32 points).
pub const GLOBAL_CONSTRAINTS: usize = 32;
/// Weight factor of the global constraints (`globalConstraintWeight`).
pub const GLOBAL_CONSTRAINT_WEIGHT: f64 = 0.01;
/// Ridge λ on the non-linear coefficients (`regularization`).
pub const RIDGE_LAMBDA: f64 = 1e-4;
/// Minimum number of cloud points.
pub const MIN_CLOUD_POINTS: usize = 1024;
/// Largest cloud accepted (≈ 0.8 GB); beyond it ε is unreasonably small for the mesh.
pub const MAX_CLOUD_POINTS: usize = 1 << 25;
/// Local neighbourhood radius in units of σ_n (`|q − p|² < 9ε`).
pub const LOCAL_RADIUS_SIGMAS: f64 = 3.0;

/// Errors of the constraint cloud and the fit.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// ε must be finite and > 0.
    #[error("kernel epsilon must be a finite number > 0 (got {0})")]
    Epsilon(f64),
    /// The mesh has no triangles of positive area.
    #[error("the mesh has no surface area to sample constraint points from")]
    EmptySurface,
    /// The cloud would be larger than [`MAX_CLOUD_POINTS`].
    #[error(
        "the constraint cloud would need {needed:.3e} points (limit {limit}): the kernel epsilon \
         is too small for a mesh of this area (the medium's mean free path 1/σ_t is tiny against \
         the object: the learned model fits the shape at that scale); fix: a σ_t nearer the \
         object's, about 50 over its size in scene units (the default start, 50, suits an object \
         about 1 unit across)"
    )]
    TooManyPoints { needed: f64, limit: usize },
    /// `points` and `normals` differ in length.
    #[error("{points} constraint points but {normals} normals")]
    LengthMismatch { points: usize, normals: usize },
    /// No constraint points.
    #[error("the constraint cloud is empty")]
    EmptyCloud,
    /// A cloud point or normal is NaN/infinite, or a normal is zero.
    #[error("constraint point {index} has a non-finite position or an invalid normal")]
    InvalidConstraint { index: usize },
    /// k-d tree construction failed.
    #[error("k-d tree construction failed: {0}")]
    KdTree(String),
    /// The fit position is NaN/infinite.
    #[error("fit position {index} is not finite")]
    NonFinitePosition { index: usize },
    /// The least-squares system could not be solved to a finite result.
    #[error("the least-squares system at fit position {index} could not be solved")]
    Singular { index: usize },
}

/// SplitMix64 finaliser (bijective 64-bit mix).
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Three uniforms in [0, 1) (24 bits each) for cloud point `i`.
#[inline]
fn point_uniforms(seed: u64, i: u64) -> [f32; 3] {
    let h1 = mix64(mix64(seed ^ 0x5851_F42D_4C95_7F2D) ^ mix64(i));
    let h2 = mix64(h1 ^ 0xD6E8_FEB8_6659_FD93);
    const S: f32 = 1.0 / 16_777_216.0;
    [
        (h1 >> 40) as f32 * S,
        ((h1 >> 16) & 0xFF_FFFF) as f32 * S,
        (h2 >> 40) as f32 * S,
    ]
}

/// Number of unknowns (`c_1..c_19`).
const NU: usize = N_COEFFS - 1;

/// Indices of the monomials containing each variable (the non-zeros of a gradient row), with the
/// exponent and the index of the derivative monomial: `∂m_k/∂u_a = e·m_src`.
const GRAD_NZ: [[(u8, u8, u8); 10]; 3] = build_grad_nz();

const fn build_grad_nz() -> [[(u8, u8, u8); 10]; 3] {
    let mut out = [[(0u8, 0u8, 0u8); 10]; 3];
    let mut axis = 0;
    while axis < 3 {
        let mut n = 0;
        let mut k = 0;
        while k < N_COEFFS {
            let (e, src) = DERIV[axis][k];
            if e > 0 {
                out[axis][n] = (k as u8, e, src);
                n += 1;
            }
            k += 1;
        }
        axis += 1;
    }
    out
}

/// Normal equations being accumulated: upper triangle of `AᵀA` (unknown index = k − 1) and `Aᵀb`.
struct Normal {
    ata: [[f64; NU]; NU],
    atb: [f64; NU],
}

impl Normal {
    fn new() -> Self {
        Normal {
            ata: [[0.0; NU]; NU],
            atb: [0.0; NU],
        }
    }

    /// Add the four rows of one constraint point with squared row weight `w2`, scaled
    /// coordinates `r` and unit normal `n`.
    #[inline]
    fn add(&mut self, w2: f64, r: [f64; 3], n: [f64; 3]) {
        let m = monomials_f64(r);
        // value row: w·m_k (k ≥ 1), target 0
        for i in 1..N_COEFFS {
            let wi = w2 * m[i];
            let row = &mut self.ata[i - 1];
            for j in i..N_COEFFS {
                row[j - 1] += wi * m[j];
            }
        }
        // gradient rows: w·∂m_k/∂r_a, target w·n_a (10 non-zeros each, indices ascending)
        for axis in 0..3 {
            let nz = &GRAD_NZ[axis];
            let g: [f64; 10] = std::array::from_fn(|t| nz[t].1 as f64 * m[nz[t].2 as usize]);
            let wn = w2 * n[axis];
            for a in 0..10 {
                let ka = nz[a].0 as usize - 1;
                let wa = w2 * g[a];
                let row = &mut self.ata[ka];
                for b in a..10 {
                    row[nz[b].0 as usize - 1] += wa * g[b];
                }
                self.atb[ka] += wn * g[a];
            }
        }
    }

    /// `self = self·s + other` (local sums are accumulated unscaled, then scaled by 1/N_tot).
    fn scale_add(&mut self, s: f64, other: &Normal) {
        for i in 0..NU {
            for j in i..NU {
                self.ata[i][j] = self.ata[i][j] * s + other.ata[i][j];
            }
            self.atb[i] = self.atb[i] * s + other.atb[i];
        }
    }

    /// Solve `(AᵀA + λ D) x = Aᵀb`; `None` if no finite solution was found.
    fn solve(&self) -> Option<[f64; NU]> {
        let mut a = SMatrix::<f64, NU, NU>::zeros();
        for i in 0..NU {
            for j in i..NU {
                a[(i, j)] = self.ata[i][j];
                a[(j, i)] = self.ata[i][j];
            }
            // unknown i is coefficient i + 1; coefficients 1..=3 (linear) are not regularised
            if i >= 3 {
                a[(i, i)] += RIDGE_LAMBDA;
            }
        }
        let b = SVector::<f64, NU>::from_column_slice(&self.atb);
        let finite = |x: &SVector<f64, NU>| x.iter().all(|v| v.is_finite());
        if let Some(ch) = a.cholesky() {
            let x = ch.solve(&b);
            if finite(&x) {
                return Some(std::array::from_fn(|i| x[i]));
            }
        }
        let svd = a.svd(true, true);
        let tol = svd.singular_values.max() * 1e-13;
        let x = svd.solve(&b, tol).ok()?;
        finite(&x).then(|| std::array::from_fn(|i| x[i]))
    }
}

/// An area-uniform surface point cloud with unit normals and a k-d tree over it
/// (docs/model.md §3.2).
pub struct ConstraintCloud {
    points: Vec<Vec3>,
    normals: Vec<Vec3>,
    tree: ImmutableKdTree<f32, 3>,
}

impl std::fmt::Debug for ConstraintCloud {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ConstraintCloud")
            .field("points", &self.points.len())
            .finish()
    }
}

impl ConstraintCloud {
    /// Cloud size for a surface of `area` and kernel `eps`: `max(⌊2·area/ε⌋, 1024)` (VKJ19
    /// `vaehelper.cpp`). Errors if ε is invalid or the count exceeds [`MAX_CLOUD_POINTS`].
    pub fn point_count(area: f64, eps: f64) -> Result<usize, FitError> {
        if !(eps.is_finite() && eps > 0.0) {
            return Err(FitError::Epsilon(eps));
        }
        if !(area.is_finite() && area > 0.0) {
            return Err(FitError::EmptySurface);
        }
        let needed = (2.0 * area / eps).floor();
        if needed.is_nan() || needed > MAX_CLOUD_POINTS as f64 {
            return Err(FitError::TooManyPoints {
                needed,
                limit: MAX_CLOUD_POINTS,
            });
        }
        Ok((needed as usize).max(MIN_CLOUD_POINTS))
    }

    /// Cloud of [`ConstraintCloud::point_count`] points sampled uniformly by area on `mesh`
    /// (deterministic in `seed`).
    pub fn from_mesh(mesh: &Mesh, eps: f64, seed: u64) -> Result<Self, FitError> {
        let sampler = AreaSampler::new(mesh);
        let n = Self::point_count(sampler.total_area(), eps)?;
        Self::sample_mesh(mesh, &sampler, n, seed)
    }

    /// Cloud of exactly `n` points (at least 1) sampled uniformly by area on `mesh`.
    pub fn from_mesh_with_count(mesh: &Mesh, n: usize, seed: u64) -> Result<Self, FitError> {
        let sampler = AreaSampler::new(mesh);
        if !(sampler.total_area() > 0.0 && sampler.total_area().is_finite()) {
            return Err(FitError::EmptySurface);
        }
        if n > MAX_CLOUD_POINTS {
            return Err(FitError::TooManyPoints {
                needed: n as f64,
                limit: MAX_CLOUD_POINTS,
            });
        }
        Self::sample_mesh(mesh, &sampler, n, seed)
    }

    fn sample_mesh(
        mesh: &Mesh,
        sampler: &AreaSampler,
        n: usize,
        seed: u64,
    ) -> Result<Self, FitError> {
        let samples: Vec<(Vec3, Vec3)> = (0..n as u64)
            .into_par_iter()
            .map(|i| {
                let s = sampler.sample(mesh, point_uniforms(seed, i));
                (s.p, s.ns)
            })
            .collect();
        let (points, normals) = samples.into_iter().unzip();
        Self::from_points(points, normals)
    }

    /// Cloud from given points and normals (normals are normalised here). The first 32 points
    /// are the global set, so they should be a random subset of the surface.
    pub fn from_points(points: Vec<Vec3>, normals: Vec<Vec3>) -> Result<Self, FitError> {
        if points.len() != normals.len() {
            return Err(FitError::LengthMismatch {
                points: points.len(),
                normals: normals.len(),
            });
        }
        if points.is_empty() {
            return Err(FitError::EmptyCloud);
        }
        if points.len() > MAX_CLOUD_POINTS {
            return Err(FitError::TooManyPoints {
                needed: points.len() as f64,
                limit: MAX_CLOUD_POINTS,
            });
        }
        let mut normals = normals;
        for (index, (p, n)) in points.iter().zip(normals.iter_mut()).enumerate() {
            let unit = n.try_normalize();
            match unit {
                Some(u) if p.is_finite() => *n = u,
                _ => return Err(FitError::InvalidConstraint { index }),
            }
        }
        let coords: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree = ImmutableKdTree::<f32, 3>::new_from_slice(&coords)
            .map_err(|e| FitError::KdTree(format!("{e:?}")))?;
        Ok(ConstraintCloud {
            points,
            normals,
            tree,
        })
    }

    /// All cloud points.
    pub fn points(&self) -> &[Vec3] {
        &self.points
    }

    /// Unit normals of the cloud points.
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Always false (a cloud has at least one point).
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The global constraint set: the first `min(32, N)` points.
    pub fn global_points(&self) -> &[Vec3] {
        &self.points[..self.points.len().min(GLOBAL_CONSTRAINTS)]
    }

    /// Visit the cloud points `q` with `|q − p|² < r2` (strict, evaluated in f64 from the stored
    /// f32 positions) as `(index, |q − p|²)`.
    fn visit_local(&self, p: Vec3, r2: f64, mut f: impl FnMut(usize, f64)) {
        // Query a hair wider in f32, then decide exactly in f64.
        let r2_query = (r2 * (1.0 + 1e-5)) as f32;
        let pd = p.as_dvec3();
        self.tree
            .query(&p.to_array())
            .within::<SquaredEuclidean<f32>>(r2_query)
            .unsorted()
            .visit(|item| {
                let i = item.item as usize;
                let d2 = (self.points[i].as_dvec3() - pd).length_squared();
                if d2 < r2 {
                    f(i, d2);
                }
            });
    }

    /// Number of cloud points within `3σ_n` of `p` (the local set of a fit with kernel `eps`).
    pub fn local_count(&self, p: Vec3, eps: f64) -> usize {
        let mut n = 0;
        self.visit_local(p, 9.0 * eps, |_, _| n += 1);
        n
    }

    /// Weighted least-squares cubic at `p` with kernel `eps` (docs/model.md §3.2; see the module
    /// docs): world axes, scaled coordinates `u = (q − p)/σ_n`, `c_0 = 0`; with `quirk_c19` the
    /// z³ coefficient is dropped (`c_19 = 0`).
    pub fn fit_at(&self, p: Vec3, eps: f64, quirk_c19: bool) -> Result<Poly3, FitError> {
        self.fit_at_indexed(p, eps, quirk_c19, 0)
    }

    fn fit_at_indexed(
        &self,
        p: Vec3,
        eps: f64,
        quirk_c19: bool,
        index: usize,
    ) -> Result<Poly3, FitError> {
        if !(eps.is_finite() && eps > 0.0) {
            return Err(FitError::Epsilon(eps));
        }
        if !p.is_finite() {
            return Err(FitError::NonFinitePosition { index });
        }
        let inv_sigma = 1.0 / eps.sqrt();
        let pd = p.as_dvec3();
        let inv_2eps = 0.5 / eps;
        let radius2 = LOCAL_RADIUS_SIGMAS * LOCAL_RADIUS_SIGMAS * eps;

        let mut local = Normal::new();
        let mut n_local = 0usize;
        self.visit_local(p, radius2, |i, d2| {
            n_local += 1;
            let r = ((self.points[i].as_dvec3() - pd) * inv_sigma).to_array();
            let n = self.normals[i].as_dvec3().to_array();
            local.add((-d2 * inv_2eps).exp(), r, n);
        });

        let globals = self.global_points();
        let mut global = Normal::new();
        // w = 0.01·sqrt(1/32) ⇒ w² = 1e-4/32
        let wg2 = GLOBAL_CONSTRAINT_WEIGHT * GLOBAL_CONSTRAINT_WEIGHT / GLOBAL_CONSTRAINTS as f64;
        for (q, n) in globals.iter().zip(&self.normals) {
            let r = ((q.as_dvec3() - pd) * inv_sigma).to_array();
            global.add(wg2, r, n.as_dvec3().to_array());
        }
        let n_tot = n_local + globals.len();
        local.scale_add(1.0 / n_tot as f64, &global);

        let x = local.solve().ok_or(FitError::Singular { index })?;
        let mut c = [0.0f32; N_COEFFS];
        for k in 1..N_COEFFS {
            c[k] = x[k - 1] as f32;
        }
        if quirk_c19 {
            c[19] = 0.0;
        }
        Ok(Poly3(c))
    }

    /// Fits at many positions in parallel (rayon); the result order follows `positions` and each
    /// fit is independent, so the output is deterministic.
    pub fn fit_points(
        &self,
        positions: &[Vec3],
        eps: f64,
        quirk_c19: bool,
    ) -> Result<Vec<Poly3>, FitError> {
        positions
            .par_iter()
            .enumerate()
            .map(|(i, &p)| self.fit_at_indexed(p, eps, quirk_c19, i))
            .collect()
    }

    /// Per-vertex fits of `mesh` (docs/model.md §3.4, VKJ19 render-time precomputation): one
    /// world-axis polynomial per entry of `mesh.positions`.
    pub fn fit_vertices(
        &self,
        mesh: &Mesh,
        eps: f64,
        quirk_c19: bool,
    ) -> Result<Vec<Poly3>, FitError> {
        self.fit_points(&mesh.positions, eps, quirk_c19)
    }
}

/// Convenience: build the cloud of `mesh` for kernel `eps` (seeded) and fit every vertex with
/// the same `eps` (docs/model.md §7.3 precomputation, one colour channel).
pub fn fit_mesh_vertices(
    mesh: &Mesh,
    eps: f64,
    seed: u64,
    quirk_c19: bool,
) -> Result<Vec<Poly3>, FitError> {
    ConstraintCloud::from_mesh(mesh, eps, seed)?.fit_vertices(mesh, eps, quirk_c19)
}

/// Barycentric interpolation of the three vertex polynomials of a triangle (docs/model.md §3.4):
/// `Σ_i b_i · c^{(i)}`, treated as a polynomial centred at the interpolated point (`c_0` stays 0).
pub fn interpolate(polys: [&Poly3; 3], bary: [f32; 3]) -> Poly3 {
    Poly3(std::array::from_fn(|k| {
        bary[0] * polys[0].0[k] + bary[1] * polys[1].0[k] + bary[2] * polys[2].0[k]
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grad_nz_lists_ten_ascending_entries() {
        for axis in 0..3 {
            let nz = GRAD_NZ[axis];
            for t in 1..10 {
                assert!(nz[t].0 > nz[t - 1].0);
            }
            assert!(nz.iter().all(|e| e.0 >= 1 && e.1 >= 1));
        }
        assert_eq!(
            GRAD_NZ[0].map(|e| e.0),
            [1, 4, 5, 6, 10, 11, 12, 13, 14, 15]
        );
    }

    #[test]
    fn uniforms_in_unit_interval_and_distinct() {
        let a = point_uniforms(7, 0);
        let b = point_uniforms(7, 1);
        assert_ne!(a, b);
        for u in a.iter().chain(&b) {
            assert!((0.0..1.0).contains(u));
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(matches!(
            ConstraintCloud::point_count(1.0, 0.0),
            Err(FitError::Epsilon(_))
        ));
        assert!(matches!(
            ConstraintCloud::point_count(1.0, 1e-12),
            Err(FitError::TooManyPoints { .. })
        ));
        assert_eq!(ConstraintCloud::point_count(1.0, 1.0).unwrap(), 1024);
        assert!(ConstraintCloud::from_points(vec![], vec![]).is_err());
        assert!(ConstraintCloud::from_points(vec![Vec3::ZERO], vec![Vec3::ZERO]).is_err());
        assert!(ConstraintCloud::from_mesh(&Mesh::default(), 0.1, 0).is_err());
        let c = ConstraintCloud::from_points(vec![Vec3::ZERO; 3], vec![Vec3::Z; 3]).unwrap();
        assert!(c.fit_at(Vec3::NAN, 0.1, false).is_err());
        assert!(c.fit_at(Vec3::ZERO, -1.0, false).is_err());
    }
}
