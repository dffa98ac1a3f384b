//! The shape descriptor's inputs: per-vertex polynomials of each channel (docs/model.md §3.4),
//! optionally with their σ_n-derivative beyond the rescaling ([`VertexFeatures::fit_with_derivative`]).

use geometry::Accel;
use scene::Medium;

use super::{RenderError, channel_sigma_n};
use crate::fit::ConstraintCloud;
use crate::model::FrameConvention;
use crate::polynomial::{Poly3, align_direction, light_space_frame};
use base::fresnel::refract;
use geometry::Frame;
use glam::Vec3;

/// Per-vertex world-axis polynomials of each colour channel, fitted with the kernel of a medium
/// (docs/model.md §3.4: once per mesh and channel; SON24 keeps them fixed while σ_t, α change).
#[derive(Clone, Debug)]
pub struct VertexFeatures {
    /// `polys[c][v]`: channel c, vertex v.
    pub polys: [Vec<Poly3>; 3],
    /// The σ_n of each channel the fits were made with.
    pub sigma_n: [f32; 3],
    /// Optional `dfit[c][v]` = dR/d ln σ_n at σ_n,fit, R(σ) = G(σ) − G(σ_fit).rescaled(σ/σ_fit)
    /// the part of a refit at σ that the rescaling misses (G(σ): the fit made at σ). With it
    /// the descriptor at σ is G_fit.rescaled(k) + ln k · dfit (k = σ/σ_fit), to first order
    /// the refit ([`VertexFeatures::fit_with_derivative`]).
    pub dfit: Option<[Vec<Poly3>; 3]>,
}

impl VertexFeatures {
    /// Fit every vertex for each channel (channels with the same kernel share one fit).
    pub fn fit(
        accel: &Accel,
        medium: &Medium,
        quirk_c19: bool,
        seed: u64,
    ) -> Result<Self, RenderError> {
        Self::fit_impl(accel, medium, quirk_c19, seed, false)
    }

    /// [`VertexFeatures::fit`] plus `dfit` by a central difference in ln σ_n (step
    /// [`DFIT_STEP`]) of fits on the same constraint cloud: three fits per channel.
    pub fn fit_with_derivative(
        accel: &Accel,
        medium: &Medium,
        quirk_c19: bool,
        seed: u64,
    ) -> Result<Self, RenderError> {
        Self::fit_impl(accel, medium, quirk_c19, seed, true)
    }

    fn fit_impl(
        accel: &Accel,
        medium: &Medium,
        quirk_c19: bool,
        seed: u64,
        derivative: bool,
    ) -> Result<Self, RenderError> {
        let sigma_n = channel_sigma_n(medium)?;
        let mesh = accel.mesh();
        let mut polys: [Vec<Poly3>; 3] = Default::default();
        let mut dfit: [Vec<Poly3>; 3] = Default::default();
        let h = DFIT_STEP;
        for c in 0..3 {
            if let Some(prev) = (0..c).find(|&k| sigma_n[k] == sigma_n[c]) {
                polys[c] = polys[prev].clone();
                dfit[c] = dfit[prev].clone();
                continue;
            }
            let eps = (sigma_n[c] as f64).powi(2);
            let cloud = ConstraintCloud::from_mesh(mesh, eps, seed)?;
            polys[c] = cloud.fit_vertices(mesh, eps, quirk_c19)?;
            if !derivative {
                continue;
            }
            let up = cloud.fit_vertices(mesh, eps * (2.0 * h as f64).exp(), quirk_c19)?;
            let down = cloud.fit_vertices(mesh, eps * (-2.0 * h as f64).exp(), quirk_c19)?;
            dfit[c] = polys[c]
                .iter()
                .zip(up.iter().zip(&down))
                .map(|(g, (u, d))| {
                    let (gu, gd) = (g.rescaled(h.exp()), g.rescaled((-h).exp()));
                    Poly3(std::array::from_fn(|i| {
                        ((u.0[i] - gu.0[i]) - (d.0[i] - gd.0[i])) / (2.0 * h)
                    }))
                })
                .collect();
        }
        Ok(VertexFeatures {
            polys,
            sigma_n,
            dfit: derivative.then_some(dfit),
        })
    }
}

/// Step in ln σ_n of the central difference of [`VertexFeatures::fit_with_derivative`].
pub const DFIT_STEP: f32 = 0.1;

/// The light-space axes (e1, e2, e3) of the shape descriptor and the outgoing frame at a camera
/// ray's entry point (direction `d`, shading normal `n_o`, boundary η `eta`, local surface
/// `poly`), in the model's frame `convention` (docs/model.md A4): VKJ19 rotates into the frame
/// of the refracted ray, aligned with the polynomial's normal; SON24 into the camera ray's.
#[inline]
pub(crate) fn light_space(
    convention: FrameConvention,
    d: Vec3,
    n_o: Vec3,
    eta: f32,
    poly: &Poly3,
) -> ([Vec3; 3], Frame) {
    match convention {
        FrameConvention::Vkj19 => {
            let d_in = if eta == 1.0 {
                d
            } else {
                refract(d, n_o, eta).unwrap_or(d)
            };
            let d_in = match poly.normal() {
                Some(n_p) => align_direction(d_in, n_o, n_p),
                None => d_in,
            };
            let f = light_space_frame(d_in);
            ([f.s, f.t, f.n], f)
        }
        FrameConvention::Son24Compat => {
            let f = Frame::from_normal(-d);
            ([-f.s, -f.t, f.n], Frame::from_normal(n_o))
        }
    }
}
