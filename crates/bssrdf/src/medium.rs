//! Medium parameters as the model sees them (docs/model.md §2): similarity-theory reduced
//! parameters, the effective-albedo remap, the kernel variance ε and the kernel scale σ_n, and the
//! network input normalisation ([`NormStats`], docs/model.md §4.1).
//!
//! Everything here is per colour channel and computed in `f64` (scalar, cheap, and the derivatives
//! are checked against finite differences).
//!
//! Reduced parameters (Wyman et al. 1989; docs/model.md §2):
//!
//! ```text
//! σ_s = α σ_t,  σ_a = σ_t − σ_s,  σ_s' = (1 − g) σ_s,  σ_t' = σ_s' + σ_a,  α' = σ_s'/σ_t'
//! ```
//!
//! so `σ_t' = σ_t (1 − gα)` and `α' = (1 − g) α / (1 − gα)` (independent of σ_t).

/// Errors of this module (invalid medium parameters or statistics input).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MediumError {
    /// σ_t must be finite and > 0.
    #[error("sigma_t must be a finite number > 0 (got {0})")]
    SigmaT(f64),
    /// α must lie in [0, 1].
    #[error("albedo must be in [0, 1] (got {0})")]
    Albedo(f64),
    /// g must lie in (−1, 1).
    #[error("anisotropy g must be in (-1, 1) (got {0})")]
    Anisotropy(f64),
    /// `NormStats::from_samples` needs at least one sample.
    #[error("cannot compute normalisation statistics from zero samples")]
    NoSamples,
    /// A statistics sample contained a NaN or infinite value.
    #[error("normalisation sample {index} contains a non-finite value")]
    NonFiniteSample { index: usize },
}

/// `1 − e^{−8}`, the constant of the effective-albedo curve (docs/model.md §2).
const ONE_MINUS_EXP_M8: f64 = 1.0 - 3.354_626_279_025_118_4e-4;

/// Effective albedo `α_eff(a) = −ln(1 − a(1 − e^{−8})) / 8` (docs/model.md §2); maps [0, 1] onto
/// [0, 1] monotonically. This is the albedo input of the networks (after normalisation).
#[inline]
pub fn effective_albedo(a: f64) -> f64 {
    -(-a * ONE_MINUS_EXP_M8).ln_1p() / 8.0
}

/// Inverse of [`effective_albedo`]: `a = (1 − e^{−8 α_eff}) / (1 − e^{−8})` (docs/model.md §2).
#[inline]
pub fn effective_albedo_inverse(a_eff: f64) -> f64 {
    -(-8.0 * a_eff).exp_m1() / ONE_MINUS_EXP_M8
}

/// `dα_eff/da = (1 − e^{−8}) / (8 (1 − a(1 − e^{−8})))`.
#[inline]
pub fn effective_albedo_derivative(a: f64) -> f64 {
    ONE_MINUS_EXP_M8 / (8.0 * (1.0 - a * ONE_MINUS_EXP_M8))
}

/// Reduced (similarity-theory) parameters of one channel (docs/model.md §2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReducedMedium {
    /// σ_t, extinction.
    pub sigma_t: f64,
    /// α, single-scattering albedo.
    pub albedo: f64,
    /// g, Henyey–Greenstein anisotropy.
    pub g: f64,
    /// σ_s = α σ_t.
    pub sigma_s: f64,
    /// σ_a = σ_t − σ_s.
    pub sigma_a: f64,
    /// σ_s' = (1 − g) σ_s.
    pub sigma_s_red: f64,
    /// σ_t' = σ_s' + σ_a.
    pub sigma_t_red: f64,
    /// α' = σ_s' / σ_t' (0 when σ_t' = 0).
    pub albedo_red: f64,
}

impl ReducedMedium {
    /// Reduced parameters without validation (non-physical input gives non-physical output, never
    /// a panic). Use [`ReducedMedium::try_new`] to validate.
    pub fn new(sigma_t: f64, albedo: f64, g: f64) -> Self {
        let sigma_s = albedo * sigma_t;
        let sigma_a = sigma_t - sigma_s;
        let sigma_s_red = (1.0 - g) * sigma_s;
        let sigma_t_red = sigma_s_red + sigma_a;
        let albedo_red = if sigma_t_red != 0.0 {
            sigma_s_red / sigma_t_red
        } else {
            0.0
        };
        ReducedMedium {
            sigma_t,
            albedo,
            g,
            sigma_s,
            sigma_a,
            sigma_s_red,
            sigma_t_red,
            albedo_red,
        }
    }

    /// Validating constructor: σ_t finite and > 0, α ∈ [0, 1], g ∈ (−1, 1).
    pub fn try_new(sigma_t: f64, albedo: f64, g: f64) -> Result<Self, MediumError> {
        if !(sigma_t.is_finite() && sigma_t > 0.0) {
            return Err(MediumError::SigmaT(sigma_t));
        }
        if !(0.0..=1.0).contains(&albedo) {
            return Err(MediumError::Albedo(albedo));
        }
        if !(g > -1.0 && g < 1.0) {
            return Err(MediumError::Anisotropy(g));
        }
        Ok(Self::new(sigma_t, albedo, g))
    }

    /// `v = 0.25 g + 0.25 α' + α_eff(α')` (docs/model.md §2, released formula, §10 A1).
    pub fn kernel_v(&self) -> f64 {
        kernel_v(self.albedo_red, self.g)
    }

    /// Kernel variance `ε = scale · 4 v² / σ_t'²` (docs/model.md §2, "kernelEps").
    pub fn kernel_epsilon(&self, scale: f64) -> f64 {
        let v = self.kernel_v();
        scale * 4.0 * v * v / (self.sigma_t_red * self.sigma_t_red)
    }

    /// Kernel scale `σ_n = sqrt(ε) = 2 v / σ_t'` (docs/model.md §2; `1/σ_n` is "fitScaleFactor").
    pub fn sigma_n(&self) -> f64 {
        2.0 * self.kernel_v() / self.sigma_t_red
    }

    /// `dα'/dα = (1 − g) / (1 − gα)²` (σ_t cancels).
    pub fn d_albedo_red_d_albedo(&self) -> f64 {
        let q = 1.0 - self.g * self.albedo;
        (1.0 - self.g) / (q * q)
    }
}

/// `v = 0.25 g + 0.25 α' + α_eff(α')` from the reduced albedo α' (docs/model.md §2).
#[inline]
pub fn kernel_v(albedo_red: f64, g: f64) -> f64 {
    0.25 * g + 0.25 * albedo_red + effective_albedo(albedo_red)
}

/// Kernel variance `ε = scale · 4 v² / σ_t'²` for one channel (docs/model.md §2); `scale` is
/// "kernelEpsScale" (1 by default).
pub fn kernel_epsilon(sigma_t: f64, albedo: f64, g: f64, scale: f64) -> f64 {
    ReducedMedium::new(sigma_t, albedo, g).kernel_epsilon(scale)
}

/// Kernel scale `σ_n = 2 v / σ_t'` for one channel (docs/model.md §2).
pub fn sigma_n(sigma_t: f64, albedo: f64, g: f64) -> f64 {
    ReducedMedium::new(sigma_t, albedo, g).sigma_n()
}

/// Analytic partial derivatives `(∂σ_n/∂σ_t, ∂σ_n/∂α)` at fixed g.
///
/// With `q = 1 − gα`: `σ_t' = σ_t q`, `α' = (1 − g)α/q`, `σ_n = 2 v(α') / (σ_t q)`, hence
///
/// ```text
/// ∂σ_n/∂σ_t = −σ_n / σ_t
/// ∂σ_n/∂α   = 2/(σ_t q) · (0.25 + α_eff'(α')) · (1 − g)/q²  +  σ_n · g / q
/// ```
///
/// (with g = 0: `∂σ_n/∂α = 2 (0.25 + α_eff'(α)) / σ_t`).
pub fn sigma_n_derivatives(sigma_t: f64, albedo: f64, g: f64) -> (f64, f64) {
    let m = ReducedMedium::new(sigma_t, albedo, g);
    let sn = m.sigma_n();
    let q = 1.0 - g * albedo;
    let dv_dalpha = (0.25 + effective_albedo_derivative(m.albedo_red)) * m.d_albedo_red_d_albedo();
    let d_sigma_t = -sn / sigma_t;
    let d_albedo = 2.0 * dv_dalpha / (sigma_t * q) + sn * g / q;
    (d_sigma_t, d_albedo)
}

/// Number of polynomial coefficients in the network input.
pub const N_POLY: usize = 20;
/// Number of network inputs: 20 coefficients ⊕ albedo ⊕ g ⊕ η.
pub const N_INPUTS: usize = N_POLY + 3;

/// Network input normalisation constants (docs/model.md §4.1): `(x − mean) · stdinv` with
/// `stdinv = 1 / sqrt(var + 0.1)`. One type serves the model file, the renderer and training:
/// the statistics of a training set ([`NormStats::from_samples`]) are what a model stores.
pub type NormStats = crate::nn::Normalisation;

/// One training sample for [`NormStats::from_samples`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StatSample {
    /// Light-space polynomial coefficients (`mlsPolyLS3`).
    pub coeffs_ls: [f32; N_POLY],
    /// The albedo whose effective albedo is the statistic. VKJ19 used the RAW albedo α of the
    /// sample here (while the network is fed α_eff(α'), docs/model.md §4.1); pass α to reproduce
    /// that.
    pub albedo: f64,
    /// Henyey–Greenstein g.
    pub g: f64,
}

/// Running mean/variance (Welford, f64) with an all-equal flag.
#[derive(Clone, Copy, Default)]
struct Moments {
    n: u64,
    mean: f64,
    m2: f64,
    first: f64,
    all_equal: bool,
}

impl Moments {
    fn push(&mut self, x: f64) {
        if self.n == 0 {
            self.first = x;
            self.all_equal = true;
        } else if x != self.first {
            self.all_equal = false;
        }
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }
    /// `(mean, 1/sqrt(var + 0.1))` with the population variance; zero variance → var := 1.
    fn stats(&self) -> (f32, f32) {
        let var = if self.all_equal {
            1.0
        } else {
            (self.m2 / self.n as f64).max(0.0)
        };
        let mean = if self.all_equal {
            self.first
        } else {
            self.mean
        };
        (mean as f32, (1.0 / (var + 0.1).sqrt()) as f32)
    }
}

impl crate::nn::Normalisation {
    /// Statistics over a training set (docs/model.md §4.1, §5 step 6): per input the mean and
    /// `stdinv = 1/sqrt(var + 0.1)` (population variance; an input with zero variance, i.e. all
    /// samples equal, gets var := 1, so stdinv = 1/sqrt(1.1) ≈ 0.953463). The albedo statistic is
    /// taken over `α_eff(sample.albedo)`.
    pub fn from_samples<'a, I>(samples: I) -> Result<Self, MediumError>
    where
        I: IntoIterator<Item = &'a StatSample>,
    {
        let mut alb = Moments::default();
        let mut g = Moments::default();
        let mut poly = [Moments::default(); N_POLY];
        for (index, s) in samples.into_iter().enumerate() {
            let ae = effective_albedo(s.albedo);
            if !ae.is_finite() || !s.g.is_finite() || s.coeffs_ls.iter().any(|c| !c.is_finite()) {
                return Err(MediumError::NonFiniteSample { index });
            }
            alb.push(ae);
            g.push(s.g);
            for (m, &c) in poly.iter_mut().zip(&s.coeffs_ls) {
                m.push(c as f64);
            }
        }
        if alb.n == 0 {
            return Err(MediumError::NoSamples);
        }
        let (eff_albedo_mean, eff_albedo_stdinv) = alb.stats();
        let (g_mean, g_stdinv) = g.stats();
        let mut poly_mean = [0.0; N_POLY];
        let mut poly_stdinv = [0.0; N_POLY];
        for k in 0..N_POLY {
            (poly_mean[k], poly_stdinv[k]) = poly[k].stats();
        }
        Ok(NormStats {
            eff_albedo_mean,
            eff_albedo_stdinv,
            g_mean,
            g_stdinv,
            poly_mean,
            poly_stdinv,
        })
    }

    /// The 23 network inputs (docs/model.md §4.1):
    /// `[(c_k − mean_k)·stdinv_k]_{k<20} ⊕ (α_eff(α') − mean)·stdinv ⊕ (g − mean)·stdinv ⊕ 2(η − 1.25)`.
    ///
    /// `coeffs_ls` are the light-space coefficients, `albedo_red` is the REDUCED albedo α'.
    pub fn normalise(
        &self,
        coeffs_ls: &[f32; N_POLY],
        albedo_red: f64,
        g: f64,
        eta: f64,
    ) -> [f32; N_INPUTS] {
        self.inputs(
            coeffs_ls,
            effective_albedo(albedo_red) as f32,
            g as f32,
            eta as f32,
        )
    }

    /// `∂ input[20] / ∂α'` = `stdinv · α_eff'(α')` (the only input that depends on the albedo;
    /// used for the α-gradient through S_abs, docs/model.md §8.2).
    pub fn d_albedo_input_d_albedo_red(&self, albedo_red: f64) -> f64 {
        self.eff_albedo_stdinv as f64 * effective_albedo_derivative(albedo_red)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduced_parameters_identities() {
        let m = ReducedMedium::new(40.0, 0.9, 0.3);
        assert!((m.sigma_t_red - 40.0 * (1.0 - 0.3 * 0.9)).abs() < 1e-12);
        assert!((m.albedo_red - 0.7 * 0.9 / (1.0 - 0.27)).abs() < 1e-12);
        assert!(ReducedMedium::try_new(0.0, 0.5, 0.0).is_err());
        assert!(ReducedMedium::try_new(1.0, 1.5, 0.0).is_err());
        assert!(ReducedMedium::try_new(1.0, 0.5, 1.0).is_err());
        assert!(ReducedMedium::try_new(1.0, 0.5, f64::NAN).is_err());
    }

    /// Worked values of docs/model.md §2 (g = 0, printed to 5 decimals).
    #[test]
    fn worked_values_of_spec_section_2() {
        let table = [
            (0.8, 0.20101, 0.40101, 0.80202),
            (0.9, 0.28745, 0.51245, 1.02489),
            (0.95, 0.37367, 0.61117, 1.22234),
            (0.98, 0.48696, 0.73196, 1.46393),
        ];
        for (a, a_eff, v, sn_st) in table {
            assert!((effective_albedo(a) - a_eff).abs() < 6e-6, "α_eff({a})");
            let m = ReducedMedium::new(1.0, a, 0.0);
            assert!((m.kernel_v() - v).abs() < 6e-6, "v({a})");
            for sigma_t in [1.0, 30.0, 77.7] {
                let sn = sigma_n(sigma_t, a, 0.0);
                assert!(
                    (sn * sigma_t - sn_st).abs() < 6e-6,
                    "σ_n σ_t ({a}, {sigma_t})"
                );
                let eps = kernel_epsilon(sigma_t, a, 0.0, 1.0);
                assert!((eps - sn * sn).abs() <= 1e-12 * eps);
                assert!((kernel_epsilon(sigma_t, a, 0.0, 2.5) - 2.5 * eps).abs() <= 1e-12 * eps);
            }
        }
        // SON24 range σ_t ∈ [30, 100], α ∈ [0.8, 0.98]: σ_n ∈ [0.008, 0.049]
        assert!((sigma_n(100.0, 0.8, 0.0) - 0.0080202).abs() < 1e-6);
        assert!((sigma_n(30.0, 0.98, 0.0) - 0.048798).abs() < 1e-5);
    }

    #[test]
    fn effective_albedo_inverse_round_trip() {
        assert_eq!(effective_albedo(0.0), 0.0);
        assert!((effective_albedo(1.0) - 1.0).abs() < 1e-14);
        for i in 0..=1000 {
            let a = i as f64 / 1000.0;
            let back = effective_albedo_inverse(effective_albedo(a));
            assert!((back - a).abs() < 1e-13, "{a} -> {back}");
            let e = a; // also the other direction
            assert!((effective_albedo(effective_albedo_inverse(e)) - e).abs() < 1e-13);
        }
        // monotone
        assert!(effective_albedo(0.5) < effective_albedo(0.6));
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for &(st, a, g) in &[
            (1.0, 0.5, 0.0),
            (50.0, 0.9, 0.0),
            (80.0, 0.98, 0.0),
            (35.0, 0.8, 0.4),
            (2.0, 0.3, -0.5),
            (10.0, 0.95, 0.9),
        ] {
            let (ds, da) = sigma_n_derivatives(st, a, g);
            let hs = 1e-5 * st;
            let fd_s = (sigma_n(st + hs, a, g) - sigma_n(st - hs, a, g)) / (2.0 * hs);
            let ha = 1e-6;
            let fd_a = (sigma_n(st, a + ha, g) - sigma_n(st, a - ha, g)) / (2.0 * ha);
            assert!(
                (ds - fd_s).abs() <= 1e-7 * fd_s.abs().max(1e-12),
                "{st} {a} {g}"
            );
            assert!(
                (da - fd_a).abs() <= 1e-6 * fd_a.abs(),
                "{st} {a} {g}: {da} vs {fd_a}"
            );
            if g == 0.0 {
                assert!((ds + sigma_n(st, a, g) / st).abs() < 1e-15);
            }
            let fd_e = (effective_albedo(a + ha) - effective_albedo(a - ha)) / (2.0 * ha);
            assert!((effective_albedo_derivative(a) - fd_e).abs() < 1e-7);
            let m = ReducedMedium::new(st, a, g);
            let fd_ar = (ReducedMedium::new(st, a + ha, g).albedo_red
                - ReducedMedium::new(st, a - ha, g).albedo_red)
                / (2.0 * ha);
            assert!((m.d_albedo_red_d_albedo() - fd_ar).abs() < 1e-7);
        }
    }

    fn son24_stats() -> NormStats {
        NormStats {
            eff_albedo_mean: 0.5773536,
            eff_albedo_stdinv: 2.337987,
            g_mean: 0.4757318,
            g_stdinv: 2.391793,
            poly_mean: [
                0.0,
                0.00228877,
                0.000364969,
                0.641748,
                0.21886,
                0.00163284,
                0.00259175,
                0.222573,
                0.00338305,
                0.426726,
                -0.00393764,
                0.0006214,
                0.00301002,
                0.0112224,
                0.00165743,
                0.00137763,
                0.000970118,
                0.000126225,
                0.000774188,
                0.0124266,
            ],
            poly_stdinv: [
                0.953463, 2.17847, 2.17086, 2.5529, 2.14151, 2.06676, 1.57265, 1.9849, 1.41885,
                1.49702, 2.96855, 2.64521, 2.45665, 2.56722, 2.05767, 2.36809, 2.88279, 2.31689,
                2.23891, 2.7686,
            ],
        }
    }

    /// Golden values of the reference-weights README (plane p = u_z, α = 0.9, g = 0, η = 1).
    #[test]
    fn golden_normalised_inputs_plane() {
        let stats = son24_stats();
        let mut c = [0.0f32; 20];
        c[3] = 1.0;
        let x = stats.normalise(&c, 0.9, 0.0, 1.0);
        assert!((x[20] - -0.67780).abs() < 6e-5, "{}", x[20]);
        assert!((x[21] - -1.13785).abs() < 6e-5, "{}", x[21]);
        assert_eq!(x[22], -0.5);
        assert!((x[3] - (1.0 - 0.641748) * 2.5529).abs() < 1e-6);
        assert!((x[0] - 0.0).abs() < 1e-9);
        assert!((x[19] - -0.0124266 * 2.7686).abs() < 1e-6);
        // derivative of the albedo input
        let h = 1e-4;
        let fd = (stats.normalise(&c, 0.9 + h, 0.0, 1.0)[20] as f64
            - stats.normalise(&c, 0.9 - h, 0.0, 1.0)[20] as f64)
            / (2.0 * h);
        assert!((stats.d_albedo_input_d_albedo_red(0.9) - fd).abs() < 1e-2);
        // serde round trip
        let json = serde_json::to_string(&stats).unwrap();
        let back: NormStats = serde_json::from_str(&json).unwrap();
        assert_eq!(back, stats);
    }

    #[test]
    fn stats_from_samples() {
        assert_eq!(
            NormStats::from_samples(&[] as &[StatSample]),
            Err(MediumError::NoSamples)
        );
        let mk = |k: usize, albedo: f64, g: f64| {
            let mut c = [0.25f32; 20];
            c[0] = 0.0;
            c[1] = k as f32;
            StatSample {
                coeffs_ls: c,
                albedo,
                g,
            }
        };
        let samples: Vec<StatSample> = (0..4).map(|k| mk(k, 0.2 * k as f64, 0.5)).collect();
        let s = NormStats::from_samples(&samples).unwrap();
        // coefficient 1: values 0,1,2,3 → mean 1.5, population variance 1.25
        assert!((s.poly_mean[1] - 1.5).abs() < 1e-6);
        assert!((s.poly_stdinv[1] - (1.0 / (1.25f64 + 0.1).sqrt()) as f32).abs() < 1e-6);
        // zero variance → var := 1 → 1/sqrt(1.1)
        for k in [0, 2, 19] {
            assert!((s.poly_stdinv[k] - 0.953_462_6).abs() < 1e-6, "k {k}");
        }
        assert_eq!(s.poly_mean[0], 0.0);
        assert_eq!(s.poly_mean[2], 0.25);
        assert_eq!(s.g_mean, 0.5);
        assert!((s.g_stdinv - 0.953_462_6).abs() < 1e-6);
        let ae: Vec<f64> = (0..4).map(|k| effective_albedo(0.2 * k as f64)).collect();
        let mean = ae.iter().sum::<f64>() / 4.0;
        let var = ae.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / 4.0;
        assert!((s.eff_albedo_mean as f64 - mean).abs() < 1e-7);
        assert!((s.eff_albedo_stdinv as f64 - 1.0 / (var + 0.1).sqrt()).abs() < 1e-6);
        let mut bad = samples.clone();
        bad[2].g = f64::NAN;
        assert_eq!(
            NormStats::from_samples(&bad),
            Err(MediumError::NonFiniteSample { index: 2 })
        );
    }
}
