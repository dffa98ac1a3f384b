//! Unbiased RGB free-flight sampling with one-sample multiple importance sampling over the three
//! channels ("hero" channel, path-level balance heuristic; cf. pbrt-v4 §14.2.2, Wilkie et al.
//! 2014 "Hero wavelength spectral sampling").
//!
//! A path picks a hero channel h uniformly and samples every free flight with σ_t[h]. The path
//! pdf under channel j is p_j = Π_i p_j(segment i); the balance-heuristic estimator of channel
//! k is f_k / ((1/3) Σ_j p_j). We keep
//!   β[k] = f_k / ((1/3) Σ_j p_j)        (the current weight, ready to multiply a radiance)
//!   r[j] = p_j / ((1/3) Σ_j p_j)        (so that mean(r) = 1 after every update)
//! and update both multiplicatively per segment, then renormalise by mean(r). Because
//! f_k/p_h ≤ 1 for α ≤ 1 and mean(r) ≥ r[h]/3, β[k] ≤ 3 for any path: no coloured fireflies,
//! unlike single-channel sampling with ratio reweighting (which Mitsuba's RGB volpath uses).
//!
//! Per segment of length t inside the medium:
//! * scattering at t:  f_k = σ_s,k e^{−σ_t,k t},  p_j = σ_t,j e^{−σ_t,j t};
//! * passing a boundary at t_b: f_k = e^{−σ_t,k t_b},  p_j = e^{−σ_t,j t_b} (probability of
//!   sampling beyond t_b).

/// Path weight state for RGB transport.
#[derive(Clone, Copy, Debug)]
pub struct SpectralWeight {
    /// Hero channel (distance sampling uses σ_t[hero]).
    pub hero: usize,
    /// Current estimator weight per channel.
    pub beta: [f32; 3],
    r: [f32; 3],
    mis: bool,
    /// Guided walks ([`crate::guided`]): the guided technique's share P of the paths (0: the
    /// classical walk alone), whether this path draws with it, and its channels' relative
    /// densities r_j under it (`r` holds the classical technique's).
    share: f32,
    guided: bool,
    rg: [f32; 3],
}

impl SpectralWeight {
    /// A fresh path with the given hero channel (chosen uniformly by the caller) and unit weight,
    /// using the balance heuristic over channels.
    pub fn new(hero: usize) -> Self {
        SpectralWeight {
            hero,
            beta: [1.0; 3],
            r: [1.0; 3],
            mis: true,
            share: 0.0,
            guided: false,
            rg: [1.0; 3],
        }
    }

    /// Like [`SpectralWeight::new`] but with plain single-channel sampling: β_k = f_k / p_h, as
    /// Mitsuba 3's RGB `volpath` does (unbiased, higher variance). For comparisons.
    pub fn new_single_channel(hero: usize) -> Self {
        SpectralWeight {
            hero,
            beta: [1.0; 3],
            r: [1.0; 3],
            mis: false,
            share: 0.0,
            guided: false,
            rg: [1.0; 3],
        }
    }

    /// Sample a free-flight distance with the hero channel's extinction: t = −ln(1 − u)/σ_t[h].
    #[inline]
    pub fn sample_distance(&self, sigma_t: &[f32; 3], u: f32) -> f32 {
        -(1.0 - u).ln() / sigma_t[self.hero]
    }

    /// Account for a real scattering event after a flight of length `t`.
    #[inline]
    pub fn scatter(&mut self, sigma_t: &[f32; 3], albedo: &[f32; 3], t: f32) {
        let h = self.hero;
        let mut mean_r = 0.0;
        for j in 0..3 {
            // p_j / p_h = (σ_t,j / σ_t,h) e^{−(σ_t,j − σ_t,h) t};  f_j / p_h = α_j · p_j / p_h.
            // For the hero itself that is exactly 1 (x/x and e^{−0}), without calling exp.
            let ratio = if j == h {
                1.0
            } else {
                sigma_t[j] / sigma_t[h] * (-(sigma_t[j] - sigma_t[h]) * t).exp()
            };
            self.r[j] *= ratio;
            self.beta[j] *= albedo[j] * ratio;
            mean_r += self.r[j];
        }
        self.renormalise(mean_r / 3.0);
    }

    /// Account for a flight of length `t_b` that reached a boundary without scattering.
    #[inline]
    pub fn pass(&mut self, sigma_t: &[f32; 3], t_b: f32) {
        let h = self.hero;
        let mut mean_r = 0.0;
        for j in 0..3 {
            let e_j = if j == h {
                1.0
            } else {
                (-(sigma_t[j] - sigma_t[h]) * t_b).exp()
            };
            self.r[j] *= e_j;
            self.beta[j] *= e_j;
            mean_r += self.r[j];
        }
        self.renormalise(mean_r / 3.0);
    }

    /// The probability, mixed over the channels as this path's weights mix them, that a free
    /// flight from here passes a boundary at distance `t`: (1/3) Σ_j r_j e^{−σ_t,j t} (mean r = 1),
    /// or the hero's e^{−σ_t,h t} with single-channel sampling. A strategy that reaches the same
    /// boundary point otherwise combines with the free flight by it ([`crate::rough`]).
    #[inline]
    pub fn pass_probability(&self, sigma_t: &[f32; 3], t: f32) -> f32 {
        if !self.mis {
            return (-sigma_t[self.hero] * t).exp();
        }
        (0..3)
            .map(|j| self.r[j] * (-sigma_t[j] * t).exp())
            .sum::<f32>()
            / 3.0
    }

    /// The same path drawn with two walk techniques, classical and guided ([`crate::guided`]),
    /// the guided one with probability `share` (`guided`: this path's draw): the balance
    /// heuristic then runs over (channel, technique) pairs, β_k = f_k / M with
    /// M = (1/n) Σ_j ((1 − P) p_j,classical + P p_j,guided) over the path (n = 3 channels with
    /// spectral MIS, the hero alone otherwise). Every later segment must go through
    /// [`SpectralWeight::segment`].
    pub fn with_techniques(mut self, share: f32, guided: bool) -> Self {
        self.share = share;
        self.guided = guided;
        self
    }

    /// Whether this path draws its directions and flights with the guided technique.
    #[inline]
    pub fn guided(&self) -> bool {
        self.guided
    }

    /// Account for a sampled segment (a direction, a flight) whose integrand is `f[k]` in channel
    /// k and whose density under technique s (0 classical, 1 guided) and channel j is `p[s][j]`,
    /// all possibly scaled by one common positive factor: β_k ← β_k f_k/p_hero and
    /// r_s,j ← r_s,j p_s,j/p_hero, renormalised so that the mixture of the r is 1.
    #[inline]
    pub fn segment(&mut self, f: [f32; 3], p: [[f32; 3]; 2]) {
        let ph = p[self.guided as usize][self.hero];
        if !(ph > 0.0 && ph.is_finite()) {
            self.beta = [0.0; 3];
            return;
        }
        let inv = 1.0 / ph;
        for j in 0..3 {
            self.beta[j] *= f[j] * inv;
            self.r[j] *= p[0][j] * inv;
            self.rg[j] *= p[1][j] * inv;
        }
        let mean = self.mixture([[1.0; 3]; 2]);
        if mean > 0.0 && mean.is_finite() {
            let inv = 1.0 / mean;
            for j in 0..3 {
                self.beta[j] *= inv;
                self.r[j] *= inv;
                self.rg[j] *= inv;
            }
        } else {
            self.beta = [0.0; 3];
        }
    }

    /// A strategy's density mixed over the channels and techniques as this path mixes them:
    /// (1/n) Σ_j ((1 − P) r_j p[0][j] + P r^g_j p[1][j]) over the channels it mixes (all three
    /// with spectral MIS, the hero otherwise), `p[s][j]` the density under technique s and
    /// channel j. With the classical walk alone, (1/3) Σ_j r_j p[0][j].
    #[inline]
    pub fn mixture(&self, p: [[f32; 3]; 2]) -> f32 {
        let q = self.share;
        let term = |j: usize| {
            let c = self.r[j] * p[0][j];
            if q > 0.0 {
                (1.0 - q) * c + q * self.rg[j] * p[1][j]
            } else {
                c
            }
        };
        if self.mis {
            (term(0) + term(1) + term(2)) / 3.0
        } else {
            term(self.hero)
        }
    }

    /// Multiply every channel by a deterministic factor (Fresnel, radiance scaling, roulette).
    #[inline]
    pub fn scale(&mut self, s: f32) {
        for b in &mut self.beta {
            *b *= s;
        }
    }

    /// Largest channel weight (Russian-roulette survival probability basis).
    #[inline]
    pub fn max(&self) -> f32 {
        self.beta[0].max(self.beta[1]).max(self.beta[2])
    }

    #[inline]
    fn renormalise(&mut self, mean_r: f32) {
        if !self.mis {
            return;
        }
        if mean_r > 0.0 && mean_r.is_finite() {
            let inv = 1.0 / mean_r;
            for j in 0..3 {
                self.r[j] *= inv;
                self.beta[j] *= inv;
            }
        } else {
            self.beta = [0.0; 3];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Closed form: for a slab-free infinite medium, the expected number-weighted albedo product
    /// after n scatterings is α_k^n for every channel, whatever the hero. Check E[β_k] after one
    /// scattering with all three heroes averaged by Monte Carlo over t.
    #[test]
    fn one_scatter_expectation_is_albedo() {
        let sigma_t = [30.0, 60.0, 90.0];
        let albedo = [0.9, 0.8, 0.5];
        let n = 200_000;
        let mut sum = [0.0f64; 3];
        let mut sum2 = [0.0f64; 3];
        let mut s = crate::rng::Sampler::new(5, 0, 0, 0);
        for _ in 0..n {
            let mut w = SpectralWeight::new(s.next_below(3) as usize);
            let t = w.sample_distance(&sigma_t, s.next_f32());
            w.scatter(&sigma_t, &albedo, t);
            for k in 0..3 {
                // The balance heuristic bounds the weight by 3·α_k.
                assert!(w.beta[k] <= 3.0 * albedo[k] + 1e-4);
                sum[k] += w.beta[k] as f64;
                sum2[k] += (w.beta[k] as f64).powi(2);
            }
        }
        for k in 0..3 {
            let mean = sum[k] / n as f64;
            let var = sum2[k] / n as f64 - mean * mean;
            let se = (var / n as f64).sqrt();
            assert!(
                (mean - albedo[k] as f64).abs() < 5.0 * se + 1e-6,
                "channel {k}: {mean} vs {}",
                albedo[k]
            );
        }
    }

    /// Transmittance through a slab of optical thickness: E[β_k · 1{t > L}] = e^{−σ_t,k L}.
    #[test]
    fn pass_expectation_is_transmittance() {
        let sigma_t = [5.0, 10.0, 20.0];
        let l = 0.1;
        let n = 200_000;
        let mut sum = [0.0f64; 3];
        let mut sum2 = [0.0f64; 3];
        let mut s = crate::rng::Sampler::new(6, 0, 0, 0);
        for _ in 0..n {
            let mut w = SpectralWeight::new(s.next_below(3) as usize);
            let t = w.sample_distance(&sigma_t, s.next_f32());
            if t >= l {
                w.pass(&sigma_t, l);
                for k in 0..3 {
                    sum[k] += w.beta[k] as f64;
                    sum2[k] += (w.beta[k] as f64).powi(2);
                }
            }
        }
        for k in 0..3 {
            let mean = sum[k] / n as f64;
            let var = sum2[k] / n as f64 - mean * mean;
            let se = (var / n as f64).sqrt();
            let expect = (-sigma_t[k] as f64 * l as f64).exp();
            assert!(
                (mean - expect).abs() < 5.0 * se,
                "channel {k}: {mean} vs {expect}"
            );
        }
    }
}
