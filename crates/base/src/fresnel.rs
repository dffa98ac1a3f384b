//! Smooth dielectric interface: exact unpolarised Fresnel reflectance, specular reflection and
//! Snell refraction (pbrt-v4 §9.5). `eta` is the relative index n_t / n_i of the side the light
//! goes INTO over the side it comes from. Note the model spec's warning: the SON24/DLW22 helper
//! squares where a square root is needed; this one does not.

use glam::Vec3;

/// Unpolarised Fresnel reflectance for incident cosine `cos_i` ∈ [0, 1] (measured on the
/// incident side) and relative index `eta` = n_t/n_i. Returns 1 under total internal reflection.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Mirror `d` (propagation direction) about the plane with normal `n`.
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Refract propagation direction `d` through the interface with unit normal `n` (either side),
/// relative index `eta` = n_t/n_i. `None` under total internal reflection.
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    // Orient the normal against the incoming direction.
    let (n, cos_i) = if d.dot(n) < 0.0 {
        (n, -d.dot(n))
    } else {
        (-n, d.dot(n))
    };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d / eta + (cos_i / eta - cos_t) * n).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_and_limits() {
        // ((η − 1)/(η + 1))² at normal incidence.
        let f = fresnel_dielectric(1.0, 1.5);
        assert!((f - 0.04).abs() < 1e-6, "{f}");
        assert_eq!(fresnel_dielectric(0.9, 1.0), 0.0);
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        // Total internal reflection beyond the critical angle (sin θc = 1/1.5).
        let cos_c = (1.0f32 - 1.0 / 2.25).sqrt();
        assert_eq!(fresnel_dielectric(cos_c - 0.01, 1.0 / 1.5), 1.0);
        assert!(fresnel_dielectric(cos_c + 0.01, 1.0 / 1.5) < 1.0);
    }

    #[test]
    fn reciprocity_of_transmittance() {
        // 1 − F is the same seen from either side along a refracted pair of directions.
        for k in 1..20 {
            let cos_i = k as f32 / 20.0;
            let sin_t = (1.0 - cos_i * cos_i).sqrt() / 1.33;
            let cos_t = (1.0 - sin_t * sin_t).sqrt();
            let a = fresnel_dielectric(cos_i, 1.33);
            let b = fresnel_dielectric(cos_t, 1.0 / 1.33);
            assert!((a - b).abs() < 1e-5, "{a} {b}");
        }
    }

    #[test]
    fn snell_law_holds() {
        let n = Vec3::Z;
        let d = Vec3::new(0.6, 0.0, -0.8);
        let t = refract(d, n, 1.5).unwrap();
        let sin_i = 0.6f32;
        let sin_t = (t.x * t.x + t.y * t.y).sqrt();
        assert!((sin_i - 1.5 * sin_t).abs() < 1e-6);
        assert!(t.z < 0.0);
        // From inside at a grazing angle: TIR.
        assert!(refract(Vec3::new(0.9, 0.0, 0.43589).normalize(), n, 1.0 / 1.5).is_none());
        assert_eq!(reflect(d, n), Vec3::new(0.6, 0.0, 0.8));
    }
}
