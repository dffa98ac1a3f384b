//! Guided random walks: Dwivedi sampling of the directions and free flights inside the medium
//! (Křivánek and d'Eon 2014, "A zero-variance-based sampling scheme for Monte Carlo subsurface
//! scattering"; Meng, Hanika and Dachsbacher 2016, "Improving the Dwivedi sampling scheme"),
//! mixed with the classical sampler so that every path keeps a non-zero density.
//!
//! **The zero-variance walk of a half-space.** In a half-space of single-scattering albedo α
//! with isotropic scattering, the radiance deep inside decays with depth z as e^{−σ_t z/ν₀},
//! where ν₀ > 1 is the positive root of the dispersion relation
//!
//!   α ν₀ artanh(1/ν₀) = 1,   i.e.  (α ν₀/2) ln((ν₀ + 1)/(ν₀ − 1)) = 1
//!
//! (ν₀ → 1 as α → 0; ν₀ ≈ √(α/(3(1 − α))) as α → 1, the diffusion limit). Sampling each step by
//! that asymptotic solution (Dwivedi 1982) gives, per steradian about the outward normal n of
//! the surface the walk should return to (μ = ω·n),
//!
//!   directions:  p_D(ω) = 1/(2π L) · 1/(ν₀ − μ),   L = ln((ν₀ + 1)/(ν₀ − 1)),
//!   flights:     p_D(t | ω) = σ̃ e^{−σ̃ t},          σ̃ = σ_t (1 − μ/ν₀),
//!
//! so a walk heading for the surface flies further (σ̃ < σ_t) and one heading inwards stops
//! sooner; the inverse CDF of the directions is μ = ν₀ − (ν₀ + 1)((ν₀ − 1)/(ν₀ + 1))^u.
//!
//! **Mixing.** Alone, those densities would leave out paths that the classical walk takes (a
//! forward-scattering phase function's peak; walks towards a light behind the object). Each path
//! therefore draws all its directions and flights with one technique, the guided one with
//! probability P ([`WalkSampling::Guided`]) and the classical one otherwise, and is weighed by
//! the balance heuristic over the two techniques at the level of the whole path:
//!
//!   β = f / ((1 − P) p_classical + P p_guided),   p_· = the product of the technique's densities,
//!
//! f the path's integrand (phase-function values, σ_s e^{−σ_t t} per flight that scatters,
//! e^{−σ_t t_b} per flight that passes a boundary at t_b, whose probability is the technique's
//! survival function). A per-segment mixture would be unbiased too, but its weight is a product
//! of factors up to 1/(1 − P) each, and over a walk of dozens of scatterings that product has
//! a heavy tail; the path-level weight stays below 1/(1 − P) times the classical walk's. A
//! direction not drawn at a scattering (the camera ray's, a boundary's) is the same for both
//! techniques; its flight is not.
//!
//! **Channels.** ν₀ depends on the channel's albedo, so under the spectral MIS of
//! [`crate::spectral`] each (channel, technique) pair has its own densities; the hero channel's
//! and the path's technique draw the path, and all six pairs enter the balance heuristic
//! ([`SpectralWeight::segment`]). The exponents are
//! shifted by the hero's smallest one before exponentiating, so a long flight does not
//! underflow.
//!
//! **Derivatives.** Only the sampling changes: every contribution's weight is still f/p of its
//! path and its dependence on the medium still (α σ_t)^k e^{−σ_t ℓ} times its phase-function
//! factors, so [`crate::derivative`]'s scores hold unchanged.
//!
//! **The normal.** n is the outward shading normal where the path last entered the medium (the
//! camera ray's entry point, Křivánek and d'Eon's setting). For anisotropic media ν₀ is taken
//! from α as for isotropic scattering: the mixture keeps the estimate unbiased whatever n and ν₀
//! are, and they only decide how much the guide helps.

use glam::Vec3;

use crate::spectral::SpectralWeight;

/// How the walks inside the medium choose their directions and free-flight distances.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum WalkSampling {
    /// The phase function and e^{−σ_t t} (the classical walk).
    #[default]
    Classical,
    /// Dwivedi sampling towards the entry surface for a share `probability` of the paths, the
    /// classical walk for the others, combined by the balance heuristic ([module docs](self)).
    Guided { probability: f32 },
}

impl WalkSampling {
    /// The guided walks' settings for a medium of albedo `albedo`, or `None` for the classical
    /// walk (or a guided share of 0). Each thread keeps the last medium's constants: a render
    /// asks for them once per path.
    pub fn guide(self, albedo: &[f32; 3]) -> Option<Dwivedi> {
        thread_local! {
            static LAST: std::cell::Cell<Option<([f32; 3], f32, Dwivedi)>> =
                const { std::cell::Cell::new(None) };
        }
        match self {
            WalkSampling::Guided { probability } if probability > 0.0 => {
                let p = probability.min(1.0);
                LAST.with(|last| match last.get() {
                    Some((a, q, d)) if a == *albedo && q == p => Some(d),
                    _ => {
                        let d = Dwivedi::new(albedo, p);
                        last.set(Some((*albedo, p, d)));
                        Some(d)
                    }
                })
            }
            _ => None,
        }
    }
}

/// The positive root ν₀ of α ν₀ artanh(1/ν₀) = 1 ([module docs](self)), for 0 < α < 1; +∞ at
/// α ≥ 1 (no decay) and 1 at α ≤ 0.
pub fn nu0(albedo: f32) -> f64 {
    let a = albedo as f64;
    if a >= 1.0 {
        return f64::INFINITY;
    }
    if a <= 0.0 {
        return 1.0;
    }
    // x = 1/ν₀ ∈ (0, 1) solves h(x) = α artanh(x) − x = 0, h < 0 below the root and > 0 above
    // (h(0) = 0, h'(0) = α − 1 < 0, h convex). Bisection to the last bit.
    let h = |x: f64| a * x.atanh() - x;
    let (mut lo, mut hi) = (f64::MIN_POSITIVE, 1.0 - f64::EPSILON);
    if h(hi) <= 0.0 {
        return 1.0 / hi;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if h(mid) < 0.0 { lo = mid } else { hi = mid }
    }
    1.0 / (0.5 * (lo + hi))
}

/// The guided walk's constants for one medium: per channel 1/ν₀ and the directions' normaliser
/// 1/(2π L), and the guided share P.
#[derive(Clone, Copy, Debug)]
pub struct Dwivedi {
    /// 1/ν₀ per channel (0 at α = 1: no guidance in that channel).
    inv_nu0: [f32; 3],
    /// 1/(2π ln((ν₀ + 1)/(ν₀ − 1))) per channel, divided by ν₀ so that the density reads
    /// `norm / (1 − μ/ν₀)` (finite at ν₀ = ∞: 1/(4π)).
    norm: [f32; 3],
    /// The guided technique's share P of the paths.
    pub probability: f32,
}

/// A flight's guided extinction: σ̃/σ_t = 1 − μ/ν₀ per channel, μ = ω·n of its direction.
#[derive(Clone, Copy, Debug)]
pub struct Flight {
    stretch: [f32; 3],
}

impl Dwivedi {
    /// The constants for a medium of `albedo` with the guided share `probability` ∈ (0, 1].
    pub fn new(albedo: &[f32; 3], probability: f32) -> Self {
        let mut inv_nu0 = [0.0f32; 3];
        let mut norm = [0.0f32; 3];
        for c in 0..3 {
            let nu = nu0(albedo[c]);
            let x = 1.0 / nu;
            inv_nu0[c] = x as f32;
            // 1/(2π ν₀ L) with ν₀ L = ν₀ (ln(1 + x) − ln(1 − x)) = 2 artanh(x)/x → 2 as x → 0.
            let nu_l = if x < 1e-8 { 2.0 } else { 2.0 * x.atanh() / x };
            norm[c] = (1.0 / (std::f64::consts::TAU * nu_l)) as f32;
        }
        Dwivedi {
            inv_nu0,
            norm,
            probability,
        }
    }

    /// Channel `c`'s guided density per steradian of a direction with μ = ω·n.
    #[inline]
    pub fn direction_pdf(&self, c: usize, mu: f32) -> f32 {
        self.norm[c] / (1.0 - mu * self.inv_nu0[c])
    }

    /// μ = ω·n of a guided direction in channel `c` from a uniform `u` (inverse CDF).
    #[inline]
    pub fn sample_mu(&self, c: usize, u: f32) -> f32 {
        let x = self.inv_nu0[c] as f64;
        if x < 1e-6 {
            return (2.0 * u - 1.0).clamp(-1.0, 1.0);
        }
        // μ = ν₀ − (ν₀ + 1) ((ν₀ − 1)/(ν₀ + 1))^u, written in x = 1/ν₀:
        // μ = (1 − (1 + x) e^{u ln((1 − x)/(1 + x))}) / x.
        let ln_ratio = (-x).ln_1p() - x.ln_1p();
        let mu = (1.0 - (1.0 + x) * (u as f64 * ln_ratio).exp()) / x;
        (mu as f32).clamp(-1.0, 1.0)
    }

    /// A direction inside the medium, drawn by the path's technique (guided about the entry
    /// normal `n` with the hero channel's ν₀, or `classical`), and the path's weight updated
    /// with the phase function's density `phase_pdf` at it ([module docs](self)). Returns ω and
    /// its density mixed over the channels and techniques as the path mixed them before it,
    /// which a strategy reaching the same point otherwise is weighed against
    /// ([`crate::rough`]).
    #[inline]
    pub fn sample_direction(
        &self,
        n: Vec3,
        w: &mut SpectralWeight,
        u: [f32; 2],
        classical: impl FnOnce(f32, f32) -> Vec3,
        phase_pdf: impl FnOnce(Vec3) -> [f32; 3],
    ) -> (Vec3, f32) {
        let dir = if w.guided() {
            let mu = self.sample_mu(w.hero, u[0]);
            let sin = (1.0 - mu * mu).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * u[1];
            geometry::Frame::from_normal(n)
                .to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), mu))
                .normalize()
        } else {
            classical(u[0], u[1])
        };
        let fp = phase_pdf(dir);
        let p = self.direction_densities(fp, dir.dot(n));
        let mixed = w.mixture(p);
        w.segment(fp, p);
        (dir, mixed)
    }

    /// The two techniques' densities per channel of a direction with μ = ω·n whose
    /// phase-function density in channel c is `fp[c]`: `[classical, guided]`.
    #[inline]
    pub fn direction_densities(&self, fp: [f32; 3], mu: f32) -> [[f32; 3]; 2] {
        [fp, std::array::from_fn(|c| self.direction_pdf(c, mu))]
    }

    /// The density of reaching, from a scattering vertex, the boundary point at distance `t`
    /// along ω (μ = ω·n, phase-function density `fp` per channel) by a direction and a flight
    /// that passes it, mixed over the channels and techniques as `w` mixes them.
    #[inline]
    pub fn flight_density(
        &self,
        w: &SpectralWeight,
        sigma_t: &[f32; 3],
        fp: [f32; 3],
        mu: f32,
        t: f32,
    ) -> f32 {
        let dir = self.direction_densities(fp, mu);
        let pass = self.survival(&self.flight(mu), sigma_t, t);
        w.mixture(std::array::from_fn(|s| {
            std::array::from_fn(|j| dir[s][j] * pass[s][j])
        }))
    }

    /// The flight along a direction with μ = ω·n.
    #[inline]
    pub fn flight(&self, mu: f32) -> Flight {
        Flight {
            stretch: std::array::from_fn(|c| 1.0 - mu * self.inv_nu0[c]),
        }
    }

    /// A free-flight distance for the hero channel, from σ̃ (guided path) or σ_t.
    #[inline]
    pub fn sample_distance(
        &self,
        f: &Flight,
        sigma_t: &[f32; 3],
        w: &SpectralWeight,
        u: f32,
    ) -> f32 {
        let h = w.hero;
        let s = if w.guided() {
            sigma_t[h] * f.stretch[h]
        } else {
            sigma_t[h]
        };
        -(1.0 - u).ln() / s
    }

    /// The flight scattered at `t`: per channel f = σ_s e^{−σ_t t} against each technique's
    /// density.
    #[inline]
    pub fn scatter(
        &self,
        f: &Flight,
        w: &mut SpectralWeight,
        sigma_t: &[f32; 3],
        albedo: &[f32; 3],
        t: f32,
    ) {
        let (fv, p) = self.flight_terms(f, w.hero, sigma_t, t, true);
        w.segment(std::array::from_fn(|c| albedo[c] * fv[c]), p);
    }

    /// The flight passed a boundary at `t`: per channel f = e^{−σ_t t} against each technique's
    /// probability of flying beyond `t`.
    #[inline]
    pub fn pass(&self, f: &Flight, w: &mut SpectralWeight, sigma_t: &[f32; 3], t: f32) {
        let (fv, p) = self.flight_terms(f, w.hero, sigma_t, t, false);
        w.segment(fv, p);
    }

    /// The probability, mixed over the channels and techniques as `w` mixes them, that a flight
    /// along `f` passes a boundary at `t` ([`SpectralWeight::pass_probability`]'s guided form).
    #[inline]
    pub fn pass_probability(
        &self,
        f: &Flight,
        w: &SpectralWeight,
        sigma_t: &[f32; 3],
        t: f32,
    ) -> f32 {
        w.mixture(self.survival(f, sigma_t, t))
    }

    /// Each technique's probability per channel of flying beyond `t`: e^{−σ_t t}, e^{−σ̃ t}.
    #[inline]
    fn survival(&self, f: &Flight, sigma_t: &[f32; 3], t: f32) -> [[f32; 3]; 2] {
        [
            std::array::from_fn(|j| (-sigma_t[j] * t).exp()),
            std::array::from_fn(|j| (-sigma_t[j] * f.stretch[j] * t).exp()),
        ]
    }

    /// The channels' f and the techniques' p of a flight to `t`, all scaled by e^{m}, m the
    /// hero's smallest exponent (so the hero's densities cannot underflow): f_c = e^{−σ_t,c t}
    /// (σ_t,c times it if `scattered`), p[s][j] the technique's density (or survival
    /// probability).
    #[inline]
    fn flight_terms(
        &self,
        f: &Flight,
        hero: usize,
        sigma_t: &[f32; 3],
        t: f32,
        scattered: bool,
    ) -> ([f32; 3], [[f32; 3]; 2]) {
        let m = sigma_t[hero] * t * f.stretch[hero].min(1.0);
        let mut fv = [0.0f32; 3];
        let mut p = [[0.0f32; 3]; 2];
        for j in 0..3 {
            let s = sigma_t[j];
            let sg = s * f.stretch[j];
            let e = (m - s * t).exp();
            let g = (m - sg * t).exp();
            if scattered {
                fv[j] = s * e;
                p[0][j] = s * e;
                p[1][j] = sg * g;
            } else {
                fv[j] = e;
                p[0][j] = e;
                p[1][j] = g;
            }
        }
        (fv, p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ν₀ solves its equation, and approaches the diffusion limit √(α/(3(1 − α))) as α → 1.
    #[test]
    fn nu0_solves_the_dispersion_relation() {
        // At α 0.1, 1 − 1/ν₀ ≈ 2e^{−2/α} ≈ 4·10⁻⁹: artanh's argument keeps about 8 digits.
        for (a, tol) in [
            (0.1f32, 1e-6),
            (0.5, 1e-9),
            (0.8, 1e-9),
            (0.95, 1e-9),
            (0.999, 1e-9),
        ] {
            let nu = nu0(a);
            let lhs = a as f64 * nu * (1.0 / nu).atanh();
            assert!((lhs - 1.0).abs() < tol, "α {a}: {lhs}");
        }
        let a = 0.9999f64;
        let diffusion = (a / (3.0 * (1.0 - a))).sqrt();
        assert!((nu0(a as f32) / diffusion - 1.0).abs() < 1e-3);
        assert_eq!(nu0(1.0), f64::INFINITY);
    }

    /// The guided direction density integrates to one over the sphere, its inverse CDF maps u to
    /// the μ whose CDF is u, and at α = 1 it is uniform.
    #[test]
    fn guided_directions_are_normalised_and_inverted() {
        for a in [0.3f32, 0.9, 0.99, 1.0] {
            let d = Dwivedi::new(&[a; 3], 0.5);
            // ∫ p dω = 2π ∫_{-1}^{1} p(μ) dμ (midpoint rule).
            let n = 200_000;
            let total: f64 = (0..n)
                .map(|i| {
                    let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                    d.direction_pdf(0, mu as f32) as f64 * 2.0 / n as f64
                })
                .sum::<f64>()
                * std::f64::consts::TAU;
            assert!((total - 1.0).abs() < 1e-4, "α {a}: ∫ p = {total}");
            for u in [0.0f32, 0.1, 0.5, 0.9, 0.999] {
                let mu = d.sample_mu(0, u) as f64;
                let cdf: f64 = (0..20_000)
                    .map(|i| {
                        let m = -1.0 + (mu + 1.0) * (i as f64 + 0.5) / 20_000.0;
                        d.direction_pdf(0, m as f32) as f64 * (mu + 1.0) / 20_000.0
                    })
                    .sum::<f64>()
                    * std::f64::consts::TAU;
                assert!((cdf - u as f64).abs() < 2e-4, "α {a}, u {u}: CDF {cdf}");
            }
        }
        let uniform = Dwivedi::new(&[1.0; 3], 0.5);
        let p = uniform.direction_pdf(1, 0.7);
        assert!((p - 1.0 / (4.0 * std::f32::consts::PI)).abs() < 1e-7);
    }

    /// A direction about n, then a flight along it, in an infinite medium, each path drawn with
    /// a uniform hero and the guided technique with probability P: the path-level balance
    /// heuristic's weight has E[β_k] = α_k after a scattering and E[β_k 1{t > L}] = e^{−σ_t,k L}
    /// for a flight that passes L (each channel's phase function and the flight densities are
    /// normalised; the phase function is chromatic, so the directions weigh the channels too),
    /// and β_k ≤ 3 α_k/(1 − P).
    #[test]
    fn path_weights_have_the_integrands_expectation() {
        use crate::phase::ChannelHg;
        use crate::rng::Sampler;
        let sigma_t = [30.0f32, 60.0, 90.0];
        let albedo = [0.8f32, 0.95, 0.99];
        let (p, len) = (0.5f32, 0.03f32);
        let dw = Dwivedi::new(&albedo, p);
        let hg = ChannelHg::new([0.3, 0.6, 0.85]);
        let normal = Vec3::new(0.3, -0.2, 0.93).normalize();
        let d_in = Vec3::new(0.1, 0.5, -0.86).normalize();
        let n = 200_000;
        let mut scatter = [(0.0f64, 0.0f64); 3];
        let mut pass = [(0.0f64, 0.0f64); 3];
        let mut s = Sampler::new(9, 0, 0, 0);
        for _ in 0..n {
            let hero = s.next_below(3) as usize;
            let start = SpectralWeight::new(hero).with_techniques(p, s.next_f32() < p);
            let mut w = start;
            let u = [s.next_f32(), s.next_f32()];
            let classical = |u1, u2| hg.sample(hero, d_in, u1, u2);
            let (dir, _) = dw.sample_direction(normal, &mut w, u, classical, |o| hg.eval(d_in, o));
            let f = dw.flight(dir.dot(normal));
            let t = dw.sample_distance(&f, &sigma_t, &w, s.next_f32());
            let mut ws = w;
            dw.scatter(&f, &mut ws, &sigma_t, &albedo, t);
            let mut wp = w;
            let passed = t >= len;
            if passed {
                dw.pass(&f, &mut wp, &sigma_t, len);
            }
            for k in 0..3 {
                let b = ws.beta[k] as f64;
                assert!(
                    b <= 3.0 * albedo[k] as f64 / (1.0 - p as f64) + 1e-4,
                    "β {b}"
                );
                scatter[k].0 += b;
                scatter[k].1 += b * b;
                let b = if passed { wp.beta[k] as f64 } else { 0.0 };
                pass[k].0 += b;
                pass[k].1 += b * b;
            }
        }
        for k in 0..3 {
            for (name, (sum, sum2), expect) in [
                ("scatter", scatter[k], albedo[k] as f64),
                ("pass", pass[k], (-(sigma_t[k] * len) as f64).exp()),
            ] {
                let mean = sum / n as f64;
                let se = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
                assert!(
                    (mean - expect).abs() < 5.0 * se,
                    "{name}, channel {k}: {mean} ± {se} against {expect}"
                );
            }
        }
    }
}
