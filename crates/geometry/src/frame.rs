//! Orthonormal frames. [`Frame::from_normal`] is the branchless basis of Duff et al. 2017,
//! "Building an Orthonormal Basis, Revisited" (JCGT 6(1)), used everywhere the model spec asks for
//! a "Duff basis" (docs/model.md §3.3).

use glam::Vec3;

/// An orthonormal frame (s, t, n): `to_local(v) = (v·s, v·t, v·n)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// Duff et al. 2017: sign = copysign(1, n_z); a = −1/(sign + n_z); b = n_x n_y a;
    /// s = (1 + sign n_x² a, sign b, −sign n_x); t = (b, sign + n_y² a, −n_y).
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { s, t, n }
    }

    /// Coordinates of a world vector in this frame.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// World vector from coordinates in this frame.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duff_basis_is_orthonormal_and_right_handed() {
        let dirs = [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.8).normalize(),
            Vec3::new(-1e-7, 0.0, -1.0).normalize(),
        ];
        for n in dirs {
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5);
            assert!((f.t.length() - 1.0).abs() < 1e-5);
            assert!(
                f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5
            );
            assert!(
                (f.s.cross(f.t) - n).length() < 1e-5,
                "not right-handed for {n}"
            );
            let v = Vec3::new(0.2, -0.7, 0.4);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }
}
