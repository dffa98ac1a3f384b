//! The settings' defaults, their resolution and the combinations they refuse.
use super::*;
use inverse::params::OneOrRgb;

fn no_depth() -> Result<DatasetFacts, RecoveryError> {
    Ok(DatasetFacts::default())
}

fn depth(d: u32) -> impl FnOnce() -> Result<DatasetFacts, RecoveryError> {
    move || Ok(DatasetFacts::at_depth(d))
}

/// The defaults resolve to the loop's own defaults: nothing is decided twice.
#[test]
fn the_defaults_are_the_loops_defaults() {
    let s = RecoverySettings::default();
    assert_eq!(
        s.optimize_config(no_depth).unwrap(),
        OptimizeConfig::default()
    );
    let cfg = s
        .resolve(PathBuf::from("d"), PathBuf::from("o"), depth(16))
        .unwrap();
    assert_eq!(cfg.optimize.volpath_max_depth, Some(16));
    assert!(cfg.model_file.is_none() && cfg.bias_correction.enabled && cfg.starts == 1);
}

/// The refinement's length follows the model and the correction; wrong combinations are
/// refused naming both settings.
#[test]
fn the_refinement_follows_the_model_and_the_correction() {
    let mut s = RecoverySettings::default();
    s.model.kind = ModelKind::Dipole;
    let c = s.optimize_config(no_depth).unwrap();
    assert_eq!((c.refine_iterations, c.volpath_max_depth), (0, None));
    s.model.kind = ModelKind::Volpath;
    let c = s.optimize_config(depth(7)).unwrap();
    assert_eq!((c.refine_iterations, c.volpath_max_depth), (0, Some(7)));

    let mut s = RecoverySettings::default();
    s.bias_correction.instead_of_refinement = true;
    assert_eq!(s.optimize_config(no_depth).unwrap().refine_iterations, 0);
    s.tracer.refine = Some(5);
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(
        e.contains("bias_correction") && e.contains("refine 5"),
        "{e}"
    );
    s.bias_correction.instead_of_refinement = false;
    s.tracer.refine = Some(0);
    s.tracer.refine_spp = Some(8);
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("refine_spp 8 without a refinement"), "{e}");
}

/// A model file for a model without networks, an unknown estimator and a view-weight floor
/// outside (0, 1] are refused, naming the setting.
#[test]
fn invalid_settings_are_refused_by_name() {
    let mut s = RecoverySettings::default();
    s.model.kind = ModelKind::Dipole;
    s.model.file = Some(PathBuf::from("m.safetensors"));
    let e = s.resolve_for(PathBuf::from("d"), PathBuf::from("o"));
    let e = e.unwrap_err().to_string();
    assert!(
        e.contains("model_file m.safetensors with model dipole"),
        "{e}"
    );
    s.model.kind = ModelKind::Learned;
    s.model.file = Some(PathBuf::from("shipped"));
    assert_eq!(s.model_file().unwrap(), None);

    let mut s = RecoverySettings::default();
    s.model.estimator = Some("ad".into());
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.starts_with("estimator: "), "{e}");
    let mut s = RecoverySettings::default();
    s.schedule.view_weight_floor = 0.0;
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("view_weight_floor must be in (0, 1]"), "{e}");
}

/// A free g runs where the tracer renders its last iterations (the refinement, or the
/// tracer as the model) and is refused elsewhere with the fix; a starting g needs it.
#[test]
fn a_free_g_needs_the_tracer_at_the_end() {
    let mut s = RecoverySettings::default();
    s.schedule.params.free_g = true;
    let c = s.optimize_config(no_depth).unwrap();
    assert!(c.params.free_g && c.refine_iterations > 0);
    s.model.kind = ModelKind::Volpath;
    assert!(s.optimize_config(no_depth).is_ok());
    s.model.estimator = Some("fd".into());
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(
        e.contains("free_g with model volpath") && e.contains("estimator ad"),
        "{e}"
    );
    s.model = ModelSettings::default();
    s.tracer.refine = Some(0);
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(
        e.contains("free_g with model learned") && e.contains("refine"),
        "{e}"
    );
    s.model.kind = ModelKind::Dipole;
    s.tracer.refine = None;
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("the dipole does not differentiate g"), "{e}");

    let mut s = RecoverySettings::default();
    s.start.init.g = Some(OneOrRgb::One(0.5));
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("init_g 0.5 without free_g"), "{e}");
    s.schedule.params.free_g = true;
    assert_eq!(
        s.optimize_config(no_depth).unwrap().init.g,
        Some(OneOrRgb::One(0.5))
    );
    s.start.init.g = Some(OneOrRgb::One(1.5));
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("must be in (-1, 1)"), "{e}");
    // A g per channel starts from three values; one g from one.
    s.start.init.g = Some(OneOrRgb::Rgb([0.5, 0.6, 0.7]));
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(
        e.contains("init_g [0.5, 0.6, 0.7] gives a g per channel") && e.contains("free_g_rgb"),
        "{e}"
    );
    s.schedule.params.g_per_channel = true;
    assert_eq!(
        s.optimize_config(no_depth).unwrap().init.g,
        Some(OneOrRgb::Rgb([0.5, 0.6, 0.7]))
    );
    s.start.init.g = Some(OneOrRgb::Rgb([0.5, -1.0, 0.7]));
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("must be in (-1, 1)"), "{e}");
}

/// A free light scale runs with every model; it is refused where the learned model's
/// bias correction would simulate the lights as stated, and a starting scale needs it.
#[test]
fn a_free_light_scale_is_refused_where_it_cannot_run() {
    let mut s = RecoverySettings::default();
    s.schedule.params.free_light_scale = true;
    assert!(s.optimize_config(no_depth).unwrap().params.free_light_scale);
    s.model.kind = ModelKind::Dipole;
    assert!(s.optimize_config(no_depth).is_ok());
    s.model.kind = ModelKind::Learned;
    s.tracer.refine = Some(0);
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(
        e.contains("free_light_scale with the bias correction"),
        "{e}"
    );
    s.bias_correction.correction.enabled = false;
    assert!(s.optimize_config(no_depth).is_ok());
    s.schedule.single_render = true;
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("single-render gradient"), "{e}");

    let mut s = RecoverySettings::default();
    s.start.init.light_scale = Some(OneOrRgb::One(2.0));
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(
        e.contains("init_light_scale 2 without free_light_scale"),
        "{e}"
    );
    s.schedule.params.free_light_scale = true;
    assert_eq!(
        s.optimize_config(no_depth).unwrap().init.light_scale,
        Some(OneOrRgb::One(2.0))
    );
    s.start.init.light_scale = Some(OneOrRgb::Rgb([1.0, -1.0, 1.0]));
    let e = s.optimize_config(no_depth).unwrap_err().to_string();
    assert!(e.contains("must be positive"), "{e}");
}

/// σ_t's start follows the dataset's stated unit unless it was given; the dataset is not read
/// when nothing needs it.
#[test]
fn the_start_follows_the_stated_unit_unless_given() {
    use scene::measured::LengthUnit;
    let mut s = RecoverySettings::default();
    let of_unit = |length_unit| {
        move || {
            Ok(DatasetFacts {
                depth: Some(16),
                length_unit,
                g: 0.0,
            })
        }
    };
    assert_eq!(
        s.optimize_config(of_unit(None)).unwrap().init.sigma_t,
        [50.0; 3]
    );
    let mm = s.optimize_config(of_unit(Some(LengthUnit::Mm))).unwrap();
    assert!((mm.init.sigma_t[0] - 1.5009).abs() < 1e-3, "{:?}", mm.init);
    s.start.sigma_t_from_units = false;
    let given = s.optimize_config(of_unit(Some(LengthUnit::Mm))).unwrap();
    assert_eq!(given.init.sigma_t, [50.0; 3]);
    s.model.kind = ModelKind::Dipole;
    let unread = || -> Result<DatasetFacts, RecoveryError> { panic!("read") };
    assert_eq!(s.optimize_config(unread).unwrap().init.sigma_t, [50.0; 3]);
}
