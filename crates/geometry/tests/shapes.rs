//! Procedural shapes: watertight, outward, centred, smooth, and close to their analytic area and
//! volume.

use std::f64::consts::PI;

use geometry::mesh::validate;
use geometry::{GeometryError, Mesh, Shape};

/// Everything every built shape must satisfy.
fn check_shape(shape: &Shape) -> Mesh {
    check_shape_with(shape, 0.5, true)
}

/// As [`check_shape`]; every corner normal must satisfy `n_v · n_face > min_dot` (coarse
/// tessellations legitimately have larger angles between vertex and face normals, and a cone
/// with 3 segments is not symmetric about the axis).
fn check_shape_with(shape: &Shape, min_dot: f32, centred: bool) -> Mesh {
    let mesh = shape
        .build()
        .unwrap_or_else(|e| panic!("{shape:?} failed: {e}"));
    // validate() again on a copy: no warnings, nothing changed.
    let mut copy = mesh.clone();
    let warnings = validate(&mut copy, shape.name()).expect("valid");
    assert!(warnings.is_empty(), "{shape:?}: warnings {warnings:?}");
    assert_eq!(copy.indices, mesh.indices);

    let edges = mesh.edge_report();
    assert!(edges.is_watertight(), "{shape:?}: {edges:?}");
    // Closed genus-g surface: V − E + F = 2 − 2g.
    let euler = mesh.positions.len() as i64 - edges.edges as i64 + mesh.triangle_count() as i64;
    let expected_euler = if matches!(shape, Shape::Torus { .. }) {
        0
    } else {
        2
    };
    assert_eq!(euler, expected_euler, "{shape:?}: Euler characteristic");
    // Every vertex is used.
    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.indices {
        for &i in t {
            used[i as usize] = true;
        }
    }
    assert!(used.iter().all(|&u| u), "{shape:?}: unreferenced vertices");

    assert!(
        mesh.signed_volume() > 0.0,
        "{shape:?}: volume {}",
        mesh.signed_volume()
    );
    let (lo, hi) = mesh.bounds();
    let extent = hi - lo;
    assert!(
        !centred || (lo + hi).abs().max_element() < 1e-3 * extent.max_element(),
        "{shape:?}: not centred: {lo} {hi}"
    );

    // Smooth unit normals that agree with the faces around them.
    let normals = mesh.normals.as_ref().expect("normals");
    assert_eq!(normals.len(), mesh.positions.len());
    for n in normals {
        assert!((n.length() - 1.0).abs() < 1e-5, "{shape:?}: normal {n}");
    }
    for (i, t) in mesh.indices.iter().enumerate() {
        let f = mesh.face_normal_raw(i).normalize();
        for &v in t {
            let d = normals[v as usize].dot(f);
            assert!(
                d > min_dot,
                "{shape:?}: triangle {i}, vertex {v}: n·n_f = {d}"
            );
        }
    }
    mesh
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn every_named_shape_is_watertight_outward_and_about_one_unit() {
    for name in Shape::NAMES {
        let shape = Shape::from_name(name).unwrap();
        assert_eq!(shape.name(), name);
        let mesh = check_shape(&shape);
        let (lo, hi) = mesh.bounds();
        let size = (hi - lo).max_element();
        assert!((0.6..=1.2).contains(&size), "{name}: size {size}");
    }
}

#[test]
fn aliases_and_unknown_names() {
    assert_eq!(Shape::from_name("box").unwrap().name(), "rounded-box");
    assert_eq!(
        Shape::from_name("Rounded_Box").unwrap().name(),
        "rounded-box"
    );
    assert_eq!(Shape::from_name("bumpy-blob").unwrap().name(), "blob");
    assert_eq!(Shape::from_name(" SPHERE ").unwrap().name(), "sphere");
    let err = Shape::from_name("teapot").unwrap_err();
    match &err {
        GeometryError::ShapeParam {
            shape,
            param,
            reason,
        } => {
            assert_eq!(shape, "teapot");
            assert_eq!(param, "name");
            for n in Shape::NAMES {
                assert!(reason.contains(n), "{reason}");
            }
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().contains("teapot"));
}

#[test]
fn sphere_area_and_volume_match_analytic() {
    let r = 0.5f64;
    let mesh = check_shape(&Shape::Sphere {
        radius: r as f32,
        subdivisions: 5,
    });
    assert_eq!(mesh.triangle_count(), 20 * 4usize.pow(5));
    assert_eq!(mesh.positions.len(), 10 * 4usize.pow(5) + 2);
    // Inscribed polyhedron: slightly smaller, error O(h²) ≈ 0.1 % here.
    let a = mesh.area();
    let v = mesh.signed_volume();
    assert!(
        a < 4.0 * PI * r * r && rel(a, 4.0 * PI * r * r) < 3e-3,
        "area {a}"
    );
    assert!(
        v < 4.0 / 3.0 * PI * r.powi(3) && rel(v, 4.0 / 3.0 * PI * r.powi(3)) < 3e-3,
        "volume {v}"
    );
    for p in &mesh.positions {
        assert!((f64::from(p.length()) - r).abs() < 1e-6);
    }
}

#[test]
fn torus_area_and_volume_match_analytic() {
    let (big_r, r) = (0.35f64, 0.15f64);
    let mesh = check_shape(&Shape::Torus {
        major: big_r as f32,
        minor: r as f32,
        segments: 128,
    });
    let a = mesh.area();
    let v = mesh.signed_volume();
    let a_exact = 4.0 * PI * PI * big_r * r;
    let v_exact = 2.0 * PI * PI * big_r * r * r;
    assert!(rel(a, a_exact) < 3e-3, "area {a} vs {a_exact}");
    assert!(rel(v, v_exact) < 3e-3, "volume {v} vs {v_exact}");
}

#[test]
fn rounded_box_area_and_volume_match_analytic() {
    let size = [0.8f64, 0.6, 0.7];
    let r = 0.1f64;
    let mesh = check_shape(&Shape::RoundedBox {
        size: size.map(|s| s as f32),
        radius: r as f32,
        segments: 64,
    });
    let [a, b, c] = size.map(|s| s - 2.0 * r);
    // Minkowski sum of a box and a ball (Steiner formula).
    let a_exact = 2.0 * (a * b + b * c + c * a) + 2.0 * PI * r * (a + b + c) + 4.0 * PI * r * r;
    let v_exact = a * b * c
        + 2.0 * r * (a * b + b * c + c * a)
        + PI * r * r * (a + b + c)
        + 4.0 / 3.0 * PI * r.powi(3);
    assert!(
        rel(mesh.area(), a_exact) < 2e-3,
        "area {} vs {a_exact}",
        mesh.area()
    );
    assert!(
        rel(mesh.signed_volume(), v_exact) < 2e-3,
        "volume {} vs {v_exact}",
        mesh.signed_volume()
    );
    let (lo, hi) = mesh.bounds();
    for k in 0..3 {
        assert!((f64::from(hi[k] - lo[k]) - size[k]).abs() < 1e-6);
    }
}

#[test]
fn rounded_box_with_maximal_radius_is_still_closed() {
    // radius = half the smallest extent: the inner box is flat along y.
    check_shape(&Shape::RoundedBox {
        size: [1.0, 0.4, 0.6],
        radius: 0.2,
        segments: 16,
    });
    // Every extent = 2·radius: a sphere.
    let mesh = check_shape(&Shape::RoundedBox {
        size: [1.0, 1.0, 1.0],
        radius: 0.5,
        segments: 48,
    });
    assert!(rel(mesh.signed_volume(), 4.0 / 3.0 * PI * 0.125) < 1e-2);
}

#[test]
fn cone_is_a_rounded_cone_with_the_requested_extents() {
    let (h, rho, r) = (1.0f32, 0.4f32, 0.08f32);
    let cone = |segments| Shape::Cone {
        height: h,
        radius: rho,
        tip_radius: r,
        segments,
    };
    let mesh = check_shape(&cone(128));
    let (lo, hi) = mesh.bounds();
    // The bounding box is exactly 2·radius × height × 2·radius.
    assert!((hi.y - lo.y - h).abs() < 1e-6, "height {}", hi.y - lo.y);
    assert!(
        (hi.x - rho).abs() < 1e-6 && (lo.x + rho).abs() < 1e-6,
        "{lo} {hi}"
    );
    assert!(
        (hi.z - rho).abs() < 1e-6 && (lo.z + rho).abs() < 1e-6,
        "{lo} {hi}"
    );
    // Discretisation converges: 128 segments are within 0.2 % of 512 in area and volume.
    let fine = cone(512).build().unwrap();
    assert!(rel(mesh.signed_volume(), fine.signed_volume()) < 2e-3);
    assert!(rel(mesh.area(), fine.area()) < 2e-3);
    // Smaller than the enclosing cylinder, larger than the inscribed sharp cone with the same
    // extents minus its rounded parts (loose sanity bounds).
    let v = mesh.signed_volume();
    let (h, rho) = (f64::from(h), f64::from(rho));
    assert!(
        v < PI * rho * rho * h && v > PI * rho * rho * h / 3.0 * 0.9,
        "volume {v}"
    );
    // The poles have axis normals.
    let normals = mesh.normals.as_ref().unwrap();
    let top = (0..mesh.positions.len())
        .max_by(|&a, &b| mesh.positions[a].y.total_cmp(&mesh.positions[b].y))
        .unwrap();
    assert!(normals[top].y > 0.999);
    let bottom = (0..mesh.positions.len())
        .min_by(|&a, &b| mesh.positions[a].y.total_cmp(&mesh.positions[b].y))
        .unwrap();
    assert!(normals[bottom].y < -0.999);
    // Smooth: vertex normals along one meridian turn by less than 2π/128 per step plus slack.
    let mut meridian: Vec<usize> = (0..mesh.positions.len())
        .filter(|&i| mesh.positions[i].z == 0.0 && mesh.positions[i].x >= 0.0)
        .collect();
    meridian.sort_by(|&a, &b| {
        let key = |i: usize| {
            let p = mesh.positions[i];
            // Order along the profile: by the angle of the normal from −y.
            let n = normals[i];
            (n.x.atan2(-n.y), p.y)
        };
        key(a).partial_cmp(&key(b)).unwrap()
    });
    for w in meridian.windows(2) {
        let turn = normals[w[0]].dot(normals[w[1]]).clamp(-1.0, 1.0).acos();
        assert!(
            turn < 2.0 * std::f32::consts::TAU / 128.0,
            "normal jumps by {turn} rad"
        );
    }
}

#[test]
fn coarse_and_unusual_parameters_still_give_closed_meshes() {
    for shape in [
        Shape::Sphere {
            radius: 2.0,
            subdivisions: 0,
        },
        Shape::Sphere {
            radius: 0.01,
            subdivisions: 2,
        },
        Shape::Cone {
            height: 0.3,
            radius: 0.5,
            tip_radius: 0.05,
            segments: 3,
        },
        Shape::Cone {
            height: 2.0,
            radius: 0.1,
            tip_radius: 0.03,
            segments: 16,
        },
        Shape::Torus {
            major: 1.0,
            minor: 0.9,
            segments: 3,
        },
        Shape::Torus {
            major: 0.3,
            minor: 0.02,
            segments: 300,
        },
        Shape::RoundedBox {
            size: [0.2, 0.3, 2.0],
            radius: 0.01,
            segments: 3,
        },
        Shape::Blob {
            radius: 0.5,
            amplitude: 0.0,
            bumps: 0,
            seed: 1,
            subdivisions: 2,
        },
        Shape::Blob {
            radius: 0.25,
            amplitude: 0.5,
            bumps: 40,
            seed: 99,
            subdivisions: 4,
        },
    ] {
        check_shape_with(&shape, -1.0, false);
    }
}

#[test]
fn cone_with_maximal_tip_radius_is_rejected_or_closed() {
    // Just below the limit at which tip and rim roundings meet: still valid.
    let mut tip = 0.1f32;
    loop {
        let shape = Shape::Cone {
            height: 1.0,
            radius: 0.4,
            tip_radius: tip,
            segments: 32,
        };
        match shape.build() {
            Ok(_) => {
                check_shape(&shape);
                tip += 0.01;
            }
            Err(GeometryError::ShapeParam { param, reason, .. }) => {
                assert_eq!(param, "tip_radius");
                assert!(
                    reason.contains("overlap") || reason.contains("smaller"),
                    "{reason}"
                );
                break;
            }
            Err(e) => panic!("{e}"),
        }
        assert!(tip < 0.4);
    }
}

#[test]
fn blob_is_deterministic_and_bumpy() {
    let a = Shape::from_name("blob").unwrap().build().unwrap();
    let b = Shape::from_name("blob").unwrap().build().unwrap();
    assert_eq!(a.positions, b.positions);
    let Shape::Blob {
        radius,
        amplitude,
        bumps,
        subdivisions,
        ..
    } = Shape::from_name("blob").unwrap()
    else {
        unreachable!()
    };
    let c = Shape::Blob {
        radius,
        amplitude,
        bumps,
        seed: 8,
        subdivisions,
    }
    .build()
    .unwrap();
    assert_ne!(a.positions, c.positions);
    // Radii vary by a visible amount but stay positive.
    let radii: Vec<f32> = a.positions.iter().map(|p| p.length()).collect();
    let (min, max) = radii.iter().fold((f32::INFINITY, 0.0f32), |(lo, hi), &r| {
        (lo.min(r), hi.max(r))
    });
    assert!(min > 0.3 && max < 0.7, "{min} {max}");
    assert!(max - min > 0.05, "not bumpy: {min} {max}");
    assert_eq!(a.triangle_count(), 20 * 4usize.pow(6));
}

#[test]
fn scaled_scales_lengths() {
    for name in Shape::NAMES {
        let shape = Shape::from_name(name).unwrap();
        let v1 = shape.build().unwrap().signed_volume();
        let big = shape.scaled(2.0);
        assert_eq!(big.name(), name);
        let v2 = big.build().unwrap().signed_volume();
        assert!(rel(v2, 8.0 * v1) < 1e-4, "{name}: {v2} vs 8·{v1}");
    }
    assert!(
        Shape::from_name("sphere")
            .unwrap()
            .scaled(0.0)
            .build()
            .is_err()
    );
}

/// The coarse shape keeps its name and size, stays watertight and outward, and has at most a
/// quarter of the default's triangles (the smoke tests' meshes); a shape already that coarse
/// (the rounded box's 32 segments) keeps its resolution.
#[test]
fn coarse_keeps_the_shape_at_a_quarter_of_the_triangles() {
    for name in Shape::NAMES {
        let shape = Shape::from_name(name).unwrap();
        let full = shape.build().unwrap();
        assert_eq!(shape.coarse().name(), name);
        let coarse = check_shape_with(&shape.coarse(), 0.3, true);
        assert!(
            4 * coarse.triangle_count() <= full.triangle_count() || shape.coarse() == shape,
            "{name}: {} of {} triangles",
            coarse.triangle_count(),
            full.triangle_count()
        );
        let (v1, v2) = (full.signed_volume(), coarse.signed_volume());
        assert!(rel(v2, v1) < 0.05, "{name}: volume {v2} against {v1}");
    }
    let tiny = Shape::Sphere {
        radius: 0.5,
        subdivisions: 2,
    };
    assert_eq!(tiny.coarse(), tiny);
}

fn expect_param_error(shape: Shape, expected_param: &str) {
    match shape.build() {
        Err(GeometryError::ShapeParam {
            shape: s,
            param,
            reason,
        }) => {
            assert_eq!(param, expected_param, "{s}: {reason}");
            assert!(!reason.is_empty());
        }
        Err(e) => panic!("{shape:?}: wrong error {e}"),
        Ok(_) => panic!("{shape:?} should have been rejected"),
    }
}

#[test]
fn bad_parameters_are_rejected_with_the_parameter_named() {
    expect_param_error(
        Shape::Sphere {
            radius: 0.0,
            subdivisions: 3,
        },
        "radius",
    );
    expect_param_error(
        Shape::Sphere {
            radius: -1.0,
            subdivisions: 3,
        },
        "radius",
    );
    expect_param_error(
        Shape::Sphere {
            radius: f32::NAN,
            subdivisions: 3,
        },
        "radius",
    );
    expect_param_error(
        Shape::Sphere {
            radius: f32::INFINITY,
            subdivisions: 3,
        },
        "radius",
    );
    expect_param_error(
        Shape::Sphere {
            radius: 1.0,
            subdivisions: 9,
        },
        "subdivisions",
    );
    expect_param_error(
        Shape::Cone {
            height: 1.0,
            radius: 0.4,
            tip_radius: 0.4,
            segments: 64,
        },
        "tip_radius",
    );
    expect_param_error(
        Shape::Cone {
            height: 1.0,
            radius: 0.4,
            tip_radius: 0.0,
            segments: 64,
        },
        "tip_radius",
    );
    expect_param_error(
        Shape::Cone {
            height: 0.0,
            radius: 0.4,
            tip_radius: 0.1,
            segments: 64,
        },
        "height",
    );
    expect_param_error(
        Shape::Cone {
            height: 1.0,
            radius: 0.4,
            tip_radius: 0.1,
            segments: 2,
        },
        "segments",
    );
    expect_param_error(
        Shape::Cone {
            height: 0.1,
            radius: 0.4,
            tip_radius: 0.3,
            segments: 64,
        },
        "tip_radius",
    );
    expect_param_error(
        Shape::Torus {
            major: 0.3,
            minor: 0.3,
            segments: 64,
        },
        "minor",
    );
    expect_param_error(
        Shape::Torus {
            major: 0.3,
            minor: 0.5,
            segments: 64,
        },
        "minor",
    );
    expect_param_error(
        Shape::Torus {
            major: -0.3,
            minor: 0.1,
            segments: 64,
        },
        "major",
    );
    expect_param_error(
        Shape::Torus {
            major: 0.3,
            minor: 0.1,
            segments: 0,
        },
        "segments",
    );
    expect_param_error(
        Shape::Torus {
            major: 0.3,
            minor: 0.1,
            segments: 100_000,
        },
        "segments",
    );
    expect_param_error(
        Shape::RoundedBox {
            size: [1.0, 0.0, 1.0],
            radius: 0.1,
            segments: 16,
        },
        "size[1]",
    );
    expect_param_error(
        Shape::RoundedBox {
            size: [1.0, 0.4, 1.0],
            radius: 0.3,
            segments: 16,
        },
        "radius",
    );
    expect_param_error(
        Shape::Blob {
            radius: 0.5,
            amplitude: -0.1,
            bumps: 3,
            seed: 0,
            subdivisions: 3,
        },
        "amplitude",
    );
    expect_param_error(
        Shape::Blob {
            radius: 0.5,
            amplitude: 0.1,
            bumps: 3,
            seed: 0,
            subdivisions: 12,
        },
        "subdivisions",
    );
}
