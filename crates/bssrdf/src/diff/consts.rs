//! Per-render constants of the derivative estimators: the offset scales σ_n(σ_t ± Δ) and
//! σ_n(α ± Δα) with their descriptor scales k = σ_n/σ_n,fit (Son et al. 2024, eq. 15–17; the
//! descriptor follows σ_n, docs/notes/recovery-recipe.md, "The descriptor follows σ_n"),
//! ∂σ_n/∂σ_t and the albedo input's derivative for `naive`, and the two perturbed scenes per
//! parameter for `fd`.

use scene::setting::Setting;

use super::*;

/// Per-render constants of the estimators.
pub(super) struct Consts<'a> {
    /// σ_n(σ_t ± Δ) per channel.
    pub(super) sn_t: [[f32; 2]; 3],
    /// σ_t ± Δ per channel (the incidence factor of the offset samples).
    pub(super) st_t: [[f32; 2]; 3],
    /// Descriptor scale k(σ_t ± Δ) per channel.
    pub(super) k_t: [[f32; 2]; 3],
    /// Descriptor scale k(α ± Δα) per channel.
    pub(super) k_a: [[f32; 2]; 3],
    /// The descriptor follows σ_n (not frozen, not planar): offset samples re-run the networks.
    pub(super) moving: bool,
    /// 1/(2Δ) per channel.
    pub(super) inv_2dt: [f32; 3],
    /// σ_n(α ± Δα) per channel.
    pub(super) sn_a: [[f32; 2]; 3],
    /// 1/(2Δα) per channel.
    pub(super) inv_2da: [f32; 3],
    /// ∂σ_n/∂σ_t per channel (Naive).
    pub(super) dsn_dt: [f32; 3],
    /// d input₂₀/dα = d input₂₀/dα' · dα'/dα per channel.
    pub(super) din_da: [f32; 3],
    /// Fd: (scene at θ + Δ, scene at θ − Δ, 1/(2Δ)) for σ_t,R..B then α_R..B.
    pub(super) fd: Vec<(LearnedScene<'a>, LearnedScene<'a>, f64)>,
    /// OursAlphaOffsets: per channel c, the scenes at α_c + Δα and α_c − Δα (network inputs,
    /// σ_n, descriptor scale and light-side tables of channel c at the offset albedo).
    pub(super) alpha: Vec<[LearnedScene<'a>; 2]>,
}

impl<'a> Consts<'a> {
    pub(super) fn new(scene: &LearnedScene<'a>, ds: &DiffSettings) -> Result<Self, RenderError> {
        let m = &scene.medium;
        if ds.estimator == Estimator::Naive && scene.settings.entry == EntrySampler::Walks {
            return Err(RenderError::Medium(format!(
                "the naive estimator differentiates the decoder's output and needs the decoder; \
                 use {} decoder with {} naive",
                Setting::EntrySampler,
                Setting::Estimator
            )));
        }
        let norm = scene.model.normalisation();
        let mut c = Consts {
            sn_t: [[0.0; 2]; 3],
            st_t: [[0.0; 2]; 3],
            k_t: [[1.0; 2]; 3],
            k_a: [[1.0; 2]; 3],
            moving: !(scene.settings.frozen_descriptor || scene.settings.planar_features),
            inv_2dt: [0.0; 3],
            sn_a: [[0.0; 2]; 3],
            inv_2da: [0.0; 3],
            dsn_dt: [0.0; 3],
            din_da: [0.0; 3],
            fd: Vec::new(),
            alpha: Vec::new(),
        };
        let mut steps_t = [0.0f64; 3];
        let mut steps_a = [0.0f64; 3];
        for ch in 0..3 {
            let (st, al) = (m.sigma_t[ch] as f64, m.albedo[ch] as f64);
            let g = m.g.channels()[ch] as f64;
            let dt = ds.delta_rel as f64 * st;
            if !(dt > 0.0 && dt < st) {
                return Err(RenderError::Medium(format!(
                    "σ_t step {dt} must lie in (0, σ_t = {st})"
                )));
            }
            let da = (ds.delta_albedo as f64).min(al).min(1.0 - al);
            steps_t[ch] = dt;
            steps_a[ch] = da;
            c.sn_t[ch] = [
                ReducedMedium::new(st + dt, al, g).sigma_n() as f32,
                ReducedMedium::new(st - dt, al, g).sigma_n() as f32,
            ];
            c.st_t[ch] = [(st + dt) as f32, (st - dt) as f32];
            c.inv_2dt[ch] = (0.5 / dt) as f32;
            if da > 0.0 {
                c.sn_a[ch] = [
                    ReducedMedium::new(st, al + da, g).sigma_n() as f32,
                    ReducedMedium::new(st, al - da, g).sigma_n() as f32,
                ];
                c.inv_2da[ch] = (0.5 / da) as f32;
            } else if matches!(ds.estimator, Estimator::OursAlphaOffsets | Estimator::Fd) {
                return Err(RenderError::Medium(format!(
                    "α = {al} leaves no room for a central α step"
                )));
            }
            c.dsn_dt[ch] = sigma_n_derivatives(st, al, g).0 as f32;
            let r = ReducedMedium::new(st, al, g);
            c.din_da[ch] =
                (norm.d_albedo_input_d_albedo_red(r.albedo_red) * r.d_albedo_red_d_albedo()) as f32;
        }
        for j in 0..2 {
            let kt = scene.descriptor_scale_at(std::array::from_fn(|ch| c.sn_t[ch][j]));
            let ka = scene.descriptor_scale_at(std::array::from_fn(|ch| c.sn_a[ch][j]));
            for ch in 0..3 {
                c.k_t[ch][j] = kt[ch];
                c.k_a[ch][j] = ka[ch];
            }
        }
        if ds.estimator == Estimator::OursAlphaOffsets {
            c.alpha_offsets(scene, steps_a)?;
        }
        if ds.estimator == Estimator::Fd {
            c.fd_scenes(scene, ds, steps_t, steps_a)?;
        }
        Ok(c)
    }

    /// `ours-alpha-offsets`: per channel c, the scenes at α_c ± Δα, with the step, σ_n and
    /// descriptor scale they actually have (the albedo rounded to f32).
    fn alpha_offsets(
        &mut self,
        scene: &LearnedScene<'a>,
        steps_a: [f64; 3],
    ) -> Result<(), RenderError> {
        for ch in 0..3 {
            let make = |sign: f64| {
                let mut med = scene.medium;
                med.albedo[ch] = (scene.medium.albedo[ch] as f64 + sign * steps_a[ch]) as f32;
                perturbed(scene, med)
            };
            let pair = [make(1.0)?, make(-1.0)?];
            // The actual f32 albedo difference.
            let diff = pair[0].medium.albedo[ch] as f64 - pair[1].medium.albedo[ch] as f64;
            self.inv_2da[ch] = (1.0 / diff) as f32;
            self.sn_a[ch] = [pair[0].sigma_n[ch], pair[1].sigma_n[ch]];
            self.k_a[ch] = [pair[0].descriptor_scale[ch], pair[1].descriptor_scale[ch]];
            self.alpha.push(pair);
        }
        Ok(())
    }

    /// `fd`: the scenes at θ ± Δ for σ_t,R..B then α_R..B, with 1/(2Δ) of the actual f32
    /// parameter difference.
    fn fd_scenes(
        &mut self,
        scene: &LearnedScene<'a>,
        ds: &DiffSettings,
        steps_t: [f64; 3],
        steps_a: [f64; 3],
    ) -> Result<(), RenderError> {
        let m = &scene.medium;
        for param in 0..6 {
            let ch = param % 3;
            let step = if param < 3 { steps_t[ch] } else { steps_a[ch] };
            let make = |sign: f64| -> Result<LearnedScene<'a>, RenderError> {
                let mut med = scene.medium;
                if param < 3 {
                    med.sigma_t[ch] = (m.sigma_t[ch] as f64 + sign * step) as f32;
                } else {
                    med.albedo[ch] = (m.albedo[ch] as f64 + sign * step) as f32;
                }
                let mut s = perturbed(scene, med)?;
                if ds.fd_fixed_sigma_n {
                    s.sigma_n = scene.sigma_n;
                    s.descriptor_scale = scene.descriptor_scale;
                }
                Ok(s)
            };
            // The actual f32 parameter difference (σ_t ± Δ is rounded to f32).
            let hi = make(1.0)?;
            let lo = make(-1.0)?;
            let diff = if param < 3 {
                hi.medium.sigma_t[ch] as f64 - lo.medium.sigma_t[ch] as f64
            } else {
                hi.medium.albedo[ch] as f64 - lo.medium.albedo[ch] as f64
            };
            self.fd.push((hi, lo, 1.0 / diff));
        }
        Ok(())
    }
}

/// `scene` with another medium (its features, model and settings).
fn perturbed<'a>(
    scene: &LearnedScene<'a>,
    med: scene::Medium,
) -> Result<LearnedScene<'a>, RenderError> {
    LearnedScene::new(
        scene.accel,
        scene.model,
        scene.features,
        med,
        scene.settings,
    )
}
