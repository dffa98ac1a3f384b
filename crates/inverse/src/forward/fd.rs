//! The `fd` estimator of the models without one of their own (the dipole and the volumetric
//! path tracer): central differences of full renders with common random numbers.
//!
//!   ∂I_c/∂σ_t,c ≈ (I_c(σ_t + Δ) − I_c(σ_t − Δ))/(2Δ_c),  Δ_c = δ·σ_t,c,
//!   ∂I_c/∂α_c ≈ (I_c(α + Δα) − I_c(α − Δα))/(2Δα_c),
//!
//! every channel's parameter moved at once: channel c's expectation depends only on channel c's
//! parameters, so the moves of the others add noise but no bias. Four renders besides the value,
//! each with the same seed, view and pixel streams as the value. Δα_c is reduced where needed to
//! keep α ± Δα_c in [0, 1). The truncation error is O(Δ²); the estimate is a reference, not a
//! fast estimator. It does not difference g (no ∂I/∂g images): a run that frees g renders with
//! `ad`.

use bssrdf::diff::{DiffImages, DiffSettings};
use scene::{Image, Medium};

use super::TracerEstimator;
use crate::error::InverseError;

/// The estimator of a model whose choices are `ad` (its own analytic derivatives) and `fd`,
/// with the steps of the latter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Differencing {
    pub estimator: TracerEstimator,
    /// Relative σ_t step of `fd`.
    pub delta_rel: f32,
    /// Albedo step of `fd`.
    pub delta_albedo: f32,
}

impl Differencing {
    /// The derivative images at `medium`: by `fd` from the renders `render`, otherwise by `ad`.
    pub fn derivatives(
        &self,
        medium: Medium,
        render: impl Fn(Medium) -> Result<Image, InverseError>,
        ad: impl FnOnce() -> Result<DiffImages, InverseError>,
    ) -> Result<DiffImages, InverseError> {
        match self.estimator {
            TracerEstimator::Fd => {
                central_differences(render, medium, self.delta_rel, self.delta_albedo)
            }
            TracerEstimator::Ad => ad(),
        }
    }
}

impl Default for Differencing {
    /// `ad`, with the learned renderer's steps for `fd`.
    fn default() -> Self {
        let d = DiffSettings::default();
        Differencing {
            estimator: TracerEstimator::Ad,
            delta_rel: d.delta_rel,
            delta_albedo: d.delta_albedo,
        }
    }
}

/// The largest albedo a perturbed render uses.
const ALBEDO_CEILING: f32 = 0.9999;

/// The value and central-difference derivative images of `render` at `medium` (module docs),
/// with relative σ_t step `delta_rel` and albedo step `delta_albedo`.
pub fn central_differences(
    render: impl Fn(Medium) -> Result<Image, InverseError>,
    medium: Medium,
    delta_rel: f32,
    delta_albedo: f32,
) -> Result<DiffImages, InverseError> {
    let value = render(medium)?;
    let h_sigma = medium.sigma_t.map(|s| delta_rel * s);
    let h_albedo = medium
        .albedo
        .map(|a| delta_albedo.min(a).min(ALBEDO_CEILING - a).max(0.0));
    let moved = |sign: f32, sigma: bool| {
        let mut m = medium;
        for c in 0..3 {
            if sigma {
                m.sigma_t[c] += sign * h_sigma[c];
            } else {
                m.albedo[c] += sign * h_albedo[c];
            }
        }
        m
    };
    let difference = |sigma: bool, h: [f32; 3]| -> Result<Image, InverseError> {
        let plus = render(moved(1.0, sigma))?;
        let minus = render(moved(-1.0, sigma))?;
        let mut out = Image::new(value.width, value.height);
        for ((o, p), m) in out.data.iter_mut().zip(&plus.data).zip(&minus.data) {
            for c in 0..3 {
                o[c] = if h[c] > 0.0 {
                    (p[c] - m[c]) / (2.0 * h[c])
                } else {
                    0.0
                };
            }
        }
        Ok(out)
    };
    Ok(DiffImages {
        d_sigma_t: difference(true, h_sigma)?,
        d_albedo: difference(false, h_albedo)?,
        d_g: None,
        value,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a render that is a known smooth function of the medium (pixel k, channel c:
    /// σ_t,c²·(k + 1) + α_c³), the differences are its derivatives up to the O(Δ²) truncation:
    /// exact for the quadratic, 2Δα² for the cubic; and the albedo step shrinks at the edge.
    #[test]
    fn differences_of_a_known_function() {
        let render = |m: Medium| -> Result<Image, InverseError> {
            let mut img = Image::new(2, 1);
            for (k, px) in img.data.iter_mut().enumerate() {
                *px = std::array::from_fn(|c| {
                    m.sigma_t[c].powi(2) * (k as f32 + 1.0) + m.albedo[c].powi(3)
                });
            }
            Ok(img)
        };
        let m = Medium {
            sigma_t: [10.0, 20.0, 40.0],
            albedo: [0.5, 0.9, 0.995],
            g: scene::Anisotropy::uniform(0.0),
            eta: 1.0,
            roughness: 0.0,
        };
        let d = central_differences(render, m, 0.02, 0.01).unwrap();
        for k in 0..2 {
            for c in 0..3 {
                let want = 2.0 * m.sigma_t[c] * (k as f32 + 1.0);
                let got = d.d_sigma_t.data[k][c];
                assert!((got - want).abs() < 2e-3 * want, "{got} vs {want}");
                let h = 0.01f32.min(ALBEDO_CEILING - m.albedo[c]);
                let want = 3.0 * m.albedo[c].powi(2) + h * h;
                let got = d.d_albedo.data[k][c];
                assert!((got - want).abs() < 0.05, "α_{c}: {got} vs {want}");
            }
        }
        assert_eq!(d.value, render(m).unwrap());
    }
}
