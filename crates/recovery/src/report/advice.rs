//! Which capture would determine σ_t for *this* rig, from the sensitivity the run already has.
//!
//! The intervals ([`inverse::uncertainty`]) hold, per view v used and channel c, the Gauss–Newton
//! bread A_v = Σ_p J_p J_pᵀ in (ln σ_t, α). Along the valley of the summed A (α refitted as σ_t
//! moves: u = (1, s), s = −a01/a11; s = 0 when α is fixed) a view's information on σ_t is
//!
//!   k_v = uᵀ A_v u = a00 + 2 s a01 + s² a11,      K = Σ_v k_v = a00 − a01²/a11 (summed A),
//!
//! the Schur complement: the profile variance of ln σ_t is inversely proportional to K when
//! every view is equally noisy. With x the images' variance of ln σ_t (the sandwich, the
//! optimiser's spread and the tracer's widening; what decides *determined*) and t the variance at
//! which σ_t counts as determined, ln(ratio)/(2 z₉₅) squared ([`DETERMINED_SIGMA_T_RATIO`]),
//! the information must grow by F = (x − o)/(t − o), where o is the part of x that more views
//! would not narrow (the optimiser's spread and drift over its last iterates; where o ≥ t the
//! run must go on longer first); views adding k_b each must number about K (F − 1)/k_b more. The views are grouped by the angle at the object's centre between the
//! directions to the camera and to the light (0°: a flash; 180°: back light). Where no view
//! lights the object from the side or from behind, such a view is rendered at the estimate
//! (its camera a captured one, its light moved round the object at the same distance,
//! [`moved_light`]) for its k_b: [`inverse::optimize::Optimizer::candidate_bread`].
//!
//! The counts assume new views as noisy as these and a run as long: they say which light
//! positions help and by about how much, not an exact plan.

use glam::{Quat, Vec3};
use serde::Serialize;
use serde_json::json;

use inverse::uncertainty::{DETERMINED_SIGMA_T_RATIO, Uncertainty, WIDEST_SD_LN_SIGMA_T, Z95};
use scene::{Camera, PointLight};

/// The angle classes of the light seen from the object: (upper bound in degrees, name).
pub const CLASSES: [(f64, &str); 3] = [
    (30.0, "within 30° of the camera (a flash)"),
    (120.0, "30°–120° from the camera (beside the object)"),
    (180.0, "over 120° from the camera (behind the object)"),
];

/// The light angles of the candidate views rendered where no captured view has its light in
/// that class.
pub const CANDIDATE_ANGLES: [f64; 2] = [90.0, 150.0];

/// The angle in degrees at `centre` between the directions to the camera and to the light.
pub fn light_angle(camera: &Camera, light: &PointLight, centre: Vec3) -> f64 {
    let (c, l) = (
        (camera.origin - centre).as_dvec3(),
        (light.position - centre).as_dvec3(),
    );
    // atan2 of |c × l| and c·l: exact near 0° and 180°, where acos of the cosine is not.
    c.cross(l).length().atan2(c.dot(l)).to_degrees()
}

/// `light` moved round `centre` to `angle_deg` from `camera`'s direction, at its own distance:
/// the camera's direction turned about the camera's image-up axis (a light on a turntable's
/// horizon).
pub fn moved_light(
    camera: &Camera,
    light: &PointLight,
    centre: Vec3,
    angle_deg: f64,
) -> PointLight {
    let dir = (camera.origin - centre).normalize();
    // Image up, made perpendicular to the direction (the camera need not look at the centre).
    let up = camera.rotation.y_axis;
    let axis = (up - dir * up.dot(dir))
        .try_normalize()
        .unwrap_or_else(|| dir.any_orthonormal_vector());
    let turned = Quat::from_axis_angle(axis, (angle_deg as f32).to_radians()) * dir;
    PointLight {
        position: centre + turned * (light.position - centre).length(),
        ..*light
    }
}

/// A view the run did not have: its bread at the estimate and its light's angle.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The captured view whose camera it uses.
    pub of_view: usize,
    pub angle_deg: f64,
    /// [a00, a01, a11] per channel in (ln σ_t, α).
    pub bread: [[f64; 3]; 3],
}

/// The views of one angle class.
#[derive(Clone, Debug, Serialize)]
pub struct Group {
    pub lights: &'static str,
    /// The dataset views in it (of those the intervals used).
    pub views: Vec<usize>,
    /// Their share of K per channel (`None` where the views used have no information).
    pub share: [Option<f64>; 3],
    /// About how many more views like these would determine σ_t, per channel (`None`: determined
    /// already, or these views carry no information on it).
    pub more_needed: [Option<f64>; 3],
}

/// A candidate view's information.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateShare {
    pub of_view: usize,
    pub angle_deg: f64,
    /// Its k against the mean k of the views used, per channel (`None` where they have none).
    pub per_view_vs_mean: [Option<f64>; 3],
    pub more_needed: [Option<f64>; 3],
}

/// The advice (module docs).
#[derive(Clone, Debug, Serialize)]
pub struct Advice {
    /// F per channel: the information on σ_t the images would need, as a multiple of what they
    /// give (`None`: determined, or no measurable information to scale).
    pub need: [Option<f64>; 3],
    /// The images' interval reached the widest the report computes: F is a lower bound.
    pub at_least: [bool; 3],
    /// The optimiser's spread and drift alone keep σ_t from being determined: more iterations
    /// first.
    pub unsettled: [bool; 3],
    pub groups: Vec<Group>,
    pub candidates: Vec<CandidateShare>,
}

/// k_v per view (in `breads`' order) and channel along the valley of `u`'s summed bread.
fn along_valley(u: &Uncertainty, breads: &[[[f64; 3]; 3]]) -> Vec<[f64; 3]> {
    let total = u.bread();
    let slope: [f64; 3] = std::array::from_fn(|c| {
        let s = -total[c][1] / total[c][2];
        if u.fixed[1] || !s.is_finite() { 0.0 } else { s }
    });
    breads
        .iter()
        .map(|b| {
            std::array::from_fn(|c| b[c][0] + 2.0 * slope[c] * b[c][1] + slope[c].powi(2) * b[c][2])
        })
        .collect()
}

/// The advice where σ_t is free and not determined in some channel, with the light angle of each
/// view in `u.view_bread` (`angles[i]` for `u.view_bread[i]`) and the candidate views rendered;
/// `None` where σ_t is determined or fixed, or where the views carry no measurable information
/// on it (the intervals say so already).
pub fn advise(u: &Uncertainty, angles: &[f64], candidates: &[Candidate]) -> Option<Advice> {
    if u.fixed[0] || angles.len() != u.view_bread.len() || angles.is_empty() {
        return None;
    }
    let breads: Vec<_> = u.view_bread.iter().map(|(_, b)| *b).collect();
    let k = along_valley(u, &breads);
    let target = (DETERMINED_SIGMA_T_RATIO.ln() / (2.0 * Z95)).powi(2);
    let total: [f64; 3] = std::array::from_fn(|c| k.iter().map(|v| v[c]).sum());
    let open = |c: usize| -> Option<f64> {
        let x = u.images[c]?[0];
        (!u.determined_sigma_t[c] && total[c] > 0.0 && x.is_finite() && x > target).then_some(x)
    };
    // The optimiser's spread and drift, o, stay whatever the views: the views' part x − o must
    // fall to t − o.
    let unsettled: [bool; 3] =
        std::array::from_fn(|c| open(c).is_some() && u.optimiser[c][0] >= target);
    let need: [Option<f64>; 3] = std::array::from_fn(|c| {
        let o = u.optimiser[c][0];
        open(c)
            .filter(|_| !unsettled[c])
            .map(|x| (x - o) / (target - o))
    });
    if need.iter().all(Option::is_none) && !unsettled.contains(&true) {
        return None;
    }
    // Widened to the cap by the tracer's sensitivity: the true need is larger.
    let at_least = std::array::from_fn(|c| {
        u.images[c].is_some_and(|m| (m[0].sqrt() / WIDEST_SD_LN_SIGMA_T - 1.0).abs() < 1e-9)
    });
    let more = |per_view: [f64; 3]| -> [Option<f64>; 3] {
        std::array::from_fn(|c| {
            need[c]
                .filter(|_| per_view[c] > 0.0)
                .map(|f| total[c] * (f - 1.0) / per_view[c])
        })
    };
    let mut lo = 0.0;
    let groups = CLASSES
        .iter()
        .filter_map(|&(hi, lights)| {
            let members: Vec<usize> = (0..k.len())
                .filter(|&i| angles[i] >= lo && (angles[i] < hi || hi == 180.0))
                .collect();
            lo = hi;
            if members.is_empty() {
                return None;
            }
            let sum: [f64; 3] = std::array::from_fn(|c| members.iter().map(|&i| k[i][c]).sum());
            Some(Group {
                lights,
                views: members.iter().map(|&i| u.view_bread[i].0).collect(),
                share: std::array::from_fn(|c| (total[c] > 0.0).then(|| sum[c] / total[c])),
                more_needed: more(sum.map(|s| s / members.len() as f64)),
            })
        })
        .collect();
    let views = k.len() as f64;
    let candidates = candidates
        .iter()
        .map(|cand| {
            let kc = along_valley(u, &[cand.bread])[0];
            CandidateShare {
                of_view: cand.of_view,
                angle_deg: cand.angle_deg,
                per_view_vs_mean: std::array::from_fn(|c| {
                    (total[c] > 0.0).then(|| kc[c] * views / total[c])
                }),
                more_needed: more(kc),
            }
        })
        .collect();
    Some(Advice {
        need,
        at_least,
        unsettled,
        groups,
        candidates,
    })
}

/// A count or factor to two significant figures (at least 1).
fn approx(n: f64) -> String {
    let n = n.max(1.0);
    let step = 10f64.powi((n.log10().floor() as i32 - 1).max(0));
    format!("{}", (n / step).ceil() * step)
}

/// Three per-channel values, `—` where there is none.
fn per_channel(v: [Option<f64>; 3], f: impl Fn(f64) -> String) -> String {
    v.map(|x| x.map_or("—".to_string(), &f)).join(", ")
}

impl Advice {
    /// The printed lines.
    pub fn lines(&self) -> Vec<String> {
        let views: usize = self.groups.iter().map(|g| g.views.len()).sum();
        let need = (0..3)
            .map(|c| match self.need[c] {
                Some(f) if self.at_least[c] => format!("≥ {}", approx(f)),
                Some(f) => approx(f),
                None => "—".into(),
            })
            .collect::<Vec<_>>()
            .join(", ");
        let mut out = vec![format!(
            "What would determine σ_t with this rig: the information these {views} views give on \
             σ_t along its valley with α would have to grow ({need})× in (R, G, B). More views \
             needed, per light position (R, G, B):"
        )];
        for g in &self.groups {
            out.push(format!(
                "  {} view{} with the light {}, ({}) % of it: {} more such views",
                g.views.len(),
                if g.views.len() == 1 { "" } else { "s" },
                g.lights,
                per_channel(g.share, |x| format!("{:.0}", 100.0 * x)),
                per_channel(g.more_needed, approx)
            ));
        }
        for c in &self.candidates {
            out.push(format!(
                "  view {}'s camera with the light moved {:.0}° round the object (rendered at the \
                 estimate), ({})× a view above on average: {} such views",
                c.of_view,
                c.angle_deg,
                per_channel(c.per_view_vs_mean, |x| format!("{x:.1}")),
                per_channel(c.more_needed, approx)
            ));
        }
        let unsettled: Vec<&str> = (0..3)
            .filter(|&c| self.unsettled[c])
            .map(|c| ["R", "G", "B"][c])
            .collect();
        if !unsettled.is_empty() {
            out.push(format!(
                "  In {} the run had not settled: its last iterates' spread and drift alone \
                 exceed ±10 % in σ_t, so more views will not do without more iterations ({}).",
                unsettled.join(", "),
                scene::setting::Setting::Iterations
            ));
        }
        out.push(
            "  (for new views as noisy as these and a run as long; —: determined already, or no \
             information; more samples per iteration narrow every interval too)"
                .into(),
        );
        out
    }

    /// result.json's `advice` block.
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "sigma_t": self,
            "method": "each view's Gauss-Newton information on ln sigma_t along the sigma_t-albedo \
                       valley; need = the images' variance of ln sigma_t over the variance at \
                       which it counts as determined; more_needed = K (need - 1) / the view's \
                       information (K: that of the views used)",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat3;

    fn camera_at(origin: Vec3) -> Camera {
        let z = (-origin).normalize();
        let x = Vec3::Y.cross(z).normalize();
        Camera {
            origin,
            rotation: Mat3::from_cols(x, z.cross(x), z),
            fov_x_deg: 30.0,
            width: 8,
            height: 8,
            crop: None,
            pinhole: None,
            mask: None,
        }
    }

    /// A moved light keeps its distance and lies at the angle asked for, on the camera's
    /// horizon.
    #[test]
    fn moved_light_angle_and_distance() {
        let cam = camera_at(Vec3::new(0.3, 0.2, 4.0));
        let light = PointLight {
            position: Vec3::new(0.5, 0.4, 3.0),
            intensity: [1.0, 2.0, 3.0],
        };
        let centre = Vec3::new(0.1, 0.0, 0.0);
        for a in [0.0, 45.0, 90.0, 150.0, 180.0] {
            let m = moved_light(&cam, &light, centre, a);
            assert!((light_angle(&cam, &m, centre) - a).abs() < 1e-3, "{a}");
            let r = |p: Vec3| (p - centre).length();
            assert!((r(m.position) - r(light.position)).abs() < 1e-5);
            assert_eq!(m.intensity, light.intensity);
        }
        assert_eq!(approx(115_191.7), "120000");
        assert_eq!(approx(35.2), "36");
        assert_eq!(approx(4.2), "5");
        assert_eq!(approx(0.3), "1");
        // A light at the camera is at angle 0, one opposite at 180.
        let flash = PointLight {
            position: cam.origin,
            intensity: [1.0; 3],
        };
        assert!(light_angle(&cam, &flash, Vec3::ZERO) < 1e-3);
    }

    /// Two flash views and one side view with known breads: the shares, the need and the
    /// counts as computed by hand.
    #[test]
    fn shares_need_and_counts_by_hand() {
        // Channel breads in (ln σ_t, α): the flash views see mostly the valley's α direction.
        let flash = [[1.0, 2.0, 4.5]; 3]; // k = 1 − 2·(2)·s + ... with s from the sum
        let side = [[9.0, 2.0, 4.0]; 3];
        let mut u = Uncertainty::new(
            [50.0; 3],
            [0.5; 3],
            [Some([1.0, 0.0, 1e-4]); 3],
            [Some([0.25, 0.0, 1e-4]); 3],
            3,
        );
        u.view_bread = vec![(0, flash), (4, flash), (8, side)];
        let angles = [2.0, 3.0, 95.0];
        let a = advise(&u, &angles, &[]).expect("σ_t is not determined");
        // Summed A: [11, 6, 13]; s = −6/13; K = 11 − 36/13.
        let s: f64 = -6.0 / 13.0;
        let k = |b: [f64; 3]| b[0] + 2.0 * s * b[1] + s * s * b[2];
        let kk = 11.0 - 36.0 / 13.0;
        assert!((2.0 * k(flash[0]) + k(side[0]) - kk).abs() < 1e-12);
        let t = (1.2f64.ln() / (2.0 * Z95)).powi(2);
        let need = a.need[1].unwrap();
        assert!((need - 0.25 / t).abs() < 1e-9 * need);
        assert_eq!(a.groups.len(), 2);
        assert_eq!(a.groups[0].views, vec![0, 4]);
        assert_eq!(a.groups[1].views, vec![8]);
        assert!((a.groups[0].share[2].unwrap() - 2.0 * k(flash[0]) / kk).abs() < 1e-12);
        let more_side = kk * (need - 1.0) / k(side[0]);
        assert!((a.groups[1].more_needed[0].unwrap() - more_side).abs() < 1e-9 * more_side);
        // A candidate with the side view's bread counts as that view does.
        let cand = Candidate {
            of_view: 0,
            angle_deg: 150.0,
            bread: side,
        };
        let a = advise(&u, &angles, &[cand]).unwrap();
        let c = &a.candidates[0];
        assert!((c.more_needed[1].unwrap() - more_side).abs() < 1e-9 * more_side);
        assert!((c.per_view_vs_mean[1].unwrap() - k(side[0]) / (kk / 3.0)).abs() < 1e-12);
        let text = a.lines().join("\n");
        assert!(text.contains("2 views with the light within 30°"), "{text}");
        assert!(text.contains("moved 150°"), "{text}");
        // A channel determined already needs nothing.
        let mut one = u.clone();
        one.determined_sigma_t[0] = true;
        let a = advise(&one, &angles, &[]).unwrap();
        assert!(a.need[0].is_none() && a.groups[1].more_needed[0].is_none());
        assert!(a.lines()[1].contains(": —, "), "{:?}", a.lines());
        // An optimiser still moving by more than the target width: more iterations first.
        let mut moving = u.clone();
        moving.optimiser = [[0.01, 0.0, 0.0]; 3];
        let a = advise(&moving, &angles, &[]).unwrap();
        assert_eq!(a.unsettled, [true; 3]);
        assert!(a.need.iter().all(Option::is_none));
        assert!(
            a.lines().join(" ").contains("had not settled"),
            "{:?}",
            a.lines()
        );
        // A settled part o shrinks what the views must do: F = (x − o)/(t − o).
        let mut part = u.clone();
        part.optimiser = [[0.5 * t, 0.0, 0.0]; 3];
        let a = advise(&part, &angles, &[]).unwrap();
        let f = (0.25 - 0.5 * t) / (0.5 * t);
        assert!((a.need[0].unwrap() - f).abs() < 1e-9 * f);
        // Determined everywhere: no advice.
        let mut d = u.clone();
        d.determined_sigma_t = [true; 3];
        assert!(advise(&d, &angles, &[]).is_none());
        // σ_t fixed: none either.
        let mut f = u.clone();
        f.fixed[0] = true;
        assert!(advise(&f, &angles, &[]).is_none());
    }
}
