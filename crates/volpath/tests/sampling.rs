//! χ² tests for every sampler the volumetric path tracer uses: Henyey–Greenstein direction
//! sampling, free-flight distance sampling (classical and guided), the guided walks' directions
//! and the pixel (camera) jitter.

use glam::Vec3;
use testkit::chi2_test;
use volpath::guided::Dwivedi;
use volpath::phase::{ChannelHg, HenyeyGreenstein};
use volpath::render::pixel_jitter;
use volpath::rng::Sampler;
use volpath::spectral::SpectralWeight;

/// Significance level of every χ² test: the probability that a correct sampler fails is 1e-3
/// (fixed seeds make each run deterministic).
const ALPHA: f64 = 1e-3;

/// The χ² test of observed bin counts against expected ones at [`ALPHA`].
fn assert_chi2(obs: &[f64], exp: &[f64], what: &str) {
    let r = chi2_test(obs, exp, 5.0);
    assert!(
        r.p_value > ALPHA,
        "{what}: χ²={} dof={} p={}",
        r.statistic,
        r.dof,
        r.p_value
    );
}

/// ∫ f over [a, b] by composite Simpson with `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
    let h = (b - a) / n as f64;
    let mut s = f(a) + f(b);
    for i in 1..n {
        s += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * h / 3.0
}

#[test]
fn henyey_greenstein_sampling_matches_its_density() {
    let n_theta = 24;
    let n_phi = 12;
    let n = 240_000;
    // A non-axis-aligned incoming direction exercises the frame construction too.
    let d_in = Vec3::new(0.3, -0.8, 0.52).normalize();
    let frame = geometry::Frame::from_normal(d_in);
    for (k, g) in [0.0f32, 0.3, -0.6, 0.9].into_iter().enumerate() {
        let hg = HenyeyGreenstein { g };
        let mut s = Sampler::new(11, k as u64, 0, 0);
        let mut obs = vec![0.0; n_theta * n_phi];
        for _ in 0..n {
            let (u1, u2) = (s.next_f32(), s.next_f32());
            let w = hg.sample(d_in, u1, u2);
            assert!((w.length() - 1.0).abs() < 1e-4);
            let l = frame.to_local(w);
            let cos_t = l.z.clamp(-1.0, 1.0) as f64;
            let phi = (l.y as f64)
                .atan2(l.x as f64)
                .rem_euclid(2.0 * std::f64::consts::PI);
            let i = (((cos_t + 1.0) / 2.0 * n_theta as f64) as usize).min(n_theta - 1);
            let j = ((phi / (2.0 * std::f64::consts::PI) * n_phi as f64) as usize).min(n_phi - 1);
            obs[i * n_phi + j] += 1.0;
        }
        let mut exp = vec![0.0; n_theta * n_phi];
        for i in 0..n_theta {
            let a = -1.0 + 2.0 * i as f64 / n_theta as f64;
            let b = a + 2.0 / n_theta as f64;
            // ∫ p(μ) dμ dφ over the bin = 2π/n_phi · ∫ p(μ) dμ.
            let p =
                simpson(|mu| hg.eval_cos(mu as f32) as f64, a, b, 400) * 2.0 * std::f64::consts::PI
                    / n_phi as f64;
            for j in 0..n_phi {
                exp[i * n_phi + j] = p * n as f64;
            }
        }
        let total: f64 = exp.iter().sum();
        assert!(
            (total / n as f64 - 1.0).abs() < 1e-3,
            "HG density does not integrate to 1 for g={g}: {total}"
        );
        assert_chi2(&obs, &exp, &format!("HG g={g}"));
    }
}

/// χ² of `n` distances from `draw` against the exponential of `rate`, in `bins` equally spaced
/// in its CDF 1 − e^{−rate·t} (equal expected counts).
fn assert_exponential(n: usize, bins: usize, rate: f64, mut draw: impl FnMut() -> f64, what: &str) {
    let mut obs = vec![0.0; bins];
    for _ in 0..n {
        let cdf = 1.0 - (-rate * draw()).exp();
        obs[((cdf * bins as f64) as usize).min(bins - 1)] += 1.0;
    }
    let exp = vec![n as f64 / bins as f64; bins];
    assert_chi2(&obs, &exp, &format!("free flight, {what}"));
}

#[test]
fn free_flight_sampling_is_exponential_for_the_hero_channel() {
    let sigma_t = [30.0f32, 55.0, 100.0];
    let bins = 40;
    let n = 200_000;
    for hero in 0..3 {
        let w = SpectralWeight::new(hero);
        let mut s = Sampler::new(12, hero as u64, 0, 0);
        let draw = || w.sample_distance(&sigma_t, s.next_f32()) as f64;
        assert_exponential(n, bins, sigma_t[hero] as f64, draw, &format!("hero {hero}"));
    }
}

/// The guided technique's directions ([`Dwivedi::sample_direction`] on a guided path) follow
/// p_D(ω) = 1/(2π L (ν₀ − μ)) about the normal n, in μ and in the azimuth, for the hero
/// channel's albedo.
#[test]
fn guided_directions_match_their_density() {
    let (n_mu, n_phi) = (24, 8);
    let n = 240_000;
    let normal = Vec3::new(-0.4, 0.7, 0.59).normalize();
    let frame = geometry::Frame::from_normal(normal);
    let albedo = [0.6f32, 0.95, 0.995];
    let dw = Dwivedi::new(&albedo, 0.5);
    let hg = ChannelHg::new([0.5; 3]);
    let d_in = Vec3::new(0.2, 0.3, -0.93).normalize();
    for hero in 0..3 {
        let mut s = Sampler::new(14, hero as u64, 0, 0);
        let mut obs = vec![0.0; n_mu * n_phi];
        for _ in 0..n {
            let mut w = SpectralWeight::new(hero).with_techniques(0.5, true);
            let u = [s.next_f32(), s.next_f32()];
            let classical = |u1, u2| hg.sample(hero, d_in, u1, u2);
            let (dir, _) = dw.sample_direction(normal, &mut w, u, classical, |o| hg.eval(d_in, o));
            let l = frame.to_local(dir);
            let mu = l.z.clamp(-1.0, 1.0) as f64;
            let phi = (l.y as f64)
                .atan2(l.x as f64)
                .rem_euclid(std::f64::consts::TAU);
            let i = (((mu + 1.0) / 2.0 * n_mu as f64) as usize).min(n_mu - 1);
            let j = ((phi / std::f64::consts::TAU * n_phi as f64) as usize).min(n_phi - 1);
            obs[i * n_phi + j] += 1.0;
        }
        let mut exp = vec![0.0; n_mu * n_phi];
        for i in 0..n_mu {
            let a = -1.0 + 2.0 * i as f64 / n_mu as f64;
            let b = a + 2.0 / n_mu as f64;
            let p = simpson(|mu| dw.direction_pdf(hero, mu as f32) as f64, a, b, 400)
                * std::f64::consts::TAU
                / n_phi as f64;
            for j in 0..n_phi {
                exp[i * n_phi + j] = p * n as f64;
            }
        }
        let what = format!("guided directions, hero {hero} (α {})", albedo[hero]);
        assert_chi2(&obs, &exp, &what);
    }
}

/// The guided technique's flights along a direction with μ = ω·n are exponential with the
/// stretched extinction σ̃ = σ_t (1 − μ/ν₀) of the hero channel; the classical technique's with
/// σ_t.
#[test]
fn guided_flights_are_exponential_in_the_stretched_extinction() {
    let sigma_t = [30.0f32, 55.0, 100.0];
    let albedo = [0.7f32, 0.9, 0.98];
    let dw = Dwivedi::new(&albedo, 0.5);
    let bins = 40;
    let n = 100_000;
    for (k, mu) in [0.9f32, -0.5].into_iter().enumerate() {
        let flight = dw.flight(mu);
        for hero in 0..3 {
            for guided in [false, true] {
                let w = SpectralWeight::new(hero).with_techniques(0.5, guided);
                let nu0 = volpath::guided::nu0(albedo[hero]);
                let rate = sigma_t[hero] as f64 * if guided { 1.0 - mu as f64 / nu0 } else { 1.0 };
                let mut s = Sampler::new(15, (k * 6 + hero * 2 + guided as usize) as u64, 0, 0);
                let draw = || dw.sample_distance(&flight, &sigma_t, &w, s.next_f32()) as f64;
                let what = format!("μ {mu}, hero {hero}, guided {guided}");
                assert_exponential(n, bins, rate, draw, &what);
            }
        }
    }
}

#[test]
fn pixel_jitter_is_uniform_over_the_pixel() {
    let grid = 8;
    let n = 64_000;
    for (case, key) in [0u64, 0xDEAD_BEEF, 12345].into_iter().enumerate() {
        let mut s = Sampler::new(13, case as u64, 0, 0);
        let mut obs = vec![0.0; grid * grid];
        for i in 0..n {
            // Past 2^16 the jitter switches to PCG; cover both regimes.
            let idx = if i < n / 2 { i } else { (1 << 16) + i };
            let (x, y) = pixel_jitter(idx, key, &mut s);
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
            obs[(y * grid as f32) as usize * grid + (x * grid as f32) as usize] += 1.0;
        }
        let exp = vec![n as f64 / (grid * grid) as f64; grid * grid];
        assert_chi2(&obs, &exp, &format!("pixel jitter key {key}"));
    }
}

/// Below 2^16 samples the jitter is dimensions 0 and 1 of the pixel's Owen-scrambled Sobol
/// sequence (`sample_4d` computes them together): the same values as `sobol_burley::sample`.
#[test]
fn pixel_jitter_is_the_first_two_sobol_dimensions() {
    let mut s = Sampler::new(1, 2, 3, 0);
    for key in [0u64, 0xDEAD_BEEF, 12345, u64::MAX] {
        for i in (0..1u32 << 16).step_by(7) {
            let (x, y) = pixel_jitter(i, key, &mut s);
            let seed = key as u32;
            assert_eq!(
                (x.to_bits(), y.to_bits()),
                (
                    sobol_burley::sample(i, 0, seed).to_bits(),
                    sobol_burley::sample(i, 1, seed).to_bits()
                ),
                "sample {i}, key {key}"
            );
        }
    }
}
