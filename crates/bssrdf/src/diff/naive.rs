//! `naive` (Son et al. 2024 §4.1, the baseline that misses the boundary term): σ_t by the
//! derivative of the sample position with visibility held fixed (interior term only):
//! dx̃/dσ_t = R·(∂σ_n/∂σ_t·y + σ_n·∂y/∂σ_t), moved along the surface at x_i with the detached
//! projection direction d: dx_i = (I − d n_gᵀ/(n_g·d))·dx̃ (n_g the normal of the hit
//! triangle), then
//!
//!   ∂C/∂σ_t = (1 − F)·V·(∂S_abs/∂σ_t·L̃ + S_abs·∇L̃(x_i)·dx_i)
//!
//! where L̃ = Sw(n·w_l)(n·w_l)/r² is the smooth light term (shading normal re-interpolated on the
//! triangle, no visibility), differentiated by a central difference of step [`NAIVE_STEP`]
//! along dx_i; ∂y/∂σ_t and ∂S_abs/∂σ_t (zero with a frozen descriptor) by central differences of
//! the networks at the offset descriptors. α as [`super::ours`].

use geometry::{Hit, Mesh};
use glam::Vec3;
use scene::PointLight;

use super::NAIVE_STEP;
use super::row::{Sample, SampleEstimator};
use crate::nn::POSITION_DIM;
use crate::render::{LearnedScene, Pending, projection_gradient};

/// The `naive` estimator.
pub(super) struct Naive;

impl SampleEstimator for Naive {
    const PAIR: bool = false;

    fn offset_sets(moving: bool) -> usize {
        if moving { 2 } else { 0 }
    }

    fn d_sigma_t(s: &Sample) -> f32 {
        let (c, k) = (s.c, s.k);
        match s.hit {
            Some(hit) if s.v > 0.0 => {
                let ((yp, sp), (ym, sm)) = (s.offsets[0], s.offsets[1]);
                let dy: [f32; POSITION_DIM] =
                    std::array::from_fn(|i| (yp[i] - ym[i]) * k.inv_2dt[c]);
                let dl = naive_light_derivative(
                    s.scene,
                    s.view.light,
                    s.p,
                    (s.y, dy),
                    (s.scene.sigma_n[c], k.dsn_dt[c]),
                    &hit,
                );
                s.p.t_cam * ((sp - sm) * k.inv_2dt[c] * s.v + s.s_abs * dl)
            }
            _ => 0.0,
        }
    }

    fn d_albedo(_: &Sample) -> Option<f32> {
        None
    }
}

/// ∇L̃(x_i)·dx_i/dσ_t of the Naive estimator (module docs): the surface motion of the projected
/// point for dx̃ = R·(∂σ_n/∂σ_t·y + σ_n·∂y/∂σ_t) along the detached direction d, and the central
/// difference of the smooth light term (no visibility) along it. `(y, dy)`: decoder output and
/// its σ_t derivative; `(sigma_n, dsigma_n)`: σ_n and ∂σ_n/∂σ_t.
fn naive_light_derivative(
    scene: &LearnedScene,
    light: &PointLight,
    p: &Pending,
    (y, dy): ([f32; POSITION_DIM], [f32; POSITION_DIM]),
    (sigma_n, dsigma_n): (f32, f32),
    hit: &Hit,
) -> f32 {
    let x_t = crate::render::proposed_point(p, y, sigma_n);
    let (grad, _) = projection_gradient(scene, p, x_t);
    let Some(d) = grad.try_normalize() else {
        return 0.0;
    };
    let dy_total = Vec3::from(y) * dsigma_n + Vec3::from(dy) * sigma_n;
    let dx_t = p.out_frame.to_world(dy_total);
    let nd = hit.ng.dot(d);
    if nd.abs() < 1e-6 {
        return 0.0;
    }
    // Intersection of the line x̃ + t·d with the plane of the hit triangle: the sign of d cancels.
    let dx_i = dx_t - d * (hit.ng.dot(dx_t) / nd);
    let len = dx_i.length();
    if len == 0.0 {
        return 0.0;
    }
    let u = dx_i / len;
    let st = scene.medium.sigma_t[p.channel as usize];
    let l = |x: Vec3, st: f32| smooth_light(scene, p, (hit.tri, hit.ng), x, light.position, st);
    let motion =
        len * (l(hit.p + NAIVE_STEP * u, st) - l(hit.p - NAIVE_STEP * u, st)) / (2.0 * NAIVE_STEP);
    // The incidence factor also depends on σ_t itself (ρ = |x_o − x_i|·σ_t), and so does the
    // curvature correction (κ/σ_t).
    let explicit = if scene.incidence.is_some() || scene.curvature.is_some() {
        let h = 1e-3 * st;
        (l(hit.p, st + h) - l(hit.p, st - h)) / (2.0 * h)
    } else {
        0.0
    };
    motion + explicit
}

/// L̃(x) = D(w_l)·A·(n·w_l)·C/r² (D the exit law of the sample, A the incidence factor and C the
/// curvature correction at extinction `sigma_t`) on the plane of triangle `tri` (no visibility, no clamping of the
/// cosine: a smooth extension), with the shading normal n interpolated at x.
fn smooth_light(
    scene: &LearnedScene,
    p: &Pending,
    (tri, ng): (u32, Vec3),
    x: Vec3,
    light: Vec3,
    sigma_t: f32,
) -> f32 {
    let n = shading_normal_at(scene.accel.mesh(), tri, ng, x);
    let to_l = light - x;
    let r2 = to_l.length_squared();
    let r = r2.sqrt();
    let cos = n.dot(to_l) / r;
    let c = p.channel as usize;
    let a = if cos > 0.0 {
        scene.incidence_factor(p, (x, n, to_l / r, cos), sigma_t).0
    } else {
        1.0
    };
    let k = scene.curvature_factor(p, sigma_t).0;
    scene.exit_law(c, p.mu_cam, cos).0 * a * k * cos / r2
}

/// The interpolated vertex normal of triangle `tri` at the point x of its plane (barycentrics
/// extended linearly outside the triangle), or `ng` for a mesh without normals.
fn shading_normal_at(mesh: &Mesh, tri: u32, ng: Vec3, x: Vec3) -> Vec3 {
    let Some(normals) = &mesh.normals else {
        return ng;
    };
    let [i0, i1, i2] = mesh.indices[tri as usize];
    let [v0, v1, v2] = mesh.triangle(tri as usize);
    let (e1, e2, q) = (v1 - v0, v2 - v0, x - v0);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (q1, q2) = (q.dot(e1), q.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det == 0.0 {
        return ng;
    }
    let b1 = (d22 * q1 - d12 * q2) / det;
    let b2 = (d11 * q2 - d12 * q1) / det;
    let n = normals[i0 as usize] * (1.0 - b1 - b2)
        + normals[i1 as usize] * b1
        + normals[i2 as usize] * b2;
    match n.try_normalize() {
        Some(n) if n.dot(ng) >= 0.0 => n,
        Some(n) => (n - 2.0 * n.dot(ng) * ng).try_normalize().unwrap_or(ng),
        None => ng,
    }
}
