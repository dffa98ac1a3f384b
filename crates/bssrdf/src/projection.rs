//! Projection Π of a proposed entry point onto the mesh (docs/model.md §7, recommendation A5).
//!
//! The decoder proposes x̃ near the surface; Π moves it onto the mesh along the DETACHED gradient
//! direction of the local polynomial at x̃ (the polynomial is an implicit surface with p < 0
//! inside, ∇p ≈ outward normal, so the surface lies along d = −sign(p(x̃))·∇p/|∇p|).
//!
//! Rules:
//! * [`ProjectionRule::Son24`] (default; Son et al.'s psdr-cuda `vaesub`): two rays (traced in one
//!   BVH traversal, [`Accel::first_hits_both_ways`]), from
//!   x̃ − o·d along +d and from x̃ + o·d along −d (o = `origin_offset`, 0.01 scene units), each
//!   with t_max = `max_dist_scale`·σ_n + o; the hit nearer to x̃ wins; no second pass, so a miss
//!   is an invalid sample (it still counts in the average, with value 0). Bounded and
//!   deterministic: the offset samples of the σ_t derivative keep the same rule.
//!
//!   The reach: SON24's scripts pass `--maxDistScale 2` ([`SON24_MAX_DIST_SCALE`]); our default
//!   is [`DEFAULT_MAX_DIST_SCALE`] = 8. Every proposal off the surface is decoder error (the
//!   training exits lie on the surface), and a miss removes its light. With reach 2 about 9 % of
//!   our decoder's samples miss, and they cost more light at high σ_t than at low σ_t: the ratio
//!   learned/volpath falls by 1.9 % from σ_t = 30 to 100 (mean over 36 cases; −0.4 % at reach 4,
//!   +0.4 % at 8, +0.5 % with the unbounded VKJ19 rule). α absorbs a level, but such a slope
//!   biases a joint σ_t, α fit low (torus: −21 % at reach 2, −9 % at reach 8).
//!   docs/notes/light-side.md, "The projection's reach with isotropic incidence" and "The
//!   projection's reach with directional incidence: 8σ_n".
//! * [`ProjectionRule::Vkj19`] (Vicini et al.'s Mitsuba plugin): along ±∇p/|∇p| with distance
//!   limit 2ε = 2σ_n² (as coded there) and, when both miss, a second, unbounded pass.

use geometry::{Accel, Hit};
use glam::Vec3;

/// Which projection rule to use.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum ProjectionRule {
    Son24 {
        max_dist_scale: f32,
        origin_offset: f32,
    },
    Vkj19,
}

/// The family of a [`ProjectionRule`], by name (`son24`, `vkj19`): what a user chooses; the
/// reach of `son24` is a separate setting.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ProjectionKind {
    /// Bounded: along the polynomial gradient, within the reach (in units of σ_n) plus 0.01,
    /// in a single pass (Son et al. 2024).
    #[default]
    Son24,
    /// 2σ_n² first, then unbounded (Vicini et al. 2019).
    Vkj19,
}

impl ProjectionKind {
    /// The rule of this kind; `max_dist_scale` is the reach of `Son24`.
    pub fn rule(self, max_dist_scale: f32) -> ProjectionRule {
        match self {
            ProjectionKind::Vkj19 => ProjectionRule::Vkj19,
            ProjectionKind::Son24 => match ProjectionRule::default() {
                ProjectionRule::Son24 { origin_offset, .. } => ProjectionRule::Son24 {
                    max_dist_scale,
                    origin_offset,
                },
                rule => rule,
            },
        }
    }
}

/// The reach SON24's scripts use (`--maxDistScale 2.0`), in units of σ_n.
pub const SON24_MAX_DIST_SCALE: f32 = 2.0;
/// Our default reach in units of σ_n (see the module documentation for the measurement).
pub const DEFAULT_MAX_DIST_SCALE: f32 = 8.0;

impl Default for ProjectionRule {
    /// The SON24 rule with reach [`DEFAULT_MAX_DIST_SCALE`] and SON24's origin offset 0.01.
    fn default() -> Self {
        ProjectionRule::Son24 {
            max_dist_scale: DEFAULT_MAX_DIST_SCALE,
            origin_offset: 0.01,
        }
    }
}

/// Project `x` onto the mesh. `grad` is the (unnormalised, detached) polynomial gradient at `x`
/// in world axes and `value` the polynomial value there (its sign says the side). Returns the
/// hit (position, normals, triangle) or `None` (invalid sample).
pub fn project(
    accel: &Accel,
    rule: ProjectionRule,
    x: Vec3,
    grad: Vec3,
    value: f32,
    sigma_n: f32,
) -> Option<Hit> {
    let g = grad.try_normalize()?;
    match rule {
        ProjectionRule::Son24 {
            max_dist_scale,
            origin_offset,
        } => {
            // Towards the surface: against the gradient when outside (p > 0).
            let d = if value > 0.0 { -g } else { g };
            let tmax = max_dist_scale * sigma_n + origin_offset;
            // Ray a: from x̃ − o·d along d, t < t_max (s ∈ (−o, t_max − o) on the line x̃ + s·d);
            // ray b: from x̃ + o·d along −d (s ∈ (o − t_max, o)); both in one traversal.
            let o = origin_offset;
            accel.nearest_hit_both_ways(x, d, (-o, tmax - o), (o - tmax, o))
        }
        ProjectionRule::Vkj19 => {
            let limit = 2.0 * sigma_n * sigma_n;
            let pass = |tmax: f32| {
                let a = accel.closest(x, g, 0.0, tmax);
                let tb = a.map_or(tmax, |h| h.t);
                let b = accel.closest(x, -g, 0.0, tb);
                nearer(x, a, b)
            };
            pass(limit).or_else(|| pass(f32::INFINITY))
        }
    }
}

#[inline]
fn nearer(x: Vec3, a: Option<Hit>, b: Option<Hit>) -> Option<Hit> {
    match (a, b) {
        (Some(a), Some(b)) => Some(
            if (a.p - x).length_squared() <= (b.p - x).length_squared() {
                a
            } else {
                b
            },
        ),
        (a, b) => a.or(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geometry::Shape;

    fn sphere() -> Accel {
        Accel::new(
            Shape::Sphere {
                radius: 0.5,
                subdivisions: 5,
            }
            .build()
            .unwrap(),
        )
    }

    /// Implicit sphere |x|² − R² (gradient 2x): points near the surface project radially.
    #[test]
    fn projects_onto_the_surface_from_both_sides() {
        let accel = sphere();
        let sigma_n = 0.02;
        for (k, dir) in [Vec3::X, Vec3::new(0.3, 0.8, -0.5).normalize(), -Vec3::Y]
            .into_iter()
            .enumerate()
        {
            for r in [0.48f32, 0.495, 0.505, 0.52] {
                let x = dir * r;
                let value = r * r - 0.25;
                let h = project(
                    &accel,
                    ProjectionRule::default(),
                    x,
                    2.0 * x,
                    value,
                    sigma_n,
                )
                .unwrap_or_else(|| panic!("case {k} r {r}"));
                // On the mesh: barycentric hit on a triangle; check it is on the ray and on the
                // tessellated sphere (|p| within the facet sag of 0.5).
                assert!(
                    (h.p.normalize() - dir).length() < 1e-4,
                    "not radial: {:?}",
                    h.p
                );
                assert!((h.p.length() - 0.5).abs() < 5e-4, "{}", h.p.length());
                let v = Accel::closest(&accel, h.p - 1e-3 * dir, dir, 0.0, 2e-3).unwrap();
                assert!((v.p - h.p).length() < 1e-5 * 0.5);
            }
        }
    }

    #[test]
    fn son24_rule_misses_beyond_its_bound_and_vkj19_falls_back() {
        let accel = sphere();
        let sigma_n = 0.01;
        let son24 = ProjectionRule::Son24 {
            max_dist_scale: SON24_MAX_DIST_SCALE,
            origin_offset: 0.01,
        };
        // 0.1 inside the surface: farther than 2σ_n + 0.01 = 0.03 (SON24's reach) and than
        // 8σ_n + 0.01 = 0.09 (the default).
        let x = Vec3::new(0.0, 0.0, 0.4);
        for rule in [son24, ProjectionRule::default()] {
            assert!(project(&accel, rule, x, 2.0 * x, 0.16 - 0.25, sigma_n).is_none());
        }
        let h = project(
            &accel,
            ProjectionRule::Vkj19,
            x,
            2.0 * x,
            0.16 - 0.25,
            sigma_n,
        )
        .expect("fallback pass");
        assert!((h.p - Vec3::new(0.0, 0.0, 0.5)).length() < 1e-3);
        // The reach is `max_dist_scale`·σ_n from x̃ on either side: 0.1 away is out of reach at
        // 9σ_n and within it at 12σ_n.
        let reach = |k: f32| ProjectionRule::Son24 {
            max_dist_scale: k,
            origin_offset: 0.01,
        };
        assert!(project(&accel, reach(9.0), x, 2.0 * x, 0.16 - 0.25, sigma_n).is_none());
        let h = project(&accel, reach(12.0), x, 2.0 * x, 0.16 - 0.25, sigma_n).expect("in reach");
        assert!((h.p - Vec3::new(0.0, 0.0, 0.5)).length() < 1e-3);
        let outside = Vec3::new(0.0, 0.0, 0.6);
        let v = 0.36 - 0.25;
        assert!(project(&accel, reach(9.0), outside, 2.0 * outside, v, sigma_n).is_none());
        let h = project(&accel, reach(12.0), outside, 2.0 * outside, v, sigma_n).expect("in reach");
        assert!((h.p - Vec3::new(0.0, 0.0, 0.5)).length() < 1e-3);
        // Within the bound it hits, and takes the nearer of the two sides.
        let x = Vec3::new(0.0, 0.0, 0.49);
        let h = project(
            &accel,
            ProjectionRule::default(),
            x,
            2.0 * x,
            0.49f32 * 0.49 - 0.25,
            sigma_n,
        )
        .unwrap();
        assert!((h.p.z - 0.5).abs() < 1e-3);
        // Zero gradient: invalid.
        assert!(
            project(
                &accel,
                ProjectionRule::default(),
                x,
                Vec3::ZERO,
                0.0,
                sigma_n
            )
            .is_none()
        );
    }
}
