use super::*;

#[test]
fn encode_decode_round_trip_and_clamps() {
    for parameterisation in [Parameterisation::Scaled, Parameterisation::Log] {
        let spec = ParamSpec {
            parameterisation,
            ..Default::default()
        };
        let p = Params {
            sigma_t: [30.0, 55.5, 100.0],
            albedo: [0.8, 0.9, 0.98],
            g: None,
            light_scale: None,
        };
        let q = spec.decode(&spec.encode(&p));
        for c in 0..3 {
            assert!((q.sigma_t[c] / p.sigma_t[c] - 1.0).abs() < 1e-6);
            assert!((q.albedo[c] - p.albedo[c]).abs() < 1e-6);
        }
        let mut u = vec![-1.0, 0.5, 0.5, -0.2, 1.5, 0.5];
        spec.clamp(&mut u);
        let c = spec.decode(&u);
        assert!(c.albedo[0] >= ALBEDO_MIN && c.albedo[1] <= ALBEDO_MAX);
        assert!(c.sigma_t[0] >= SIGMA_T_MIN * 0.999);
    }
}

#[test]
fn chain_rule_matches_finite_differences_and_options() {
    let p = Params {
        sigma_t: [40.0, 60.0, 80.0],
        albedo: [0.9; 3],
        g: None,
        light_scale: None,
    };
    // ℓ(σ) = Σ σ_c² ⇒ ∂ℓ/∂σ_c = 2σ_c; check ∂ℓ/∂u by FD through decode.
    for parameterisation in [Parameterisation::Scaled, Parameterisation::Log] {
        let spec = ParamSpec {
            parameterisation,
            ..Default::default()
        };
        let g = spec.chain(&p, p.sigma_t.map(|s| 2.0 * s), [0.0; 3], [0.0; 3], [0.0; 3]);
        let u = spec.encode(&p);
        for c in 0..3 {
            let h = 1e-3f32;
            let mut up = u.clone();
            up[c] += h;
            let mut um = u.clone();
            um[c] -= h;
            let l = |v: &[f32]| spec.decode(v).sigma_t.iter().map(|s| s * s).sum::<f64>();
            let fd = (l(&up) - l(&um)) / (2.0 * h as f64);
            assert!((fd / g[c] as f64 - 1.0).abs() < 1e-3, "{fd} vs {}", g[c]);
        }
    }
    let mono = ParamSpec {
        monochrome: true,
        fix_albedo: true,
        ..Default::default()
    };
    let g = mono.chain(&p, [1.0, 2.0, 3.0], [1.0, 1.0, 1.0], [5.0; 3], [6.0; 3]);
    assert_eq!(g, vec![200.0, 200.0, 200.0, 0.0, 0.0, 0.0]);
}

/// A free g is the seventh variable: encoded as itself, clamped to ±G_MAX, its gradient
/// passed through; without it the vector has six and the medium takes the object's g.
#[test]
fn a_free_g_is_the_seventh_variable() {
    let spec = ParamSpec {
        free_g: true,
        ..Default::default()
    };
    let p = Params {
        g: Some(OneOrRgb::One(0.7)),
        ..Params::new([40.0; 3], [0.9; 3])
    };
    let u = spec.encode(&p);
    assert_eq!((u.len(), spec.len()), (7, 7));
    assert!((spec.decode(&u).g.unwrap().channel(1) - 0.7).abs() < 1e-6);
    let mut v = u.clone();
    v[6] = 1.5;
    spec.clamp(&mut v);
    assert!((v[6] as f64 - G_MAX).abs() < 1e-6);
    let g = spec.chain(&p, [0.0; 3], [0.0; 3], [-2.0, -1.0, 0.5], [1.0; 3]);
    assert_eq!(g.len(), 7);
    assert_eq!(g[6], -2.5);
    let base = stated_g_03(1.4, 0.1);
    assert_eq!(p.medium(&base).g, scene::Anisotropy::uniform(0.7));
    assert_eq!(
        Params::new([40.0; 3], [0.9; 3]).medium(&base).g,
        scene::Anisotropy::uniform(0.3)
    );
    let fixed = ParamSpec::default();
    assert_eq!(fixed.encode(&p).len(), 6);
    assert_eq!(fixed.decode(&fixed.encode(&p)).g, None);
}

/// A g per channel is three variables before the light scale: each encoded as itself and
/// clamped, each channel's gradient its own; the medium takes them per channel, and one g
/// from three starts at their mean.
#[test]
fn a_g_per_channel_is_three_variables() {
    let spec = ParamSpec {
        free_g: true,
        g_per_channel: true,
        free_light_scale: true,
        ..Default::default()
    };
    assert_eq!(
        (spec.len(), spec.g_indices(), spec.light_scale_index()),
        (10, 6..9, Some(9))
    );
    let p = Params {
        g: Some(OneOrRgb::Rgb([0.6, 0.7, 0.8])),
        light_scale: Some(OneOrRgb::One(2.0)),
        ..Params::new([40.0; 3], [0.9; 3])
    };
    let mut u = spec.encode(&p);
    assert_eq!(u.len(), 10);
    u[8] = -3.0;
    spec.clamp(&mut u);
    let q = spec.decode(&u);
    let g = q.g.unwrap();
    assert!((g.channel(0) - 0.6).abs() < 1e-6 && (g.channel(1) - 0.7).abs() < 1e-6);
    assert!((g.channel(2) + G_MAX).abs() < 1e-6);
    assert!((q.light_scale_of(1) - 2.0).abs() < 1e-5);
    let d = spec.chain(&p, [0.0; 3], [0.0; 3], [-2.0, -1.0, 0.5], [1.0; 3]);
    assert_eq!(d[6..], [-2.0, -1.0, 0.5, 3.0]);
    let base = stated_g_03(1.0, 0.0);
    assert_eq!(p.medium(&base).g, scene::Anisotropy([0.6, 0.7, 0.8]));
    let one = ParamSpec {
        free_g: true,
        ..Default::default()
    };
    assert!((one.encode(&p)[6] - 0.7).abs() < 1e-6);
    let back: Params = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
    assert_eq!(back, p);
}

/// A free light scale follows g as ln k; the lights scale by it.
#[test]
fn a_free_light_scale_is_the_last_variable() {
    let spec = ParamSpec {
        free_g: true,
        free_light_scale: true,
        ..Default::default()
    };
    assert_eq!(
        (spec.len(), spec.g_index(), spec.light_scale_index()),
        (8, Some(6), Some(7))
    );
    let p = Params {
        g: Some(OneOrRgb::One(0.3)),
        light_scale: Some(OneOrRgb::One(2.5)),
        ..Params::new([40.0; 3], [0.9; 3])
    };
    let u = spec.encode(&p);
    assert!((u[7] as f64 - 2.5f64.ln()).abs() < 1e-6);
    let q = spec.decode(&u);
    let g = q.g.unwrap().channel(0);
    assert!((q.light_scale_of(2) - 2.5).abs() < 1e-5 && (g - 0.3).abs() < 1e-6);
    assert_eq!(
        spec.chain(&p, [0.0; 3], [0.0; 3], [1.0, 0.0, 0.0], [-1.0, -0.5, -1.5])[6..],
        [1.0, -3.0]
    );
    let only_k = ParamSpec {
        free_light_scale: true,
        ..Default::default()
    };
    assert_eq!((only_k.len(), only_k.light_scale_index()), (7, Some(6)));
    let mut v = only_k.encode(&p);
    v[6] = 20.0;
    only_k.clamp(&mut v);
    assert!((only_k.decode(&v).light_scale_of(0) / LIGHT_SCALE_MAX - 1.0).abs() < 1e-5);
    let light = scene::PointLight {
        position: glam::Vec3::ZERO,
        intensity: [1.0, 2.0, 4.0],
    };
    assert_eq!(p.light(&light).intensity, [2.5, 5.0, 10.0]);
    assert_eq!(Params::new([1.0; 3], [0.5; 3]).light(&light), light);
}

/// Per channel, the light scale is the last three variables, each ln k_c with its own
/// channel's gradient; the lights scale channel by channel, and a single starting k starts
/// every channel. In JSON one factor is a number and per-channel ones an array.
#[test]
fn a_per_channel_light_scale_is_three_variables() {
    let spec = ParamSpec {
        free_light_scale: true,
        light_scale_per_channel: true,
        ..Default::default()
    };
    assert_eq!((spec.len(), spec.light_scale_indices()), (9, 6..9));
    let p = Params {
        light_scale: Some(OneOrRgb::Rgb([0.5, 1.0, 2.0])),
        ..Params::new([40.0; 3], [0.9; 3])
    };
    let u = spec.encode(&p);
    assert!((u[6] as f64 - 0.5f64.ln()).abs() < 1e-6 && u[7].abs() < 1e-7);
    let q = spec.decode(&u);
    for c in 0..3 {
        assert!((q.light_scale_of(c) / p.light_scale_of(c) - 1.0).abs() < 1e-6);
    }
    assert_eq!(
        spec.chain(&p, [0.0; 3], [0.0; 3], [9.0, 0.0, 0.0], [1.0, -2.0, 3.0])[6..],
        [1.0, -2.0, 3.0]
    );
    let light = scene::PointLight {
        position: glam::Vec3::ZERO,
        intensity: [1.0, 2.0, 4.0],
    };
    assert_eq!(p.light(&light).intensity, [0.5, 2.0, 8.0]);
    let start = Params {
        light_scale: Some(OneOrRgb::One(2.0)),
        ..p
    };
    let s = spec.decode(&spec.encode(&start));
    assert!((0..3).all(|c| (s.light_scale_of(c) - 2.0).abs() < 1e-5));
    // One factor from per-channel ones: their geometric mean.
    let one = ParamSpec {
        free_light_scale: true,
        ..Default::default()
    };
    assert!((one.decode(&one.encode(&p)).light_scale_of(1) - 1.0).abs() < 1e-6);
    let json = |p: &Params| serde_json::to_value(p).unwrap()["light_scale"].clone();
    assert_eq!(json(&start), serde_json::json!(2.0));
    assert_eq!(json(&p), serde_json::json!([0.5, 1.0, 2.0]));
    let back: Params = serde_json::from_value(serde_json::to_value(p).unwrap()).unwrap();
    assert_eq!(back, p);
}

/// A medium whose object states g 0.3, with boundary `eta` and `roughness`.
fn stated_g_03(eta: f32, roughness: f32) -> Medium {
    let object = scene::Object {
        eta,
        roughness,
        g: scene::Anisotropy::uniform(0.3),
    };
    object.medium([1.0; 3], [0.5; 3])
}
