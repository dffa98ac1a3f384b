//! Standard normal samples by inversion: z = Φ⁻¹(u) = √2·erfinv(2u − 1) (what SON24 uses for the
//! VAE latent, docs/model.md §4.1). Acklam's rational approximation (relative error < 1.2e-9) in
//! f64; inversion keeps stratification of the uniforms.

/// Φ⁻¹(u) for u ∈ (0, 1); clamps u into [1e-12, 1 − 1e-12].
pub fn probit(u: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383_577_518_672_69e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let p = u.clamp(1e-12, 1.0 - 1e-12);
    const P_LOW: f64 = 0.02425;
    if p < P_LOW {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - P_LOW {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        let q = (-2.0 * (1.0 - p).ln()).sqrt();
        -(((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_quantiles() {
        assert!(probit(0.5).abs() < 1e-12);
        assert!((probit(0.975) - 1.959_963_984_540_054).abs() < 1e-8);
        assert!((probit(0.001) + 3.090_232_306_167_813_6).abs() < 1e-8);
        assert!((probit(0.841_344_746_068_542_9) - 1.0).abs() < 1e-8);
        for k in 1..100 {
            let u = k as f64 / 100.0;
            assert!((probit(u) + probit(1.0 - u)).abs() < 1e-9);
        }
    }

    #[test]
    fn samples_are_standard_normal() {
        // χ² over 20 equiprobable bins of N(0, 1), from uniforms on a fine grid + jitter.
        let n = 100_000;
        let mut obs = vec![0.0; 20];
        let mut s = 12345u64;
        for _ in 0..n {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            let z = probit(u);
            // Φ(z) by erfc via its relation to the bins: bin = floor(20·Φ(z)) = floor(20·u) up to
            // the approximation error, so check consistency and count.
            let bin = ((u * 20.0) as usize).min(19);
            let lo = if bin == 0 {
                f64::NEG_INFINITY
            } else {
                probit(bin as f64 / 20.0)
            };
            let hi = if bin == 19 {
                f64::INFINITY
            } else {
                probit((bin + 1) as f64 / 20.0)
            };
            assert!(z >= lo - 1e-9 && z <= hi + 1e-9);
            obs[bin] += 1.0;
        }
        let exp = vec![n as f64 / 20.0; 20];
        assert!(testkit::chi2_test(&obs, &exp, 5.0).p_value > 1e-3);
    }
}
