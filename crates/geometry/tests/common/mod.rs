//! Support shared by the geometry crate's integration tests.

use geometry::triangle::WatertightRay;
use geometry::{Mesh, Vec3, Vec3A};

/// (t, original triangle) of every hit of the watertight test along the ray, sorted by
/// (t, triangle): the brute-force answer the BVH's queries must match.
pub fn brute_all(mesh: &Mesh, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Vec<(f32, u32)> {
    let wr = WatertightRay::new(o.into(), d.into());
    let mut v: Vec<(f32, u32)> = (0..mesh.triangle_count())
        .filter_map(|i| {
            let [a, b, c] = mesh.triangle(i).map(Vec3A::from);
            wr.intersect(a, b, c, tmin, tmax)
                .map(|(t, ..)| (t, i as u32))
        })
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    v
}
