//! The rough boundary's own reflection in the learned renderer.
//!
//! A smooth boundary reflects a point light into one direction only, which no camera ray takes:
//! it adds nothing to the image. A rough one (GGX microfacets of roughness α, Walter et al.
//! 2007, the BSDF of the tracer and of Mitsuba 3's `roughdielectric`,
//! [`base::microfacet::RoughDielectric`]) spreads the reflection into a highlight. Per camera
//! sample that meets the object at x_o from outside, the renderer adds to every channel c
//!
//!   L_s = f_r(ω_cam, ω_l)·|cos θ_l| · V(x_o, light) · I_c / r²
//!
//! with ω_cam = −d the direction back to the camera and ω_l the unit direction to the light, both
//! in the frame of the shading normal at x_o (Walter et al. eq. 20: f_r = F(ω_cam·h) D(h)
//! G₁(ω_cam, h) G₁(ω_l, h) / (4 |cos θ_cam| |cos θ_l|), h the half vector), V the visibility of
//! the light. This is next-event estimation of the first boundary vertex exactly as the tracer
//! does it; the light reflected on to another part of the object (concave shapes only) is left
//! out. L_s does not depend on σ_t, α or g, so the derivative images get nothing from it; it
//! enters the value (and with it the loss) of every render and estimator, since every one of
//! them prepares its rows through `prepare_row`.
//!
//! The rough surface also passes a different share of the light than a smooth one: the energy
//! that crosses from outside at cosine μ is T(μ) = ∫ D_μ(h) (1 − F(ω·h)) G₁(ω_t, h) dh over the
//! visible normals ([`RoughDielectric::transmittance`]), smaller than the smooth 1 − F(μ) where
//! the single-scattering microfacet model loses energy. The camera side's factor 1 − F(cos θ_cam)
//! becomes T(cos θ_cam). On the light side the walks behind the exit law and the absorption
//! network crossed a smooth boundary, so the light term is scaled by T(μ_l)/(1 − F(μ_l)): the
//! first-order change of the light that leaves at μ_l (the internal reflections stay those of
//! the smooth boundary). T is tabulated per scene on [`TABLE`] cosines and interpolated linearly.

use base::boundary::transmittance;
use base::microfacet::RoughDielectric;
use geometry::bvh::offset_origin;
use geometry::{Accel, Frame, Hit};
use glam::Vec3;
use scene::{Medium, PointLight};

/// Cosines of the transmittance table (μ = k/(TABLE − 1), k = 0 … TABLE − 1).
pub(crate) const TABLE: usize = 65;

/// Quadrature points per axis of each table entry ([`RoughDielectric::transmittance`]).
const QUADRATURE: usize = 24;

/// The reflection and transmission of a rough boundary ([module docs](self)).
#[derive(Clone, Debug)]
pub struct Surface {
    bsdf: RoughDielectric,
    /// T(μ) at μ = k/(TABLE − 1).
    transmit: [f32; TABLE],
}

impl Surface {
    /// The surface of `medium`'s boundary when it reflects a point light into a spread of
    /// directions (η > 1 and roughness > 0); `None` for a smooth or index-matched boundary.
    pub fn of(medium: &Medium) -> Option<Self> {
        (medium.eta > 1.0 && medium.roughness > 0.0).then(|| {
            let bsdf = RoughDielectric::new(medium.eta, medium.roughness);
            let transmit = std::array::from_fn(|k| {
                bsdf.transmittance(k as f32 / (TABLE - 1) as f32, QUADRATURE)
            });
            Surface { bsdf, transmit }
        })
    }

    /// Adds the reflection at `hit` ([`Surface::reflection`]) times the light's intensity to
    /// every channel of a pixel's sums.
    #[inline]
    pub(crate) fn add_reflection(
        &self,
        accel: &Accel,
        light: &PointLight,
        hit: &Hit,
        d: Vec3,
        sums: &mut [f64; 3],
    ) {
        let f = self.reflection(accel, light, hit, d);
        if f > 0.0 {
            for (acc, i) in sums.iter_mut().zip(light.intensity) {
                *acc += (f * i) as f64;
            }
        }
    }

    /// T(μ), the energy crossing from outside at cosine `mu` ([module docs](self)).
    #[inline]
    pub fn transmittance(&self, mu: f32) -> f32 {
        let x = mu.clamp(0.0, 1.0) * (TABLE - 1) as f32;
        let k = (x as usize).min(TABLE - 2);
        let t = x - k as f32;
        self.transmit[k] * (1.0 - t) + self.transmit[k + 1] * t
    }

    /// T(μ_l)/(1 − F(μ_l)): the light side's change from the smooth boundary of the walks
    /// ([module docs](self)); 1 where the smooth boundary passes (almost) nothing.
    #[inline]
    pub(crate) fn light_side_factor(&self, mu_l: f32) -> f32 {
        let smooth = transmittance(mu_l, self.bsdf.eta);
        if smooth < 1e-3 {
            return 1.0;
        }
        self.transmittance(mu_l) / smooth
    }

    /// f_r(ω_cam, ω_l)·|cos θ_l| · V / r² at the camera ray's hit `hit` (direction `d`, from
    /// outside), without the light's intensity; 0 when the light is below the surface, hidden,
    /// or the directions disagree with the geometric normal.
    #[inline]
    pub fn reflection(&self, accel: &Accel, light: &PointLight, hit: &Hit, d: Vec3) -> f32 {
        let frame = Frame::from_normal(hit.ns);
        let wi = frame.to_local(-d);
        if wi.z <= 0.0 || d.dot(hit.ng) >= 0.0 {
            return 0.0;
        }
        let to_l = light.position - hit.p;
        let r2 = to_l.length_squared();
        if r2.is_nan() || r2 <= 0.0 {
            return 0.0;
        }
        let r = r2.sqrt();
        let wl = to_l / r;
        let wl_local = frame.to_local(wl);
        if wl_local.z <= 0.0 || wl.dot(hit.ng) <= 0.0 {
            return 0.0;
        }
        let f = self.bsdf.eval(wi, wl_local);
        if f.is_nan() || f <= 0.0 {
            return 0.0;
        }
        if !accel.exit_is_final(hit.tri)
            && accel.occluded(offset_origin(hit.p, hit.ng, wl), wl, 0.0, r)
        {
            return 0.0;
        }
        f / r2
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geometry::Mesh;

    /// The square [−1, 1]² in z = 0, facing +z.
    fn square() -> Accel {
        let p = |x, y| Vec3::new(x, y, 0.0);
        Accel::new(Mesh {
            positions: vec![p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)],
            normals: None,
            indices: vec![[0, 1, 2], [0, 2, 3]],
        })
    }

    fn medium(eta: f32, roughness: f32) -> Medium {
        Medium {
            sigma_t: [10.0; 3],
            albedo: [0.9; 3],
            g: scene::Anisotropy::uniform(0.0),
            eta,
            roughness,
        }
    }

    #[test]
    fn only_a_rough_refractive_boundary_reflects() {
        assert!(Surface::of(&medium(1.0, 0.0)).is_none());
        assert!(Surface::of(&medium(1.5, 0.0)).is_none());
        assert!(Surface::of(&medium(1.5, 0.3)).is_some());
    }

    /// A square in z = 0 facing +z, a camera ray straight down onto its centre and a light
    /// at 45°: the value is Walter et al.'s f_r·cos θ_l / r² written out here.
    #[test]
    fn the_reflection_is_the_microfacet_brdf_towards_the_light() {
        let accel = square();
        let (eta, alpha) = (1.5f32, 0.3f32);
        let s = Surface::of(&medium(eta, alpha)).unwrap();
        let d = Vec3::NEG_Z;
        let hit = accel
            .closest(Vec3::new(0.0, 0.0, 2.0), d, 0.0, 10.0)
            .unwrap();
        let light = PointLight {
            position: Vec3::new(2.0, 0.0, 2.0),
            intensity: [1.0; 3],
        };
        let got = s.reflection(&accel, &light, &hit, d);

        let wi = Vec3::Z;
        let r2 = 8.0f32;
        let wl = Vec3::new(1.0, 0.0, 1.0).normalize();
        let h = (wi + wl).normalize();
        let a2 = alpha * alpha;
        let dh = 1.0 / (std::f32::consts::PI * a2 * (h.x * h.x / a2 + h.z * h.z).powi(2));
        let g1 = |v: Vec3| {
            let tan2 = (1.0 - v.z * v.z) / (v.z * v.z);
            2.0 / (1.0 + (1.0 + a2 * tan2).sqrt())
        };
        let f = base::fresnel::fresnel_dielectric(wi.dot(h), eta);
        let want = f * dh * g1(wi) * g1(wl) / (4.0 * wi.z * wl.z) * wl.z / r2;
        assert!((got - want).abs() < 1e-5 * want, "{got} vs {want}");

        // Behind the surface: nothing.
        let below = PointLight {
            position: Vec3::new(2.0, 0.0, -2.0),
            ..light
        };
        assert_eq!(s.reflection(&accel, &below, &hit, d), 0.0);
    }

    /// The table interpolates the quadrature, and the light side's factor is the ratio to the
    /// smooth boundary's transmittance.
    #[test]
    fn the_transmittance_table_follows_the_quadrature() {
        let s = Surface::of(&medium(1.5, 0.3)).unwrap();
        let b = RoughDielectric::new(1.5, 0.3);
        for mu in [0.05f32, 0.33, 0.5, 0.91, 1.0] {
            let (got, want) = (s.transmittance(mu), b.transmittance(mu, QUADRATURE));
            assert!((got - want).abs() < 2e-3, "μ {mu}: {got} against {want}");
            let ratio = s.light_side_factor(mu);
            assert!((ratio - got / transmittance(mu, 1.5)).abs() < 1e-6);
        }
        // Tilted microfacets face grazing light: more passes there, 1–3 % less near the normal
        // (at α 0.3, η 1.5: 1.67× at μ 0.1, 0.974× at μ 0.6).
        assert!(s.light_side_factor(0.1) > 1.5);
        assert!((0.95..0.99).contains(&s.light_side_factor(0.6)));
    }
}
