use super::*;

#[test]
fn box_muller_is_standard_normal_in_moments() {
    let mut s = Sampler::new(1, 2, 3, 4);
    let n = 200_000;
    let (mut m1, mut m2) = (0.0f64, 0.0f64);
    for _ in 0..n / 2 {
        let (a, b) = box_muller(s.next_f32(), s.next_f32());
        for v in [a as f64, b as f64] {
            m1 += v;
            m2 += v * v;
        }
    }
    let mean = m1 / n as f64;
    let var = m2 / n as f64 - mean * mean;
    // Standard errors: 1/sqrt(n) for the mean, sqrt(2/n) for the variance.
    assert!(mean.abs() < 4.0 / (n as f64).sqrt(), "mean {mean}");
    assert!(
        (var - 1.0).abs() < 4.0 * (2.0 / n as f64).sqrt(),
        "var {var}"
    );
}
