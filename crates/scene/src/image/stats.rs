//! Statistics of an image A against a reference B, per channel: the mean ratio
//! mean(A)/mean(B), the RMSE, the relative RMSE (RMSE / mean(B)) and the relative MSE
//! Σ(A − B)² / Σ(B² + 10⁻²·mean(B)²), pbrt's `imgtool diff` relMSE with a floor that keeps dark
//! pixels from dominating.

use super::Image;
use crate::SceneError;

/// Statistics of one image pair, per channel.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct PairStats {
    pub mean_a: [f64; 3],
    pub mean_b: [f64; 3],
    pub mean_ratio: [f64; 3],
    pub rmse: [f64; 3],
    /// RMSE divided by the mean of B (relative RMSE).
    pub rel_rmse: [f64; 3],
    pub rel_mse: [f64; 3],
}

/// Compares `a` against the reference `b` (of the same size). A ratio with a zero denominator is
/// 1 when its numerator is 0 too, +∞ otherwise.
pub fn pair_stats(a: &Image, b: &Image) -> Result<PairStats, SceneError> {
    if a.width != b.width || a.height != b.height {
        return Err(SceneError::Invalid {
            location: "image comparison".into(),
            reason: format!(
                "image sizes differ: {}×{} vs {}×{}; fix: compare images of the same resolution",
                a.width, a.height, b.width, b.height
            ),
        });
    }
    let (ma, mb) = (a.mean(), b.mean());
    let n = a.data.len().max(1) as f64;
    let mut se = [0.0f64; 3];
    let mut rel_den = [0.0f64; 3];
    for (pa, pb) in a.data.iter().zip(&b.data) {
        for c in 0..3 {
            let d = pa[c] as f64 - pb[c] as f64;
            se[c] += d * d;
            rel_den[c] += (pb[c] as f64).powi(2) + 1e-2 * mb[c] * mb[c];
        }
    }
    let ratio = |x: f64, y: f64| {
        if y != 0.0 {
            x / y
        } else if x == 0.0 {
            1.0
        } else {
            f64::INFINITY
        }
    };
    let rmse = se.map(|s| (s / n).sqrt());
    Ok(PairStats {
        mean_a: ma,
        mean_b: mb,
        mean_ratio: [0, 1, 2].map(|c| ratio(ma[c], mb[c])),
        rmse,
        rel_rmse: [0, 1, 2].map(|c| ratio(rmse[c], mb[c])),
        rel_mse: [0, 1, 2].map(|c| ratio(se[c], rel_den[c])),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A = 2·B: ratio 2, RMSE = mean(B) on a constant image, relMSE = 1/(1 + 10⁻²); a zero
    /// channel in both is a ratio of 1; different sizes are refused.
    #[test]
    fn stats_of_a_scaled_image() {
        let mut b = Image::new(4, 3);
        for p in &mut b.data {
            *p = [0.5, 0.0, 2.0];
        }
        let a = b.scaled(2.0);
        let s = pair_stats(&a, &b).unwrap();
        assert_eq!(s.mean_ratio, [2.0, 1.0, 2.0]);
        assert!((s.rmse[0] - 0.5).abs() < 1e-12 && (s.rmse[2] - 2.0).abs() < 1e-12);
        assert!((s.rel_rmse[0] - 1.0).abs() < 1e-12);
        assert!((s.rel_mse[2] - 1.0 / 1.01).abs() < 1e-12);
        assert_eq!(s.rel_mse[1], 1.0);
        let e = pair_stats(&a, &Image::new(2, 2)).unwrap_err().to_string();
        assert!(e.contains("sizes differ"), "{e}");
    }
}
