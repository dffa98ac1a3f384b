//! The monomials of the cubic in coefficient order (docs/model.md §3.1), their gradients, and
//! the index tables of the quadratic and cubic blocks that the polynomial's algebra uses.

use glam::Vec3;
use std::ops::Mul;

/// Number of coefficients of a full cubic in 3 variables.
pub const N_COEFFS: usize = 20;

/// Exponents `(a, b, c)` of monomial `k` = `x^a y^b z^c`, in coefficient order
/// (docs/model.md §3.1).
pub const POWERS: [[u8; 3]; N_COEFFS] = build_powers();

/// Coefficient index of `x^a y^b z^c` (`a + b + c ≤ 3`): `i(i+1)/2 + j + d(d+1)(d+2)/6` with
/// `d = a+b+c`, `i = d − a`, `j = c` (docs/model.md §3.1).
pub const fn power_to_index(a: usize, b: usize, c: usize) -> usize {
    let d = a + b + c;
    let i = d - a;
    let j = c;
    i * (i + 1) / 2 + j + d * (d + 1) * (d + 2) / 6
}

pub(super) const fn build_powers() -> [[u8; 3]; N_COEFFS] {
    let mut out = [[0u8; 3]; N_COEFFS];
    let mut d: i32 = 0;
    while d <= 3 {
        // decreasing power of x, then decreasing power of y
        let mut a = d;
        while a >= 0 {
            let mut b = d - a;
            while b >= 0 {
                let c = d - a - b;
                let (au, bu, cu) = (a as usize, b as usize, c as usize);
                out[power_to_index(au, bu, cu)] = [au as u8, bu as u8, cu as u8];
                b -= 1;
            }
            a -= 1;
        }
        d += 1;
    }
    out
}

/// For `axis` and monomial `k`: `∂m_k/∂u_axis = DERIV[axis][k].0 · m_{DERIV[axis][k].1}`
/// (factor 0 when the monomial does not contain that variable).
pub(crate) const DERIV: [[(u8, u8); N_COEFFS]; 3] = build_deriv();

pub(super) const fn build_deriv() -> [[(u8, u8); N_COEFFS]; 3] {
    let mut out = [[(0u8, 0u8); N_COEFFS]; 3];
    let mut axis = 0;
    while axis < 3 {
        let mut k = 0;
        while k < N_COEFFS {
            let p = POWERS[k];
            if p[axis] > 0 {
                let mut q = [p[0] as usize, p[1] as usize, p[2] as usize];
                q[axis] -= 1;
                out[axis][k] = (p[axis], power_to_index(q[0], q[1], q[2]) as u8);
            }
            k += 1;
        }
        axis += 1;
    }
    out
}

#[inline]
pub(super) fn monomials_generic<T: Copy + Mul<Output = T> + From<u8>>(
    x: T,
    y: T,
    z: T,
) -> [T; N_COEFFS] {
    let (xx, xy, xz, yy, yz, zz) = (x * x, x * y, x * z, y * y, y * z, z * z);
    [
        T::from(1u8),
        x,
        y,
        z,
        xx,
        xy,
        xz,
        yy,
        yz,
        zz,
        xx * x,
        xx * y,
        xx * z,
        xy * y,
        xy * z,
        xz * z,
        yy * y,
        yy * z,
        yz * z,
        zz * z,
    ]
}

#[inline]
pub(super) fn monomial_gradients_generic<T: Copy + Mul<Output = T> + From<u8>>(
    m: &[T; N_COEFFS],
) -> [[T; N_COEFFS]; 3] {
    let zero = T::from(0u8);
    let mut g = [[zero; N_COEFFS]; 3];
    for axis in 0..3 {
        for k in 0..N_COEFFS {
            let (f, src) = DERIV[axis][k];
            if f > 0 {
                g[axis][k] = T::from(f) * m[src as usize];
            }
        }
    }
    g
}

/// The 20 monomials `m_k(u)` in coefficient order.
#[inline]
pub fn monomials(u: Vec3) -> [f32; N_COEFFS] {
    monomials_generic(u.x, u.y, u.z)
}

/// The 20 monomials in `f64`.
#[inline]
pub fn monomials_f64(u: [f64; 3]) -> [f64; N_COEFFS] {
    monomials_generic(u[0], u[1], u[2])
}

/// Partial derivatives of the monomials: `out[axis][k] = ∂m_k/∂u_axis (u)`.
#[inline]
pub fn monomial_gradients(u: Vec3) -> [[f32; N_COEFFS]; 3] {
    monomial_gradients_generic(&monomials(u))
}

/// Partial derivatives of the monomials in `f64`: `out[axis][k] = ∂m_k/∂u_axis (u)`.
#[inline]
pub fn monomial_gradients_f64(u: [f64; 3]) -> [[f64; N_COEFFS]; 3] {
    monomial_gradients_generic(&monomials_f64(u))
}

/// Coefficient index of the monomial x_a·x_b (any order).
pub(super) const SYM2: [[u8; 3]; 3] = {
    let mut out = [[0u8; 3]; 3];
    let mut a = 0;
    while a < 3 {
        let mut b = 0;
        while b < 3 {
            let mut p = [0usize; 3];
            p[a] += 1;
            p[b] += 1;
            out[a][b] = power_to_index(p[0], p[1], p[2]) as u8;
            b += 1;
        }
        a += 1;
    }
    out
};

/// 1 on the diagonal, ½ off it: the symmetric-matrix share of a quadratic coefficient.
pub(super) const HALF2: [[f32; 3]; 3] = [[1.0, 0.5, 0.5], [0.5, 1.0, 0.5], [0.5, 0.5, 1.0]];

/// The axes of monomial `p`, sorted, one per factor (x²y → [0, 0, 1]); unused slots 0.
pub(super) const fn sorted_axes(p: [u8; 3]) -> [u8; 3] {
    let mut idx = [0u8; 3];
    let mut n = 0;
    let mut axis = 0;
    while axis < 3 {
        let mut r = 0;
        while r < p[axis] {
            idx[n] = axis as u8;
            n += 1;
            r += 1;
        }
        axis += 1;
    }
    idx
}

/// Small factorial for the monomial multiplicities.
pub(super) const fn factorial(n: u8) -> u32 {
    if n <= 1 {
        1
    } else {
        n as u32 * factorial(n - 1)
    }
}

/// Sorted index pair of each quadratic monomial (coefficients 4..10).
pub(super) const REP2: [[u8; 2]; 6] = {
    let mut out = [[0u8; 2]; 6];
    let mut k = 0;
    while k < 6 {
        let idx = sorted_axes(POWERS[4 + k]);
        out[k] = [idx[0], idx[1]];
        k += 1;
    }
    out
};

/// Coefficient index of the monomial x_a·x_b·x_c (any order).
pub(super) const SYM3: [[[u8; 3]; 3]; 3] = {
    let mut out = [[[0u8; 3]; 3]; 3];
    let mut a = 0;
    while a < 27 {
        let (i, j, k) = (a / 9, (a / 3) % 3, a % 3);
        let mut p = [0usize; 3];
        p[i] += 1;
        p[j] += 1;
        p[k] += 1;
        out[i][j][k] = power_to_index(p[0], p[1], p[2]) as u8;
        a += 1;
    }
    out
};

/// Sorted index triple of each cubic monomial (coefficients 10..20).
pub(super) const REP3: [[u8; 3]; 10] = {
    let mut out = [[0u8; 3]; 10];
    let mut k = 0;
    while k < 10 {
        out[k] = sorted_axes(POWERS[10 + k]);
        k += 1;
    }
    out
};

/// 1/(number of index permutations) of each cubic monomial: p_x!·p_y!·p_z!/3!.
pub(super) const INV_MULT3: [f32; 10] = {
    let mut out = [0.0f32; 10];
    let mut k = 0;
    while k < 10 {
        let p = POWERS[10 + k];
        out[k] = (factorial(p[0]) * factorial(p[1]) * factorial(p[2])) as f32 / 6.0;
        k += 1;
    }
    out
};

/// Local index, inside its degree block, of the monomial `x^a y^b z^c`: `i(i+1)/2 + j`.
#[inline]
pub(super) const fn local_index(p: [u8; 3]) -> usize {
    let i = (p[1] + p[2]) as usize;
    i * (i + 1) / 2 + p[2] as usize
}

/// Multiply a homogeneous polynomial of degree `d` (coefficients in local block order, `N` of
/// them) by the linear form `l·u`, giving a homogeneous polynomial of degree `d + 1` (`M` coeffs).
#[inline]
pub(super) fn mul_linear<const N: usize, const M: usize>(
    h: &[f64; N],
    first: usize,
    l: [f64; 3],
) -> [f64; M] {
    let mut out = [0.0; M];
    for (local, &coef) in h.iter().enumerate() {
        if coef == 0.0 {
            continue;
        }
        let p = POWERS[first + local];
        for axis in 0..3 {
            let mut q = p;
            q[axis] += 1;
            out[local_index(q)] += coef * l[axis];
        }
    }
    out
}
