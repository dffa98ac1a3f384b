//! The per-direction triangle lists around a point light ([`geometry::LightBins`]) answer the
//! shadow-ray queries exactly as the BVH does: `inside_length` bit for bit and `occluded`
//! identically, on a concave torus, the bumpy blob and a sharp box (rays through vertices and
//! along edges), for lights near and far; and the bins are refused where their error bound does
//! not hold (light inside or too close to the bounding sphere). Deterministic (fixed seeds).

use geometry::bvh::offset_origin;
use geometry::light_bins::MIN_LIGHT_DISTANCE;
use geometry::{Accel, LightBins, Shape, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;
use testkit::random_unit_vector;

fn shape(name: &str) -> Accel {
    Accel::new(
        Shape::from_name(name)
            .expect("built-in")
            .build()
            .expect("valid mesh"),
    )
}

/// Bounding-sphere centre and radius of the accel's mesh (vertices).
fn bounding_sphere(accel: &Accel) -> (Vec3, f32) {
    let (lo, hi) = accel.mesh().bounds();
    let c = 0.5 * (lo + hi);
    let r = accel
        .mesh()
        .positions
        .iter()
        .map(|&p| (p - c).length())
        .fold(0.0, f32::max);
    (c, r)
}

/// Points to query: uniform in the bounding box grown by 10 %, half of them kept only when
/// inside the mesh (the shadow rays' origins), plus vertices of the mesh (rays through them).
fn query_points(accel: &Accel, rng: &mut Pcg32, n: usize) -> Vec<Vec3> {
    let (lo, hi) = accel.mesh().bounds();
    let (c, h) = (0.5 * (lo + hi), 0.55 * (hi - lo));
    let mut pts = Vec::with_capacity(n);
    while pts.len() < n {
        let p = c + h * Vec3::new(
            2.0 * rng.random::<f32>() - 1.0,
            2.0 * rng.random::<f32>() - 1.0,
            2.0 * rng.random::<f32>() - 1.0,
        );
        if pts.len() % 2 == 1 || accel.contains(p) {
            pts.push(p);
        }
    }
    let verts = &accel.mesh().positions;
    for k in 0..n / 10 {
        pts.push(verts[(k * 7919) % verts.len()]);
    }
    pts
}

/// Lights at `dist` bounding radii from the centre in random directions.
fn lights(accel: &Accel, rng: &mut Pcg32, dists: &[f32]) -> Vec<Vec3> {
    let (c, r) = bounding_sphere(accel);
    dists
        .iter()
        .map(|&k| c + k * r * random_unit_vector(rng))
        .collect()
}

/// The lists' inside length from `p` to the light equals the BVH's bit for bit; returns it.
fn assert_same_inside_length(accel: &Accel, bins: &LightBins, p: Vec3, what: &str) -> f32 {
    let light = bins.light();
    let want = accel.inside_length(p, light);
    let got = bins.inside_length(accel, p);
    assert_eq!(
        got.to_bits(),
        want.to_bits(),
        "{what}: light {light}, p {p}: lists {got} vs BVH {want}"
    );
    want
}

#[test]
fn inside_length_equals_the_bvh_bit_for_bit() {
    let mut rng = Pcg32::seed_from_u64(1);
    let mut queries = 0;
    let mut crossing = 0;
    for name in ["torus", "blob", "cone"] {
        let accel = shape(name);
        let pts = query_points(&accel, &mut rng, 3000);
        for light in lights(&accel, &mut rng, &[1.1, 1.6, 3.0, 20.0]) {
            // `build_with_resolution`: the blob (81,920 triangles) is above `MAX_TRIANGLES`.
            let bins = LightBins::build_with_resolution(&accel, light, 300)
                .expect("light outside the sphere");
            assert!(bins.mean_candidates() > 0.0);
            for &p in &pts {
                let want = assert_same_inside_length(&accel, &bins, p, name);
                queries += 1;
                crossing += (want > 0.0) as usize;
            }
        }
    }
    // The comparison is not vacuous: most segments cross the medium.
    assert!(crossing * 2 > queries, "{crossing} of {queries}");
}

/// A box with flat faces split into two triangles each: rays from its corners and edge midpoints
/// graze edges and pass through vertices, where the watertight test's tie-breaking decides.
#[test]
fn inside_length_through_vertices_and_edges_of_a_sharp_box() {
    let accel = Accel::new(geometry::sharp_box(
        Vec3::new(-0.4, -0.3, -0.2),
        Vec3::new(0.4, 0.3, 0.2),
    ));
    let mut rng = Pcg32::seed_from_u64(2);
    let verts = accel.mesh().positions.clone();
    // Lights on the box's axes and diagonals: segments to its vertices run along faces.
    let mut ls = vec![
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, -3.0),
        Vec3::new(1.2, 0.9, 0.6),
        Vec3::new(0.4, 0.3, 5.0),
    ];
    ls.extend(lights(&accel, &mut rng, &[1.2, 4.0]));
    for light in ls {
        let bins = LightBins::build(&accel, light).expect("light outside the sphere");
        let mut pts: Vec<Vec3> = verts.clone();
        for i in 0..verts.len() {
            for j in 0..verts.len() {
                pts.push(0.5 * (verts[i] + verts[j]));
                pts.push(0.25 * verts[i] + 0.75 * verts[j]);
            }
        }
        for p in pts {
            assert_same_inside_length(&accel, &bins, p, "sharp box");
        }
    }
}

#[test]
fn occluded_equals_the_bvh_for_rays_toward_the_light() {
    let mut rng = Pcg32::seed_from_u64(3);
    let mut blocked = 0;
    let mut total = 0;
    for name in ["torus", "blob"] {
        let accel = shape(name);
        let pts = query_points(&accel, &mut rng, 1000);
        for light in lights(&accel, &mut rng, &[1.1, 3.0]) {
            let bins = LightBins::build_with_resolution(&accel, light, 300)
                .expect("light outside the sphere");
            for &p in &pts {
                let to = light - p;
                let (r, dir) = (to.length(), to.normalize());
                // Also from a surface point offset toward the light, as the renderers do.
                let h = accel.closest(p, -dir, 0.0, f32::INFINITY);
                let mut rays = vec![(p, 0.0, r)];
                if let Some(h) = h {
                    let o = offset_origin(h.p, h.ng, dir);
                    let d = (light - o).normalize();
                    rays.push((o, 0.0, (light - o).length()));
                    assert_eq!(
                        bins.occluded(&accel, o, d, 0.0, (light - o).length()),
                        accel.occluded(o, d, 0.0, (light - o).length())
                    );
                }
                for (o, tmin, tmax) in rays {
                    let d = (light - o).normalize();
                    let want = accel.occluded(o, d, tmin, tmax);
                    assert_eq!(bins.occluded(&accel, o, d, tmin, tmax), want, "{name} {o}");
                    // A ray that does not point at the light is answered by the BVH.
                    let off = (d + 0.05 * random_unit_vector(&mut rng)).normalize();
                    assert_eq!(
                        bins.occluded(&accel, o, off, tmin, tmax),
                        accel.occluded(o, off, tmin, tmax)
                    );
                    blocked += want as usize;
                    total += 1;
                }
            }
        }
    }
    assert!(
        blocked > total / 4 && blocked < total,
        "{blocked} of {total}"
    );
}

#[test]
fn bins_are_refused_where_the_error_bound_fails() {
    let accel = shape("torus");
    let (c, r) = bounding_sphere(&accel);
    let dir = Vec3::new(0.3, -0.5, 0.8).normalize();
    assert!(LightBins::build(&accel, c).is_none(), "light at the centre");
    assert!(
        LightBins::build(&accel, c + 0.9 * r * dir).is_none(),
        "inside the sphere"
    );
    assert!(
        LightBins::build(&accel, c + 0.99 * MIN_LIGHT_DISTANCE * r * dir).is_none(),
        "closer than the minimum distance"
    );
    assert!(LightBins::build(&accel, Vec3::new(f32::NAN, 0.0, 0.0)).is_none());
    assert!(LightBins::build_with_resolution(&accel, c + 3.0 * r * dir, 0).is_none());
    let bins = LightBins::build(&accel, c + 1.01 * MIN_LIGHT_DISTANCE * r * dir).expect("built");
    assert!(bins.resolution() >= 32);
}

/// The default resolution keeps the lists short: a handful of candidates per bin on average
/// over the film (the shadow query's cost), for a far and a near light, on the torus and on the
/// 81,920-triangle blob; meshes above `MAX_TRIANGLES` keep the BVH.
#[test]
fn default_lists_are_short() {
    let big = Accel::new(
        Shape::Sphere {
            radius: 0.5,
            subdivisions: 7,
        }
        .build()
        .expect("valid mesh"),
    );
    assert!(big.mesh().triangle_count() > geometry::light_bins::MAX_TRIANGLES);
    assert!(LightBins::build(&big, Vec3::new(0.0, 3.0, 0.0)).is_none());
    let mut rng = Pcg32::seed_from_u64(4);
    for name in ["torus", "blob"] {
        let accel = shape(name);
        assert!(accel.mesh().triangle_count() <= geometry::light_bins::MAX_TRIANGLES);
        for light in lights(&accel, &mut rng, &[1.2, 10.0]) {
            let bins = LightBins::build(&accel, light).expect("built");
            let m = bins.mean_candidates();
            assert!(
                m > 0.5 && m < 16.0,
                "{name}: mean candidates {m} at {light}"
            );
        }
    }
}
