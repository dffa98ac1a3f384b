//! A mesh as a scanner or a simplifier would give it: coarser ([`decimate`]), smoothed
//! ([`taubin_smooth`]) or noisy along its normals ([`normal_noise`]). The worked capture example
//! writes its scan with these, and the capture-errors experiment measures what each does to a
//! recovery.
//!
//! [`decimate`] is vertex clustering (Rossignac and Borrel 1993): the vertices of each cell of a
//! uniform grid merge into their mean, and triangles that lose a vertex disappear. It keeps the
//! silhouette within a cell's size but is cruder than a quadric-error simplifier at the same
//! triangle count, so a recovery's error on it bounds what a scanner's own simplification
//! does from above.

use std::collections::HashMap;

use glam::Vec3;

use crate::Mesh;

/// The mesh with about `triangle_count / factor` triangles: vertex clustering on the uniform
/// grid whose cell size gives the nearest count (found by bisection on the cell size, within
/// 40 steps). `factor ≤ 1` returns the mesh unchanged.
pub fn decimate(mesh: &Mesh, factor: f32) -> Mesh {
    if factor <= 1.0 || mesh.indices.is_empty() {
        return mesh.clone();
    }
    let target = (mesh.indices.len() as f32 / factor).max(4.0);
    let (lo, hi) = mesh.bounds();
    let diag = (hi - lo).length().max(f32::MIN_POSITIVE);
    // Cell sizes from a thousandth of the diagonal (every vertex its own cell, as good as
    // never merging) to the whole diagonal (a handful of cells).
    let (mut small, mut large) = (diag * 1e-3, diag);
    let mut best = clustered(mesh, lo, small);
    for _ in 0..40 {
        let mid = (small * large).sqrt();
        let m = clustered(mesh, lo, mid);
        let n = m.indices.len() as f32;
        if (n - target).abs() < (best.indices.len() as f32 - target).abs() {
            best = m;
        }
        if n > target {
            small = mid;
        } else {
            large = mid;
        }
        if large / small < 1.0 + 1e-4 {
            break;
        }
    }
    best
}

/// Vertex clustering on the grid of cell size `h` anchored at `lo`: each occupied cell's
/// vertices become their mean; degenerate and repeated triangles are dropped.
fn clustered(mesh: &Mesh, lo: Vec3, h: f32) -> Mesh {
    let mut cells: HashMap<[i32; 3], u32> = HashMap::new();
    let mut sums: Vec<(Vec3, u32)> = Vec::new();
    let remap: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let k = ((*p - lo) / h).floor();
            let key = [k.x as i32, k.y as i32, k.z as i32];
            let id = *cells.entry(key).or_insert_with(|| {
                sums.push((Vec3::ZERO, 0));
                (sums.len() - 1) as u32
            });
            sums[id as usize].0 += *p;
            sums[id as usize].1 += 1;
            id
        })
        .collect();
    let positions: Vec<Vec3> = sums.iter().map(|(s, n)| *s / *n as f32).collect();
    let mut seen = std::collections::HashSet::new();
    let indices: Vec<[u32; 3]> = mesh
        .indices
        .iter()
        .map(|t| t.map(|i| remap[i as usize]))
        .filter(|[a, b, c]| a != b && b != c && a != c)
        .filter(|t| {
            // The same triangle twice (in either orientation) is one.
            let mut key = *t;
            key.sort_unstable();
            seen.insert(key)
        })
        .collect();
    Mesh {
        positions,
        normals: None,
        indices,
    }
}

/// Taubin's λ|μ smoothing (Taubin 1995), `passes` pairs of steps: x ← x + λ·L(x), then
/// x ← x + μ·L(x), with L the uniform Laplacian (mean of the neighbours − x), λ = 0.5,
/// μ = −0.53. It removes the fine detail a scan's reconstruction loses without the shrinking of
/// plain Laplacian smoothing.
pub fn taubin_smooth(mesh: &Mesh, passes: u32) -> Mesh {
    const LAMBDA: f32 = 0.5;
    const MU: f32 = -0.53;
    let n = mesh.positions.len();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in &mesh.indices {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            for (u, v) in [(a, b), (b, a)] {
                let list = &mut neighbours[u as usize];
                if !list.contains(&v) {
                    list.push(v);
                }
            }
        }
    }
    let mut x = mesh.positions.clone();
    let mut next = x.clone();
    for _ in 0..passes {
        for step in [LAMBDA, MU] {
            for (i, out) in next.iter_mut().enumerate() {
                let nb = &neighbours[i];
                *out = if nb.is_empty() {
                    x[i]
                } else {
                    let mean = nb.iter().map(|&j| x[j as usize]).sum::<Vec3>() / nb.len() as f32;
                    x[i] + step * (mean - x[i])
                };
            }
            std::mem::swap(&mut x, &mut next);
        }
    }
    Mesh {
        positions: x,
        normals: None,
        indices: mesh.indices.clone(),
    }
}

/// The mesh with each vertex moved along its normal by N(0, (fraction·diagonal)²), the
/// diagonal of its bounding box; `rng_normal` draws standard normal numbers. `fraction ≤ 0`
/// returns it unchanged.
pub fn normal_noise(mesh: &Mesh, fraction: f32, mut rng_normal: impl FnMut() -> f32) -> Mesh {
    if fraction <= 0.0 {
        return mesh.clone();
    }
    let (lo, hi) = mesh.bounds();
    let sd = fraction * (hi - lo).length();
    let normals = mesh.compute_vertex_normals();
    let positions: Vec<Vec3> = mesh
        .positions
        .iter()
        .zip(&normals)
        .map(|(p, n)| *p + *n * (sd * rng_normal()))
        .collect();
    Mesh {
        positions,
        normals: None,
        ..mesh.clone()
    }
}

/// The root-mean-square distance between the vertices of two meshes with the same vertices
/// (a smoothing's or a noise's displacement).
pub fn rms_displacement(a: &Mesh, b: &Mesh) -> f32 {
    let n = a.positions.len().min(b.positions.len()).max(1);
    let s: f32 = a
        .positions
        .iter()
        .zip(&b.positions)
        .map(|(p, q)| (*p - *q).length_squared())
        .sum();
    (s / n as f32).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::Shape;

    fn blob() -> Mesh {
        Shape::from_name("blob").unwrap().build().unwrap()
    }

    /// Decimation reaches its triangle count within a few per cent, keeps the mesh closed and
    /// its volume within a few per cent; factor 1 changes nothing.
    #[test]
    fn decimation_reaches_its_count_and_keeps_the_shape() {
        let m = blob();
        let v0 = m.signed_volume();
        for factor in [10.0, 50.0] {
            let d = decimate(&m, factor);
            let want = m.indices.len() as f32 / factor;
            let got = d.indices.len() as f32;
            assert!(
                (got / want - 1.0).abs() < 0.15,
                "×{factor}: {got} for {want}"
            );
            let v = d.signed_volume();
            assert!((v / v0 - 1.0).abs() < 0.1, "×{factor}: volume {v} of {v0}");
        }
        assert_eq!(decimate(&m, 1.0).indices, m.indices);
    }

    /// Taubin smoothing moves a fine mesh a little and keeps its volume (plain Laplacian
    /// smoothing would shrink it); noise moves vertices by the stated standard deviation.
    #[test]
    fn smoothing_keeps_the_volume_and_noise_has_its_size() {
        let m = blob();
        let s = taubin_smooth(&m, 10);
        let (lo, hi) = m.bounds();
        let diag = (hi - lo).length();
        assert!((s.signed_volume() / m.signed_volume() - 1.0).abs() < 0.02);
        let moved = rms_displacement(&m, &s) / diag;
        assert!(moved > 1e-5 && moved < 0.01, "{moved}");
        let n = normal_noise(&m, 0.002, || 1.0);
        let d = rms_displacement(&m, &n) / diag;
        assert!((d - 0.002).abs() < 1e-4, "{d}");
        assert_eq!(normal_noise(&m, 0.0, || 1.0).positions, m.positions);
    }
}
