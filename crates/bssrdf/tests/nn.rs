//! Batched MLP inference: agreement with the naive f64 reference (features, absorption, decoder,
//! encoder; serial and parallel; odd chunk sizes), the forward-mode input derivative of Absorb
//! against central finite differences, batch validation, allocation-free warm workspaces, and a
//! printed (not asserted) decoder throughput measurement. Deterministic (fixed seeds, Pcg32).

use std::time::Instant;

use bssrdf::model::ModelInfo;
use bssrdf::nn::{
    ALBEDO_INPUT, Dense, Encoder, INPUT_DIM, LATENT_DIM, Normalisation, POSITION_DIM,
    ShapeAdaptiveModel, Workspace, reference,
};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;

/// Random models and inputs.
mod support {
    use super::*;

    /// A layer with He-like uniform weights and small random biases (so that ReLUs are mixed).
    pub fn layer(rng: &mut Pcg32, n_in: usize, n_out: usize) -> Dense {
        let s = (6.0 / n_in as f32).sqrt();
        let w = (0..n_in * n_out).map(|_| rng.random_range(-s..s)).collect();
        let b = (0..n_out).map(|_| rng.random_range(-0.3..0.3)).collect();
        Dense::new(n_in, n_out, w, b).unwrap()
    }

    pub fn block(rng: &mut Pcg32, widths: &[usize]) -> Vec<Dense> {
        widths.windows(2).map(|w| layer(rng, w[0], w[1])).collect()
    }

    /// A random model with feature widths `[23, hidden…, F]`, absorption hidden width, decoder
    /// and encoder hidden widths.
    pub fn model(
        seed: u64,
        feature: &[usize],
        absorption_hidden: usize,
        hidden: &[usize],
    ) -> ShapeAdaptiveModel {
        let mut rng = Pcg32::seed_from_u64(seed);
        let f = *feature.last().unwrap();
        let feat = block(&mut rng, feature);
        let abs = block(&mut rng, &[f, absorption_hidden, 1]);
        let dec_w: Vec<usize> = std::iter::once(LATENT_DIM + f)
            .chain(hidden.iter().copied())
            .chain(std::iter::once(POSITION_DIM))
            .collect();
        let dec = block(&mut rng, &dec_w);
        let enc_w: Vec<usize> = std::iter::once(POSITION_DIM + f)
            .chain(hidden.iter().copied())
            .collect();
        let h = *hidden.last().unwrap();
        let enc = Encoder::new(
            block(&mut rng, &enc_w),
            layer(&mut rng, h, LATENT_DIM),
            layer(&mut rng, h, LATENT_DIM),
        )
        .unwrap();
        ShapeAdaptiveModel::new(
            feat,
            abs,
            dec,
            Some(enc),
            Normalisation::identity(),
            ModelInfo::default(),
        )
        .unwrap()
    }

    /// SON24 "light" widths: 23 → 32 → 32, absorption 32 → 16 → 1, decoder 36 → 32 → 32 → 3.
    pub fn son24_like(seed: u64) -> ShapeAdaptiveModel {
        model(seed, &[23, 32, 32], 16, &[32, 32])
    }

    /// VKJ19 widths: 23 → 64 → 64 → 64, absorption 64 → 32 → 1, decoder 68 → 64³ → 3.
    pub fn vkj19_like(seed: u64) -> ShapeAdaptiveModel {
        model(seed, &[23, 64, 64, 64], 32, &[64, 64, 64])
    }

    pub fn inputs(rng: &mut Pcg32, n: usize) -> Vec<[f32; INPUT_DIM]> {
        (0..n)
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.5..1.5)))
            .collect()
    }

    pub fn latents(rng: &mut Pcg32, n: usize) -> Vec<[f32; LATENT_DIM]> {
        (0..n)
            .map(|_| std::array::from_fn(|_| rng.random_range(-2.5..2.5)))
            .collect()
    }

    /// Max over the batch of |got − want| / max(|want|, floor), with `floor` the RMS of `want`
    /// (values near zero after cancellation are compared at the batch's scale).
    pub fn max_rel_err(got: &[f32], want: &[f64]) -> f64 {
        assert_eq!(got.len(), want.len());
        let rms = (want.iter().map(|v| v * v).sum::<f64>() / want.len() as f64).sqrt();
        got.iter()
            .zip(want)
            .map(|(&g, &w)| (g as f64 - w).abs() / w.abs().max(rms).max(1e-30))
            .fold(0.0, f64::max)
    }

    pub fn percentile(v: &mut [f64], p: f64) -> f64 {
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        v[((v.len() - 1) as f64 * p).round() as usize]
    }
}

use support::*;

const TOL: f64 = 1e-5;

#[test]
fn features_and_absorb_match_reference() {
    for (name, model) in [("son24", son24_like(1)), ("vkj19", vkj19_like(2))] {
        let mut rng = Pcg32::seed_from_u64(3);
        let n = 2_500; // not a multiple of any chunk size used
        let x = inputs(&mut rng, n);
        let f_dim = model.feature_dim();
        let want_f: Vec<Vec<f64>> = x.iter().map(|r| reference::features(&model, r)).collect();
        let want_flat: Vec<f64> = want_f.iter().flatten().copied().collect();
        let want_a: Vec<f64> = want_f
            .iter()
            .map(|f| reference::absorb(&model, f))
            .collect();

        // Parallel path.
        let mut f = vec![0.0; n * f_dim];
        model.features(&x, &mut f).unwrap();
        let e = max_rel_err(&f, &want_flat);
        assert!(e < TOL, "{name}: features (parallel) max rel err {e:e}");
        let mut a = vec![0.0; n];
        model.absorb(&f, &mut a).unwrap();
        let e = max_rel_err(&a, &want_a);
        assert!(e < TOL, "{name}: absorb (parallel) max rel err {e:e}");
        assert!(a.iter().all(|&v| v > 0.0 && v < 1.0));
        // Mixed ReLU activity: the test would be vacuous if all features were 0 or all positive.
        let zeros = f.iter().filter(|&&v| v == 0.0).count();
        assert!(
            zeros > n && zeros < n * f_dim - n,
            "{name}: {zeros} zero features"
        );

        // Serial path with odd chunk sizes, including chunk 1.
        for chunk in [1, 7, 256, 4096] {
            let mut ws = Workspace::with_chunk_rows(chunk);
            let mut f2 = vec![0.0; n * f_dim];
            model.features_with(&x, &mut f2, &mut ws).unwrap();
            let e = max_rel_err(&f2, &want_flat);
            assert!(e < TOL, "{name}: features chunk {chunk} max rel err {e:e}");
            let mut a2 = vec![0.0; n];
            model.absorb_with(&f2, &mut a2, &mut ws).unwrap();
            let e = max_rel_err(&a2, &want_a);
            assert!(e < TOL, "{name}: absorb chunk {chunk} max rel err {e:e}");
        }
    }
}

#[test]
fn decode_matches_reference_with_shared_features() {
    for (name, model) in [("son24", son24_like(4)), ("vkj19", vkj19_like(5))] {
        let mut rng = Pcg32::seed_from_u64(6);
        let n_points = 37;
        let n_samples = 3_001;
        let x = inputs(&mut rng, n_points);
        let f_dim = model.feature_dim();
        let mut f = vec![0.0; n_points * f_dim];
        model.features(&x, &mut f).unwrap();
        let z = latents(&mut rng, n_samples);
        let idx: Vec<u32> = (0..n_samples)
            .map(|_| rng.random_range(0..n_points as u32))
            .collect();
        // The reference uses the same f32 features (widened), so only the decoder is compared.
        let want: Vec<f64> = z
            .iter()
            .zip(&idx)
            .flat_map(|(zs, &p)| {
                let fp: Vec<f64> = f[p as usize * f_dim..(p as usize + 1) * f_dim]
                    .iter()
                    .map(|&v| v as f64)
                    .collect();
                reference::decode(&model, &fp, zs)
            })
            .collect();
        let mut out = vec![[0.0; 3]; n_samples];
        model.decode(&f, &z, &idx, &mut out).unwrap();
        let e = max_rel_err(out.as_flattened(), &want);
        assert!(e < TOL, "{name}: decode (parallel) max rel err {e:e}");
        for chunk in [1, 13, 1024] {
            let mut ws = Workspace::with_chunk_rows(chunk);
            let mut out2 = vec![[0.0; 3]; n_samples];
            model.decode_with(&f, &z, &idx, &mut out2, &mut ws).unwrap();
            let e = max_rel_err(out2.as_flattened(), &want);
            assert!(e < TOL, "{name}: decode chunk {chunk} max rel err {e:e}");
        }
    }
}

#[test]
fn encode_matches_reference() {
    let model = son24_like(7);
    let mut rng = Pcg32::seed_from_u64(8);
    let (n_points, n) = (11, 777);
    let x = inputs(&mut rng, n_points);
    let f_dim = model.feature_dim();
    let mut f = vec![0.0; n_points * f_dim];
    model.features(&x, &mut f).unwrap();
    let pos: Vec<[f32; 3]> = (0..n)
        .map(|_| std::array::from_fn(|_| rng.random_range(-3.0..3.0)))
        .collect();
    let idx: Vec<u32> = (0..n).map(|i| (i % n_points) as u32).collect();
    let mut mean = vec![[0.0; 4]; n];
    let mut logvar = vec![[0.0; 4]; n];
    let mut ws = Workspace::with_chunk_rows(100);
    model
        .encode_with(&f, &pos, &idx, &mut mean, &mut logvar, &mut ws)
        .unwrap();
    let (mut wm, mut wl) = (Vec::new(), Vec::new());
    for (p, &i) in pos.iter().zip(&idx) {
        let fp: Vec<f64> = f[i as usize * f_dim..(i as usize + 1) * f_dim]
            .iter()
            .map(|&v| v as f64)
            .collect();
        let (m, l) = reference::encode(&model, &fp, p).unwrap();
        wm.extend(m);
        wl.extend(l);
    }
    let e = max_rel_err(mean.as_flattened(), &wm).max(max_rel_err(logvar.as_flattened(), &wl));
    assert!(e < TOL, "encode max rel err {e:e}");
}

/// Absorb of one input row with the f64 reference.
fn absorb_ref(model: &ShapeAdaptiveModel, x: &[f64; INPUT_DIM]) -> f64 {
    let f = reference::mlp(model.feature_mlp(), x);
    reference::absorb(model, &f)
}

#[test]
fn absorb_input_derivative_matches_finite_differences() {
    for (name, model) in [("son24", son24_like(9)), ("vkj19", vkj19_like(10))] {
        let mut rng = Pcg32::seed_from_u64(11);
        let n = 2_000;
        let x = inputs(&mut rng, n);
        for k in [ALBEDO_INPUT, 21, 22, 3, 0] {
            let mut a = vec![0.0; n];
            let mut d = vec![0.0; n];
            model
                .absorb_input_derivative(&x, k, &mut a, &mut d)
                .unwrap();
            let mut ws = Workspace::with_chunk_rows(97);
            let (mut a2, mut d2) = (vec![0.0; n], vec![0.0; n]);
            model
                .absorb_input_derivative_with(&x, k, &mut a2, &mut d2, &mut ws)
                .unwrap();
            // Other chunk sizes change gemm's blocking, hence the last bits only.
            let close = |u: &[f32], v: &[f32]| {
                u.iter()
                    .zip(v)
                    .map(|(p, q)| (p - q).abs())
                    .fold(0.0f32, f32::max)
            };
            assert!(
                close(&a, &a2) < 1e-6,
                "{name}: serial and parallel Absorb differ"
            );
            assert!(
                close(&d, &d2) < 1e-6,
                "{name}: serial and parallel derivatives differ"
            );
            // Absorb itself equals the plain forward pass.
            let mut f = vec![0.0; n * model.feature_dim()];
            model.features(&x, &mut f).unwrap();
            let mut a3 = vec![0.0; n];
            model.absorb(&f, &mut a3).unwrap();
            for (u, v) in a.iter().zip(&a3) {
                assert!((u - v).abs() <= 1e-6, "{name}: Absorb {u} vs {v}");
            }

            // Central differences of the f64 reference (h small: few steps cross a ReLU kink).
            let h = 1e-5;
            let scale = d.iter().map(|v| v.abs() as f64).fold(0.0, f64::max);
            let mut errs: Vec<f64> = x
                .iter()
                .zip(&d)
                .map(|(row, &dk)| {
                    let mut xp: [f64; INPUT_DIM] = std::array::from_fn(|i| row[i] as f64);
                    let mut xm = xp;
                    xp[k] += h;
                    xm[k] -= h;
                    let fd = (absorb_ref(&model, &xp) - absorb_ref(&model, &xm)) / (2.0 * h);
                    (dk as f64 - fd).abs() / fd.abs().max(1e-3 * scale)
                })
                .collect();
            let median = percentile(&mut errs, 0.5);
            let p95 = percentile(&mut errs, 0.95);
            let p99 = percentile(&mut errs, 0.99);
            eprintln!(
                "{name} d Absorb / d input {k}: max |d| {scale:.3e}, rel err median {median:.2e}, \
                 p95 {p95:.2e}, p99 {p99:.2e}"
            );
            assert!(median < 1e-5, "{name} input {k}: median rel err {median:e}");
            assert!(
                p95 < 1e-4,
                "{name} input {k}: 95th percentile rel err {p95:e}"
            );
        }
    }
}

#[test]
fn batch_errors_are_reported() {
    let model = son24_like(12);
    let f_dim = model.feature_dim();
    let x = vec![[0.0; INPUT_DIM]; 4];
    let mut f = vec![0.0; 4 * f_dim - 1];
    assert!(model.features(&x, &mut f).is_err());
    let f = vec![0.0; 4 * f_dim];
    let mut a = vec![0.0; 3];
    assert!(model.absorb(&f, &mut a).is_err());
    assert!(model.absorb(&f[..f_dim + 1], &mut [0.0; 1]).is_err());
    let z = vec![[0.0; 4]; 5];
    let mut out = vec![[0.0; 3]; 5];
    let err = model
        .decode(&f, &z, &[0, 1, 2, 3, 4], &mut out)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sample 4") && err.contains("shading point 4"),
        "{err}"
    );
    assert!(model.decode(&f, &z, &[0, 1], &mut out).is_err());
    let mut ws = Workspace::new();
    assert!(
        model
            .decode_with(&f, &z, &[0; 5], &mut out[..4], &mut ws)
            .is_err()
    );
    let (mut a, mut d) = (vec![0.0; 4], vec![0.0; 4]);
    let err = model
        .absorb_input_derivative(&x, INPUT_DIM, &mut a, &mut d)
        .unwrap_err()
        .to_string();
    assert!(err.contains("input index 23"), "{err}");
    // Empty batches are fine.
    model.features(&[], &mut []).unwrap();
    model.decode(&f, &[], &[], &mut []).unwrap();
}

#[test]
fn warm_workspace_does_not_grow() {
    let model = son24_like(13);
    let mut rng = Pcg32::seed_from_u64(14);
    let x = inputs(&mut rng, 5_000);
    let z = latents(&mut rng, 20_000);
    let idx: Vec<u32> = (0..20_000).map(|i| (i % 5_000) as u32).collect();
    let mut f = vec![0.0; 5_000 * model.feature_dim()];
    let mut a = vec![0.0; 5_000];
    let mut d = vec![0.0; 5_000];
    let mut out = vec![[0.0; 3]; 20_000];
    let mut ws = Workspace::new();
    let mut run = |ws: &mut Workspace| {
        model.features_with(&x, &mut f, ws).unwrap();
        model.absorb_with(&f, &mut a, ws).unwrap();
        model
            .absorb_input_derivative_with(&x, ALBEDO_INPUT, &mut a, &mut d, ws)
            .unwrap();
        model.decode_with(&f, &z, &idx, &mut out, ws).unwrap();
    };
    run(&mut ws);
    let size = ws.capacity_bytes();
    run(&mut ws);
    assert_eq!(ws.capacity_bytes(), size);
    assert!(size > 0);
}

/// CPU time of the calling thread in seconds (Linux), or `None`.
fn thread_cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    Some(s.split_whitespace().next()?.parse::<f64>().ok()? * 1e-9)
}

/// `some avg10` of /proc/pressure/cpu (share of time tasks waited for a CPU), if available.
fn cpu_pressure() -> String {
    std::fs::read_to_string("/proc/pressure/cpu")
        .ok()
        .and_then(|s| s.lines().next().map(str::to_string))
        .unwrap_or_else(|| "n/a".to_string())
}

/// Decoder throughput (printed, not asserted): samples/s on 1 and 2 threads for 1M samples
/// spread over 4096 shading points (256 samples per point). Single-thread figures use the
/// thread's CPU time (robust on a shared machine), two-thread figures wall time; best of 5.
/// Meaningful only in an optimised build, hence ignored by default: `cargo test --release -p
/// translucent-bssrdf --test integration nn::decoder_throughput -- --ignored --nocapture`.
#[test]
#[ignore = "timing; run with --release -- --ignored --nocapture"]
fn decoder_throughput() {
    let n = 1 << 20;
    let n_points = 4096;
    eprintln!("CPU pressure before: {}", cpu_pressure());
    for (name, model) in [("son24 light", son24_like(15)), ("vkj19", vkj19_like(16))] {
        let mut rng = Pcg32::seed_from_u64(17);
        let x = inputs(&mut rng, n_points);
        let mut f = vec![0.0; n_points * model.feature_dim()];
        model.features(&x, &mut f).unwrap();
        let z = latents(&mut rng, n);
        let idx: Vec<u32> = (0..n).map(|i| (i % n_points) as u32).collect();
        let mut out = vec![[0.0; 3]; n];
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut best_wall = f64::INFINITY;
            let mut best_cpu = f64::INFINITY;
            for _ in 0..5 {
                let t = Instant::now();
                let cpu = pool.install(|| {
                    let c0 = thread_cpu_seconds();
                    model.decode(&f, &z, &idx, &mut out).unwrap();
                    c0.zip(thread_cpu_seconds()).map(|(a, b)| b - a)
                });
                best_wall = best_wall.min(t.elapsed().as_secs_f64());
                if let Some(c) = cpu {
                    best_cpu = best_cpu.min(c);
                }
            }
            let rate = |s: f64| n as f64 / s / 1e6;
            if threads == 1 && best_cpu.is_finite() {
                eprintln!(
                    "decoder {name}, 1 thread: {:.2} M samples/s (thread CPU time), {:.2} M/s wall",
                    rate(best_cpu),
                    rate(best_wall)
                );
            } else {
                eprintln!(
                    "decoder {name}, {threads} threads: {:.2} M samples/s wall",
                    rate(best_wall)
                );
            }
        }
        // Features + absorption (one evaluation per shading point), 1 thread, for comparison.
        let xs = inputs(&mut rng, n);
        let mut fs = vec![0.0; n * model.feature_dim()];
        let mut a = vec![0.0; n];
        let mut ws = Workspace::new();
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t = Instant::now();
            let c0 = thread_cpu_seconds();
            model.features_with(&xs, &mut fs, &mut ws).unwrap();
            model.absorb_with(&fs, &mut a, &mut ws).unwrap();
            let c = c0.zip(thread_cpu_seconds()).map(|(a, b)| b - a);
            best = best.min(c.unwrap_or(t.elapsed().as_secs_f64()));
        }
        eprintln!(
            "features + absorb {name}, 1 thread: {:.2} M points/s",
            n as f64 / best / 1e6
        );
    }
    eprintln!("CPU pressure after: {}", cpu_pressure());
}
