//! Stage 3 of the learned renderer: the entry point x_i of a sample and the light term there.
//! x̃ = x_o + σ_n·R·y is projected onto the mesh (Π, [`crate::projection`], along the gradient of
//! the sample's polynomial), and the light is evaluated at the hit:
//!
//!   L = D(w_l) · (A/N) · max(0, n_i·w_l) · V / r²,
//!
//! D the light-side exit law ([`crate::exit`]), A/N the light-side incidence factor
//! ([`crate::incidence`]), V the visibility of the point light; with
//! [`LightCurvature::Ball`] times the curvature correction C at the camera point
//! ([`crate::curvature`]). The offset samples of
//! [`crate::diff`] call the same functions with σ_n(θ ± Δ) and σ_t ± Δ.

use geometry::bvh::offset_origin;
use glam::Vec3;

use super::{LearnedScene, Pending, ViewRays};
use crate::nn::POSITION_DIM;
use crate::projection::project;
use base::boundary::sw;

/// Whether the light's direction of incidence moves the light around its entry point
/// ([`crate::incidence`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum Incidence {
    /// Light entering obliquely leaves mostly ahead of its entry point (default).
    ///
    /// The half-space factor A(α; μ_l, ρ, ψ) of [`crate::incidence`].
    #[default]
    Directional,
    /// No dependence on the light's azimuth, as Vicini et al. 2019 and Son et al. 2024.
    ///
    /// No factor (A = 1): the light side is isotropic in azimuth, as in VKJ19 and SON24.
    Isotropic,
}

impl Incidence {
    /// The value of a settings file without the field (written before the factor existed).
    pub(super) fn absent() -> Self {
        Incidence::Isotropic
    }
}

/// Whether the light term is corrected for the curvature at the camera point
/// ([`crate::curvature`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum LightCurvature {
    /// No correction: the half-space light side.
    ///
    /// The light term as on a plane, whatever the curvature at the camera point.
    None,
    /// Corrected by walks in balls of the surface's curvature (default).
    ///
    /// C = exact/model of index-matched balls of the medium's g
    /// ([`crate::curvature::CurvatureTable::for_medium`]), also behind a rough boundary; none
    /// behind a smooth dielectric one.
    #[default]
    Ball,
}

impl LightCurvature {
    /// The value of a settings file without the field (written before the correction existed).
    pub(super) fn absent() -> Self {
        LightCurvature::None
    }
}

impl LearnedScene<'_> {
    /// The light-side exit law D(w_l) per steradian-cosine and ∂D/∂α_c for channel `c`, camera
    /// cosine `mu_cam` and light cosine `cos_l`: f(α_c; μ_cam, cos_l)/π ([`crate::exit`]) or
    /// the cosine law's Sw(w_l) (docs/model.md §1; no α dependence).
    #[inline]
    pub(crate) fn exit_law(&self, c: usize, mu_cam: f32, cos_l: f32) -> (f32, f32) {
        match &self.exit {
            Some(slices) => {
                let (f, df) = slices[c].eval(mu_cam, cos_l);
                (
                    f * std::f32::consts::FRAC_1_PI,
                    df * std::f32::consts::FRAC_1_PI,
                )
            }
            None => (sw(cos_l, self.medium.eta), 0.0),
        }
    }

    /// The light side's change by a rough boundary ([`super::surface`]) and its α-derivative:
    /// with the half-space exit law the ratio E_rough(μ_cam)/E_smooth(μ_cam) of the energy that
    /// escapes half-space walks through the rough and through the smooth boundary (the exit law
    /// itself is the rough walks'); with the cosine law T(μ_l)/(1 − F(μ_l)); (1, 0) for a smooth
    /// or index-matched boundary.
    #[inline]
    pub(crate) fn rough_light_side(&self, p: &Pending, cos_l: f32) -> (f32, f32) {
        match (&self.escape, &self.surface) {
            (Some(e), _) => {
                let (rough, smooth) = &e[p.channel as usize];
                let ((er, der), (es, des)) = (rough.eval(p.mu_cam), smooth.eval(p.mu_cam));
                if es <= 0.0 {
                    return (1.0, 0.0);
                }
                (er / es, (der * es - er * des) / (es * es))
            }
            (None, Some(s)) => (s.light_side_factor(cos_l), 0.0),
            (None, None) => (1.0, 0.0),
        }
    }

    /// The normalised incidence factor A/N and its α-derivative ([`crate::incidence`]) for
    /// light entering at x_i (shading normal n_i, unit direction w_l to the light, cosine μ_l)
    /// and leaving at the camera point of sample `p`, at extinction `sigma_t`; (1, 0) with
    /// [`Incidence::Isotropic`].
    #[inline]
    pub(crate) fn incidence_factor(
        &self,
        p: &Pending,
        light_side: (Vec3, Vec3, Vec3, f32),
        sigma_t: f32,
    ) -> (f32, f32) {
        match &self.incidence {
            Some(slices) => slices[p.channel as usize].at_points(
                light_side,
                (p.x_o, p.mu_cam, p.cam_fwd),
                sigma_t,
            ),
            None => (1.0, 0.0),
        }
    }
}

impl LearnedScene<'_> {
    /// The curvature correction C and ∂C/∂α ([`crate::curvature`]) of sample `p` for its view's
    /// light at extinction `sigma_t`: the table at the camera point's coordinates
    /// (`Pending::curv`) and the mean curvature of the sample's fitted cubic at x_o
    /// (`Pending::kappa`), both taken once per camera sample, in units of 1/σ_t; (1, 0) without
    /// [`LightCurvature::Ball`].
    #[inline]
    pub(crate) fn curvature_factor(&self, p: &Pending, sigma_t: f32) -> (f32, f32) {
        match &self.curvature {
            Some(slices) => slices[p.channel as usize].eval_coords(&p.curv, p.kappa / sigma_t),
            None => (1.0, 0.0),
        }
    }
}

/// The (unnormalised, detached) projection direction and the side value at the proposed point
/// `x_t` of sample `p` (docs/model.md A5): the gradient and value of the fixed interpolated
/// polynomial at `(x_t − x_o)/σ_n,fit`, or (n_o, 1) with planar features.
#[inline]
pub(crate) fn projection_gradient(scene: &LearnedScene, p: &Pending, x_t: Vec3) -> (Vec3, f32) {
    if scene.settings.planar_features {
        (p.n_o, 1.0)
    } else {
        let (value, grad) = p
            .poly
            .eval_with_gradient((x_t - p.x_o) / scene.features.sigma_n[p.channel as usize]);
        (grad, value)
    }
}

/// x̃ = x_o + σ_n·(y₁e₁ + y₂e₂ + y₃e₃) and x_i = Π(x̃) for the decoder output `y` at the kernel
/// scale `sigma_n` (the offset samples of [`crate::diff`] call this with σ_n(θ ± Δ)).
#[inline]
pub(crate) fn place_and_project(
    scene: &LearnedScene,
    p: &Pending,
    y: [f32; POSITION_DIM],
    sigma_n: f32,
) -> Option<geometry::Hit> {
    // A walk sampler's sample without an escaping walk (`render::walks`).
    if y[0].is_nan() {
        return None;
    }
    let x_t = proposed_point(p, y, sigma_n);
    let (grad, value) = projection_gradient(scene, p, x_t);
    project(
        scene.accel,
        scene.settings.projection,
        x_t,
        grad,
        value,
        sigma_n,
    )
}

/// x̃ = x_o + σ_n·R·y.
#[inline]
pub(crate) fn proposed_point(p: &Pending, y: [f32; POSITION_DIM], sigma_n: f32) -> Vec3 {
    p.x_o + sigma_n * p.out_frame.to_world(Vec3::new(y[0], y[1], y[2]))
}

/// L = D(w_l) · A · max(0, n_i·w_l) · V / r² at the entry point `hit` of sample `p` (without
/// the intensity) and ∂L/∂α of the sample's channel; D is the exit law
/// ([`LearnedScene::exit_law`]), A the incidence factor ([`LearnedScene::incidence_factor`]) at
/// extinction `sigma_t` (the σ_t the sample was placed with: the offset samples of
/// [`crate::diff`] pass σ_t ± Δ).
#[inline]
pub(crate) fn light_contribution(
    scene: &LearnedScene,
    view: &ViewRays,
    p: &Pending,
    hit: &geometry::Hit,
    sigma_t: f32,
) -> (f32, f32) {
    let (x_i, n_i, ng) = (hit.p, hit.ns, hit.ng);
    let to_l = view.light.position - x_i;
    let r2 = to_l.length_squared();
    if r2 <= 0.0 {
        return (0.0, 0.0);
    }
    let r = r2.sqrt();
    let dir = to_l / r;
    let cos_l = n_i.dot(dir);
    if cos_l <= 0.0 || ng.dot(dir) <= 0.0 {
        return (0.0, 0.0);
    }
    // Leaving through a supporting plane (`Accel::exit_is_final`; ng·dir > 0 here) the shadow
    // ray moves into a half-space that holds no part of the mesh: nothing can occlude it.
    if !scene.accel.exit_is_final(hit.tri)
        && scene
            .accel
            .occluded(offset_origin(x_i, ng, dir), dir, 0.0, r)
    {
        return (0.0, 0.0);
    }
    let (d, dd) = scene.exit_law(p.channel as usize, p.mu_cam, cos_l);
    let (a, da) = scene.incidence_factor(p, (x_i, n_i, dir, cos_l), sigma_t);
    let g = cos_l / r2;
    let (v, dv) = ((d * a) * g, (dd * a + d * da) * g);
    let (k, dk) = scene.curvature_factor(p, sigma_t);
    let (v, dv) = (v * k, dv * k + v * dk);
    let (s, ds) = scene.rough_light_side(p, cos_l);
    (v * s, dv * s + v * ds)
}

#[cfg(test)]
mod tests {
    use super::super::LearnedSettings;
    use super::Incidence;

    /// New settings use the directional factor; settings files written before it existed (no
    /// `incidence` field: checkpoints, result files, the experiment's run records) read as
    /// isotropic, which is how they were rendered.
    #[test]
    fn settings_without_the_field_are_isotropic() {
        assert_eq!(LearnedSettings::default().incidence, Incidence::Directional);
        let old: LearnedSettings =
            serde_json::from_str(r#"{"exit": "half-space", "planar_features": false}"#).unwrap();
        assert_eq!(old.incidence, Incidence::Isotropic);
        let new: LearnedSettings =
            serde_json::from_str(&serde_json::to_string(&LearnedSettings::default()).unwrap())
                .unwrap();
        assert_eq!(new.incidence, Incidence::Directional);
    }

    /// The same for the curvature correction: on by default, off in files written before it.
    #[test]
    fn settings_without_the_curvature_field_are_uncorrected() {
        use super::LightCurvature;
        assert_eq!(
            LearnedSettings::default().light_curvature,
            LightCurvature::Ball
        );
        let old: LearnedSettings =
            serde_json::from_str(r#"{"exit": "half-space", "incidence": "directional"}"#).unwrap();
        assert_eq!(old.light_curvature, LightCurvature::None);
        let new: LearnedSettings =
            serde_json::from_str(&serde_json::to_string(&LearnedSettings::default()).unwrap())
                .unwrap();
        assert_eq!(new.light_curvature, LightCurvature::Ball);
    }
}
