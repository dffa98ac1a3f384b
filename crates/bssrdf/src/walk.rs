//! Random walks inside the fitted cubic polynomial surface (docs/model.md §5 step 3; VKJ19
//! `sss_particle_tracer.cpp`, `render.cpp` sampleVolpathPoly3D).
//!
//! The medium is the set `{x : p((x − x_in)/σ_n) < 0}` of the polynomial `p` fitted at the entry
//! point `x_in` (scaled coordinates, world axes, docs/model.md §3.2). Positions are kept in `f64`
//! relative to `x_in`, in world units.
//!
//! **Boundary intersection** (exact, not VKJ19's ray marching): along the ray `u(s) = a + s d`
//! (`a = (x − x_in)/σ_n`, unit `d`, `s` in units of σ_n) the polynomial is the cubic
//! `f(s) = c₀ + c₁ s + c₂ s² + c₃ s³` with
//!
//! ```text
//! c₀ = p(a),  c₁ = ∇p(a)·d,  c₂ = ½ dᵀ∇²p(a) d,  c₃ = p₃(d) (the cubic part at d)
//! ```
//!
//! expanded per homogeneous degree ([`WalkSurface::ray_cubic`], exact, evaluated in `f64`). [`first_root`] finds the first sign change of `f` in
//! `(lo, hi]`: the roots of `f'` split the interval into monotone pieces, the first piece whose end
//! value has the opposite sign brackets the root, refined by Newton steps safeguarded by bisection.
//! Degenerate (lower-degree) cubics need no special case. A ray starting ON the surface (entry
//! point, after a specular reflection) uses the deflated quadratic `f(s)/s = c₁ + c₂ s + c₃ s²`,
//! which removes the root at `s = 0`. VKJ19's marching covers at most 500 steps of 0.1 world units:
//! roots beyond [`MAX_DISTANCE`] (50 world units) count as "no hit".
//!
//! **Walk** (analog, throughput always 1, VKJ19 semantics):
//! * first segment: distance from the exponential truncated to the first boundary hit,
//!   `t = −ln(1 − u(1 − e^{−σ_t t_hit}))/σ_t` (plain exponential without a hit); a first ray that
//!   points out of the medium is [`WalkOutcome::Invalid`];
//! * at each scattering: absorbed with probability `1 − α` (analog Russian roulette of VKJ19),
//!   else a new direction from Henyey–Greenstein(g); more than [`MAX_BOUNCES`] events ⇒ absorbed;
//! * free flights `t = −ln(1 − u)/σ_t`; at a boundary hit with normal `n = ∇p/|∇p|`: a hit from
//!   outside (`n·d ≤ 0`) is invalid; specular reflection with probability `F(n·d, 1/η)`, else
//!   refraction out (Snell) ⇒ [`WalkOutcome::Exited`].
//!
//! Everything is allocation-free; the random stream is a [`Sampler`].

use crate::polynomial::{N_COEFFS, Poly3, monomials_f64};
use base::fresnel::{fresnel_dielectric, reflect, refract};
use base::phase::HenyeyGreenstein;
use base::rng::Sampler;
use glam::{DVec3, Vec3};

/// More scattering events than this count as absorption (VKJ19).
pub const MAX_BOUNCES: u32 = 10_000;
/// Longest boundary search along one ray, in world units (VKJ19: 500 marching steps of 0.1).
pub const MAX_DISTANCE: f64 = 50.0;

/// Medium of a walk (original, not reduced, parameters; docs/model.md §2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkMedium {
    /// Extinction σ_t (1/world unit).
    pub sigma_t: f64,
    /// Single-scattering albedo α.
    pub albedo: f64,
    /// Henyey–Greenstein g.
    pub g: f64,
    /// Relative index of refraction η = n_inside/n_outside.
    pub eta: f64,
}

/// The implicit surface `p((x − x_in)/σ_n) = 0` of one configuration, `f64` coefficients.
#[derive(Clone, Copy, Debug)]
pub struct WalkSurface {
    c: [f64; N_COEFFS],
    sigma_n: f64,
    inv_sigma_n: f64,
}

/// Why a path was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InvalidReason {
    /// The first ray does not point into the medium (`∇p(0)·d_in ≥ 0`).
    FirstRayOutside,
    /// A ray met the boundary from outside (`∇p·d ≤ 0` at the hit).
    HitFromOutside,
    /// A scattering vertex ended up outside the medium (numerical, rare).
    VertexOutside,
}

/// An escaped path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exit {
    /// Exit point relative to the entry point, world units (`f64`).
    pub position: DVec3,
    /// Outward unit normal `∇p/|∇p|` at the exit point (world).
    pub normal: Vec3,
    /// Direction leaving the medium (world, unit, after refraction).
    pub direction: Vec3,
    /// Number of scattering events.
    pub bounces: u32,
}

/// Result of one random walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WalkOutcome {
    /// Left the medium through the polynomial surface.
    Exited(Exit),
    /// Absorbed (or more than [`MAX_BOUNCES`] events) after `bounces` scattering events.
    Absorbed { bounces: u32 },
    /// Rejected path (VKJ19 "invalid"); counts as an attempt, not as a finished path.
    Invalid(InvalidReason),
}

/// `f(s) = c₀ + c₁ s + c₂ s² + c₃ s³` and `f'(s)` by Horner's rule.
#[inline]
fn horner(c: &[f64; 4], s: f64) -> (f64, f64) {
    let f = ((c[3] * s + c[2]) * s + c[1]) * s + c[0];
    let df = (3.0 * c[3] * s + 2.0 * c[2]) * s + c[1];
    (f, df)
}

/// Sign of `f` just to the right of `lo` (first non-zero Taylor term), in {−1, 0, 1}.
fn sign_right_of(c: &[f64; 4], lo: f64) -> f64 {
    let (f, df) = horner(c, lo);
    let d2 = 3.0 * c[3] * lo + c[2];
    for v in [f, df, d2, c[3]] {
        if v != 0.0 {
            return v.signum();
        }
    }
    0.0
}

/// Real roots of `a t² + b t + c` (numerically stable form), unsorted, `NaN` for missing ones.
#[inline]
fn quadratic_roots(a: f64, b: f64, c: f64) -> [f64; 2] {
    if a == 0.0 {
        return if b != 0.0 {
            [-c / b, f64::NAN]
        } else {
            [f64::NAN; 2]
        };
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return [f64::NAN; 2];
    }
    let q = -0.5 * (b + disc.sqrt().copysign(b));
    if q == 0.0 {
        // b = 0 and c = 0: double root at 0.
        return [0.0, f64::NAN];
    }
    [q / a, c / q]
}

/// First point in `(lo, hi]` where the cubic `c₀ + c₁ s + c₂ s² + c₃ s³` changes sign relative to
/// its sign just right of `lo` (see the module docs), or `None`.
///
/// Critical points (roots of `f'`) inside `(lo, hi)` cut the interval into monotone pieces; the
/// first piece whose right end has the opposite sign contains exactly one crossing, which is refined
/// to `|Δs| ≤ 1e-13·max(1, |s|)` by Newton steps kept inside the bracket (bisection otherwise).
/// Tangential double roots without a sign change are not reported (measure zero for random rays).
pub fn first_root(c: [f64; 4], lo: f64, hi: f64) -> Option<f64> {
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) || c.iter().any(|v| !v.is_finite())
    {
        return None;
    }
    let s0 = sign_right_of(&c, lo);
    if s0 == 0.0 {
        return None; // f ≡ 0
    }
    // Cheap exclusion: with x = s − lo ∈ [0, h], s0·f(s) ≥ Σ_k min(s0·b_k, 0) h^k + s0·b_0 where
    // b_k are the Taylor coefficients at lo; if that bound is positive there is no crossing.
    if lo == 0.0 {
        let h = hi;
        let b = c.map(|v| v * s0);
        let bound = b[0] + h * (b[1].min(0.0) + h * (b[2].min(0.0) + h * b[3].min(0.0)));
        if bound > 0.0 {
            return None;
        }
    }
    let [r1, r2] = quadratic_roots(3.0 * c[3], 2.0 * c[2], c[1]);
    let (r1, r2) = if r1 <= r2 { (r1, r2) } else { (r2, r1) };
    let mut ends = [hi; 3];
    let mut n = 0;
    for r in [r1, r2] {
        if r > lo && r < hi {
            ends[n] = r;
            n += 1;
        }
    }
    ends[n] = hi;
    let mut a = lo;
    for &b in &ends[..=n] {
        let fb = horner(&c, b).0;
        if fb * s0 <= 0.0 {
            return Some(refine(&c, a, b, s0));
        }
        a = b;
    }
    None
}

/// Root of the monotone piece `[a, b]` with `s0·f(a⁺) > 0 ≥ s0·f(b)`.
fn refine(c: &[f64; 4], mut a: f64, mut b: f64, s0: f64) -> f64 {
    let mut x = 0.5 * (a + b);
    for _ in 0..200 {
        let (f, df) = horner(c, x);
        if f == 0.0 {
            return x;
        }
        if f * s0 > 0.0 {
            a = x;
        } else {
            b = x;
        }
        if (b - a) <= 1e-13 * a.abs().max(b.abs()).max(1.0) {
            break;
        }
        let newton = x - f / df;
        x = if df != 0.0 && newton > a && newton < b {
            newton
        } else {
            0.5 * (a + b)
        };
    }
    b
}

impl WalkSurface {
    /// The surface of `poly` (scaled coordinates `u = (x − x_in)/σ_n`, world axes).
    pub fn new(poly: &Poly3, sigma_n: f64) -> Self {
        WalkSurface {
            c: poly.0.map(|v| v as f64),
            sigma_n,
            inv_sigma_n: 1.0 / sigma_n,
        }
    }

    /// σ_n of the scaled coordinates (world units).
    pub fn sigma_n(&self) -> f64 {
        self.sigma_n
    }

    /// `p(u)` in scaled coordinates.
    #[inline]
    pub fn eval_scaled(&self, u: DVec3) -> f64 {
        let m = monomials_f64(u.to_array());
        let mut s = 0.0;
        for k in 1..N_COEFFS {
            s += self.c[k] * m[k];
        }
        s + self.c[0]
    }

    /// `p` at the world offset `r = x − x_in`.
    #[inline]
    pub fn value(&self, r: DVec3) -> f64 {
        self.eval_scaled(r * self.inv_sigma_n)
    }

    /// `∇_u p` at the world offset `r` (its direction is the world outward normal).
    pub fn gradient(&self, r: DVec3) -> DVec3 {
        let u = r * self.inv_sigma_n;
        let [x, y, z] = u.to_array();
        let c = &self.c;
        // ∂/∂x, ∂/∂y, ∂/∂z of the 20 monomials, written out (ordering of docs/model.md §3.1).
        let gx = c[1]
            + 2.0 * c[4] * x
            + c[5] * y
            + c[6] * z
            + 3.0 * c[10] * x * x
            + 2.0 * c[11] * x * y
            + 2.0 * c[12] * x * z
            + c[13] * y * y
            + c[14] * y * z
            + c[15] * z * z;
        let gy = c[2]
            + c[5] * x
            + 2.0 * c[7] * y
            + c[8] * z
            + c[11] * x * x
            + 2.0 * c[13] * x * y
            + c[14] * x * z
            + 3.0 * c[16] * y * y
            + 2.0 * c[17] * y * z
            + c[18] * z * z;
        let gz = c[3]
            + c[6] * x
            + c[8] * y
            + 2.0 * c[9] * z
            + c[12] * x * x
            + c[14] * x * y
            + 2.0 * c[15] * x * z
            + c[17] * y * y
            + 2.0 * c[18] * y * z
            + 3.0 * c[19] * z * z;
        DVec3::new(gx, gy, gz)
    }

    /// Gradient of the cubic part `p₃` at `x`.
    #[inline]
    fn cubic_gradient(&self, x: DVec3) -> DVec3 {
        let c = &self.c;
        let (x, y, z) = (x.x, x.y, x.z);
        DVec3::new(
            3.0 * c[10] * x * x
                + 2.0 * c[11] * x * y
                + 2.0 * c[12] * x * z
                + c[13] * y * y
                + c[14] * y * z
                + c[15] * z * z,
            c[11] * x * x
                + 2.0 * c[13] * x * y
                + c[14] * x * z
                + 3.0 * c[16] * y * y
                + 2.0 * c[17] * y * z
                + c[18] * z * z,
            c[12] * x * x
                + c[14] * x * y
                + 2.0 * c[15] * x * z
                + c[17] * y * y
                + 2.0 * c[18] * y * z
                + 3.0 * c[19] * z * z,
        )
    }

    /// Coefficients `[c₀, c₁, c₂, c₃]` of `s ↦ p(a + s d)` (scaled `a`, unit `d`).
    ///
    /// Expanded per homogeneous degree: linear `l·a + s l·d`; quadratic
    /// `Q(a) + s·2aᵀAd + s² Q(d)`; cubic `C(a) + s d·∇C(a) + s² a·∇C(d) + s³ C(d)` (Euler's
    /// identity `x·∇C(x) = 3C(x)` gives `C(a) = a·∇C(a)/3`, `C(d) = d·∇C(d)/3`).
    #[inline]
    pub fn ray_cubic(&self, a: DVec3, d: DVec3) -> [f64; 4] {
        let c = &self.c;
        let l = DVec3::new(c[1], c[2], c[3]);
        // Symmetric matrix A of the quadratic part: Q(x) = xᵀ A x.
        let ad = DVec3::new(
            c[4] * d.x + 0.5 * (c[5] * d.y + c[6] * d.z),
            0.5 * c[5] * d.x + c[7] * d.y + 0.5 * c[8] * d.z,
            0.5 * (c[6] * d.x + c[8] * d.y) + c[9] * d.z,
        );
        let aa = DVec3::new(
            c[4] * a.x + 0.5 * (c[5] * a.y + c[6] * a.z),
            0.5 * c[5] * a.x + c[7] * a.y + 0.5 * c[8] * a.z,
            0.5 * (c[6] * a.x + c[8] * a.y) + c[9] * a.z,
        );
        let gca = self.cubic_gradient(a);
        let gcd = self.cubic_gradient(d);
        let c0 = c[0] + l.dot(a) + a.dot(aa) + a.dot(gca) / 3.0;
        let c1 = l.dot(d) + 2.0 * a.dot(ad) + d.dot(gca);
        let c2 = d.dot(ad) + a.dot(gcd);
        let c3 = d.dot(gcd) / 3.0;
        [c0, c1, c2, c3]
    }

    /// First boundary crossing along `r + t d` (world offset `r`, unit `d`) with `t ∈ (0, t_max]`
    /// (world units). `on_surface`: `r` lies on the surface and the root at `t = 0` is removed by
    /// deflation. Returns `Err` when the ray starts outside / points outwards from the surface.
    #[inline]
    pub fn intersect(
        &self,
        r: DVec3,
        d: DVec3,
        t_max: f64,
        on_surface: bool,
    ) -> Result<Option<f64>, InvalidReason> {
        let c = self.ray_cubic(r * self.inv_sigma_n, d);
        let s_max = t_max.min(MAX_DISTANCE) * self.inv_sigma_n;
        let root = if on_surface {
            if c[1] >= 0.0 {
                return Err(InvalidReason::FirstRayOutside);
            }
            first_root([c[1], c[2], c[3], 0.0], 0.0, s_max)
        } else {
            if c[0] >= 0.0 {
                return Err(InvalidReason::VertexOutside);
            }
            first_root(c, 0.0, s_max)
        };
        Ok(root.map(|s| s * self.sigma_n))
    }
}

/// `−ln(1 − u)/σ_t` for `u ∈ [0, 1)`.
#[inline]
fn exp_flight(u: f32, sigma_t: f64) -> f64 {
    -(-(u as f64)).ln_1p() / sigma_t
}

/// One VKJ19 random walk from the entry point (offset 0, on the surface) with the aligned
/// incident direction `d_in` (unit, into the medium). See the module docs for the physics.
pub fn random_walk(
    surface: &WalkSurface,
    medium: &WalkMedium,
    d_in: Vec3,
    rng: &mut Sampler,
) -> WalkOutcome {
    let sigma_t = medium.sigma_t;
    let eta_out = (1.0 / medium.eta) as f32; // n_outside / n_inside, leaving the medium
    let phase = HenyeyGreenstein { g: medium.g as f32 };
    let mut d = d_in.as_dvec3().normalize();
    // First segment: exponential truncated to the first hit (conditioned on ≥ 1 scattering).
    let first = match surface.intersect(DVec3::ZERO, d, MAX_DISTANCE, true) {
        Ok(h) => h,
        Err(_) => return WalkOutcome::Invalid(InvalidReason::FirstRayOutside),
    };
    let u = rng.next_f32() as f64;
    let t = match first {
        Some(t_hit) => {
            if surface.gradient(d * t_hit).dot(d) <= 0.0 {
                return WalkOutcome::Invalid(InvalidReason::HitFromOutside);
            }
            let mass = -(-sigma_t * t_hit).exp_m1(); // 1 − e^{−σ_t t_hit}
            (-(-u * mass).ln_1p() / sigma_t).min(t_hit * (1.0 - 1e-9))
        }
        None => -(-u).ln_1p() / sigma_t,
    };
    let mut r = d * t;
    let mut bounces: u32 = 0;
    loop {
        // Scattering event at r.
        bounces += 1;
        if bounces > MAX_BOUNCES || rng.next_f32() as f64 >= medium.albedo {
            return WalkOutcome::Absorbed { bounces };
        }
        let (u1, u2) = (rng.next_f32(), rng.next_f32());
        d = phase.sample(d.as_vec3(), u1, u2).as_dvec3();
        let mut on_surface = false;
        loop {
            let t_s = exp_flight(rng.next_f32(), sigma_t);
            let hit = match surface.intersect(r, d, t_s, on_surface) {
                Ok(h) => h,
                Err(reason) => {
                    let reason = if on_surface {
                        InvalidReason::HitFromOutside
                    } else {
                        reason
                    };
                    return WalkOutcome::Invalid(reason);
                }
            };
            let Some(t_hit) = hit else {
                r += d * t_s;
                break;
            };
            let p = r + d * t_hit;
            let n = surface.gradient(p).normalize();
            let cos = n.dot(d);
            if cos.is_nan() || cos <= 0.0 {
                return WalkOutcome::Invalid(InvalidReason::HitFromOutside);
            }
            let (nf, df) = (n.as_vec3(), d.as_vec3());
            let fr = if medium.eta == 1.0 {
                0.0
            } else {
                fresnel_dielectric(cos as f32, eta_out)
            };
            let out = if fr > 0.0 && rng.next_f32() < fr {
                None
            } else {
                refract(df, nf, eta_out)
            };
            match out {
                Some(dir) => {
                    return WalkOutcome::Exited(Exit {
                        position: p,
                        normal: nf,
                        direction: dir,
                        bounces,
                    });
                }
                None => {
                    // Specular internal reflection; keep flying from the surface point.
                    d = reflect(df, nf).as_dvec3().normalize();
                    r = p;
                    on_surface = true;
                }
            }
        }
    }
}
