//! Area-uniform surface point sampling (alias-free: binary search in the triangle-area CDF, then
//! the uniform triangle map (1 − √u₁, u₂√u₁)).
//!
//! `u[0]` picks triangle `i` with probability `A_i / A` (binary search in the f64 CDF of the
//! triangle areas); `u[1]`, `u[2]` place the point uniformly inside it with the barycentrics
//! `b0 = 1 − √u₁`, `b1 = u₂·√u₁`, `b2 = 1 − b0 − b1` (Shirley's square-to-triangle map, whose
//! Jacobian is the constant 2·A_i). The density is therefore `1 / A` with respect to area. The
//! three uniforms are used independently (no rescaling of `u[0]`), so low-discrepancy points keep
//! their stratification in the triangle.

use glam::Vec3;

use crate::Mesh;
use crate::bvh::shading_normal;

/// A sampled surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    pub p: Vec3,
    /// Unit geometric normal (outward).
    pub ng: Vec3,
    /// Unit shading normal.
    pub ns: Vec3,
    pub tri: u32,
    /// Area density 1/A.
    pub pdf: f32,
}

/// Samples points uniformly by area.
pub struct AreaSampler {
    /// `cdf[i]` = total area of triangles `0..=i` (f64, unnormalised; last entry = total area).
    cdf: Vec<f64>,
    total_area: f64,
}

impl AreaSampler {
    pub fn new(mesh: &Mesh) -> Self {
        let mut acc = 0.0f64;
        let cdf = (0..mesh.triangle_count())
            .map(|i| {
                let [a, b, c] = mesh.triangle(i).map(|v| v.as_dvec3());
                acc += 0.5 * (b - a).cross(c - a).length();
                acc
            })
            .collect();
        AreaSampler {
            cdf,
            total_area: acc,
        }
    }
    pub fn total_area(&self) -> f64 {
        self.total_area
    }
    /// Triangle index chosen by the uniform `u0 ∈ [0, 1)` (probability `A_i / A`).
    #[inline]
    pub fn pick_triangle(&self, u0: f32) -> usize {
        let x = (u0 as f64).clamp(0.0, 1.0) * self.total_area;
        // First i with cdf[i] > x: zero-area triangles are never chosen.
        let i = self.cdf.partition_point(|&c| c <= x);
        if i < self.cdf.len() {
            i
        } else {
            // u0 = 1: the last triangle of positive area (first to reach the total).
            self.cdf
                .partition_point(|&c| c < self.total_area)
                .min(self.cdf.len().saturating_sub(1))
        }
    }
    /// Probability of picking triangle `i` (its share of the area).
    pub fn triangle_probability(&self, i: usize) -> f64 {
        let prev = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (self.cdf[i] - prev) / self.total_area
    }
    /// Map three uniforms in [0,1) to a surface point.
    ///
    /// `mesh` must be the mesh the sampler was built from. An empty or zero-area mesh gives a
    /// sample at the origin with `pdf = 0`.
    #[inline]
    pub fn sample(&self, mesh: &Mesh, u: [f32; 3]) -> SurfaceSample {
        if self.cdf.is_empty() || self.total_area.is_nan() || self.total_area <= 0.0 {
            return SurfaceSample {
                p: Vec3::ZERO,
                ng: Vec3::Z,
                ns: Vec3::Z,
                tri: 0,
                pdf: 0.0,
            };
        }
        let i = self.pick_triangle(u[0]);
        let [v0, v1, v2] = mesh.triangle(i);
        let su = u[1].clamp(0.0, 1.0).sqrt();
        let b0 = 1.0 - su;
        let b1 = u[2].clamp(0.0, 1.0) * su;
        let b2 = 1.0 - b0 - b1;
        let p = v0 * b0 + v1 * b1 + v2 * b2;
        let raw = (v1 - v0).cross(v2 - v0);
        let ng = raw.try_normalize().unwrap_or_else(|| {
            let (a, b, c) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
            (b - a).cross(c - a).normalize_or_zero().as_vec3()
        });
        let ns = match &mesh.normals {
            Some(normals) => {
                let [i0, i1, i2] = mesh.indices[i];
                match (
                    normals.get(i0 as usize),
                    normals.get(i1 as usize),
                    normals.get(i2 as usize),
                ) {
                    (Some(&n0), Some(&n1), Some(&n2)) => {
                        shading_normal(n0 * b0 + n1 * b1 + n2 * b2, ng)
                    }
                    _ => ng,
                }
            }
            None => ng,
        };
        SurfaceSample {
            p,
            ng,
            ns,
            tri: i as u32,
            pdf: (1.0 / self.total_area) as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_picks_zero_area_triangles() {
        let z = Vec3::ZERO;
        let mesh = Mesh {
            positions: vec![z, Vec3::X, Vec3::Y, Vec3::X * 2.0],
            normals: None,
            // zero-area, unit/2, zero-area, zero-area
            indices: vec![[0, 1, 3], [0, 1, 2], [0, 3, 1], [0, 0, 2]],
        };
        let s = AreaSampler::new(&mesh);
        assert_eq!(s.total_area(), 0.5);
        for u0 in [0.0, 0.3, 0.999_999_94, 1.0] {
            assert_eq!(s.pick_triangle(u0), 1, "u0 {u0}");
            let smp = s.sample(&mesh, [u0, 0.5, 0.5]);
            assert_eq!(smp.tri, 1);
            assert_eq!(smp.pdf, 2.0);
            assert_eq!(smp.ng, Vec3::Z);
        }
        let empty = AreaSampler::new(&Mesh::default());
        assert_eq!(empty.sample(&Mesh::default(), [0.5; 3]).pdf, 0.0);
    }
}
