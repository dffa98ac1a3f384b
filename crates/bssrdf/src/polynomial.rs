//! The cubic implicit polynomial of the local shape descriptor (docs/model.md §3.1, §3.3, §3.5).
//!
//! A [`Poly3`] holds the 20 coefficients of `p(u) = Σ_k c_k m_k(u)`, a full cubic in the three
//! coordinates `u = (x, y, z)`. The monomials are ordered by total degree `d`, then by decreasing
//! power of x, then decreasing power of y (VKJ19 `powerToIndex`, docs/model.md §3.1):
//!
//! ```text
//! 0:1 | 1:x 2:y 3:z | 4:x² 5:xy 6:xz 7:y² 8:yz 9:z² |
//! 10:x³ 11:x²y 12:x²z 13:xy² 14:xyz 15:xz² 16:y³ 17:y²z 18:yz² 19:z³
//! ```
//!
//! `index(a, b, c) = i(i+1)/2 + j + d(d+1)(d+2)/6` with `d = a+b+c`, `i = d − a`, `j = c`.
//!
//! Coordinates are SCALED, `u = (q − p_ref)/σ_n`, in whatever axes the coefficients refer to
//! (world axes for stored fits, light space for the network). Sign convention: `c_0 = 0`, the
//! gradient approximates the outward unit normal, `p < 0` inside the medium.

use geometry::Frame;
use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::ops::{Add, Mul};

mod monomials;

pub(crate) use monomials::DERIV;
use monomials::*;
pub use monomials::{
    N_COEFFS, POWERS, monomial_gradients, monomial_gradients_f64, monomials, monomials_f64,
    power_to_index,
};

/// A full cubic implicit polynomial in scaled coordinates (see the module docs for the ordering).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Poly3(pub [f32; N_COEFFS]);

impl Poly3 {
    /// The zero polynomial.
    pub const ZERO: Poly3 = Poly3([0.0; N_COEFFS]);

    /// The plane through the origin with unit normal `n`: `p(u) = n·u`.
    pub fn plane(n: Vec3) -> Poly3 {
        let mut c = [0.0; N_COEFFS];
        c[1] = n.x;
        c[2] = n.y;
        c[3] = n.z;
        Poly3(c)
    }

    /// The same surface at another length scale: with `p` fitted in coordinates u = (q − x)/σ_fit
    /// (unit gradient on the surface, docs/model.md §3.2) and k = σ/σ_fit, the polynomial in
    /// u' = (q − x)/σ is p(k·u')/k, i.e. c'_m = c_m·k^(deg m − 1): linear terms unchanged,
    /// quadratic ×k, cubic ×k². Exact for the surface (the fit's kernel, also σ-scaled, is not
    /// re-applied: a refit at σ differs by the change of the weighting only).
    pub fn rescaled(&self, k: f32) -> Poly3 {
        let (k1, k2) = (k, k * k);
        let mut c = self.0;
        for (i, v) in c.iter_mut().enumerate() {
            match i {
                0 => *v /= k,
                4..=9 => *v *= k1,
                10..=19 => *v *= k2,
                _ => {}
            }
        }
        Poly3(c)
    }

    /// The coefficients.
    #[inline]
    pub fn coeffs(&self) -> &[f32; N_COEFFS] {
        &self.0
    }

    /// Mean curvature of the surface p = 0 at the origin, (|∇p|²·tr H − ∇pᵀH∇p)/(2|∇p|³) with
    /// ∇p and the Hessian H at the origin: positive where the surface bends away from ∇p (convex
    /// for an outward gradient), in the inverse units of the polynomial's argument; 0 without a
    /// gradient.
    pub fn mean_curvature(&self) -> f64 {
        let c: [f64; N_COEFFS] = self.0.map(|v| v as f64);
        let g = [c[1], c[2], c[3]];
        let h = [
            [2.0 * c[4], c[5], c[6]],
            [c[5], 2.0 * c[7], c[8]],
            [c[6], c[8], 2.0 * c[9]],
        ];
        let g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        if g2 <= 0.0 {
            return 0.0;
        }
        let tr = h[0][0] + h[1][1] + h[2][2];
        let mut ghg = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                ghg += g[i] * h[i][j] * g[j];
            }
        }
        (g2 * tr - ghg) / (2.0 * g2.powf(1.5))
    }

    /// `p(u) = Σ_k c_k m_k(u)`.
    #[inline]
    pub fn eval(&self, u: Vec3) -> f32 {
        let m = monomials(u);
        self.0.iter().zip(&m).map(|(c, m)| c * m).sum()
    }

    /// `p(u)` evaluated in `f64`.
    #[inline]
    pub fn eval_f64(&self, u: [f64; 3]) -> f64 {
        let m = monomials_f64(u);
        self.0.iter().zip(&m).map(|(&c, m)| c as f64 * m).sum()
    }

    /// `∇p(u)` with respect to the (scaled) coordinates u.
    #[inline]
    pub fn gradient(&self, u: Vec3) -> Vec3 {
        self.eval_with_gradient(u).1
    }

    /// `(p(u), ∇p(u))`.
    #[inline]
    pub fn eval_with_gradient(&self, u: Vec3) -> (f32, Vec3) {
        let m = monomials(u);
        let c = &self.0;
        let value = c.iter().zip(&m).map(|(c, m)| c * m).sum();
        let mut g = [0.0f32; 3];
        for (axis, ga) in g.iter_mut().enumerate() {
            for k in 0..N_COEFFS {
                let (f, src) = DERIV[axis][k];
                if f > 0 {
                    *ga += c[k] * f as f32 * m[src as usize];
                }
            }
        }
        (value, Vec3::from(g))
    }

    /// `∇p(u)` evaluated in `f64`.
    pub fn gradient_f64(&self, u: [f64; 3]) -> [f64; 3] {
        let g = monomial_gradients_f64(u);
        let mut out = [0.0; 3];
        for axis in 0..3 {
            out[axis] = self
                .0
                .iter()
                .zip(&g[axis])
                .map(|(&c, m)| c as f64 * m)
                .sum();
        }
        out
    }

    /// Unit normal at the reference point, `normalize(c_1, c_2, c_3)` (= normalised `∇p(0)`),
    /// or `None` when the linear part vanishes or is not finite.
    pub fn normal(&self) -> Option<Vec3> {
        let g = DVec3::new(self.0[1] as f64, self.0[2] as f64, self.0[3] as f64);
        let n = g.try_normalize()?;
        Some(n.as_vec3())
    }

    /// Exact change of coordinates (docs/model.md §3.3): the polynomial `p'` with
    /// `p'(u') = p(u'_1 e1 + u'_2 e2 + u'_3 e3)`.
    ///
    /// For an orthonormal frame (e1, e2, e3) expressed in the current axes, `p'` is the same
    /// surface seen in that frame. The map is computed by substitution: every original variable is
    /// the linear form `x_t = Σ_j (e_j)_t u'_j`, and each monomial is expanded by multiplying out
    /// these forms (degree-0 unchanged, degree-1 = projections of (c_1, c_2, c_3), …). Works for
    /// any 3×3 matrix, not only rotations; computed in `f64`.
    pub fn rotate(&self, e1: Vec3, e2: Vec3, e3: Vec3) -> Poly3 {
        let cols = [e1.as_dvec3(), e2.as_dvec3(), e3.as_dvec3()];
        // l[t] = coefficients of the linear form giving original variable t.
        let l: [[f64; 3]; 3] = std::array::from_fn(|t| std::array::from_fn(|j| cols[j][t]));
        let c: [f64; N_COEFFS] = std::array::from_fn(|k| self.0[k] as f64);
        let mut out = [0.0f64; N_COEFFS];
        out[0] = c[0];
        // degree 1
        for t in 0..3 {
            for j in 0..3 {
                out[1 + j] += c[1 + t] * l[t][j];
            }
        }
        // degree 2: products of two linear forms, one per quadratic monomial (first = 4)
        let mut quad = [[0.0f64; 6]; 6];
        for (local, q) in quad.iter_mut().enumerate() {
            let (t1, t2) = factor_axes2(POWERS[4 + local]);
            let lin: [f64; 3] = l[t1];
            *q = mul_linear::<3, 6>(&lin, 1, l[t2]);
            for (o, v) in out[4..10].iter_mut().zip(q.iter()) {
                *o += c[4 + local] * v;
            }
        }
        // degree 3: (product of the first two factors) × third factor
        for local in 0..10 {
            let k = 10 + local;
            if c[k] == 0.0 {
                continue;
            }
            let p = POWERS[k];
            let (pair, t3) = split_cubic(p);
            let cub = mul_linear::<6, 10>(&quad[pair], 4, l[t3]);
            for (o, v) in out[10..20].iter_mut().zip(cub.iter()) {
                *o += c[k] * v;
            }
        }
        Poly3(out.map(|v| v as f32))
    }

    /// [`Poly3::rotate`] in `f32` by tensor contraction, for the renderer's per-sample hot loop.
    ///
    /// With the frame matrix L (L[t][j] = (e_j)_t, x = L·u): the quadratic part as a symmetric
    /// matrix Q (Q_aa = c_{x_a²}, Q_ab = c_{x_a x_b}/2) becomes Q' = Lᵀ·Q·L, the cubic part as a
    /// symmetric tensor T (each monomial's coefficient spread evenly over its 3!/(p_x!p_y!p_z!)
    /// index permutations) becomes T'_ijk = Σ_abc L_ai L_bj L_ck T_abc, two mode products of 81
    /// multiply-adds each and the third only for the 10 distinct outputs; the coefficients are read back with the multiplicities. Same map
    /// as the reference substitution of [`Poly3::rotate`] (tested against it); about 4× faster.
    pub fn rotate_fast(&self, e1: Vec3, e2: Vec3, e3: Vec3) -> Poly3 {
        let cols = [e1, e2, e3];
        let l: [[f32; 3]; 3] = std::array::from_fn(|t| std::array::from_fn(|j| cols[j][t]));
        let c = &self.0;
        let mut out = [0.0f32; N_COEFFS];
        out[0] = c[0];
        for j in 0..3 {
            out[1 + j] = c[1] * l[0][j] + c[2] * l[1][j] + c[3] * l[2][j];
        }
        // Quadratic: Q' = Lᵀ Q L.
        let q: [[f32; 3]; 3] =
            std::array::from_fn(|a| std::array::from_fn(|b| c[SYM2[a][b] as usize] * HALF2[a][b]));
        let ql: [[f32; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|j| q[a][0] * l[0][j] + q[a][1] * l[1][j] + q[a][2] * l[2][j])
        });
        for (k, &[i, j]) in REP2.iter().enumerate() {
            let (i, j) = (i as usize, j as usize);
            let v = l[0][i] * ql[0][j] + l[1][i] * ql[1][j] + l[2][i] * ql[2][j];
            out[4 + k] = if i == j { v } else { 2.0 * v };
        }
        // Cubic: three mode products.
        let mut t = [[[0.0f32; 3]; 3]; 3];
        for (a, ta) in t.iter_mut().enumerate() {
            for (b, tab) in ta.iter_mut().enumerate() {
                for (cc, v) in tab.iter_mut().enumerate() {
                    let k = SYM3[a][b][cc] as usize;
                    *v = c[k] * INV_MULT3[k - 10];
                }
            }
        }
        // T1_ibc = Σ_a L_ai T_abc, T2_ijc = Σ_b L_bj T1_ibc, T3_ijk = Σ_c L_ck T2_ijc.
        let mut t1 = [[[0.0f32; 3]; 3]; 3];
        for i in 0..3 {
            for b in 0..3 {
                for cc in 0..3 {
                    t1[i][b][cc] =
                        l[0][i] * t[0][b][cc] + l[1][i] * t[1][b][cc] + l[2][i] * t[2][b][cc];
                }
            }
        }
        let mut t2 = [[[0.0f32; 3]; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                for cc in 0..3 {
                    t2[i][j][cc] =
                        l[0][j] * t1[i][0][cc] + l[1][j] * t1[i][1][cc] + l[2][j] * t1[i][2][cc];
                }
            }
        }
        for (k, &[a, b, cc]) in REP3.iter().enumerate() {
            let (a, b, cc) = (a as usize, b as usize, cc as usize);
            let v = l[0][cc] * t2[a][b][0] + l[1][cc] * t2[a][b][1] + l[2][cc] * t2[a][b][2];
            out[10 + k] = v / INV_MULT3[k];
        }
        Poly3(out)
    }

    /// The polynomial in the light-space frame of the incident direction `d_in`
    /// ([`light_space_frame`]): what the network sees (`mlsPolyLS3`, docs/model.md §3.3).
    pub fn to_light_space(&self, d_in: Vec3) -> Poly3 {
        let f = light_space_frame(d_in);
        self.rotate(f.s, f.t, f.n)
    }
}

impl Add for Poly3 {
    type Output = Poly3;
    fn add(self, o: Poly3) -> Poly3 {
        Poly3(std::array::from_fn(|k| self.0[k] + o.0[k]))
    }
}

impl Mul<f32> for Poly3 {
    type Output = Poly3;
    fn mul(self, s: f32) -> Poly3 {
        Poly3(self.0.map(|c| c * s))
    }
}

/// Axes of the two factors of a quadratic monomial, `t1 ≤ t2`.
#[inline]
fn factor_axes2(p: [u8; 3]) -> (usize, usize) {
    let mut axes = [0usize; 2];
    let mut n = 0;
    for (axis, &e) in p.iter().enumerate() {
        for _ in 0..e {
            axes[n] = axis;
            n += 1;
        }
    }
    (axes[0], axes[1])
}

/// A cubic monomial as (local index of its quadratic factor over the two lowest axes, third axis).
#[inline]
fn split_cubic(p: [u8; 3]) -> (usize, usize) {
    let mut axes = [0usize; 3];
    let mut n = 0;
    for (axis, &e) in p.iter().enumerate() {
        for _ in 0..e {
            axes[n] = axis;
            n += 1;
        }
    }
    let mut q = [0u8; 3];
    q[axes[0]] += 1;
    q[axes[1]] += 1;
    (local_index(q), axes[2])
}

/// Light-space frame of the incident direction `d_in` (pointing INTO the medium),
/// docs/model.md §3.3: `e3 = −normalize(d_in)` and `(e1, e2)` the Duff basis of `e3`
/// ([`Frame::from_normal`]). Returned as a [`Frame`] `{ s: e1, t: e2, n: e3 }`.
pub fn light_space_frame(d_in: Vec3) -> Frame {
    let e3 = (-d_in).try_normalize().unwrap_or(Vec3::Z);
    Frame::from_normal(e3)
}

/// Incident-direction alignment (docs/model.md §3.5, VKJ19 `adjustRayDirForPolynomialTracing`):
/// rotate `d` by the rotation that maps the mesh normal `n_mesh` onto the polynomial normal
/// `n_poly` (both normalised here; `n_poly` may be the raw `(c_1, c_2, c_3)`). The rotation has
/// axis `n × n_p` and angle `acos(n·n_p)`; it is skipped (d returned unchanged) when
/// `|n × n_p| < 1e-8` or either normal is zero/non-finite. Rodrigues' formula in `f64`:
/// `d' = d cosθ + (a × d) + a (a·d)(1 − cosθ)/|a|²` with `a = n × n_p`, `|a| = sinθ`.
pub fn align_direction(d: Vec3, n_mesh: Vec3, n_poly: Vec3) -> Vec3 {
    let (Some(n), Some(np)) = (
        n_mesh.as_dvec3().try_normalize(),
        n_poly.as_dvec3().try_normalize(),
    ) else {
        return d;
    };
    let a = n.cross(np);
    let s2 = a.length_squared();
    if s2.sqrt() < 1e-8 {
        return d;
    }
    let c = n.dot(np);
    let d64 = d.as_dvec3();
    (d64 * c + a.cross(d64) + a * (a.dot(d64) * (1.0 - c) / s2)).as_vec3()
}

#[cfg(test)]
mod tests;
