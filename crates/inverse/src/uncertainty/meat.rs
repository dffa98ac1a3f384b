//! The sandwich's middle B and the remaining Gauss–Newton step, each taken from the two
//! independent renders of every view so that neither holds those renders' own Monte Carlo
//! noise.
//!
//! **B.** View v has two estimates of its gradient g_v = Σ_p J_p r_p (half the gradient of its
//! loss at the estimate),
//!
//!   g¹_v = Σ_p J²_p (I¹_p − T_p),   g²_v = Σ_p J¹_p (I²_p − T_p),
//!
//! each taking its derivative and its value from different renders. Their render noises e¹_v,
//! e²_v are independent with mean zero, so with d^k_v = g^k_v − ḡ^k
//!
//!   B = V/(V − 1) · ½ Σ_v (d¹_v d²_vᵀ + d²_v d¹_vᵀ)
//!
//! has as its expectation the spread of the views' noise-free gradients (the targets' noise and
//! the model's error from view to view), while the product of one render's d_v with itself (or
//! of the two renders' mean) adds the render noise's variance, a property of the computation
//! rather than of the capture (docs/notes/uncertainty.md, "The interval renders' own noise").
//! With a few views the cross product can be indefinite: its negative eigenvalues are set to
//! zero, and each diagonal entry is at least its own standard error over the views, the
//! smallest value it cannot be told from.
//!
//! **The remaining step.** The estimate θ̂ is the optimiser's last iterate. Where it has not
//! reached the minimum of the loss (a run still moving along a flat valley when it stops), the
//! Gauss–Newton step Δ = −A⁻¹ Σ_v g_v goes from θ̂ to the minimum of the images' loss, and the
//! sandwich A⁻¹BA⁻¹ is the spread of that minimum about the truth over captures. The truth then
//! lies about Δ from θ̂, so the covariance adds C_step = Δ Δᵀ: in one dimension, with the truth
//! at N(Δ, s²) from θ̂, the interval ±1.96·√(s² + Δ²) holds it with probability at least 95 %
//! whatever Δ/s. Estimated without the render noise, as for B: ½(Δ¹Δ²ᵀ + Δ²Δ¹ᵀ) with
//! Δ^k = A⁻¹ Σ_v g^k_v, whose expectation is Δ̄Δ̄ᵀ; its negative eigenvalue is set to zero.
//! Where the run has converged, Δ is of the order of the sandwich's own standard deviation or
//! less, and C_step adds little; C_drift ([`super::iterate_drift`]) sees the movement of the
//! iterates behind θ̂, C_step the distance still ahead of it.

use nalgebra::{DMatrix, DVector};

/// B from the two estimates `g1`, `g2` of every view's gradient (module docs), or `None` with
/// fewer than two views.
pub fn cross_meat(g1: &[DVector<f64>], g2: &[DVector<f64>]) -> Option<DMatrix<f64>> {
    let v = g1.len();
    if v < 2 || g2.len() != v {
        return None;
    }
    let n = g1[0].len();
    let mean = |g: &[DVector<f64>]| g.iter().fold(DVector::zeros(n), |acc, x| acc + x) / v as f64;
    let (m1, m2) = (mean(g1), mean(g2));
    let d: Vec<(DVector<f64>, DVector<f64>)> =
        g1.iter().zip(g2).map(|(a, b)| (a - &m1, b - &m2)).collect();
    let f = v as f64 / (v as f64 - 1.0);
    let mut b = DMatrix::zeros(n, n);
    for (a, c) in &d {
        b += 0.5 * (a * c.transpose() + c * a.transpose());
    }
    b *= f;
    let mut b = positive_part(&b);
    for i in 0..n {
        // The standard error of B_ii: f·√(V·s²) with s² the variance over the views of d¹_i d²_i.
        let x: Vec<f64> = d.iter().map(|(a, c)| a[i] * c[i]).collect();
        let mx = x.iter().sum::<f64>() / v as f64;
        let s2 = x.iter().map(|x| (x - mx).powi(2)).sum::<f64>() / (v as f64 - 1.0);
        let se = f * (v as f64 * s2).sqrt();
        if b[(i, i)] < se {
            b[(i, i)] = se;
        }
    }
    Some(b)
}

/// C_step from A⁻¹ (`inv`) and the two estimates `g1`, `g2` of every view's gradient (module
/// docs).
pub fn remaining_step(
    inv: &DMatrix<f64>,
    g1: &[DVector<f64>],
    g2: &[DVector<f64>],
) -> DMatrix<f64> {
    let n = inv.nrows();
    let sum = |g: &[DVector<f64>]| g.iter().fold(DVector::zeros(n), |acc, x| acc + x);
    let (d1, d2) = (inv * sum(g1), inv * sum(g2));
    positive_part(&(0.5 * (&d1 * d2.transpose() + &d2 * d1.transpose())))
}

/// The symmetric matrix `m` with its negative eigenvalues set to zero (the nearest positive
/// semi-definite matrix in the Frobenius norm); zero where `m` is not finite.
pub fn positive_part(m: &DMatrix<f64>) -> DMatrix<f64> {
    let n = m.nrows();
    if n == 0 || m.iter().any(|x| !x.is_finite()) {
        return DMatrix::zeros(n, n);
    }
    let e = m.clone().symmetric_eigen();
    let l = DMatrix::from_diagonal(&e.eigenvalues.map(|x| x.max(0.0)));
    &e.eigenvectors * l * e.eigenvectors.transpose()
}

/// The 2×2 symmetric matrix [m00, m01, m11] as a matrix.
pub(super) fn from_packed(m: [f64; 3]) -> DMatrix<f64> {
    DMatrix::from_row_slice(2, 2, &[m[0], m[1], m[1], m[2]])
}

/// A 2×2 symmetric matrix as [m00, m01, m11].
pub(super) fn to_packed(m: &DMatrix<f64>) -> [f64; 3] {
    [m[(0, 0)], 0.5 * (m[(0, 1)] + m[(1, 0)]), m[(1, 1)]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v2(a: f64, b: f64) -> DVector<f64> {
        DVector::from_vec(vec![a, b])
    }

    /// With one render used twice the cross product is the plain spread of the views.
    #[test]
    fn the_same_render_twice_gives_the_plain_spread() {
        let g = vec![v2(1.0, 0.5), v2(-2.0, 0.1), v2(0.5, -0.4), v2(0.3, 0.2)];
        let b = cross_meat(&g, &g).unwrap();
        let mean = g.iter().fold(v2(0.0, 0.0), |a, x| a + x) / 4.0;
        let mut want = DMatrix::zeros(2, 2);
        for x in &g {
            want += (x - &mean) * (x - &mean).transpose() * (4.0 / 3.0);
        }
        assert!((b - want).abs().max() < 1e-12);
    }

    /// Independent noise of the two renders leaves B, in expectation: with V = 16 views whose
    /// true gradients spread by sd 1 and render noise of sd 10 on each estimate, the mean of the
    /// cross product over many draws is within its standard error of V·1 (B is the variance of
    /// the sum over the views), the plain product's near V·(1 + 100).
    #[test]
    fn render_noise_leaves_the_cross_product() {
        let mut rng = base::rng::Sampler::new(7, 0, 0, 0);
        let mut normal = || {
            let u = (rng.next_f32() as f64).max(1e-9);
            let w = rng.next_f32() as f64;
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * w).cos()
        };
        let (draws, views) = (4000, 16);
        let (mut cross, mut plain) = (Vec::new(), 0.0);
        for _ in 0..draws {
            let (mut g1, mut g2) = (Vec::new(), Vec::new());
            for _ in 0..views {
                let t = normal();
                g1.push(DVector::from_vec(vec![t + 10.0 * normal()]));
                g2.push(DVector::from_vec(vec![t + 10.0 * normal()]));
            }
            // Without the floor: the raw cross product's mean is what is unbiased.
            let m1 = g1.iter().map(|x| x[0]).sum::<f64>() / views as f64;
            let m2 = g2.iter().map(|x| x[0]).sum::<f64>() / views as f64;
            let raw: f64 = g1
                .iter()
                .zip(&g2)
                .map(|(a, b)| (a[0] - m1) * (b[0] - m2))
                .sum::<f64>()
                * (views as f64 / (views as f64 - 1.0));
            cross.push(raw);
            plain += cross_meat(&g1, &g1).unwrap()[(0, 0)] / draws as f64;
        }
        let m = cross.iter().sum::<f64>() / draws as f64;
        let sd = (cross.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (draws as f64 - 1.0)).sqrt();
        let se = sd / (draws as f64).sqrt();
        assert!((m - 16.0).abs() < 4.0 * se, "mean {m} ± {se}");
        assert!((plain / 16.0 - 101.0).abs() < 5.0, "plain {plain}");
    }

    /// The floor: a cross product that comes out negative is raised to its standard error.
    #[test]
    fn a_negative_cross_product_is_floored() {
        let g1 = vec![v2(1.0, 0.0), v2(-1.0, 0.0), v2(2.0, 0.0), v2(-2.0, 0.0)];
        let g2: Vec<_> = g1.iter().map(|x| -x).collect();
        let b = cross_meat(&g1, &g2).unwrap();
        assert!(b[(0, 0)] > 0.0 && b[(1, 1)] == 0.0, "{b}");
        assert!(positive_part(&b).symmetric_eigen().eigenvalues.min() >= -1e-12);
    }

    /// The step: two equal estimates give Δ Δᵀ with Δ = A⁻¹ Σ g.
    #[test]
    fn the_step_is_the_gauss_newton_step() {
        let inv = DMatrix::from_row_slice(2, 2, &[2.0, 0.5, 0.5, 1.0]);
        let g = vec![v2(0.3, -0.1), v2(0.2, 0.4)];
        let c = remaining_step(&inv, &g, &g);
        let d = &inv * v2(0.5, 0.3);
        assert!((c - &d * d.transpose()).abs().max() < 1e-12);
        // Opposite estimates (pure noise): nothing is added along their common direction.
        let h: Vec<_> = g.iter().map(|x| -x).collect();
        assert!(remaining_step(&inv, &g, &h).abs().max() < 1e-12);
    }
}
