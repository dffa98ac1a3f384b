//! Batched, allocation-free MLP inference for the shape-adaptive BSSRDF (docs/model.md §4).
//!
//! The model is four small fully connected networks (VKJ19; SON24 uses narrower widths):
//!
//! | block | input | layers | output |
//! |---|---|---|---|
//! | feature MLP (shared) | 23 = 20 normalised light-space coefficients ⊕ α_eff ⊕ g ⊕ η | ReLU on **every** layer | feature vector f (width F) |
//! | absorption | f | hidden ReLU layers, last layer linear | Absorb = sigmoid(·) ∈ (0, 1) |
//! | decoder | z (4) ⊕ f, **z first** | hidden ReLU layers, last layer linear | y ∈ R³ (light space, units of σ_n) |
//! | encoder (training only) | x (3) ⊕ f, **x first** | hidden ReLU layers | μ ∈ R⁴ and log σ² ∈ R⁴ (two linear heads) |
//!
//! Inference runs over row-major batches in chunks of [`CHUNK_ROWS`] rows: one `gemm` call per
//! layer and chunk, then one fused pass adding the bias and applying the ReLU. A [`Workspace`]
//! holds the intermediate buffers, so once it has grown to size nothing allocates. Every batched
//! method comes in two forms: `*_with(…, &mut Workspace)` runs on the calling thread, the plain
//! form splits the rows over the rayon pool (one thread-local workspace per worker thread).
//!
//! The decoder's first layer is split as `W·[z; f] = W_z z + W_f f`: the `W_f f + b` part is
//! computed once per shading point and shared by all the samples of that point, which halves
//! the cost of a decoder sample with the SON24 widths.
//!
//! The model and its batched entry points are in `nn/shape_adaptive.rs` (re-exported here);
//! [`reference`] is a naive f64 implementation (plain loops) that the tests compare against.
//!
//! Throughput (release build, one core of the 2-vCPU project VM, 1M decoder samples over 4096
//! shading points): about 22 M samples/s with the SON24 widths, 4.8 M samples/s with the VKJ19
//! widths (`tests/nn.rs`, `decoder_throughput`).

use std::cell::RefCell;
use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::model::error::ModelError;

pub mod reference;
mod shape_adaptive;

pub use shape_adaptive::{Encoder, ShapeAdaptiveModel};

/// Number of network inputs: 20 polynomial coefficients, effective albedo, g, η.
pub const INPUT_DIM: usize = 23;
/// Number of polynomial coefficients among the inputs (indices 0..20).
pub const N_POLY: usize = 20;
/// Index of the normalised effective albedo α_eff(α') among the inputs.
pub const ALBEDO_INPUT: usize = 20;
/// Index of the normalised anisotropy g among the inputs.
pub const G_INPUT: usize = 21;
/// Index of the normalised relative IOR η among the inputs.
pub const ETA_INPUT: usize = 22;
/// Latent dimension of the VAE (decoder input z).
pub const LATENT_DIM: usize = 4;
/// Dimension of a position (decoder output, encoder input x).
pub const POSITION_DIM: usize = 3;
/// Default number of rows per `gemm` chunk.
pub const CHUNK_ROWS: usize = 1024;

// ---------------------------------------------------------------------------------------------
// Normalisation

/// Input normalisation constants of a model (dataset statistics, docs/model.md §4.1).
///
/// Inputs are `(c_k − poly_mean_k)·poly_stdinv_k` for the 20 light-space coefficients,
/// `(α_eff − eff_albedo_mean)·eff_albedo_stdinv`, `(g − g_mean)·g_stdinv` and the fixed
/// `2(η − 1.25)`. The formula for α_eff lives in [`crate::medium`]; this struct stores only the
/// constants.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    /// Mean of α_eff over the training set.
    pub eff_albedo_mean: f32,
    /// 1/sqrt(var + 0.1) of α_eff over the training set.
    pub eff_albedo_stdinv: f32,
    /// Mean of g over the training set.
    pub g_mean: f32,
    /// 1/sqrt(var + 0.1) of g over the training set.
    pub g_stdinv: f32,
    /// Mean of each light-space polynomial coefficient.
    pub poly_mean: [f32; N_POLY],
    /// 1/sqrt(var + 0.1) of each light-space polynomial coefficient.
    pub poly_stdinv: [f32; N_POLY],
}

impl Normalisation {
    /// η is normalised as `ETA_SCALE·(η − ETA_CENTER)` in every model (not a dataset statistic).
    pub const ETA_CENTER: f32 = 1.25;
    /// See [`Normalisation::ETA_CENTER`].
    pub const ETA_SCALE: f32 = 2.0;

    /// Identity normalisation (means 0, scales 1); for tests and untrained models.
    pub fn identity() -> Self {
        Self {
            eff_albedo_mean: 0.0,
            eff_albedo_stdinv: 1.0,
            g_mean: 0.0,
            g_stdinv: 1.0,
            poly_mean: [0.0; N_POLY],
            poly_stdinv: [1.0; N_POLY],
        }
    }

    /// The 23 network inputs from light-space coefficients, the effective albedo α_eff(α'),
    /// g and η.
    pub fn inputs(
        &self,
        poly_ls: &[f32; N_POLY],
        eff_albedo: f32,
        g: f32,
        eta: f32,
    ) -> [f32; INPUT_DIM] {
        let mut x = [0.0; INPUT_DIM];
        for k in 0..N_POLY {
            x[k] = (poly_ls[k] - self.poly_mean[k]) * self.poly_stdinv[k];
        }
        x[ALBEDO_INPUT] = (eff_albedo - self.eff_albedo_mean) * self.eff_albedo_stdinv;
        x[G_INPUT] = (g - self.g_mean) * self.g_stdinv;
        x[ETA_INPUT] = Self::ETA_SCALE * (eta - Self::ETA_CENTER);
        x
    }

    /// The first non-finite constant, as (name, index, value).
    pub fn first_non_finite(&self) -> Option<(&'static str, usize, f32)> {
        let scalars = [
            ("eff_albedo_mean", self.eff_albedo_mean),
            ("eff_albedo_stdinv", self.eff_albedo_stdinv),
            ("g_mean", self.g_mean),
            ("g_stdinv", self.g_stdinv),
        ];
        for (name, v) in scalars {
            if !v.is_finite() {
                return Some((name, 0, v));
            }
        }
        for (name, arr) in [
            ("poly_mean", &self.poly_mean),
            ("poly_stdinv", &self.poly_stdinv),
        ] {
            if let Some(i) = arr.iter().position(|v| !v.is_finite()) {
                return Some((name, i, arr[i]));
            }
        }
        None
    }
}

// ---------------------------------------------------------------------------------------------
// Dense layer and MLP

/// A fully connected layer `y = W x + b`, W stored `[n_out × n_in]` row-major
/// (`W[o][i]` at `o·n_in + i`, the layout of PyTorch and of the reference weights).
///
/// The fields are private so that the buffer sizes always match the dimensions (the `gemm`
/// calls rely on it); the values are mutable through [`Dense::weights_mut`] and
/// [`Dense::bias_mut`].
#[derive(Clone, Debug, PartialEq)]
pub struct Dense {
    w: Vec<f32>,
    b: Vec<f32>,
    n_in: usize,
    n_out: usize,
}

impl Dense {
    /// A layer from its weights `[n_out × n_in]` and bias `[n_out]`.
    pub fn new(n_in: usize, n_out: usize, w: Vec<f32>, b: Vec<f32>) -> Result<Self, ModelError> {
        if n_in == 0 || n_out == 0 {
            return Err(ModelError::Architecture(format!(
                "a dense layer needs at least one input and one output, got {n_in} -> {n_out}"
            )));
        }
        if w.len() != n_in * n_out || b.len() != n_out {
            return Err(ModelError::Architecture(format!(
                "dense layer {n_in} -> {n_out} needs {} weights and {n_out} biases, got {} and {}",
                n_in * n_out,
                w.len(),
                b.len()
            )));
        }
        Ok(Self { w, b, n_in, n_out })
    }

    /// Number of inputs.
    pub fn n_in(&self) -> usize {
        self.n_in
    }

    /// Number of outputs.
    pub fn n_out(&self) -> usize {
        self.n_out
    }

    /// Weights `[n_out × n_in]`, row-major.
    pub fn weights(&self) -> &[f32] {
        &self.w
    }

    /// Bias `[n_out]`.
    pub fn bias(&self) -> &[f32] {
        &self.b
    }

    /// Mutable weights (fixed length).
    pub fn weights_mut(&mut self) -> &mut [f32] {
        &mut self.w
    }

    /// Mutable bias (fixed length).
    pub fn bias_mut(&mut self) -> &mut [f32] {
        &mut self.b
    }

    /// Number of parameters (weights + biases).
    pub fn n_params(&self) -> usize {
        self.w.len() + self.b.len()
    }

    /// `out[r] = act(W x[r] + b)` for `rows` rows of `x` (row-major, `n_in` per row), on the
    /// calling thread. Training (crate `learn`) runs its forward passes through this same
    /// function, so inference and training share one implementation.
    pub fn forward_rows(&self, x: &[f32], rows: usize, out: &mut [f32], relu: bool) {
        let out = &mut out[..rows * self.n_out];
        matmul_wt(x, rows, self.n_in, &self.w, self.n_in, self.n_out, out);
        bias_act(out, &self.b, relu);
    }
}

/// `out[r][j] = Σ_k x[r·k_dim + k] · w[j·w_stride + k]` (x Wᵀ) for `rows` rows and `n` outputs,
/// with `gemm` on the calling thread. `out` is written, not read.
///
/// # Panics
/// If the buffers are smaller than the dimensions say.
pub fn matmul_wt(
    x: &[f32],
    rows: usize,
    k_dim: usize,
    w: &[f32],
    w_stride: usize,
    n: usize,
    out: &mut [f32],
) {
    if rows == 0 || n == 0 {
        return;
    }
    // These bounds make the raw-pointer accesses below stay inside the slices.
    assert!(
        k_dim >= 1
            && x.len() >= rows * k_dim
            && out.len() >= rows * n
            && w_stride >= k_dim
            && w.len() >= (n - 1) * w_stride + k_dim,
        "matmul_wt: buffer sizes do not match the dimensions"
    );
    // SAFETY: dst is rows×n with row stride n (checked above), lhs is rows×k_dim with row stride
    // k_dim, rhs is the k_dim×n matrix Wᵀ read as rhs[k][j] = w[k + j·w_stride] (checked above).
    // gemm 0.19 computes dst = alpha·dst + beta·lhs·rhs; with read_dst = false dst is not read.
    unsafe {
        gemm::gemm(
            rows,
            n,
            k_dim,
            out.as_mut_ptr(),
            1,
            n as isize,
            false,
            x.as_ptr(),
            1,
            k_dim as isize,
            w.as_ptr(),
            w_stride as isize,
            1,
            0.0,
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        );
    }
}

/// Adds the bias to every row of `out` and applies the ReLU if asked (one fused pass).
fn bias_act(out: &mut [f32], b: &[f32], relu: bool) {
    if relu {
        for row in out.chunks_exact_mut(b.len()) {
            for (o, &bb) in row.iter_mut().zip(b) {
                *o = (*o + bb).max(0.0);
            }
        }
    } else {
        for row in out.chunks_exact_mut(b.len()) {
            for (o, &bb) in row.iter_mut().zip(b) {
                *o += bb;
            }
        }
    }
}

/// A multi-layer perceptron: ReLU after every hidden layer; the last layer is linear unless
/// `relu_output` (the feature MLP has a ReLU on its last layer too).
#[derive(Clone, Debug, PartialEq)]
pub struct Mlp {
    layers: Vec<Dense>,
    relu_output: bool,
}

impl Mlp {
    /// An MLP from its layers (at least one; each layer's input width is the previous output).
    pub fn new(layers: Vec<Dense>, relu_output: bool) -> Result<Self, ModelError> {
        if layers.is_empty() {
            return Err(ModelError::Architecture(
                "an MLP needs at least one layer".to_string(),
            ));
        }
        for (i, pair) in layers.windows(2).enumerate() {
            if pair[0].n_out != pair[1].n_in {
                return Err(ModelError::Architecture(format!(
                    "layer {i} has {} outputs but layer {} has {} inputs",
                    pair[0].n_out,
                    i + 1,
                    pair[1].n_in
                )));
            }
        }
        Ok(Self {
            layers,
            relu_output,
        })
    }

    /// The layers.
    pub fn layers(&self) -> &[Dense] {
        &self.layers
    }

    /// Mutable layers (their number and shapes are fixed).
    pub fn layers_mut(&mut self) -> &mut [Dense] {
        &mut self.layers
    }

    /// Whether the last layer has a ReLU.
    pub fn relu_output(&self) -> bool {
        self.relu_output
    }

    /// Input width.
    pub fn n_in(&self) -> usize {
        self.layers[0].n_in
    }

    /// Output width.
    pub fn n_out(&self) -> usize {
        self.layers[self.layers.len() - 1].n_out
    }

    /// Widths `[n_in, hidden…, n_out]`.
    pub fn widths(&self) -> Vec<usize> {
        std::iter::once(self.n_in())
            .chain(self.layers.iter().map(|l| l.n_out))
            .collect()
    }

    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        self.layers.iter().map(Dense::n_params).sum()
    }

    /// Forward pass over a row-major batch `x` (`n_in` per row) into `out` (`n_out` per row),
    /// on the calling thread.
    pub fn forward_with(
        &self,
        x: &[f32],
        out: &mut [f32],
        ws: &mut Workspace,
    ) -> Result<(), ModelError> {
        let rows = batch_rows("MLP input", x.len(), self.n_in())?;
        expect_len("MLP output", out.len(), rows * self.n_out())?;
        self.forward_unchecked(x, rows, out, ws);
        Ok(())
    }

    /// Forward pass, rows split over the rayon pool.
    pub fn forward(&self, x: &[f32], out: &mut [f32]) -> Result<(), ModelError> {
        let rows = batch_rows("MLP input", x.len(), self.n_in())?;
        expect_len("MLP output", out.len(), rows * self.n_out())?;
        let n_in = self.n_in();
        par_rows(out, self.n_out(), |r, o, ws| {
            self.forward_unchecked(&x[r.start * n_in..r.end * n_in], r.len(), o, ws);
        });
        Ok(())
    }

    fn forward_unchecked(&self, x: &[f32], rows: usize, out: &mut [f32], ws: &mut Workspace) {
        let (n_in, n_out) = (self.n_in(), self.n_out());
        for r in chunks(rows, ws.chunk_rows) {
            run_layers(
                &self.layers,
                self.relu_output,
                &x[r.start * n_in..r.end * n_in],
                r.len(),
                &mut out[r.start * n_out..r.end * n_out],
                &mut ws.bufs,
            );
        }
    }
}

/// Runs `layers` (ReLU after each, and after the last one iff `relu_last`) on `rows` rows,
/// ping-ponging between the two buffers.
fn run_layers(
    layers: &[Dense],
    relu_last: bool,
    x: &[f32],
    rows: usize,
    out: &mut [f32],
    bufs: &mut [Vec<f32>; 2],
) {
    let n = layers.len();
    let [a, b] = bufs;
    let (mut src, mut dst) = (a, b);
    for (i, layer) in layers.iter().enumerate() {
        let input: &[f32] = if i == 0 { x } else { &src[..rows * layer.n_in] };
        if i + 1 == n {
            layer.forward_rows(input, rows, out, relu_last);
        } else {
            grow(dst, rows * layer.n_out);
            layer.forward_rows(input, rows, dst, true);
            std::mem::swap(&mut src, &mut dst);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Workspace and parallel helpers

/// Reusable intermediate buffers of the batched forward passes. They grow on first use and are
/// then reused: with a warm workspace the forward passes do not allocate.
#[derive(Clone, Debug)]
pub struct Workspace {
    bufs: [Vec<f32>; 2],
    tangents: [Vec<f32>; 2],
    hidden: Vec<f32>,
    points: Vec<f32>,
    chunk_rows: usize,
}

impl Default for Workspace {
    fn default() -> Self {
        Self::new()
    }
}

impl Workspace {
    /// An empty workspace processing [`CHUNK_ROWS`] rows per `gemm` call.
    pub fn new() -> Self {
        Self::with_chunk_rows(CHUNK_ROWS)
    }

    /// An empty workspace processing `chunk_rows` rows (at least 1) per `gemm` call.
    pub fn with_chunk_rows(chunk_rows: usize) -> Self {
        Self {
            bufs: [Vec::new(), Vec::new()],
            tangents: [Vec::new(), Vec::new()],
            hidden: Vec::new(),
            points: Vec::new(),
            chunk_rows: chunk_rows.max(1),
        }
    }

    /// Rows per `gemm` call.
    pub fn chunk_rows(&self) -> usize {
        self.chunk_rows
    }

    /// Bytes currently held.
    pub fn capacity_bytes(&self) -> usize {
        let v = [
            &self.bufs[0],
            &self.bufs[1],
            &self.tangents[0],
            &self.tangents[1],
            &self.hidden,
            &self.points,
        ];
        v.iter().map(|b| b.capacity() * 4).sum()
    }
}

/// Grows `v` to at least `len` elements (allocates only when it is too small).
fn grow(v: &mut Vec<f32>, len: usize) {
    if v.len() < len {
        v.resize(len, 0.0);
    }
}

/// Row ranges of at most `chunk` rows covering `0..rows`.
fn chunks(rows: usize, chunk: usize) -> impl Iterator<Item = Range<usize>> {
    (0..rows)
        .step_by(chunk.max(1))
        .map(move |s| s..(s + chunk).min(rows))
}

thread_local! {
    static SCRATCH: RefCell<Workspace> = RefCell::new(Workspace::new());
}

/// Runs `f` with this thread's workspace (a fresh one if it is already borrowed).
fn with_scratch<R>(f: impl FnOnce(&mut Workspace) -> R) -> R {
    SCRATCH.with(|cell| match cell.try_borrow_mut() {
        Ok(mut ws) => f(&mut ws),
        Err(_) => f(&mut Workspace::new()),
    })
}

/// Splits `out` (`per_row` values per row) into chunks of [`CHUNK_ROWS`] rows and runs `f` on
/// each over the rayon pool, with the worker's thread-local workspace.
fn par_rows<O: Send>(
    out: &mut [O],
    per_row: usize,
    f: impl Fn(Range<usize>, &mut [O], &mut Workspace) + Sync,
) {
    out.par_chunks_mut(CHUNK_ROWS * per_row)
        .enumerate()
        .for_each(|(i, o)| {
            let start = i * CHUNK_ROWS;
            let r = start..start + o.len() / per_row;
            with_scratch(|ws| f(r, o, ws));
        });
}

/// Number of rows of a flat batch of `len` values with `width` values per row.
fn batch_rows(what: &str, len: usize, width: usize) -> Result<usize, ModelError> {
    if width == 0 || !len.is_multiple_of(width) {
        return Err(ModelError::Batch(format!(
            "{what} has {len} values, not a multiple of the row width {width}"
        )));
    }
    Ok(len / width)
}

fn expect_len(what: &str, got: usize, expected: usize) -> Result<(), ModelError> {
    if got != expected {
        return Err(ModelError::Batch(format!(
            "{what} has {got} values, expected {expected}"
        )));
    }
    Ok(())
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}
