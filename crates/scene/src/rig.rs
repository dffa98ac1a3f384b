//! Multi-view rigs: N cameras on a Fibonacci sphere looking at a target, with one fixed light
//! or a light attached to each camera.
//!
//! The directions are the ones the Mitsuba reference renders use (`render_reference.py`):
//! `y_i = 1 − (2i + 1)/N`, `φ_i = 0.3 + i·π(3 − √5)`, direction
//! `(√(1 − y²) cos φ, y, √(1 − y²) sin φ)`, so a rig of 8 views at radius 0.5 reproduces
//! the cameras of `mitsuba-sphere-rgb-64` exactly.

use glam::Vec3;

use crate::scene_file::desc::ViewDesc;
use crate::{Camera, PointLight, SceneError};

/// Azimuth of the first direction (radians), as in the reference renders.
pub const FIBONACCI_PHASE: f64 = 0.3;

/// `n` unit directions spread evenly over the whole sphere (deterministic, view 0 nearest +Y).
pub fn fibonacci_sphere(n: usize) -> Vec<Vec3> {
    fibonacci_band(n, -90.0, 90.0)
}

/// `n` unit directions spread evenly (equal area) over the band of elevations
/// `[min_elev_deg, max_elev_deg]` (degrees above the XZ plane, −90…90), highest first.
pub fn fibonacci_band(n: usize, min_elev_deg: f64, max_elev_deg: f64) -> Vec<Vec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let y_lo = min_elev_deg.to_radians().sin();
    let y_hi = max_elev_deg.to_radians().sin();
    (0..n)
        .map(|i| {
            // Equal-area strata in y: for the full sphere this is 1 − (2i+1)/n.
            let u = (2 * i + 1) as f64 / (2 * n) as f64;
            let y = y_hi - (y_hi - y_lo) * u;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let phi = FIBONACCI_PHASE + i as f64 * golden;
            Vec3::new((r * phi.cos()) as f32, y as f32, (r * phi.sin()) as f32)
        })
        .collect()
}

/// The `up` vector used for a camera looking along `dir`: +Y, unless `dir` is within about 8° of
/// ±Y, then +Z.
pub fn rig_up(dir: Vec3) -> Vec3 {
    if dir.normalize_or_zero().y.abs() > 0.99 {
        Vec3::Z
    } else {
        Vec3::Y
    }
}

/// Where the light of a rig is, by name (the data of [`RigLight`] aside).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum RigLightKind {
    /// Moves with each camera, offset from it (a flash; default).
    #[default]
    Attached,
    /// One position for every view.
    Fixed,
}

/// Where the light of a rig sits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RigLight {
    /// The same world position for every view.
    Fixed { position: Vec3 },
    /// At the camera position plus `offset` in the camera frame: offset.x along the camera x axis
    /// (image LEFT, Mitsuba convention), offset.y along image up, offset.z along the view
    /// direction. `[0, 0, 0]` is a light co-located with the camera.
    Attached { offset: Vec3 },
}

/// A multi-view rig: `views` cameras at distance `radius` from `target`, looking at it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rig {
    pub views: usize,
    pub radius: f32,
    pub target: Vec3,
    pub fov_x_deg: f32,
    pub width: u32,
    pub height: u32,
    pub light: RigLight,
    /// Radiant intensity per channel [W/sr].
    pub intensity: [f32; 3],
    /// Elevation band in degrees (−90…90); `(-90, 90)` is the whole sphere.
    pub elevation_deg: (f32, f32),
}

impl Rig {
    /// Check the numbers; `context` (e.g. "scene.toml: rig") goes into the error.
    pub fn validate(&self, context: &str) -> Result<(), SceneError> {
        let bad = |field: &str, reason: String| SceneError::Invalid {
            location: format!("{context}.{field}"),
            reason,
        };
        if self.views == 0 || self.views > 100_000 {
            return Err(bad(
                "views",
                format!(
                    "= {}: number of views must be between 1 and 100000; fix: use e.g. 8",
                    self.views
                ),
            ));
        }
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(bad(
                "radius",
                format!(
                    "= {}: camera distance must be > 0 (scene units); fix: use e.g. 3 for an object 1 unit across",
                    self.radius
                ),
            ));
        }
        if !self.target.is_finite() {
            return Err(bad(
                "target",
                format!("= {:?}: must be finite", self.target.to_array()),
            ));
        }
        let (lo, hi) = self.elevation_deg;
        if !(lo.is_finite()
            && hi.is_finite()
            && (-90.0..=90.0).contains(&lo)
            && (-90.0..=90.0).contains(&hi)
            && lo < hi)
        {
            return Err(bad(
                "elevation",
                format!(
                    "= [{lo}, {hi}]: must be [min, max] degrees with −90 ≤ min < max ≤ 90; fix: e.g. [-30, 60]"
                ),
            ));
        }
        check_intensity(&self.intensity, &format!("{context}.intensity"))?;
        match self.light {
            RigLight::Fixed { position } if !position.is_finite() => Err(bad(
                "light_position",
                format!("= {:?}: must be finite", position.to_array()),
            )),
            RigLight::Attached { offset } if !offset.is_finite() => Err(bad(
                "light_offset",
                format!("= {:?}: must be finite", offset.to_array()),
            )),
            _ => Ok(()),
        }
    }

    /// The views of the rig (not validated; call [`Rig::validate`] first).
    pub fn build(&self) -> Vec<ViewDesc> {
        let dirs = fibonacci_band(
            self.views,
            self.elevation_deg.0 as f64,
            self.elevation_deg.1 as f64,
        );
        dirs.into_iter()
            .map(|d| {
                let origin = self.target + self.radius * d;
                let camera = Camera::look_at(
                    origin,
                    self.target,
                    rig_up(-d),
                    self.fov_x_deg,
                    self.width,
                    self.height,
                );
                let position = match self.light {
                    RigLight::Fixed { position } => position,
                    RigLight::Attached { offset } => origin + camera.rotation * offset,
                };
                ViewDesc {
                    camera,
                    light: PointLight {
                        position,
                        intensity: self.intensity,
                    },
                }
            })
            .collect()
    }
}

/// N views at distance `radius` from the origin looking at it (Fibonacci directions), with a
/// light fixed in the world or attached to each camera. See [`Rig`] for more control.
pub fn build_views(
    n: usize,
    radius: f32,
    fov_x_deg: f32,
    width: u32,
    height: u32,
    light: RigLight,
    intensity: [f32; 3],
) -> Vec<ViewDesc> {
    Rig {
        views: n,
        radius,
        target: Vec3::ZERO,
        fov_x_deg,
        width,
        height,
        light,
        intensity,
        elevation_deg: (-90.0, 90.0),
    }
    .build()
}

/// Radiant intensity must be finite and ≥ 0 per channel. `location` is "file: field".
pub(crate) fn check_intensity(i: &[f32; 3], location: &str) -> Result<(), SceneError> {
    for (c, v) in i.iter().enumerate() {
        if !(v.is_finite() && *v >= 0.0) {
            return Err(SceneError::Invalid {
                location: format!("{location}[{c}] = {v}"),
                reason:
                    "radiant intensity must be ≥ 0 and finite (W/sr per channel; irradiance I/r² \
                         facing the light); fix: use e.g. 1"
                        .into(),
            });
        }
    }
    Ok(())
}

/// The house rig: `views` cameras at radius 2 around the origin (fov 35°, `res`²), intensity 12 on
/// every channel, with the given light placement and elevation range (degrees).
pub fn house_rig(views: usize, res: u32, light: RigLight, elevation_deg: (f32, f32)) -> Rig {
    Rig {
        views,
        radius: 2.0,
        target: Vec3::ZERO,
        fov_x_deg: 35.0,
        width: res,
        height: res,
        light,
        intensity: [12.0; 3],
        elevation_deg,
    }
}

/// The paper's kind of data (docs/model.md §8.3): views all around, ONE fixed point light.
pub fn paper_rig(views: usize, res: u32) -> Rig {
    house_rig(
        views,
        res,
        RigLight::Fixed {
            position: Vec3::new(1.2, 1.6, 0.8),
        },
        (-90.0, 90.0),
    )
}

#[cfg(test)]
#[allow(clippy::excessive_precision, clippy::type_complexity)] // numbers copied verbatim from Mitsuba's scene.json
mod tests {
    use super::*;

    #[test]
    fn fibonacci_sphere_is_unit_deterministic_and_balanced() {
        let a = fibonacci_sphere(100);
        assert_eq!(a, fibonacci_sphere(100));
        assert_eq!(a.len(), 100);
        let mut sum = Vec3::ZERO;
        for d in &a {
            assert!((d.length() - 1.0).abs() < 1e-6);
            sum += *d;
        }
        assert!(sum.length() / 100.0 < 0.02, "evenly spread: mean {sum}");
        assert!(fibonacci_sphere(0).is_empty());
        assert_eq!(
            fibonacci_sphere(1),
            vec![Vec3::new(0.3f64.cos() as f32, 0.0, 0.3f64.sin() as f32)]
        );
    }

    #[test]
    fn rig_reproduces_the_mitsuba_reference_cameras() {
        // Origins of views 0, 1 and 7 of reference-renders/mitsuba-sphere-rgb-64/scene.json.
        let views = build_views(
            8,
            0.5,
            40.0,
            64,
            64,
            RigLight::Fixed {
                position: Vec3::new(0.2672612419124244, 0.4008918628686366, 0.1336306209562122),
            },
            [0.785; 3],
        );
        let want = [
            (0, [0.23125014452548345, 0.4375, 0.07153405242919639]),
            (1, [-0.3528644108831139, 0.3125, 0.1668246310714128]),
            (7, [-0.043102033611939004, -0.4375, -0.23819312479270952]),
        ];
        for (i, o) in want {
            let o = Vec3::from_array(o.map(|v: f64| v as f32));
            assert!(
                (views[i].camera.origin - o).length() < 1e-6,
                "view {i}: {} vs {o}",
                views[i].camera.origin
            );
            assert!((views[i].camera.direction() + o.normalize()).length() < 1e-6);
        }
        // View 0's x axis (image left) from its to_world.
        let x0 = Vec3::new(-0.29552020666133955, 0.0, 0.955336489125606);
        assert!((views[0].camera.rotation.x_axis - x0).length() < 1e-6);
        assert!(views.iter().all(|v| v.light.position
            == Vec3::new(0.2672612419124244, 0.4008918628686366, 0.1336306209562122)));
    }

    #[test]
    fn attached_light_follows_the_camera() {
        let rig = Rig {
            views: 5,
            radius: 3.0,
            target: Vec3::new(0.0, 1.0, 0.0),
            fov_x_deg: 30.0,
            width: 16,
            height: 8,
            light: RigLight::Attached {
                offset: Vec3::new(0.0, 0.5, 0.0),
            },
            intensity: [1.0, 2.0, 3.0],
            elevation_deg: (-10.0, 10.0),
        };
        rig.validate("rig").unwrap();
        for v in rig.build() {
            let c = &v.camera;
            assert!(((c.origin - rig.target).length() - 3.0).abs() < 1e-5);
            assert!((v.light.position - (c.origin + 0.5 * c.rotation.y_axis)).length() < 1e-6);
            let elev = (c.origin - rig.target).normalize().y.asin().to_degrees();
            assert!((-10.0..=10.0).contains(&elev));
            assert_eq!(v.light.intensity, [1.0, 2.0, 3.0]);
        }
    }

    #[test]
    fn pole_views_use_z_up() {
        let views = build_views(
            1000,
            2.0,
            40.0,
            8,
            8,
            RigLight::Attached { offset: Vec3::ZERO },
            [1.0; 3],
        );
        assert!(views[0].camera.direction().y < -0.99);
        for v in &views {
            v.camera.validate("pole").unwrap();
            assert_eq!(v.light.position, v.camera.origin);
        }
    }

    #[test]
    fn rig_validation_names_fields() {
        let ok = Rig {
            views: 4,
            radius: 1.0,
            target: Vec3::ZERO,
            fov_x_deg: 40.0,
            width: 8,
            height: 8,
            light: RigLight::Fixed {
                position: Vec3::ONE,
            },
            intensity: [1.0; 3],
            elevation_deg: (-90.0, 90.0),
        };
        ok.validate("r").unwrap();
        let e = |r: Rig| r.validate("r").unwrap_err().to_string();
        assert!(e(Rig { views: 0, ..ok }).contains("r.views"));
        assert!(e(Rig { radius: -1.0, ..ok }).contains("r.radius"));
        assert!(
            e(Rig {
                elevation_deg: (10.0, 0.0),
                ..ok
            })
            .contains("r.elevation")
        );
        assert!(
            e(Rig {
                intensity: [1.0, -1.0, 1.0],
                ..ok
            })
            .contains("r.intensity[1]")
        );
        assert!(
            e(Rig {
                light: RigLight::Fixed {
                    position: Vec3::NAN
                },
                ..ok
            })
            .contains("r.light_position")
        );
    }
}
