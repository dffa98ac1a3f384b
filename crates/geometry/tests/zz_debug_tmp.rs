#[path = "bvh.rs"]
#[allow(dead_code)]
mod main_tests;
use main_tests::support::*;
use geometry::{Accel, Vec3, Vec3A, triangle::WatertightRay};

#[test]
fn dbg() {
    let mesh = noisy_icosphere(5, 0.1, 0.05, 11);
    let accel = Accel::new(mesh.clone());
    let o = Vec3::new(0.2625359, -0.8349255, 0.55180466);
    let d = Vec3::new(-0.34783754, -0.046293993, 0.93641114);
    let b = brute_all(&mesh, o, d, f32::NEG_INFINITY, f32::INFINITY);
    println!("brute {:?}", b);
    let mut buf = vec![];
    accel.all_hits(o, d, f32::NEG_INFINITY, f32::INFINITY, &mut buf);
    println!("bvh {:?}", buf.iter().map(|h| (h.t, h.tri, h.entering(d))).collect::<Vec<_>>());
    let wr = WatertightRay::new(o.into(), d.into());
    // fan of the vertex at o
    let vi = mesh.positions.iter().position(|&p| p == o).unwrap() as u32;
    println!("vertex {vi}");
    for (i, t) in mesh.indices.iter().enumerate() {
        if t.contains(&vi) {
            let [a, bb, c] = t.map(|k| wr.shear * (Vec3A::from(mesh.positions[k as usize]) - wr.org));
            let hit = wr.intersect(a.into(), bb, c, f32::NEG_INFINITY, f32::INFINITY);
            let n = mesh.face_normal_raw(i);
            println!("tri {i} {:?} a {a} b {bb} c {c} hit {:?} facing_in {}", t, hit.map(|_| 0), d.dot(n) < 0.0);
        }
    }
}
