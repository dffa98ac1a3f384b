//! The run's 95 % intervals at its current parameters ([`Optimizer::uncertainty`]): two
//! independent derivative renders of evenly spread views through the run's forward model, and
//! the spread and drift of the last iterates ([`crate::uncertainty`]).

use base::rng::hash_key;
use bssrdf::render::RenderSettings;

use super::{InverseError, Optimizer};
use crate::forward::MediumRenderer;
use crate::params::OneOrRgb;
use crate::uncertainty::joint::{self, JointAccumulator, Shared};
use crate::uncertainty::{
    Accumulator, SharedUncertainty, Uncertainty, UncertaintySettings, ViewRenders, add_covariances,
    iterate_covariance, iterate_drift,
};
use bssrdf::diff::DiffImages;
use geometry::Accel;
use scene::{Camera, Image, PointLight};
use volpath::VolpathSettings;

use crate::forward::fd::Differencing;
use crate::forward::volpath::Volpath;
use crate::forward::{ForwardModel, TracerEstimator};

impl Optimizer<'_> {
    /// The uncertainty of the current parameters from the target images
    /// ([`crate::uncertainty`]): two independent derivative renders of `s.views` views spread
    /// evenly over the targets, at `s.spp`, plus the spread and drift of the last iterates. Parameters the
    /// run keeps fixed get no interval.
    ///
    /// `capture`: δI of each draw of a stated capture error, per interval view
    /// ([`Optimizer::capture_deltas`]), added as C_capture ([`crate::uncertainty::capture`]);
    /// empty for none.
    pub fn uncertainty(
        &self,
        s: &UncertaintySettings,
        capture: &[Vec<Image>],
    ) -> Result<Uncertainty, InverseError> {
        let c = &self.config;
        let p = self.params();
        let at = self.forward.at(p.medium(&self.base))?;
        let n = self.targets.len();
        let k = s.views.clamp(1, n);
        if let Some(d) = capture.iter().find(|d| d.len() != k) {
            return Err(InverseError::Invalid(format!(
                "a capture error's draw has {} images for {k} interval views",
                d.len()
            )));
        }
        let mut acc = Accumulator::default();
        // With a free g or light scale, the sandwich over all variables at once ([`joint`]).
        let shared = self.shared_params();
        let mut acc_joint = (!shared.is_empty()).then(|| JointAccumulator::new(shared.clone()));
        for (i, v) in self.interval_views(s).into_iter().enumerate() {
            let t = &self.targets[v];
            let (a, b) = derivative_pair(at.as_ref(), t.camera, &p.light(t.light), s, c.seed, v)?;
            let renders = ViewRenders {
                value: [&a.value, &b.value],
                d_sigma_t: [&a.d_sigma_t, &b.d_sigma_t],
                d_albedo: [&a.d_albedo, &b.d_albedo],
                target: t.image,
            };
            acc.add_view(&renders, p.sigma_t);
            for (draw, deltas) in capture.iter().enumerate() {
                acc.add_capture(draw, &renders, &deltas[i], p.sigma_t);
            }
            if let Some(j) = acc_joint.as_mut() {
                let d_shared = shared_derivatives(&shared, &a, &b)?;
                j.add_view(&renders, &d_shared, p.sigma_t);
                for (draw, deltas) in capture.iter().enumerate() {
                    j.add_capture(draw, &renders, &d_shared, &deltas[i], p.sigma_t);
                }
            }
        }
        let tail = ((self.history.len() as f64 * s.tail_fraction).ceil() as usize)
            .clamp(2.min(self.history.len()), self.history.len());
        let iterates: Vec<([f64; 3], [f64; 3])> = self.history[self.history.len() - tail..]
            .iter()
            .map(|r| (r.params.sigma_t, r.params.albedo))
            .chain(std::iter::once((p.sigma_t, p.albedo)))
            .collect();
        let (walk, drift) = (iterate_covariance(&iterates), iterate_drift(&iterates));
        let spread: [[f64; 3]; 3] =
            std::array::from_fn(|c| std::array::from_fn(|k| walk[c][k] + drift[c][k]));
        let fixed = [c.params.fix_sigma_t, c.params.fix_albedo];
        let (cov, images, shared_var) = match &acc_joint {
            None => (
                add_covariances(acc.covariance_fixed(s.model_brightness_sd, fixed), spread),
                add_covariances(acc.covariance_fixed(0.0, fixed), spread),
                None,
            ),
            Some(j) => {
                let iterates: Vec<_> = self.history[self.history.len() - tail..]
                    .iter()
                    .map(|r| r.params)
                    .chain(std::iter::once(p))
                    .collect();
                let (cov, images, shared_var) = joint_parts(j, &shared, &iterates, s, fixed);
                (cov, images, Some(shared_var))
            }
        };
        let mut u = Uncertainty::new(p.sigma_t, p.albedo, cov, images, k);
        let (mut gs, mut scales) = (Vec::new(), Vec::new());
        for (s, var, images_var) in shared_var.into_iter().flatten() {
            match s {
                Shared::G(ch) => {
                    let g = p.g_or(self.base.g).channels()[ch.unwrap_or(0)] as f64;
                    gs.push(SharedUncertainty::g(g, var, images_var));
                }
                Shared::LnLightScale(ch) => {
                    let k = p.light_scale_of(ch.unwrap_or(0));
                    scales.push(SharedUncertainty::light_scale(k, var, images_var));
                }
            }
        }
        let one_or_rgb = |v: Vec<SharedUncertainty>| match v[..] {
            [one] => Some(OneOrRgb::One(one)),
            [r, g, b] => Some(OneOrRgb::Rgb([r, g, b])),
            _ => None,
        };
        u.g = one_or_rgb(gs);
        u.light_scale = one_or_rgb(scales);
        u.view_bread = (0..k)
            .map(|i| i * n / k)
            .zip(acc.view_breads().iter().copied())
            .collect();
        u.fixed = fixed;
        u.optimiser = spread;
        u.mesh_error = s.mesh_error.filter(|_| !capture.is_empty());
        if c.params.fix_sigma_t {
            u.sigma_t = [None; 3];
            u.sd_ln_sigma_t = [None; 3];
            u.determined_sigma_t = [false; 3];
        }
        if c.params.fix_albedo {
            u.albedo = [None; 3];
            u.sd_albedo = [None; 3];
            u.determined_albedo = [false; 3];
        }
        Ok(u)
    }

    /// The parameters besides σ_t and α that the run frees (g and ln k, each one or per
    /// channel), in the joint sandwich's order.
    fn shared_params(&self) -> Vec<Shared> {
        let per = |n: usize, of: fn(Option<usize>) -> Shared| -> Vec<Shared> {
            match n {
                0 => vec![],
                1 => vec![of(None)],
                _ => (0..3).map(|c| of(Some(c))).collect(),
            }
        };
        let spec = &self.config.params;
        let mut shared = per(spec.g_count(), Shared::G);
        shared.extend(per(spec.light_scale_count(), Shared::LnLightScale));
        shared
    }

    /// The targets whose renders the intervals take ([`Optimizer::uncertainty`]): `s.views`
    /// spread evenly over them (all when there are fewer).
    pub fn interval_views(&self, s: &UncertaintySettings) -> Vec<usize> {
        let n = self.targets.len();
        let k = s.views.clamp(1, n);
        (0..k).map(|i| i * n / k).collect()
    }

    /// δI of each draw of a stated capture error at the current parameters
    /// ([`crate::uncertainty::capture`]): per interval view ([`Optimizer::interval_views`]), the
    /// volumetric path tracer's image of the scene on each mesh of `perturbed` minus its image
    /// on the run's own mesh, both from the same random numbers, at `s.spp`; `[draw][view]`.
    /// The tracer renders them whatever the run's model: δI is the physics' response to the
    /// error, to which the run's own derivatives are then applied.
    pub fn capture_deltas(
        &self,
        s: &UncertaintySettings,
        perturbed: &[&Accel],
    ) -> Result<Vec<Vec<Image>>, InverseError> {
        let p = self.params();
        let medium = p.medium(&self.base);
        let settings = VolpathSettings {
            max_depth: self.config.tracer_depth(),
            ..VolpathSettings::default()
        };
        let estimator = Differencing {
            estimator: TracerEstimator::Ad,
            delta_rel: self.config.delta_rel,
            delta_albedo: 0.0,
        };
        let reference = Volpath::new(self.accel, settings, estimator);
        let models: Vec<Volpath> = perturbed
            .iter()
            .map(|a| Volpath::new(a, settings, estimator))
            .collect();
        let at_ref = reference.at(medium)?;
        let ats = models
            .iter()
            .map(|m| m.at(medium))
            .collect::<Result<Vec<_>, _>>()?;
        let views = self.interval_views(s);
        let mut deltas = vec![Vec::with_capacity(views.len()); perturbed.len()];
        for &v in &views {
            let t = &self.targets[v];
            let light = p.light(t.light);
            let rs = RenderSettings {
                spp: s.spp.max(1),
                seed: hash_key(&[self.config.seed, 0xCA97_0000]),
                view: v as u64,
            };
            let base = at_ref.view(t.camera, &light).value(&rs, None)?;
            for (at, d) in ats.iter().zip(&mut deltas) {
                let mut img = at.view(t.camera, &light).value(&rs, None)?;
                for (x, b) in img.data.iter_mut().zip(&base.data) {
                    *x = [0, 1, 2].map(|c| x[c] - b[c]);
                }
                d.push(img);
            }
        }
        Ok(deltas)
    }

    /// The Gauss–Newton A (per channel, [a00, a01, a11] in (ln σ_t, α)) that a view which was
    /// not captured would add: `camera` and `light` (its stated intensity; the run's light scale
    /// applies) rendered at the current parameters by the run's final model, two independent
    /// derivative renders at `s.spp` as for the intervals' own views ([`crate::uncertainty`]).
    /// `key` tells such views apart in the renders' seeds.
    pub fn candidate_bread(
        &self,
        camera: &Camera,
        light: &PointLight,
        s: &UncertaintySettings,
        key: usize,
    ) -> Result<[[f64; 3]; 3], InverseError> {
        let p = self.params();
        let at = self.forward.at(p.medium(&self.base))?;
        let key = self.targets.len() + key;
        let (a, b) = derivative_pair(
            at.as_ref(),
            camera,
            &p.light(light),
            s,
            self.config.seed,
            key,
        )?;
        let mut acc = Accumulator::default();
        acc.add_view(
            &ViewRenders {
                value: [&a.value, &b.value],
                d_sigma_t: [&a.d_sigma_t, &b.d_sigma_t],
                d_albedo: [&a.d_albedo, &b.d_albedo],
                // The bread does not depend on the target.
                target: &a.value,
            },
            p.sigma_t,
        );
        Ok(acc.view_breads()[0])
    }
}

/// The derivative images of the shared parameters `shared` in the two renders `a`, `b`.
fn shared_derivatives<'r>(
    shared: &[Shared],
    a: &'r DiffImages,
    b: &'r DiffImages,
) -> Result<Vec<[&'r Image; 2]>, InverseError> {
    shared
        .iter()
        .map(|s| match s {
            // Channel c's ∂I_c/∂g_c: of the one g, or of g_c alone (`JointAccumulator::add_view`).
            Shared::G(_) => match (&a.d_g, &b.d_g) {
                (Some(ga), Some(gb)) => Ok([ga, gb]),
                _ => Err(InverseError::Invalid(
                    "the intervals of a free g need ∂I/∂g, which the run's final model does \
                     not render"
                        .into(),
                )),
            },
            // The images are linear in k: ∂I/∂ln k = I (in k_c's channel alone for one factor
            // per channel, `JointAccumulator::add_view`).
            Shared::LnLightScale(_) => Ok([&a.value, &b.value]),
        })
        .collect()
}

/// Two independent derivative renders of one view (index `view` in the seeds) at `s.spp`.
fn derivative_pair(
    at: &dyn MediumRenderer,
    camera: &Camera,
    light: &PointLight,
    s: &UncertaintySettings,
    seed: u64,
    view: usize,
) -> Result<(DiffImages, DiffImages), InverseError> {
    let prepared = at.view(camera, light);
    let render = |stream: u64| {
        let rs = RenderSettings {
            spp: s.spp.max(1),
            seed: hash_key(&[seed, 0x5A4D_0000, stream]),
            view: view as u64,
        };
        prepared.derivatives(&rs, None)
    };
    Ok((render(1)?, render(2)?))
}

/// The per-channel covariances (with and without the model's error) and, per shared parameter,
/// its two variances.
type JointParts = (
    [Option<[f64; 3]>; 3],
    [Option<[f64; 3]>; 3],
    Vec<(Shared, Option<f64>, Option<f64>)>,
);

/// Per channel, the (ln σ_t, α) blocks of the joint sandwich plus the iterates' spread and
/// drift: with the model's brightness error and from the images alone; and each shared
/// parameter's two variances likewise.
fn joint_parts(
    j: &JointAccumulator,
    shared: &[Shared],
    iterates: &[crate::params::Params],
    s: &UncertaintySettings,
    fixed: [bool; 2],
) -> JointParts {
    let spread =
        joint::iterate_covariance(iterates, shared) + joint::iterate_drift(iterates, shared);
    let part = |sd: f64| {
        j.covariance(sd, fixed)
            .map(|m| joint::blocks(&(m + &spread)))
    };
    let (all, img) = (part(s.model_brightness_sd), part(0.0));
    let var = |x: &Option<([[f64; 3]; 3], Vec<f64>)>, i: usize| x.as_ref().map(|x| x.1[i]);
    let shared_var = shared
        .iter()
        .enumerate()
        .map(|(i, sh)| (*sh, var(&all, i), var(&img, i)))
        .collect();
    (
        all.map_or([None; 3], |x| x.0.map(Some)),
        img.map_or([None; 3], |x| x.0.map(Some)),
        shared_var,
    )
}
