//! The volumetric path tracer's curvature along a σ_t valley ([`inverse::sensitivity`]) on a
//! small sphere: the estimate from two renders with derivatives is unbiased, so a cheap and an
//! expensive measurement agree within their standard errors (Σ J² alone would not: its noise
//! bias falls as 1/spp); α at its bound measures along σ_t alone.

use crate::common;

use geometry::{Accel, Vec3};
use inverse::consistency::CheckView;
use inverse::sensitivity::{Sensitivity, measure};
use scene::{Camera, Image, Medium, PointLight};

struct Setup {
    accel: Accel,
    camera: Camera,
    side: PointLight,
    blank: Image,
}

fn setup() -> Setup {
    let accel = common::sphere(0.5);
    let eye = Vec3::new(0.0, 0.0, 2.0);
    Setup {
        accel,
        camera: Camera::look_at(eye, Vec3::ZERO, Vec3::Y, 20.0, 20, 20),
        side: PointLight {
            position: Vec3::new(2.0, 0.0, 0.0),
            intensity: [10.0; 3],
        },
        blank: Image::new(20, 20),
    }
}

fn medium(albedo: f32) -> Medium {
    Medium {
        sigma_t: [30.0; 3],
        albedo: [albedo; 3],
        g: scene::Anisotropy::uniform(0.0),
        eta: 1.0,
        roughness: 0.0,
    }
}

fn run(s: &Setup, light: &PointLight, m: &Medium, slope: f64, spp: u32, seed: u64) -> Sensitivity {
    let views = [CheckView {
        camera: &s.camera,
        light,
        target: &s.blank,
        index: 0,
    }];
    // A learned curvature of 1 per view: ratio = 1 / (the tracer's lower end).
    let bread = [[[1.0, 0.0, 0.0]; 3]];
    measure(&s.accel, m, &views, &bread, [slope; 3], spp, 32, seed).unwrap()
}

#[test]
fn cheap_and_expensive_measurements_agree() {
    let s = setup();
    let m = medium(0.9);
    let cheap = run(&s, &s.side, &m, 0.0, 16, 1);
    let dear = run(&s, &s.side, &m, 0.0, 256, 11);
    for c in 0..3 {
        let tol = 3.0 * (cheap.volpath_se[c].powi(2) + dear.volpath_se[c].powi(2)).sqrt();
        assert!(
            (cheap.volpath[c] - dear.volpath[c]).abs() <= tol,
            "channel {c}: {} (16 spp) against {} (256 spp), tolerance {tol}",
            cheap.volpath[c],
            dear.volpath[c]
        );
        assert!(
            dear.volpath[c] > 4.0 * dear.volpath_se[c],
            "side light: curvature detected"
        );
        assert_eq!(cheap.learned[c], 1.0);
    }
}

#[test]
fn albedo_at_its_bound_measures_along_sigma_t_alone() {
    let s = setup();
    let m = medium(0.9995);
    let r = run(&s, &s.side, &m, -0.05, 16, 5);
    assert_eq!(r.slope, [0.0; 3]);
    for c in 0..3 {
        assert!(r.volpath[c].is_finite() && r.ratio[c].is_finite());
    }
    // Inside the margin the valley's direction is kept.
    let m = medium(0.996);
    let r = run(&s, &s.side, &m, -0.05, 16, 5);
    assert_eq!(r.slope, [-0.05; 3]);
}
