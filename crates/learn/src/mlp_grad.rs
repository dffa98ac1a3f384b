//! Backward pass of dense layers and MLPs on `gemm` (reverse-mode differentiation of
//! `y = act(x Wᵀ + b)`).
//!
//! The forward pass runs through [`Dense::forward_rows`], the same code inference uses, and keeps
//! every layer's input and (post-activation) output in an [`MlpTape`]. For a layer with output
//! gradient δ = ∂L/∂y (rows × n_out), masked by the ReLU derivative (`y > 0`) where the layer has a
//! ReLU:
//!
//! * ∂L/∂W = δᵀ X   (n_out × n_in, accumulated),
//! * ∂L/∂b = Σ_rows δ,
//! * ∂L/∂X = δ W    (rows × n_in).

use bssrdf::nn::{Dense, Mlp};

/// `dst (m × n, row stride ld) = [dst +] lhs · rhs` with explicit strides (gemm 0.19).
///
/// `lhs(i, k) = lhs[i·lhs_rs + k·lhs_cs]`, `rhs(k, j) = rhs[k·rhs_rs + j·rhs_cs]`.
#[allow(clippy::too_many_arguments)]
fn gemm_strided(
    m: usize,
    n: usize,
    k: usize,
    dst: &mut [f32],
    ld: usize,
    accumulate: bool,
    lhs: &[f32],
    (lhs_rs, lhs_cs): (usize, usize),
    rhs: &[f32],
    (rhs_rs, rhs_cs): (usize, usize),
) {
    if m == 0 || n == 0 || k == 0 {
        if !accumulate {
            for i in 0..m {
                dst[i * ld..i * ld + n].fill(0.0);
            }
        }
        return;
    }
    let max = |rs: usize, cs: usize, r: usize, c: usize| (r - 1) * rs + (c - 1) * cs;
    // These bounds keep the raw-pointer accesses of gemm inside the slices.
    assert!(
        ld >= n
            && dst.len() > max(ld, 1, m, n)
            && lhs.len() > max(lhs_rs, lhs_cs, m, k)
            && rhs.len() > max(rhs_rs, rhs_cs, k, n),
        "gemm_strided: buffer sizes do not match the dimensions"
    );
    // SAFETY: every index gemm forms is bounded by the maxima checked above; dst does not alias
    // lhs or rhs (distinct borrows). gemm computes dst = alpha·dst + beta·lhs·rhs and reads dst
    // only when read_dst is true.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst.as_mut_ptr(),
            1,
            ld as isize,
            accumulate,
            lhs.as_ptr(),
            lhs_cs as isize,
            lhs_rs as isize,
            rhs.as_ptr(),
            rhs_cs as isize,
            rhs_rs as isize,
            if accumulate { 1.0 } else { 0.0 },
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        );
    }
}

/// Gradient of one dense layer: `W` (`n_out × n_in`, row-major) then `b`, laid out as in the
/// flat parameter vector of [`crate::cvae`].
#[allow(clippy::too_many_arguments)]
pub fn dense_backward(
    layer: &Dense,
    x: &[f32],
    y: &[f32],
    relu: bool,
    rows: usize,
    delta: &mut [f32],
    grad: &mut [f32],
    dx: Option<&mut [f32]>,
) {
    let (n_in, n_out) = (layer.n_in(), layer.n_out());
    let delta = &mut delta[..rows * n_out];
    if relu {
        for (d, &o) in delta.iter_mut().zip(&y[..rows * n_out]) {
            if o <= 0.0 {
                *d = 0.0;
            }
        }
    }
    let (gw, gb) = grad.split_at_mut(n_out * n_in);
    // ∂L/∂W (n_out × n_in) += δᵀ (n_out × rows) · X (rows × n_in)
    gemm_strided(
        n_out,
        n_in,
        rows,
        gw,
        n_in,
        true,
        delta,
        (1, n_out),
        x,
        (n_in, 1),
    );
    for row in delta.chunks_exact(n_out) {
        for (g, &d) in gb.iter_mut().zip(row) {
            *g += d;
        }
    }
    if let Some(dx) = dx {
        // ∂L/∂X (rows × n_in) = δ (rows × n_out) · W (n_out × n_in)
        gemm_strided(
            rows,
            n_in,
            n_out,
            dx,
            n_in,
            false,
            delta,
            (n_out, 1),
            layer.weights(),
            (n_in, 1),
        );
    }
}

/// Activations of one MLP forward pass over a batch: `acts[0]` is the input, `acts[k + 1]` the
/// output of layer `k` (after its activation).
#[derive(Clone, Debug, Default)]
pub struct MlpTape {
    acts: Vec<Vec<f32>>,
    deltas: [Vec<f32>; 2],
    rows: usize,
}

fn fit(v: &mut Vec<f32>, n: usize) {
    v.resize(n, 0.0);
}

impl MlpTape {
    /// Forward pass of `mlp` on `rows` rows of `x`, recording the activations.
    pub fn forward(&mut self, mlp: &Mlp, x: &[f32], rows: usize) {
        let layers = mlp.layers();
        self.acts.resize(layers.len() + 1, Vec::new());
        self.rows = rows;
        fit(&mut self.acts[0], rows * mlp.n_in());
        self.acts[0].copy_from_slice(&x[..rows * mlp.n_in()]);
        for (k, layer) in layers.iter().enumerate() {
            let relu = k + 1 < layers.len() || mlp.relu_output();
            let (before, after) = self.acts.split_at_mut(k + 1);
            fit(&mut after[0], rows * layer.n_out());
            layer.forward_rows(&before[k], rows, &mut after[0], relu);
        }
    }

    /// The output of the last forward pass.
    pub fn output(&self) -> &[f32] {
        self.acts.last().map(|v| v.as_slice()).unwrap_or(&[])
    }

    /// Backward pass: `d_out` = ∂L/∂output (rows × n_out). Parameter gradients are ADDED to
    /// `grad` (the MLP's slice of the flat gradient: layer 0's W, b, layer 1's W, b, …);
    /// ∂L/∂input is written to `d_in` if given.
    pub fn backward(
        &mut self,
        mlp: &Mlp,
        d_out: &[f32],
        grad: &mut [f32],
        d_in: Option<&mut [f32]>,
    ) {
        let layers = mlp.layers();
        let rows = self.rows;
        let mut offsets = Vec::with_capacity(layers.len());
        let mut o = 0;
        for l in layers {
            offsets.push(o);
            o += l.n_params();
        }
        let [cur, next] = &mut self.deltas;
        fit(cur, d_out.len());
        cur.copy_from_slice(d_out);
        let mut d_in = d_in;
        for k in (0..layers.len()).rev() {
            let layer = &layers[k];
            let relu = k + 1 < layers.len() || mlp.relu_output();
            let g = &mut grad[offsets[k]..offsets[k] + layer.n_params()];
            if k > 0 {
                fit(next, rows * layer.n_in());
                dense_backward(
                    layer,
                    &self.acts[k],
                    &self.acts[k + 1],
                    relu,
                    rows,
                    cur,
                    g,
                    Some(next),
                );
                std::mem::swap(cur, next);
            } else {
                dense_backward(
                    layer,
                    &self.acts[0],
                    &self.acts[1],
                    relu,
                    rows,
                    cur,
                    g,
                    d_in.take(),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strided_gemm_matches_loops() {
        let (m, n, k) = (3, 4, 5);
        let a: Vec<f32> = (0..m * k).map(|i| (i as f32 * 0.37).sin()).collect();
        let b: Vec<f32> = (0..k * n).map(|i| (i as f32 * 0.71).cos()).collect();
        let mut c = vec![1.0f32; m * n];
        gemm_strided(m, n, k, &mut c, n, true, &a, (k, 1), &b, (n, 1));
        for i in 0..m {
            for j in 0..n {
                let want: f32 = 1.0 + (0..k).map(|t| a[i * k + t] * b[t * n + j]).sum::<f32>();
                assert!((c[i * n + j] - want).abs() < 1e-5);
            }
        }
    }
}
