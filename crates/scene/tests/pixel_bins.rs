//! The camera's per-pixel triangle lists ([`Camera::pixel_bins`], [`geometry::PixelBins`])
//! against the BVH they replace for primary rays: for every ray the answer must be exactly
//! `Accel::closest` of the same ray (same `Hit`, bit for bit). Rays: every pixel at jitters that
//! include the pixel's corners and its far edge (0.99999994), random jitters, and rays through the
//! projections of mesh vertices and edge midpoints (a hit on a shared vertex or edge, where the
//! tie-break decides). Deterministic.

use geometry::{Accel, Mesh, Shape, Vec3, bvh::offset_origin, sharp_box};
use glam::Mat3;
use scene::Camera;

/// SplitMix64 uniforms in [0, 1) (a fixed, dependency-free stream).
struct Uniforms(u64);

impl Uniforms {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn meshes() -> Vec<(String, Mesh)> {
    let mut out: Vec<(String, Mesh)> = Shape::NAMES
        .iter()
        .map(|name| {
            (
                name.to_string(),
                Shape::from_name(name).unwrap().build().unwrap(),
            )
        })
        .collect();
    out.push((
        "sharp box".into(),
        sharp_box(Vec3::new(-0.5, -0.3, -0.4), Vec3::new(0.5, 0.3, 0.4)),
    ));
    out
}

/// Each test mesh with its BVH, bounding-box centre and half-diagonal.
fn scenes() -> impl Iterator<Item = (String, Mesh, Accel, Vec3, f32)> {
    meshes().into_iter().map(|(name, mesh)| {
        let accel = Accel::new(mesh.clone());
        let (lo, hi) = mesh.bounds();
        let (center, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
        (name, mesh, accel, center, radius)
    })
}

fn cameras(center: Vec3, radius: f32) -> Vec<Camera> {
    let mut out = Vec::new();
    for (k, (dir, dist, fov)) in [
        (Vec3::new(0.0, 0.3, 1.0), 3.0f32, 45.0f32),
        (Vec3::new(1.0, 0.8, -0.6), 2.0, 70.0),
        (Vec3::new(-0.2, -1.0, 0.1), 6.0, 20.0),
        // Along an axis: the sharp box's faces are seen exactly edge-on at the silhouette.
        (Vec3::X, 4.0, 30.0),
    ]
    .into_iter()
    .enumerate()
    {
        let origin = center + dir.normalize() * dist * radius;
        let up = if dir.cross(Vec3::Y).length() < 1e-3 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        let (w, h) = if k % 2 == 0 { (40, 32) } else { (33, 47) };
        out.push(Camera::look_at(origin, center, up, fov, w, h));
    }
    // A crop window of a larger film.
    let full = Camera::look_at(
        center + Vec3::new(0.4, 0.2, 1.0).normalize() * 3.0 * radius,
        center,
        Vec3::Y,
        40.0,
        96,
        80,
    );
    out.push(full.cropped(30, 21, 37, 29).unwrap());
    // A calibrated camera: the principal point off the centre, f_y ≠ f_x; and a crop of it.
    let k = scene::Intrinsics {
        fx: 70.0,
        fy: 77.5,
        cx: 41.3,
        cy: 33.9,
    };
    let calibrated = Camera::look_at(
        center + Vec3::new(-0.5, 0.4, 0.9).normalize() * 3.0 * radius,
        center,
        Vec3::Y,
        40.0,
        64,
        56,
    )
    .with_intrinsics(&k);
    assert!(calibrated.pinhole.is_some());
    out.push(calibrated.cropped(5, 9, 41, 30).unwrap());
    out.push(calibrated);
    out
}

/// `bins.closest`, `bins.closest_film` and `accel.closest` for the ray through film point
/// (x + jx, y + jy).
fn check(
    cam: &Camera,
    accel: &Accel,
    bins: &geometry::PixelBins,
    x: u32,
    y: u32,
    j: (f32, f32),
) -> bool {
    let (o, d) = cam.ray(x as f32 + j.0, y as f32 + j.1);
    let want = accel.closest(o, d, 0.0, f32::INFINITY);
    let got = bins.closest(accel, x, y, d, 0.0, f32::INFINITY);
    assert_eq!(got, want, "pixel ({x}, {y}) jitter {j:?}: ray {o} {d}");
    // With the film-space edge pre-test (x + jx may round up to the pixel's right edge).
    let (fx, fy) = (x as f32 + j.0, y as f32 + j.1);
    let got = bins.closest_film(accel, fx, fy, d, 0.0, f32::INFINITY);
    assert_eq!(got, want, "closest_film ({fx}, {fy}): ray {o} {d}");
    // The RayGen path the renderers use generates the same ray.
    assert_eq!(cam.ray_gen().ray(x as f32 + j.0, y as f32 + j.1), (o, d));
    want.is_some()
}

/// Counts of the continued queries ([`continuation`]): answered by the lists, left to the BVH.
#[derive(Default)]
struct Continued {
    answered: usize,
    declined: usize,
}

/// The camera ray through film point `(fx, fy)` continued through every boundary it crosses
/// as an index-matched medium's path does before it scatters: from the spawned origin, a short
/// flight (`tmax` drawn on the scale of `radius`) and then an unlimited one, through one cursor
/// and through a fresh one, each answer equal to
/// `accel.closest` of the same ray whenever the lists give one. Every other origin is also
/// moved sideways by `push` (× radius): the lists must then decline or still be exact.
#[allow(clippy::too_many_arguments)]
fn continuation(
    cam: &Camera,
    accel: &Accel,
    bins: &geometry::PixelBins,
    (fx, fy): (f32, f32),
    radius: f32,
    push: f32,
    u: &mut Uniforms,
    n: &mut Continued,
) {
    let (o, d) = cam.ray(fx, fy);
    let project = cam.projector();
    let mut cursor = bins.cursor(fx, fy);
    let mut hit = bins.closest_first(accel, &mut cursor, d, 0.0, f32::INFINITY);
    assert_eq!(hit, accel.closest(o, d, 0.0, f32::INFINITY));
    let side = d.any_orthonormal_vector();
    for crossing in 0..16 {
        let Some(h) = hit else { break };
        let mut o2 = offset_origin(h.p, h.ng, d);
        if crossing % 2 == 1 {
            o2 += push * radius * side;
        }
        let at = project(o2).expect("in front of the camera");
        let short = -(1.0 - u.next()).ln() * 0.2 * radius;
        for tmax in [short, f32::INFINITY] {
            let want = accel.closest(o2, d, 0.0, tmax);
            let fresh = bins.closest_next(accel, &mut bins.cursor(fx, fy), o2, at, d, 0.0, tmax);
            let got = bins.closest_next(accel, &mut cursor, o2, at, d, 0.0, tmax);
            assert_eq!(got, fresh, "cursor and fresh lists differ at ({fx}, {fy})");
            match got {
                Some(got) => {
                    assert_eq!(got, want, "continued ray at ({fx}, {fy}), tmax {tmax}");
                    n.answered += 1;
                }
                None => n.declined += 1,
            }
            hit = want;
        }
    }
}

#[test]
fn pixel_bins_answer_primary_rays_exactly_like_the_bvh() {
    let mut u = Uniforms(11);
    for (name, mesh, accel, center, radius) in scenes() {
        let (mut hits, mut misses) = (0, 0);
        for cam in cameras(center, radius) {
            let bins = cam
                .pixel_bins(&accel)
                .unwrap_or_else(|| panic!("{name}: no bins for {cam:?}"));
            assert_eq!(bins.size(), (cam.width, cam.height));
            let mut count = |hit: bool| if hit { hits += 1 } else { misses += 1 };
            for y in 0..cam.height {
                for x in 0..cam.width {
                    for j in [(0.0, 0.0), (0.5, 0.5), (0.999_999_94, 0.999_999_94)] {
                        count(check(&cam, &accel, &bins, x, y, j));
                    }
                    for _ in 0..4 {
                        let j = (u.next(), u.next());
                        count(check(&cam, &accel, &bins, x, y, j));
                    }
                }
            }
            // Rays through vertices and edge midpoints that the camera sees.
            for (k, tri) in mesh.indices.iter().enumerate().step_by(5) {
                let a = mesh.positions[tri[0] as usize];
                let b = mesh.positions[tri[1 + k % 2] as usize];
                for p in [a, 0.5 * (a + b)] {
                    let Some((px, py)) = cam.project(p) else {
                        continue;
                    };
                    if px < 0.0 || py < 0.0 || px >= cam.width as f32 || py >= cam.height as f32 {
                        continue;
                    }
                    let (x, y) = (px.floor(), py.floor());
                    count(check(
                        &cam,
                        &accel,
                        &bins,
                        x as u32,
                        y as u32,
                        (px - x, py - y),
                    ));
                }
            }
            // Outside the image: nothing.
            let (_, d) = cam.ray(0.5, 0.5);
            assert_eq!(
                bins.closest(&accel, cam.width, 0, d, 0.0, f32::INFINITY),
                None
            );
        }
        assert!(
            hits > 1000 && misses > 1000,
            "{name}: {hits} hits, {misses} misses: not a discriminating test"
        );
    }
}

/// Rays continuing a camera ray through an index-matched boundary (the volumetric tracer's
/// first flight inside and its search for re-entries) get the BVH's answer from the lists, bit
/// for bit, or are handed back to the BVH; origins pushed 10⁻⁵ of the object's size off the
/// line are still answered, origins pushed 10⁻² must be declined.
#[test]
fn pixel_bins_answer_continued_rays_exactly_like_the_bvh() {
    let mut u = Uniforms(12);
    for (name, _, accel, center, radius) in scenes() {
        for (push, should_answer) in [(1e-5, true), (1e-2, false)] {
            let mut n = Continued::default();
            for cam in cameras(center, radius) {
                let bins = cam.pixel_bins(&accel).expect("bins");
                for y in 0..cam.height {
                    for x in 0..cam.width {
                        let f = (x as f32 + u.next(), y as f32 + u.next());
                        continuation(&cam, &accel, &bins, f, radius, push, &mut u, &mut n);
                    }
                }
            }
            let Continued { answered, declined } = n;
            assert!(answered > 2000, "{name}: only {answered} continued queries");
            if should_answer {
                assert_eq!(declined, 0, "{name}: {declined} of {answered} declined");
            } else {
                assert!(
                    declined > answered / 4,
                    "{name}: pushed 10⁻² off the line, {declined} declined, {answered} answered"
                );
            }
        }
    }
}

/// Where the exactness argument does not hold the lists are not built and the renderers keep the
/// BVH: geometry on or behind the camera plane, a rotation that is not orthonormal (then
/// `project` is not the inverse of `ray`), and lists too long to pay (huge overlapping
/// triangles).
#[test]
fn pixel_bins_are_not_built_where_they_cannot_be_exact() {
    let mesh = Shape::from_name("sphere").unwrap().build().unwrap();
    let accel = Accel::new(mesh);
    // Inside the sphere: corners behind the camera.
    let inside = Camera::look_at(Vec3::ZERO, Vec3::Z, Vec3::Y, 60.0, 16, 16);
    assert!(inside.pixel_bins(&accel).is_none());
    let outside = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 60.0, 16, 16);
    assert!(outside.pixel_bins(&accel).is_some());
    let mut skewed = outside.clone();
    skewed.rotation = Mat3::from_cols(
        Vec3::new(-1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.01),
        Vec3::new(0.0, 0.0, -1.0),
    );
    assert!(skewed.pixel_bins(&accel).is_none());
    // 400 stacked triangles that each cover the whole 16 × 16 image.
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for k in 0..400u32 {
        let z = -(k as f32) * 0.01;
        positions.extend([
            Vec3::new(-50.0, -50.0, z),
            Vec3::new(50.0, -50.0, z),
            Vec3::new(0.0, 50.0, z),
        ]);
        indices.push([3 * k, 3 * k + 1, 3 * k + 2]);
    }
    let wall = Accel::new(Mesh {
        positions,
        normals: None,
        indices,
    });
    assert!(outside.pixel_bins(&wall).is_none());
}
