//! The estimators behind a rough dielectric boundary (η 1.4, GGX α 0.2) stay what they are on an
//! index-matched isotropic object: `ours` is the same-seed FD render for σ_t and agrees with FD
//! on independent random numbers; its ∂I/∂α is the FD through S_abs and the light side with σ_n
//! held fixed; `ours-alpha-offsets` is the full FD sample for sample and agrees with it on
//! independent numbers. The surface's own reflection does not depend on the medium: it cancels
//! in every difference.
//!
//! Two media, both with the default light side (the half-space exit law behind the rough
//! boundary, directional incidence, the curvature correction): an isotropic one, whose walk
//! tables at η 1.4 the planar test of this binary makes as well, and a forward-scattering one
//! (g 0.3, the networks' g), whose exit, incidence and curvature tables are simulated for its g,
//! so that the tables' ∂/∂α enter ∂I/∂α at g > 0 too. A new (g, η) costs its tables' walks,
//! about 100 s on 2 cores, per test process without a kept copy ([`tables::disk`];
//! docs/notes/test-time.md).

use super::*;

#[test]
fn estimators_match_finite_differences_behind_a_rough_boundary() {
    let rough = Medium {
        eta: 1.4,
        roughness: 0.2,
        ..rgb_medium()
    };
    check(&sphere_setup(rough), "rough");
    check(
        &sphere_setup(Medium {
            g: scene::Anisotropy::uniform(0.3),
            ..rough
        }),
        "rough g 0.3",
    );
}

/// The comparisons of the module docs on `s`.
fn check(s: &Setup, label: &str) {
    let scene = s.scene();
    let (spp, r) = (16, 12);
    let ours = replicate(s, &scene, &ds(Estimator::Ours), spp, 0..r);
    let fd_same = replicate(s, &scene, &ds(Estimator::Fd), spp, 0..r);
    assert_same_seed_fd(label, &ours, &fd_same);
    let fd = replicate(s, &scene, &ds(Estimator::Fd), spp, r..2 * r);
    report(&format!("{label} ours dσ_t"), &ours, D_T);
    report(&format!("{label} fd dσ_t"), &fd, D_T);
    for c in 0..3 {
        assert!(
            fd.mean[D_T][c].abs() > 6.0 * fd.se[D_T][c],
            "{label} channel {c}: the derivative sum should be clearly non-zero"
        );
        let zc = z(&ours, &fd, D_T, c);
        eprintln!("{label} channel {c}: ours vs fd dσ_t z = {zc:.2}");
        assert!(zc < 4.0, "{label} channel {c}: z = {zc:.2}");
    }
    // Channel 2's α 0.95 is a knot of the tables' spline in ln(1 − α), which is C¹ there: a
    // central difference across it errs by O(Δα). Measured behind this boundary (difference /
    // Σ|D| in channel 2): −2.0e-3, −2.9e-3, −4.1e-3, −6.6e-3, −1.3e-2 at Δα 5e-5, 1e-4, 2e-4
    // (the default), 4e-4, 1e-3. Hence the smaller step.
    let fine = DiffSettings {
        delta_albedo: 5e-5,
        ..fd_sabs()
    };
    let fd_sabs = replicate(s, &scene, &fine, spp, 0..r);
    // As in `alpha_derivatives` (a): O(Δα²) and ReLU sign changes within ±Δα.
    assert_d_alpha_close(
        &format!("{label}: ours vs S_abs-only FD"),
        &ours,
        &fd_sabs,
        3e-3,
    );
    let offs = replicate(s, &scene, &ds(Estimator::OursAlphaOffsets), spp, 0..r);
    assert_d_alpha_close(
        &format!("{label}: α offsets vs same-seed FD"),
        &offs,
        &fd_same,
        1e-3,
    );
    for c in 0..3 {
        let zc = z(&offs, &fd, D_A, c);
        eprintln!("{label} channel {c}: α offsets vs fd z = {zc:.2}");
        assert!(zc < 4.0, "{label} channel {c}: z = {zc:.2}");
    }
}

/// Σ∂I/∂α of `a` and `b` differ by less than `tol` of Σ|∂I/∂α| of `a` in every channel.
fn assert_d_alpha_close(label: &str, a: &Est, b: &Est, tol: f64) {
    for c in 0..3 {
        let rel = (a.mean[D_A][c] - b.mean[D_A][c]).abs() / a.mean[ABS_D_A][c];
        eprintln!("{label} channel {c}: dα difference / Σ|D| = {rel:.2e}");
        assert!(
            rel < tol,
            "{label} channel {c}: relative difference {rel:.2e}"
        );
    }
}
