//! Shared fixtures of the training-gradient tests: an independent f64 reference of the networks
//! over the flat parameter vector (`learn::cvae`'s order), random data, a small model, and the
//! comparison of an analytic gradient with f64 central differences (tolerances derived in
//! `gradients.rs`'s module doc).

#![allow(dead_code)]

use base::rng::Sampler;
use bssrdf::model::ModelInfo;
use bssrdf::nn::{
    Dense, INPUT_DIM, LATENT_DIM, Mlp, Normalisation, POSITION_DIM, ShapeAdaptiveModel,
};
use learn::cvae::{Widths, flat_to_params, init_model, params_to_flat};

pub const H: f64 = 1e-6;
pub const MARGIN: f64 = 1e-4;

pub fn uniform(s: &mut Sampler, n: usize, a: f32) -> Vec<f32> {
    (0..n).map(|_| a * (2.0 * s.next_f32() - 1.0)).collect()
}

/// One layer: (n_in, n_out, relu); parameters W (n_out × n_in) then b, consecutive.
pub type Shape = (usize, usize, bool);

pub fn mlp_shapes(mlp: &Mlp) -> Vec<Shape> {
    let n = mlp.layers().len();
    mlp.layers()
        .iter()
        .enumerate()
        .map(|(i, l)| (l.n_in(), l.n_out(), i + 1 < n || mlp.relu_output()))
        .collect()
}

/// `act(W x + b)` layer by layer from `p[off..]`; records min |pre-activation| of ReLU units.
pub fn forward64(
    p: &[f64],
    mut off: usize,
    shapes: &[Shape],
    x: &[f64],
    margin: &mut f64,
) -> Vec<f64> {
    let mut h = x.to_vec();
    for &(n_in, n_out, relu) in shapes {
        let (w, b) = (&p[off..off + n_in * n_out], &p[off + n_in * n_out..]);
        h = (0..n_out)
            .map(|o| {
                let s: f64 = (0..n_in).map(|i| w[o * n_in + i] * h[i]).sum::<f64>() + b[o];
                if relu {
                    *margin = margin.min(s.abs());
                    s.max(0.0)
                } else {
                    s
                }
            })
            .collect();
        off += n_in * n_out + n_out;
    }
    h
}

pub fn n_shape_params(shapes: &[Shape]) -> usize {
    shapes.iter().map(|&(i, o, _)| i * o + o).sum()
}

/// The whole model in f64, blocks in the flat order of `learn::cvae`.
pub struct Model64 {
    pub blocks: [Vec<Shape>; 6],
}

pub const BLOCK_NAMES: [&str; 6] = [
    "feature",
    "absorption",
    "decoder",
    "encoder hidden",
    "mean head",
    "logvar head",
];

impl Model64 {
    pub fn new(m: &ShapeAdaptiveModel) -> Self {
        let e = m.encoder().unwrap();
        let head = |d: &Dense| vec![(d.n_in(), d.n_out(), false)];
        Self {
            blocks: [
                mlp_shapes(m.feature_mlp()),
                mlp_shapes(m.absorption_mlp()),
                mlp_shapes(m.decoder()),
                mlp_shapes(e.hidden()),
                head(e.mean()),
                head(e.logvar()),
            ],
        }
    }

    /// Row `i` of `d` through the f64 networks at parameters `p`: the target x, the features f
    /// and the absorption logit s (ReLU margins into `margin`).
    pub fn row(
        &self,
        p: &[f64],
        d: &Data,
        i: usize,
        margin: &mut f64,
    ) -> (Vec<f64>, Vec<f64>, f64) {
        let off = self.offsets();
        let to64 = |v: &[f32]| v.iter().map(|&v| v as f64).collect::<Vec<f64>>();
        let u = to64(&d.inputs[i * INPUT_DIM..(i + 1) * INPUT_DIM]);
        let x = to64(&d.targets[i * POSITION_DIM..(i + 1) * POSITION_DIM]);
        let f = forward64(p, off[0].start, &self.blocks[0], &u, margin);
        let s = forward64(p, off[1].start, &self.blocks[1], &f, margin)[0];
        (x, f, s)
    }

    pub fn offsets(&self) -> [std::ops::Range<usize>; 6] {
        let mut o = 0;
        std::array::from_fn(|k| {
            let n = n_shape_params(&self.blocks[k]);
            o += n;
            o - n..o
        })
    }
}

pub struct Data {
    pub inputs: Vec<f32>,
    pub targets: Vec<f32>,
    pub absorption: Vec<f32>,
    pub eps: Vec<f32>,
}

pub fn data(rows: usize, seed: u64) -> Data {
    let mut s = Sampler::new(seed, 7, 7, 7);
    Data {
        inputs: uniform(&mut s, rows * INPUT_DIM, 1.5),
        targets: uniform(&mut s, rows * POSITION_DIM, 2.0),
        absorption: uniform(&mut s, rows, 0.45)
            .into_iter()
            .map(|v| v + 0.5)
            .collect(),
        eps: uniform(&mut s, rows * LATENT_DIM, 1.7),
    }
}

/// A small model with non-zero biases (so bias gradients are tested away from the init).
pub fn small_model(seed: u64) -> ShapeAdaptiveModel {
    let w = Widths {
        feature: vec![10, 8],
        absorption_hidden: vec![5],
        decoder_hidden: vec![7, 6],
        encoder_hidden: vec![6, 5],
    };
    let mut m = init_model(&w, Normalisation::identity(), ModelInfo::default(), seed).unwrap();
    let mut p = params_to_flat(&m);
    let mut s = Sampler::new(seed, 9, 9, 9);
    p.iter_mut()
        .for_each(|v| *v += 0.05 * (2.0 * s.next_f32() - 1.0));
    flat_to_params(&mut m, &p);
    m
}

/// Compares the analytic gradient `grad` (flat, all parameters) at the parameters `idx` with f64
/// central differences of `loss64` (which returns the loss and the smallest ReLU margin) around
/// `p0`; `loss32` is the f32 loss the code reported at `p0`.
pub fn check_gradient(
    label: &str,
    r: &Model64,
    grad: &[f32],
    loss32: f64,
    p0: &[f64],
    idx: &[usize],
    loss64: impl Fn(&[f64]) -> (f64, f64),
) {
    let (l0, margin) = loss64(p0);
    assert!(margin > MARGIN, "{label}: ReLU kink too close ({margin:e})");
    assert!(
        (loss32 - l0).abs() <= 1e-5 * l0.abs().max(1.0),
        "{label}: f32 loss {loss32} vs f64 reference {l0}"
    );
    // Largest component over the whole gradient for the absolute part of the tolerance.
    let gmax = grad.iter().fold(0.0f32, |a, b| a.max(b.abs())) as f64;
    for &i in idx {
        let (mut a, mut b) = (p0.to_vec(), p0.to_vec());
        a[i] += H;
        b[i] -= H;
        let fd = (loss64(&a).0 - loss64(&b).0) / (2.0 * H);
        let g = grad[i] as f64;
        let tol = 1e-4 * g.abs() + 1e-5 * gmax + 1e-6;
        let block = r.offsets().iter().position(|o| o.contains(&i)).unwrap();
        assert!(
            (g - fd).abs() <= tol,
            "{label}: {} parameter {i}: analytic {g} vs f64 FD {fd} (tol {tol:.3e})",
            BLOCK_NAMES[block]
        );
    }
}

/// `n` random parameter indices of every block.
pub fn indices_per_block(r: &Model64, n: usize, seed: u64) -> Vec<usize> {
    let mut s = Sampler::new(seed, 5, 5, 5);
    r.offsets()
        .iter()
        .flat_map(|o| {
            let o = o.clone();
            (0..n)
                .map(|_| o.start + s.next_below(o.len() as u32) as usize)
                .collect::<Vec<_>>()
        })
        .collect()
}

/// `f` run on a fresh rayon pool of `threads` threads.
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}
