//! The optimiser's part of the intervals, per channel: the spread of the run's last iterates
//! (C_opt: with one view and few samples per iteration Adam's steps are a random walk about the
//! minimum, and the estimate is a draw from it) and their drift (C_drift: a run still moving
//! when it stops). The joint sandwich's versions over all variables are in [`super::joint`].

/// The covariance per channel in (ln σ_t, α) of the iterates `params` (σ_t, α per channel).
pub fn iterate_covariance(params: &[([f64; 3], [f64; 3])]) -> [[f64; 3]; 3] {
    let n = params.len();
    if n < 2 {
        return [[0.0; 3]; 3];
    }
    std::array::from_fn(|c| {
        let x: Vec<[f64; 2]> = params.iter().map(|(s, a)| [s[c].ln(), a[c]]).collect();
        let m = [0, 1].map(|k| x.iter().map(|v| v[k]).sum::<f64>() / n as f64);
        let mut cov = [0.0; 3];
        for v in &x {
            let d = [v[0] - m[0], v[1] - m[1]];
            cov[0] += d[0] * d[0];
            cov[1] += d[0] * d[1];
            cov[2] += d[1] * d[1];
        }
        cov.map(|v| v / (n as f64 - 1.0))
    })
}

/// The drift of the iterates `params` (σ_t, α per channel) as a covariance per channel in
/// (ln σ_t, α): d dᵀ with d the mean of their second half minus the mean of their first half.
/// A run still moving along a flat valley when it stops is further from its limit than its
/// iterates' spread says; the movement over the window is the allowance for that (module docs,
/// C_drift). Where the iterates are stationary, d is of the order of the spread's standard error.
pub fn iterate_drift(params: &[([f64; 3], [f64; 3])]) -> [[f64; 3]; 3] {
    let n = params.len();
    if n < 2 {
        return [[0.0; 3]; 3];
    }
    let (first, second) = params.split_at(n / 2);
    let mean = |part: &[([f64; 3], [f64; 3])], c: usize| -> [f64; 2] {
        let k = part.len() as f64;
        [
            part.iter().map(|(s, _)| s[c].ln()).sum::<f64>() / k,
            part.iter().map(|(_, a)| a[c]).sum::<f64>() / k,
        ]
    };
    std::array::from_fn(|c| {
        let (a, b) = (mean(first, c), mean(second, c));
        let d = [b[0] - a[0], b[1] - a[1]];
        [d[0] * d[0], d[0] * d[1], d[1] * d[1]]
    })
}
