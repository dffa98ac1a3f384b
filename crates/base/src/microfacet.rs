//! The rough dielectric boundary: GGX microfacets (Walter et al. 2007, "Microfacet Models for
//! Refraction through Rough Surfaces") with sampling of the visible normals (Heitz 2018,
//! "Sampling the GGX Distribution of Visible Normals"), the BSDF of Mitsuba 3's
//! `roughdielectric` with `distribution = "ggx"` and `sample_visible = true`.
//!
//! Directions are in the local frame of the macro surface: z is its normal, pointing to the
//! outside of the object. `wi` points back along the path (towards the camera), `wo` to where
//! the light comes from; η = n_inside / n_outside > 1. For a `wi` below the surface (inside) the
//! frame is mirrored so that the incident side is +z with the relative index η_t/η_i = 1/η.
//!
//! With the microfacet normal h, η' = η_t/η_i, F the Fresnel reflectance at wi·h and the
//! separable Smith term G = G1(wi, h) G1(wo, h):
//!
//! * D(h) = 1 / (π α² ((h_x² + h_y²)/α² + h_z²)²) (Walter eq. 33);
//! * G1(v, h) = 2 / (1 + √(1 + α² tan²θ_v)), 0 when v·h and v_z differ in sign (eq. 34);
//! * reflection, f·|cos θ_o| = F D G / (4 |cos θ_i|), h = (wi + wo)/|wi + wo| (eq. 20);
//! * transmission, f·|cos θ_o| = (1 − F) D G |wi·h| |wo·h| / (|cos θ_i| (wi·h + η' wo·h)²),
//!   h = −(wi + η' wo)/|…| (eq. 21 with the 1/η'² of radiance transport, which makes the
//!   radiance across the interface scale by (η_i/η_t)²);
//! * sampling: h from the visible normals of wi, pdf D_wi(h) = G1(wi, h) (wi·h) D(h) / cos θ_i;
//!   reflection with probability F, else refraction; the weight f·|cos θ_o| / pdf is G1(wo, h)
//!   for a reflection and G1(wo, h) / η'² for a refraction.

use std::f32::consts::PI;

use glam::Vec3;

use crate::fresnel::{fresnel_dielectric, reflect, refract};

/// The isotropic GGX (Trowbridge–Reitz) microfacet distribution of roughness `alpha`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    /// D(h), the density of microfacet normals per projected area (0 below the surface).
    #[inline]
    pub fn d(&self, h: Vec3) -> f32 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let t = (h.x * h.x + h.y * h.y) / a2 + h.z * h.z;
        let d = 1.0 / (PI * a2 * t * t);
        if d * h.z > 1e-20 { d } else { 0.0 }
    }

    /// Smith's masking G1(v, h) (0 when the microfacet faces away from `v`).
    #[inline]
    pub fn g1(&self, v: Vec3, h: Vec3) -> f32 {
        if v.dot(h) * v.z <= 0.0 {
            return 0.0;
        }
        let xy = self.alpha * self.alpha * (v.x * v.x + v.y * v.y);
        if xy == 0.0 {
            return 1.0;
        }
        2.0 / (1.0 + (1.0 + xy / (v.z * v.z)).sqrt())
    }

    /// A microfacet normal visible from `wi` (wi.z > 0), from two uniform numbers (Heitz 2018).
    #[inline]
    pub fn sample_visible(&self, wi: Vec3, u1: f32, u2: f32) -> Vec3 {
        let a = self.alpha;
        let vh = Vec3::new(a * wi.x, a * wi.y, wi.z).normalize();
        let lensq = vh.x * vh.x + vh.y * vh.y;
        let t1 = if lensq > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        let r = u1.sqrt();
        let phi = 2.0 * PI * u2;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
    }

    /// The density of [`Ggx::sample_visible`] (per solid angle of h): G1(wi, h) (wi·h) D(h) /
    /// cos θ_i.
    #[inline]
    pub fn pdf_visible(&self, wi: Vec3, h: Vec3) -> f32 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        self.g1(wi, h) * wi.dot(h).max(0.0) * self.d(h) / wi.z
    }
}

/// A rough dielectric interface of relative index `eta` = n_inside / n_outside and GGX
/// roughness `alpha` ([module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoughDielectric {
    pub eta: f32,
    pub ggx: Ggx,
}

/// Two directions seen from the side of `wi`, with their half vector.
#[derive(Clone, Copy)]
struct Pair {
    wi: Vec3,
    wo: Vec3,
    eta: f32,
    h: Vec3,
    ih: f32,
    oh: f32,
}

/// A direction drawn by [`RoughDielectric::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundarySample {
    /// The new direction (local frame).
    pub wo: Vec3,
    /// f·|cos θ_o| / pdf.
    pub weight: f32,
    /// Whether the direction crossed the surface.
    pub transmitted: bool,
}

impl RoughDielectric {
    pub fn new(eta: f32, alpha: f32) -> Self {
        RoughDielectric {
            eta,
            ggx: Ggx { alpha },
        }
    }

    /// `wi`, `wo` mirrored so that `wi` is above the surface, and η' = η_t/η_i seen from `wi`.
    #[inline]
    fn oriented(&self, wi: Vec3, wo: Vec3) -> (Vec3, Vec3, f32) {
        if wi.z >= 0.0 {
            (wi, wo, self.eta)
        } else {
            let flip = Vec3::new(1.0, 1.0, -1.0);
            (wi * flip, wo * flip, 1.0 / self.eta)
        }
    }

    /// The half vector of (wi, wo) (reflection when both lie on one side), on +z, with η'.
    #[inline]
    fn half(wi: Vec3, wo: Vec3, eta: f32) -> Option<Vec3> {
        let reflect = wo.z > 0.0;
        let h = if reflect { wi + wo } else { wi + eta * wo };
        let len = h.length();
        if len.is_nan() || len <= 1e-12 {
            return None;
        }
        let h = h / len;
        Some(if h.z < 0.0 { -h } else { h })
    }

    /// `wi`, `wo` oriented ([`RoughDielectric::oriented`]), η', their half vector h and wi·h,
    /// wo·h; `None` for directions in the surface or without a half vector.
    #[inline]
    fn pair(&self, wi: Vec3, wo: Vec3) -> Option<Pair> {
        let (wi, wo, eta) = self.oriented(wi, wo);
        if wi.z == 0.0 || wo.z == 0.0 {
            return None;
        }
        let h = Self::half(wi, wo, eta)?;
        Some(Pair {
            wi,
            wo,
            eta,
            h,
            ih: wi.dot(h),
            oh: wo.dot(h),
        })
    }

    /// f(wi, wo)·|cos θ_o| in radiance transport (Mitsuba's `eval`).
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some(p) = self.pair(wi, wo) else {
            return 0.0;
        };
        let (ih, oh, eta) = (p.ih, p.oh, p.eta);
        let d = self.ggx.d(p.h);
        let g = self.ggx.g1(p.wi, p.h) * self.ggx.g1(p.wo, p.h);
        let f = fresnel_dielectric(ih.abs(), if ih >= 0.0 { eta } else { 1.0 / eta });
        if p.wo.z > 0.0 {
            f * d * g / (4.0 * p.wi.z)
        } else {
            // Both sides of the microfacet must be consistent: wi in front, wo behind it.
            if ih * oh >= 0.0 {
                return 0.0;
            }
            let denom = ih + eta * oh;
            ((1.0 - f) * d * g * ih * oh / (p.wi.z * denom * denom)).abs()
        }
    }

    /// The density of [`RoughDielectric::sample`] per solid angle of `wo`.
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let Some(p) = self.pair(wi, wo) else {
            return 0.0;
        };
        let (ih, oh, eta) = (p.ih, p.oh, p.eta);
        if ih <= 0.0 {
            return 0.0;
        }
        let f = fresnel_dielectric(ih, eta);
        let ph = self.ggx.pdf_visible(p.wi, p.h);
        if p.wo.z > 0.0 {
            ph * f / (4.0 * oh.abs())
        } else {
            if oh >= 0.0 {
                return 0.0;
            }
            let denom = ih + eta * oh;
            ph * (1.0 - f) * eta * eta * oh.abs() / (denom * denom)
        }
    }

    /// The fraction of the energy arriving from outside at cosine `mu` (to the macro normal)
    /// that crosses into the object: ∫ D_wi(h) (1 − F(wi·h)) G1(wt, h) dh over the visible
    /// normals h, with wt the refraction of wi through h (the transmission weight G1/η'² of
    /// [`RoughDielectric::sample`] times η'², which undoes radiance's scaling by (η_i/η_t)²).
    /// A midpoint rule over an `n` × `n` grid of the visible-normal sampler's numbers. Smaller
    /// than the smooth 1 − F(μ) where the single-scattering microfacet model loses energy
    /// (grazing angles, large α); equal to it as α → 0.
    pub fn transmittance(&self, mu: f32, n: usize) -> f32 {
        let mu = mu.clamp(1e-4, 1.0);
        let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
        let mut sum = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let (u1, u2) = ((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let h = self.ggx.sample_visible(wi, u1, u2);
                let ih = wi.dot(h);
                if ih <= 0.0 {
                    continue;
                }
                let Some(wt) = refract(-wi, h, self.eta) else {
                    continue;
                };
                if wt.z >= 0.0 {
                    continue;
                }
                let t = (1.0 - fresnel_dielectric(ih, self.eta)) * self.ggx.g1(wt, h);
                if t.is_finite() {
                    sum += t as f64;
                }
            }
        }
        (sum / (n * n) as f64) as f32
    }

    /// Draws `wo` for `wi` from three uniform numbers: a visible microfacet normal, then
    /// reflection with probability F or refraction. `None` when the sample leaves no valid
    /// direction (a grazing `wi`, or an outgoing direction on the wrong side of the surface).
    pub fn sample(&self, wi: Vec3, u_lobe: f32, u1: f32, u2: f32) -> Option<BoundarySample> {
        let flip = wi.z < 0.0;
        let (wi, _, eta) = self.oriented(wi, Vec3::Z);
        if wi.z <= 0.0 {
            return None;
        }
        let h = self.ggx.sample_visible(wi, u1, u2);
        let ih = wi.dot(h);
        if ih <= 0.0 {
            return None;
        }
        let f = fresnel_dielectric(ih, eta);
        let (wo, weight, transmitted) = if u_lobe < f {
            let wo = reflect(-wi, h);
            if wo.z <= 0.0 {
                return None;
            }
            (wo, self.ggx.g1(wo, h), false)
        } else {
            let wo = refract(-wi, h, eta)?;
            if wo.z >= 0.0 {
                return None;
            }
            (wo, self.ggx.g1(wo, h) / (eta * eta), true)
        };
        if weight.is_nan() || weight <= 0.0 {
            return None;
        }
        let wo = if flip {
            Vec3::new(wo.x, wo.y, -wo.z)
        } else {
            wo
        };
        Some(BoundarySample {
            wo,
            weight,
            transmitted,
        })
    }
}

#[cfg(test)]
mod tests;
