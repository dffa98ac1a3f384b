//! BVH build time and ray throughput on a noisy icosphere (level 7: 327,680 triangles, radius
//! 0.85–1.15).
//!
//! `cargo bench -p translucent-geometry --bench bvh`
//!
//! Ray sets (100k rays each, fixed seed):
//! * `out`: origin on the sphere of radius 3, aimed at a uniform point of the unit ball;
//! * `in`: origin uniform in the ball of radius 0.8 (inside the object, whose radius is
//!   0.85–1.15), uniform direction (the random-walk case);
//! * occlusion `in` uses a random `tmax` in [0, 1]; occlusion `out` an infinite one;
//! * `inside_length`: from a point inside to a point on the sphere of radius 3 (the NEE shadow
//!   segment of the volumetric path tracer);
//! * `closest_short`: origin inside, uniform direction, `tmax` exponential with mean 0.03 (the
//!   free-flight boundary test of the volumetric path tracer);
//! * `light_inside_length_bvh` / `light_inside_length_lists`: from a point inside to ONE point
//!   light at distance 3 (the shadow rays of one view), by the BVH and by the light's
//!   per-direction triangle lists ([`geometry::LightBins`], built outside the timing;
//!   `light_lists_build` times the build).
//! * `pixel_bins_build`: the per-pixel triangle lists of a 256² pinhole view from distance 3
//!   ([`geometry::PixelBins`]), which every rendered view builds for its camera rays.
//!
//! Every ray benchmark traces the whole batch on an explicit rayon pool of 1 or 2 threads
//! (`args`), and reports the throughput in rays/s (divan "item/s"); Mrays/s = item/s / 1e6.

use std::sync::LazyLock;

use divan::counter::ItemsCount;
use geometry::{Accel, LightBins, Mesh, PixelBins, Shape, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;

fn main() {
    divan::main();
}

const RAYS: usize = 100_000;
const CHUNK: usize = 256;

/// Unit icosphere with `level` subdivisions, CCW outward: the library's `Shape::Sphere`, without
/// normals (the benchmark displaces the vertices).
fn icosphere(level: u32) -> Mesh {
    let mut mesh = Shape::Sphere {
        radius: 1.0,
        subdivisions: level,
    }
    .build()
    .expect("valid sphere");
    mesh.normals = None;
    mesh
}

/// Level-7 icosphere with smooth radial noise (radius 0.85–1.15, two octaves of products of
/// sines), like the dependency survey's benchmark mesh.
static MESH: LazyLock<Mesh> = LazyLock::new(|| {
    let mut mesh = icosphere(7);
    for p in &mut mesh.positions {
        let d = *p;
        let b1 = (5.0 * d.x + 1.0).sin() * (4.0 * d.y + 2.0).sin() * (6.0 * d.z + 0.5).sin();
        let b2 = (13.0 * d.x + 0.3).sin() * (11.0 * d.y + 1.7).sin() * (17.0 * d.z + 2.9).sin();
        *p = d * (1.0 + 0.1 * b1 + 0.05 * b2);
    }
    mesh
});

static ACCEL: LazyLock<Accel> = LazyLock::new(|| Accel::new(MESH.clone()));

fn unit_vector(rng: &mut Pcg32) -> Vec3 {
    let z = 2.0 * rng.random::<f32>() - 1.0;
    let phi = std::f32::consts::TAU * rng.random::<f32>();
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

fn in_ball(rng: &mut Pcg32, radius: f32) -> Vec3 {
    unit_vector(rng) * radius * rng.random::<f32>().cbrt()
}

/// (origin, unit direction, tmax)
type Ray = (Vec3, Vec3, f32);

static RAYS_OUT: LazyLock<Vec<Ray>> = LazyLock::new(|| {
    let mut rng = Pcg32::seed_from_u64(100);
    (0..RAYS)
        .map(|_| {
            let o = unit_vector(&mut rng) * 3.0;
            (o, (in_ball(&mut rng, 1.0) - o).normalize(), f32::INFINITY)
        })
        .collect()
});

/// `RAYS` rays from a uniform point of the ball of radius 0.8 along a uniform direction, with
/// `tmax` drawn by `tmax`.
fn inside_rays(seed: u64, tmax: impl Fn(&mut Pcg32) -> f32) -> Vec<Ray> {
    let mut rng = Pcg32::seed_from_u64(seed);
    (0..RAYS)
        .map(|_| {
            let o = in_ball(&mut rng, 0.8);
            let d = unit_vector(&mut rng);
            (o, d, tmax(&mut rng))
        })
        .collect()
}

static RAYS_IN: LazyLock<Vec<Ray>> = LazyLock::new(|| inside_rays(200, |r| r.random::<f32>()));

static RAYS_SHORT: LazyLock<Vec<Ray>> =
    LazyLock::new(|| inside_rays(400, |r| -r.random::<f32>().ln() * 0.03));

static SEGMENTS: LazyLock<Vec<(Vec3, Vec3)>> = LazyLock::new(|| {
    let mut rng = Pcg32::seed_from_u64(300);
    (0..RAYS)
        .map(|_| (in_ball(&mut rng, 0.8), unit_vector(&mut rng) * 3.0))
        .collect()
});

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// Trace `rays` with `f` on a pool of `threads`, returning a checksum (kept alive by divan).
fn run<T: Sync>(bencher: divan::Bencher, threads: usize, rays: &[T], f: impl Fn(&T) -> u32 + Sync) {
    let pool = pool(threads);
    LazyLock::force(&ACCEL);
    bencher.counter(ItemsCount::new(rays.len())).bench(|| {
        pool.install(|| {
            rays.par_chunks(CHUNK)
                .map(|c| c.iter().map(&f).sum::<u32>())
                .sum::<u32>()
        })
    });
}

#[divan::bench(sample_count = 5, sample_size = 1)]
fn build(bencher: divan::Bencher) {
    let mesh = MESH.clone();
    bencher
        .counter(ItemsCount::new(mesh.triangle_count()))
        .with_inputs(|| mesh.clone())
        .bench_values(Accel::new);
}

/// Deciding `Accel::exit_is_final` for every triangle (each is decided on first use), one
/// thread.
#[divan::bench(sample_count = 5, sample_size = 1)]
fn supporting_planes(bencher: divan::Bencher) {
    let mesh = MESH.clone();
    let n = mesh.triangle_count() as u32;
    bencher
        .counter(ItemsCount::new(n))
        .with_inputs(|| Accel::new(mesh.clone()))
        .bench_values(|a| (0..n).filter(|&i| a.exit_is_final(i)).count());
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn closest_out(bencher: divan::Bencher, threads: usize) {
    run(bencher, threads, &RAYS_OUT, |&(o, d, _)| {
        ACCEL
            .closest(o, d, 0.0, f32::INFINITY)
            .map_or(0, |h| h.tri & 1)
    });
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn closest_in(bencher: divan::Bencher, threads: usize) {
    run(bencher, threads, &RAYS_IN, |&(o, d, _)| {
        ACCEL
            .closest(o, d, 0.0, f32::INFINITY)
            .map_or(0, |h| h.tri & 1)
    });
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn occluded_out(bencher: divan::Bencher, threads: usize) {
    run(bencher, threads, &RAYS_OUT, |&(o, d, tmax)| {
        ACCEL.occluded(o, d, 0.0, tmax) as u32
    });
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn occluded_in(bencher: divan::Bencher, threads: usize) {
    run(bencher, threads, &RAYS_IN, |&(o, d, tmax)| {
        ACCEL.occluded(o, d, 0.0, tmax) as u32
    });
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn inside_length(bencher: divan::Bencher, threads: usize) {
    run(bencher, threads, &SEGMENTS, |&(a, b)| {
        (ACCEL.inside_length(a, b) > 0.5) as u32
    });
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn closest_short(bencher: divan::Bencher, threads: usize) {
    run(bencher, threads, &RAYS_SHORT, |&(o, d, tmax)| {
        ACCEL.closest(o, d, 0.0, tmax).map_or(0, |h| h.tri & 1)
    });
}

/// The point light of the `light_*` benchmarks and the interior points of its shadow rays.
const LIGHT: Vec3 = Vec3::new(1.2, 2.4, 1.2);

static LIGHT_POINTS: LazyLock<Vec<Vec3>> = LazyLock::new(|| {
    let mut rng = Pcg32::seed_from_u64(500);
    (0..RAYS).map(|_| in_ball(&mut rng, 0.8)).collect()
});

/// Lists at the default resolution N = ⌈2√T⌉ (clamped). `LightBins::build` itself declines
/// meshes above `MAX_TRIANGLES` (the tracer keeps the BVH there, measured faster); this mesh is
/// above it, so the lists are built explicitly to measure that trade-off.
fn build_light_bins() -> LightBins {
    let n = ((2.0 * (MESH.triangle_count() as f32).sqrt()).ceil() as u32)
        .clamp(32, geometry::light_bins::MAX_RESOLUTION);
    LightBins::build_with_resolution(&ACCEL, LIGHT, n).expect("light outside the mesh's sphere")
}

static LIGHT_BINS: LazyLock<LightBins> = LazyLock::new(build_light_bins);

#[divan::bench(sample_count = 5, sample_size = 1)]
fn light_lists_build(bencher: divan::Bencher) {
    LazyLock::force(&ACCEL);
    bencher
        .counter(ItemsCount::new(MESH.triangle_count()))
        .bench(build_light_bins);
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn light_inside_length_bvh(bencher: divan::Bencher, threads: usize) {
    run(bencher, threads, &LIGHT_POINTS, |&a| {
        (ACCEL.inside_length(a, LIGHT) > 0.5) as u32
    });
}

#[divan::bench(args = [1, 2], sample_count = 10, sample_size = 1)]
fn light_inside_length_lists(bencher: divan::Bencher, threads: usize) {
    LazyLock::force(&LIGHT_BINS);
    run(bencher, threads, &LIGHT_POINTS, |&a| {
        (LIGHT_BINS.inside_length(&ACCEL, a) > 0.5) as u32
    });
}

#[divan::bench(sample_count = 10, sample_size = 1)]
fn pixel_bins_build(bencher: divan::Bencher) {
    LazyLock::force(&ACCEL);
    let (w, h) = (256u32, 256u32);
    let origin = Vec3::new(0.0, 0.0, 3.0);
    let t = 20f32.to_radians().tan();
    // Looking down −z, x to the right of the image, y up.
    let project = move |p: Vec3| {
        let d = p - origin;
        let z = -d.z;
        (z > 0.0).then(|| {
            let px = (1.0 + d.x / z / t) * 0.5 * w as f32;
            let py = (1.0 - d.y / z / t) * 0.5 * h as f32;
            (px, py, z)
        })
    };
    bencher
        .counter(ItemsCount::new(MESH.triangle_count()))
        .bench(|| PixelBins::build(&ACCEL, w, h, origin, project).map(|b| b.mean_candidates()));
}
