//! Tests of the training-data generator (docs/model.md §5): the exact ray/cubic intersection, the
//! random walk inside the fitted polynomial, an analytic half-space reference (Chandrasekhar's
//! H-function), determinism, and the samples file.

use base::rng::Sampler;
use bssrdf::fit::ConstraintCloud;
use bssrdf::polynomial::Poly3;
use geometry::{AreaSampler, Shape};
use glam::{DVec3, Vec3};
use learn::datagen::{DataConfig, generate};
use learn::sample::{SAMPLE_BYTES, Sample};
use learn::samplefile::{SampleFileError, SampleFileHeader, read_samples, write_samples};
use learn::walk::{WalkMedium, WalkOutcome, WalkSurface, first_root, random_walk};

fn horner(c: &[f64; 4], s: f64) -> f64 {
    ((c[3] * s + c[2]) * s + c[1]) * s + c[0]
}

/// First sign change of the cubic on a dense grid over (lo, hi]: the grid cell containing it.
fn brute_first_root(c: &[f64; 4], lo: f64, hi: f64, n: usize) -> Option<(f64, f64)> {
    let s0 = horner(c, lo).signum();
    let mut prev = lo;
    for i in 1..=n {
        let t = lo + (hi - lo) * i as f64 / n as f64;
        if horner(c, t) * s0 <= 0.0 {
            return Some((prev, t));
        }
        prev = t;
    }
    None
}

#[test]
fn cubic_first_root_matches_dense_sampling() {
    let mut rng = Sampler::new(11, 0, 0, 0);
    let mut u = || rng.next_f32() as f64 * 2.0 - 1.0;
    let n = 20_000;
    let mut hits = 0;
    for case in 0..2000 {
        // Random cubics, some degenerate (lower degree), with roots placed inside the interval.
        let mut c = [u(), u(), u(), u()];
        match case % 5 {
            0 => c[3] = 0.0,
            1 => {
                c[3] = 0.0;
                c[2] = 0.0;
            }
            2 => c[3] *= 1e-9,
            _ => {}
        }
        let (lo, hi) = (0.0, 0.5 + 3.0 * (u() + 1.0));
        if horner(&c, lo) == 0.0 {
            continue;
        }
        let ours = first_root(c, lo, hi);
        let brute = brute_first_root(&c, lo, hi, n);
        let h = (hi - lo) / n as f64;
        match (ours, brute) {
            (Some(t), Some((a, b))) => {
                hits += 1;
                assert!(
                    t >= a - 1e-9 && t <= b + 1e-9,
                    "case {case}: {c:?} root {t} not in [{a}, {b}]"
                );
                let df = (3.0 * c[3] * t + 2.0 * c[2]) * t + c[1];
                assert!(
                    horner(&c, t).abs() <= 1e-10 * (1.0 + df.abs()),
                    "case {case}: f(t) = {}",
                    horner(&c, t)
                );
            }
            (None, None) => {}
            (Some(t), None) => {
                // Only a pair of roots closer than the grid spacing can hide from the grid.
                let next = first_root(c, t, hi).unwrap_or(hi);
                assert!(next - t < 2.0 * h, "case {case}: {c:?} spurious root {t}");
            }
            (None, Some((a, b))) => panic!("case {case}: {c:?} missed root in [{a}, {b}]"),
        }
    }
    assert!(hits > 500, "too few cases with a root: {hits}");
}

fn random_poly(rng: &mut Sampler) -> Poly3 {
    let mut c = [0.0f32; 20];
    for (k, v) in c.iter_mut().enumerate().skip(1) {
        let scale = if k < 4 { 1.0 } else { 0.3 };
        *v = scale * (2.0 * rng.next_f32() - 1.0);
    }
    Poly3(c)
}

#[test]
fn ray_cubic_and_intersection_match_polynomial() {
    let mut rng = Sampler::new(12, 0, 0, 0);
    for case in 0..300 {
        let poly = random_poly(&mut rng);
        let sigma = 0.3 + 2.0 * rng.next_f32() as f64;
        let surf = WalkSurface::new(&poly, sigma);
        let r = DVec3::new(
            rng.next_f32() as f64 - 0.5,
            rng.next_f32() as f64 - 0.5,
            rng.next_f32() as f64 - 0.5,
        );
        let d = DVec3::new(
            rng.next_f32() as f64 - 0.5,
            rng.next_f32() as f64 - 0.5,
            rng.next_f32() as f64 - 0.5,
        )
        .normalize();
        let c = surf.ray_cubic(r / sigma, d);
        for k in 0..5 {
            let s = k as f64 * 0.7 - 1.3;
            let direct = poly.eval_f64((r / sigma + d * s).to_array());
            assert!(
                (horner(&c, s) - direct).abs() < 1e-9 * (1.0 + direct.abs()),
                "case {case}"
            );
        }
        // Intersection from an inside point against dense marching of p along the ray.
        if surf.value(r) >= 0.0 {
            continue;
        }
        let t_max = 5.0;
        let hit = surf.intersect(r, d, t_max, false).unwrap();
        let n = 50_000;
        let brute = (1..=n)
            .map(|i| t_max * i as f64 / n as f64)
            .find(|&t| surf.value(r + d * t) >= 0.0);
        match (hit, brute) {
            (Some(t), Some(b)) => {
                assert!(
                    (t - b).abs() <= t_max / n as f64 + 1e-9,
                    "case {case}: {t} vs {b}"
                );
                assert!(surf.value(r + d * t).abs() < 1e-9, "case {case}");
            }
            (None, None) => {}
            (a, b) => {
                // Tangential double roots may differ; both must then be nearly tangent.
                let t = a.or(b).unwrap();
                assert!(
                    surf.gradient(r + d * t).normalize().dot(d).abs() < 0.05,
                    "case {case}: {a:?} {b:?}"
                );
            }
        }
    }
}

#[test]
fn walk_exits_lie_on_the_fitted_surface() {
    let mut mesh = Shape::from_name("torus")
        .unwrap()
        .scaled(20.0)
        .build()
        .unwrap();
    mesh.transform(glam::Mat4::from_scale(Vec3::new(1.0, 2.5, 0.5)));
    let cloud = ConstraintCloud::from_mesh(&mesh, learn::datagen::cloud_epsilon(), 3).unwrap();
    let sampler = AreaSampler::new(&mesh);
    let mut rng = Sampler::new(13, 0, 0, 0);
    let (mut exits, mut absorbed) = (0, 0);
    for k in 0..40 {
        let s = sampler.sample(&mesh, [rng.next_f32(), rng.next_f32(), rng.next_f32()]);
        let medium = WalkMedium {
            sigma_t: 1.0,
            albedo: 0.9,
            g: if k % 2 == 0 { 0.0 } else { 0.7 },
            eta: if k % 3 == 0 { 1.0 } else { 1.4 },
        };
        let sn = bssrdf::medium::sigma_n(medium.sigma_t, medium.albedo, medium.g);
        let poly = cloud.fit_at(s.p, sn * sn, true).unwrap();
        let n = poly.normal().unwrap();
        let surf = WalkSurface::new(&poly, sn);
        for _ in 0..200 {
            match random_walk(&surf, &medium, -n, &mut rng) {
                WalkOutcome::Exited(e) => {
                    exits += 1;
                    let p = poly.eval_f64((e.position / sn).to_array());
                    assert!(p.abs() < 1e-4, "p(exit) = {p}");
                    assert!(e.normal.dot(e.direction) > 0.0);
                    let g = surf.gradient(e.position).normalize().as_vec3();
                    assert!(g.dot(e.normal) > 0.9999);
                    assert!(e.bounces >= 1 && e.position.is_finite());
                    assert!((e.direction.length() - 1.0).abs() < 1e-4);
                }
                WalkOutcome::Absorbed { bounces } => {
                    absorbed += 1;
                    assert!(bounces >= 1);
                }
                WalkOutcome::Invalid(_) => {}
            }
        }
    }
    assert!(exits > 1000 && absorbed > 100, "{exits} {absorbed}");
}

/// Chandrasekhar's H-function for isotropic scattering with albedo `w`: fixed point of
/// `H(μ) = 1 / (1 − (w/2) μ ∫₀¹ H(μ')/(μ + μ') dμ')` on a Gauss–Legendre grid: `(H(1), ∫₀¹ H dμ)`.
fn chandrasekhar_h(w: f64) -> (f64, f64) {
    let n = 64;
    let (x, wt) = gauss_legendre01(n);
    let mut h = vec![1.0; n];
    let hh = |h: &[f64], mu: f64| {
        let integral: f64 = (0..n).map(|j| wt[j] * h[j] / (mu + x[j])).sum();
        1.0 / (1.0 - 0.5 * w * mu * integral)
    };
    for _ in 0..20_000 {
        let next: Vec<f64> = x.iter().map(|&mu| hh(&h, mu)).collect();
        let diff = next
            .iter()
            .zip(&h)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        h = next;
        if diff < 1e-13 {
            break;
        }
    }
    let moment0 = (0..n).map(|j| wt[j] * h[j]).sum();
    (hh(&h, 1.0), moment0)
}

fn chandrasekhar_h1(w: f64) -> f64 {
    chandrasekhar_h(w).0
}

/// Gauss–Legendre nodes and weights on [0, 1] (Newton on P_n).
fn gauss_legendre01(n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut x, mut w) = (Vec::new(), Vec::new());
    for i in 0..n {
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-15 {
                break;
            }
        }
        x.push(0.5 * (1.0 - z));
        w.push(1.0 / ((1.0 - z * z) * dp * dp));
    }
    (x, w)
}

#[test]
fn h_function_reference_values() {
    // H ≡ 1 for w → 0; zeroth moment identity α₀ = ∫₀¹ H dμ = (2/w)(1 − sqrt(1 − w))
    // (Chandrasekhar 1960, §28); H(1) grows with w.
    assert!((chandrasekhar_h1(1e-9) - 1.0).abs() < 1e-6);
    let mut last = 1.0;
    for w in [0.3, 0.7, 0.95] {
        let (h1, a0) = chandrasekhar_h(w);
        let exact = 2.0 / w * (1.0 - (1.0 - w).sqrt());
        assert!((a0 - exact).abs() < 1e-6, "w = {w}: {a0} vs {exact}");
        assert!(h1 > last, "{h1}");
        last = h1;
    }
}

#[test]
fn half_space_absorption_matches_chandrasekhar() {
    // p = u_z (half-space z < 0), η = 1, g = 0, normal incidence: the escape probability is the
    // plane albedo A(1) = 1 − H(1)·sqrt(1 − α) (Chandrasekhar 1960), so P(absorbed) = H(1)√(1 − α).
    let poly = Poly3::plane(Vec3::Z);
    for (k, &alpha) in [0.3, 0.7, 0.95].iter().enumerate() {
        let medium = WalkMedium {
            sigma_t: 2.0,
            albedo: alpha,
            g: 0.0,
            eta: 1.0,
        };
        let surf = WalkSurface::new(&poly, bssrdf::medium::sigma_n(2.0, alpha, 0.0));
        let mut rng = Sampler::new(14, k as u64, 0, 0);
        let n = 200_000;
        let mut absorbed = 0u64;
        for _ in 0..n {
            match random_walk(&surf, &medium, -Vec3::Z, &mut rng) {
                WalkOutcome::Absorbed { .. } => absorbed += 1,
                WalkOutcome::Exited(e) => assert!(e.position.z.abs() < 1e-9 && e.direction.z > 0.0),
                WalkOutcome::Invalid(r) => panic!("invalid path {r:?}"),
            }
        }
        let expected = chandrasekhar_h1(alpha) * (1.0 - alpha).sqrt();
        let p = absorbed as f64 / n as f64;
        let se = (expected * (1.0 - expected) / n as f64).sqrt();
        assert!(
            (p - expected).abs() < 4.0 * se,
            "α = {alpha}: {p} vs {expected} ± {se}"
        );
    }
}

fn small_config(seed: u64) -> DataConfig {
    DataConfig {
        meshes: 2,
        configs_per_mesh: 12,
        path_attempts: 256,
        seed,
        ..Default::default()
    }
}

#[test]
fn generated_samples_are_consistent() {
    let cfg = small_config(5);
    let (samples, summary) = generate(&cfg, None).unwrap();
    assert_eq!(summary.samples, samples.len());
    assert_eq!(
        samples.len(),
        (summary.configs - summary.configs_skipped) * cfg.samples_per_config
    );
    assert!(samples.len() >= 16 * 20, "{summary:?}");
    for (i, s) in samples.iter().enumerate() {
        let floats: &[f32] = bytemuck::cast_slice::<Sample, f32>(std::slice::from_ref(s));
        assert!(floats[..47].iter().all(|v| v.is_finite()), "sample {i}");
        assert!((0.0..=1.0).contains(&s.absorption_prob));
        assert!(s.albedo > 0.0 && s.albedo <= 1.0 && s.g >= 0.0 && s.g < 1.0);
        assert!(s.eta >= 1.0 && s.eta <= 1.5 && s.sigma_t > 0.0 && s.bounces >= 1);
        assert_eq!(s.poly_ls[0], 0.0);
        let sn = bssrdf::medium::sigma_n(s.sigma_t as f64, s.albedo as f64, s.g as f64);
        assert!((s.sigma_n as f64 - sn).abs() < 1e-5 * sn);
        // out_ls = R_LSᵀ(out − in)/σ_n.
        let f = bssrdf::polynomial::light_space_frame(Vec3::from(s.in_dir));
        let r = (Vec3::from(s.out_pos) - Vec3::from(s.in_pos)) / s.sigma_n;
        let ls = f.to_local(r);
        let tol = 1e-4 * (1.0 + Vec3::from(s.in_pos).length() / s.sigma_n);
        assert!(
            (ls - Vec3::from(s.out_ls)).abs().max_element() < tol,
            "sample {i}"
        );
        // The exit lies on the LS polynomial; out normal · out dir > 0; in_dir enters.
        let p = Poly3(s.poly_ls).eval_f64(Vec3::from(s.out_ls).as_dvec3().to_array());
        let scale = 1.0 + Vec3::from(s.out_ls).length().powi(3) as f64;
        assert!(p.abs() < 1e-4 * scale, "sample {i}: p = {p}");
        assert!(Vec3::from(s.out_normal).dot(Vec3::from(s.out_dir)) > 0.0);
        assert!(Vec3::from(s.in_normal).dot(Vec3::from(s.in_dir)) < 0.0);
        let mesh = learn::datagen::mesh_of(s, cfg.configs_per_mesh);
        assert!(mesh < 2);
    }
    for m in &summary.meshes {
        assert!(
            samples[m.first_sample..m.first_sample + m.samples]
                .iter()
                .all(|s| learn::datagen::mesh_of(s, cfg.configs_per_mesh) == m.index)
        );
    }
    // The g = 0 / η = 1 masses exist.
    assert!(samples.iter().any(|s| s.g == 0.0) && samples.iter().any(|s| s.eta == 1.0));
    assert!(samples.iter().any(|s| s.g > 0.0) && samples.iter().any(|s| s.eta > 1.0));
}

#[test]
fn generation_is_deterministic_for_any_thread_count() {
    let cfg = small_config(6);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| generate(&cfg, None).unwrap().0)
    };
    let a = run(1);
    let b = run(3);
    let c = generate(&cfg, None).unwrap().0;
    assert!(!a.is_empty());
    let bytes = |v: &Vec<Sample>| bytemuck::cast_slice::<Sample, u8>(v).to_vec();
    assert_eq!(bytes(&a), bytes(&b));
    assert_eq!(bytes(&a), bytes(&c));
    let other = generate(&small_config(7), None).unwrap().0;
    assert_ne!(bytes(&a), bytes(&other));
}

#[test]
fn samples_file_round_trip_and_errors() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = DataConfig {
        meshes: 1,
        configs_per_mesh: 3,
        path_attempts: 64,
        ..Default::default()
    };
    let (samples, summary) = generate(&cfg, None).unwrap();
    let header = SampleFileHeader::new(&cfg, Some(&summary));
    let path = dir.path().join("train.samples");
    write_samples(&path, &header, &samples, false).unwrap();
    let (h, back) = read_samples(&path).unwrap();
    assert_eq!(h.sample_count as usize, samples.len());
    assert_eq!(h.record_size, SAMPLE_BYTES);
    assert_eq!(back, samples);
    // Refuses to overwrite unless told.
    assert!(matches!(
        write_samples(&path, &header, &samples, false),
        Err(SampleFileError::Exists { .. })
    ));
    write_samples(&path, &header, &samples[..2], true).unwrap();
    assert_eq!(read_samples(&path).unwrap().1.len(), 2);
    write_samples(&path, &header, &samples, true).unwrap();
    let good = std::fs::read(&path).unwrap();
    let hlen = u32::from_le_bytes(good[12..16].try_into().unwrap()) as usize;
    let corrupt = |name: &str, bytes: Vec<u8>| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let e = read_samples(&p).unwrap_err();
        assert!(e.to_string().contains(name), "{e}");
        e
    };
    let mut b = good.clone();
    b[0] = b'X';
    assert!(matches!(
        corrupt("magic", b),
        SampleFileError::BadMagic { .. }
    ));
    let mut b = good.clone();
    b[8] = 9;
    assert!(matches!(
        corrupt("version", b),
        SampleFileError::Version { found: 9, .. }
    ));
    assert!(matches!(
        corrupt("short", good[..20].to_vec()),
        SampleFileError::Truncated { .. }
    ));
    let mut b = good.clone();
    b[16] = b'!';
    assert!(matches!(corrupt("json", b), SampleFileError::Header { .. }));
    let json = String::from_utf8(good[16..16 + hlen].to_vec()).unwrap();
    let with_json = |j: String| {
        let mut b = good[..8].to_vec();
        b.extend_from_slice(&1u32.to_le_bytes());
        b.extend_from_slice(&(j.len() as u32).to_le_bytes());
        b.extend_from_slice(j.as_bytes());
        b.extend_from_slice(&good[16 + hlen..]);
        b
    };
    let e = corrupt(
        "recsize",
        with_json(json.replace("\"record_size\":196", "\"record_size\":200")),
    );
    assert!(matches!(e, SampleFileError::RecordSize { found: 200, .. }));
    let e = corrupt(
        "layout",
        with_json(json.replace("\"out_ls\"", "\"out_xx\"")),
    );
    assert!(matches!(e, SampleFileError::Layout { .. }));
    let e = corrupt("length", good[..good.len() - 4].to_vec());
    assert!(matches!(e, SampleFileError::Length { .. }));
    let mut b = good.clone();
    let off = 16 + hlen + SAMPLE_BYTES + 92; // record 1, albedo
    b[off..off + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    match corrupt("nan", b) {
        SampleFileError::NonFinite { record, field, .. } => {
            assert_eq!(record, 1);
            assert_eq!(field, "albedo");
        }
        e => panic!("{e}"),
    }
    // No temporary files are left behind.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(left.is_empty());
}

/// Throughput (release): `cargo test --release -p translucent-learn --test integration
/// datagen::throughput -- --ignored --nocapture`.
#[test]
#[ignore]
fn throughput() {
    let cfg = DataConfig {
        meshes: 2,
        configs_per_mesh: 1500,
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let (samples, summary) = generate(&cfg, None).unwrap();
    let s = t.elapsed().as_secs_f64();
    println!(
        "{} samples in {s:.2} s = {:.0} samples/s on {} threads; paths {} ({:.0}/s), skipped {}, invalid {}",
        samples.len(),
        samples.len() as f64 / s,
        rayon::current_num_threads(),
        summary.paths,
        summary.paths as f64 / s,
        summary.configs_skipped,
        summary.invalid
    );
}
