//! Statistical test support for Monte Carlo code (used by the test suites only).
//!
//! * [`chi2_test`]: Pearson's χ² goodness-of-fit with pooling of sparse bins (pbrt-v4 and
//!   Mitsuba 3's `chi2.py` do the same), returning the p-value.
//! * [`gamma_q`]: the regularised upper incomplete gamma function Q(a, x) (Numerical Recipes
//!   §6.2: series for x < a + 1, Lentz continued fraction otherwise), so the χ² survival function
//!   is Q(dof/2, χ²/2).
//! * [`MeanEstimate`]: running mean and standard error, to compare an estimator against a known
//!   value at a tolerance derived from its own variance.
//! * [`random_unit_vector`]: uniform directions by rejection from the cube, for test fixtures.
//! * [`CsvTable`]: a CSV table a command wrote, read back as a header and rows of fields, for
//!   the command-line tests.

/// ln Γ(x) by the Lanczos approximation (g = 7, n = 9), |error| < 1e-13 for x > 0.
pub fn ln_gamma(x: f64) -> f64 {
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x) = Γ(a, x)/Γ(a).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        // Series for P(a, x).
        let mut ap = a;
        let mut sum = 1.0 / a;
        let mut del = sum;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        // Continued fraction for Q(a, x) (modified Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// Result of a χ² test.
#[derive(Clone, Copy, Debug)]
pub struct Chi2Result {
    pub statistic: f64,
    pub dof: usize,
    pub p_value: f64,
}

/// Pearson χ² test of `observed` counts against `expected` counts (same total). Bins with
/// expected count < `min_expected` (use 5) are pooled together, as in pbrt-v4's `Chi2Test`;
/// dof = bins after pooling − 1. Panics (it is test code) if no bins remain.
pub fn chi2_test(observed: &[f64], expected: &[f64], min_expected: f64) -> Chi2Result {
    assert_eq!(observed.len(), expected.len());
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].partial_cmp(&expected[b]).unwrap());
    let (mut pooled_o, mut pooled_e) = (0.0, 0.0);
    let mut stat = 0.0;
    let mut bins = 0usize;
    for &i in &order {
        if expected[i] < min_expected {
            pooled_o += observed[i];
            pooled_e += expected[i];
            if pooled_e >= min_expected {
                stat += (pooled_o - pooled_e).powi(2) / pooled_e;
                bins += 1;
                pooled_o = 0.0;
                pooled_e = 0.0;
            }
        } else {
            stat += (observed[i] - expected[i]).powi(2) / expected[i];
            bins += 1;
        }
    }
    if pooled_e > 0.0 {
        stat += (pooled_o - pooled_e).powi(2) / pooled_e.max(1e-300);
        bins += 1;
    }
    assert!(bins >= 2, "chi2_test: fewer than two usable bins");
    let dof = bins - 1;
    Chi2Result {
        statistic: stat,
        dof,
        p_value: gamma_q(dof as f64 / 2.0, stat / 2.0),
    }
}

/// Two-sample χ² test: are the histograms `a` and `b` (counts, any totals N_a, N_b) drawn from
/// the same distribution? Statistic Σ (√(N_b/N_a)·a_i − √(N_a/N_b)·b_i)² / (a_i + b_i)
/// (Press et al., Numerical Recipes §14.3), with bins of fewer than `min_count` joint counts
/// pooled (in order of their joint count) and dof = bins − 1. Both samples' noise is accounted
/// for, unlike [`chi2_test`] against expected counts estimated from a reference sample.
pub fn chi2_two_sample(a: &[f64], b: &[f64], min_count: f64) -> Chi2Result {
    assert_eq!(a.len(), b.len());
    let (na, nb) = (a.iter().sum::<f64>(), b.iter().sum::<f64>());
    assert!(na > 0.0 && nb > 0.0, "chi2_two_sample: an empty sample");
    let (ka, kb) = ((nb / na).sqrt(), (na / nb).sqrt());
    let term = |x: f64, y: f64| (ka * x - kb * y).powi(2) / (x + y);
    let mut order: Vec<usize> = (0..a.len()).filter(|&i| a[i] + b[i] > 0.0).collect();
    order.sort_by(|&i, &j| (a[i] + b[i]).total_cmp(&(a[j] + b[j])));
    let (mut pa, mut pb, mut stat, mut bins) = (0.0, 0.0, 0.0, 0usize);
    for &i in &order {
        if a[i] + b[i] < min_count {
            pa += a[i];
            pb += b[i];
            if pa + pb >= min_count {
                stat += term(pa, pb);
                bins += 1;
                (pa, pb) = (0.0, 0.0);
            }
        } else {
            stat += term(a[i], b[i]);
            bins += 1;
        }
    }
    if pa + pb > 0.0 {
        stat += term(pa, pb);
        bins += 1;
    }
    assert!(bins >= 2, "chi2_two_sample: fewer than two usable bins");
    let dof = bins - 1;
    Chi2Result {
        statistic: stat,
        dof,
        p_value: gamma_q(dof as f64 / 2.0, stat / 2.0),
    }
}

/// Running mean and standard error of i.i.d. samples (Welford).
#[derive(Clone, Copy, Debug, Default)]
pub struct MeanEstimate {
    n: u64,
    mean: f64,
    m2: f64,
}

impl MeanEstimate {
    pub fn push(&mut self, x: f64) {
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
    }
    pub fn count(&self) -> u64 {
        self.n
    }
    pub fn mean(&self) -> f64 {
        self.mean
    }
    pub fn variance(&self) -> f64 {
        if self.n < 2 {
            0.0
        } else {
            self.m2 / (self.n - 1) as f64
        }
    }
    /// Standard error of the mean.
    pub fn std_error(&self) -> f64 {
        (self.variance() / self.n.max(1) as f64).sqrt()
    }
    /// |mean − expected| in standard errors (infinite when the variance is zero and they differ).
    pub fn z_score(&self, expected: f64) -> f64 {
        let se = self.std_error();
        if se == 0.0 {
            if (self.mean - expected).abs() < 1e-12 {
                0.0
            } else {
                f64::INFINITY
            }
        } else {
            (self.mean - expected).abs() / se
        }
    }
}

/// A uniformly distributed unit vector: a point uniform in the cube [−1, 1]³, kept when its
/// length lies in (0.1, 1] (inside the unit ball, away from the origin where normalising loses
/// precision), normalised. Uniform on the sphere by the ball's rotational symmetry. Draws three
/// `f32` per attempt, so a seeded generator gives the same sequence of directions on every run.
pub fn random_unit_vector<R: rand::Rng + ?Sized>(rng: &mut R) -> glam::Vec3 {
    use rand::RngExt;
    loop {
        let v = glam::Vec3::new(
            2.0 * rng.random::<f32>() - 1.0,
            2.0 * rng.random::<f32>() - 1.0,
            2.0 * rng.random::<f32>() - 1.0,
        );
        let l = v.length();
        if l > 0.1 && l <= 1.0 {
            return v / l;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_q_matches_known_values() {
        // χ² survival with 1 dof at 3.841 is 0.05; with 10 dof at 18.307 is 0.05.
        assert!((gamma_q(0.5, 3.841_458_8 / 2.0) - 0.05).abs() < 1e-6);
        assert!((gamma_q(5.0, 18.307_038 / 2.0) - 0.05).abs() < 1e-6);
        assert!((gamma_q(49.5, 123.225_2 / 2.0) - 0.05).abs() < 1e-5);
        // Q(1, x) = e^{-x}.
        for x in [0.1, 1.0, 5.0, 30.0] {
            assert!((gamma_q(1.0, x) - (-x).exp()).abs() < 1e-12);
        }
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12);
    }

    #[test]
    fn chi2_rejects_wrong_and_accepts_right() {
        let expected = vec![100.0; 10];
        let good = vec![
            95.0, 105.0, 98.0, 102.0, 100.0, 97.0, 103.0, 99.0, 101.0, 100.0,
        ];
        let bad = vec![
            150.0, 50.0, 100.0, 100.0, 100.0, 100.0, 100.0, 100.0, 100.0, 100.0,
        ];
        assert!(chi2_test(&good, &expected, 5.0).p_value > 0.5);
        assert!(chi2_test(&bad, &expected, 5.0).p_value < 1e-6);
    }

    #[test]
    fn two_sample_chi2_rejects_wrong_and_accepts_right() {
        let a = vec![
            95.0, 105.0, 98.0, 102.0, 100.0, 97.0, 103.0, 99.0, 101.0, 100.0,
        ];
        // Twice the draws of the same distribution, and a distorted one.
        let same: Vec<f64> = a.iter().rev().map(|v| 2.0 * v).collect();
        let mut bad = same.clone();
        (bad[0], bad[1]) = (300.0, 100.0);
        assert!(chi2_two_sample(&a, &same, 5.0).p_value > 0.5);
        assert!(chi2_two_sample(&a, &bad, 5.0).p_value < 1e-6);
    }
}

/// A CSV table a command wrote (plain comma-separated fields, no quoting: what the commands
/// write), read back for a test: the header's names and the rows' fields.
#[derive(Clone, Debug)]
pub struct CsvTable {
    /// The file's text, for assertion messages.
    pub text: String,
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl CsvTable {
    /// Reads `path`; panics with the path when it cannot be read or has no header line.
    pub fn read(path: impl AsRef<std::path::Path>) -> Self {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path)
            .unwrap_or_else(|e| panic!("{}: cannot read: {e}", path.display()));
        let mut lines = text.lines();
        let header = lines
            .next()
            .unwrap_or_else(|| panic!("{}: empty, no header", path.display()))
            .split(',')
            .map(String::from)
            .collect();
        let rows = lines
            .map(|l| l.split(',').map(String::from).collect())
            .collect();
        Self { text, header, rows }
    }

    /// The index of the column `name`; panics naming the columns there are.
    pub fn column(&self, name: &str) -> usize {
        self.header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name:?} in {:?}", self.header))
    }

    /// The first `n` fields of each row, joined by spaces (e.g. "case method").
    pub fn keys(&self, n: usize) -> Vec<String> {
        self.rows
            .iter()
            .map(|r| r[..n.min(r.len())].join(" "))
            .collect()
    }
}

#[cfg(test)]
mod csv_tests {
    use super::CsvTable;

    #[test]
    fn reads_header_rows_and_keys() {
        let dir = std::env::temp_dir().join(format!("testkit-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.csv");
        std::fs::write(&path, "case,method,value\na,ours,1.5\nb,naive,2\n").unwrap();
        let t = CsvTable::read(&path);
        assert_eq!(t.header, ["case", "method", "value"]);
        assert_eq!(t.rows.len(), 2);
        assert_eq!(t.column("value"), 2);
        assert_eq!(t.keys(2), ["a ours", "b naive"]);
        assert_eq!(t.rows[1][2], "2");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
