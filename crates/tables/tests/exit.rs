//! The light-side exit law (`tables::exit`): the shipped table against its generator, its
//! normalisation, and the α-interpolation with its derivative.

use tables::exit::{ExitTable, ExitTableSettings, MU_BINS, ONE_MINUS_ALBEDO};

fn lambert_mass(j: usize) -> f64 {
    let (lo, hi) = (j as f64 / MU_BINS as f64, (j + 1) as f64 / MU_BINS as f64);
    hi * hi - lo * lo
}

/// Escaped walks of row `r` and their exit-bin counts, recovered from the table.
fn counts(t: &ExitTable, r: usize) -> (f64, Vec<f64>) {
    let n = t.escaped[r] as f64 * t.settings.walks as f64;
    let c = (0..MU_BINS)
        .map(|j| t.f[r * MU_BINS + j] as f64 * lambert_mass(j) * n)
        .collect();
    (n, c)
}

#[test]
fn every_row_is_a_distribution_over_exit_directions() {
    for t in [
        ExitTable::index_matched_isotropic(),
        ExitTable::for_medium(0.4, 1.3, 0.0),
    ] {
        assert_eq!(t.f.len(), ONE_MINUS_ALBEDO.len() * MU_BINS * MU_BINS);
        for r in 0..ONE_MINUS_ALBEDO.len() * MU_BINS {
            let total: f64 = (0..MU_BINS)
                .map(|j| t.f[r * MU_BINS + j] as f64 * lambert_mass(j))
                .sum();
            assert!((total - 1.0).abs() < 1e-4, "row {r}: Σ f·P_cos = {total}");
            assert!(t.escaped[r] > 0.0 && t.escaped[r] < 1.0);
        }
    }
}

/// The shipped table is what `ExitTable::generate` makes with its recorded settings: a fresh
/// table from independent walks agrees bin by bin within 5 standard errors of the difference of
/// two multinomial frequencies, and the escaped fractions within 5 binomial standard errors.
#[test]
fn the_shipped_table_is_the_generators_output() {
    let shipped = ExitTable::index_matched_isotropic();
    assert_eq!((shipped.settings.g, shipped.settings.eta), (0.0, 1.0));
    assert!(shipped.settings.walks >= 1_000_000);
    let fresh = ExitTable::generate(ExitTableSettings {
        walks: 20_000,
        seed: 99,
        ..shipped.settings
    });
    let mut worst: f64 = 0.0;
    for r in 0..ONE_MINUS_ALBEDO.len() * MU_BINS {
        let (n1, c1) = counts(&shipped, r);
        let (n2, c2) = counts(&fresh, r);
        for j in 0..MU_BINS {
            let (p1, p2) = (c1[j] / n1, c2[j] / n2);
            let p = (c1[j] + c2[j]) / (n1 + n2);
            let se = (p * (1.0 - p) * (1.0 / n1 + 1.0 / n2)).sqrt();
            let z = (p1 - p2).abs() / se.max(1e-12);
            worst = worst.max(z);
            assert!(z < 5.0, "row {r}, bin {j}: {p1} vs {p2} (z = {z:.2})");
        }
        let (e1, e2) = (shipped.escaped[r] as f64, fresh.escaped[r] as f64);
        let se = (e1 * (1.0 - e1) / fresh.settings.walks as f64).sqrt();
        assert!((e1 - e2).abs() < 5.0 * se, "row {r}: escaped {e1} vs {e2}");
    }
    eprintln!("largest |z| over {} bins: {worst:.2}", 256 * MU_BINS);
}

/// At a grid albedo the slice is the table's row; between grid albedos ∂f/∂α is the slope of
/// the interpolation (checked by a central difference), and the law departs from the cosine
/// law in the way the walks say: grazing-in, grazing-out far above 1, normal-in, normal-out below.
/// The same holds for the escaped share over the entry cosine.
#[test]
fn slices_interpolate_with_their_derivative() {
    let t = ExitTable::index_matched_isotropic();
    let n = MU_BINS * MU_BINS;
    let a = 6;
    let s = t.slice(1.0 - ONE_MINUS_ALBEDO[a]);
    for (i, j) in [(0, 0), (3, 9), (15, 15)] {
        let mu = |k: usize| (k as f32 + 0.5) / MU_BINS as f32;
        let (f, _) = s.eval(mu(i), mu(j));
        let want = t.f[a * n + i * MU_BINS + j];
        assert!((f - want).abs() <= 1e-5 * want, "({i}, {j}): {f} vs {want}");
    }
    let alpha = 0.85f32;
    let h = 1e-3f32;
    for (mc, ml) in [(0.1f32, 0.1f32), (0.5, 0.8), (0.97, 0.2), (0.99, 0.99)] {
        let (_, d) = t.slice(alpha).eval(mc, ml);
        let fd =
            (t.slice(alpha + h).eval(mc, ml).0 - t.slice(alpha - h).eval(mc, ml).0) / (2.0 * h);
        assert!(
            (d - fd).abs() <= 1e-2 * fd.abs().max(1e-3),
            "({mc}, {ml}): {d} vs {fd}"
        );
    }
    let s = t.slice(alpha);
    assert!(s.eval(0.03, 0.03).0 > 3.0);
    assert!(s.eval(1.0, 1.0).0 < 0.97);
    // The escaped share: the row's value at a grid albedo and bin centre, its α-derivative
    // the interpolation's slope.
    let e = t.escape(1.0 - ONE_MINUS_ALBEDO[a]);
    let want = t.escaped[a * MU_BINS + 4];
    assert!((e.eval(4.5 / MU_BINS as f32).0 - want).abs() <= 1e-6 * want);
    for mc in [0.1f32, 0.5, 0.97] {
        let (_, d) = t.escape(alpha).eval(mc);
        let fd = (t.escape(alpha + h).eval(mc).0 - t.escape(alpha - h).eval(mc).0) / (2.0 * h);
        assert!(d > 0.0 && (d - fd).abs() <= 1e-2 * fd, "{mc}: {d} vs {fd}");
    }
}

/// The tables are read through `TableFile::from_json`, which checks them against this build's
/// grid: the shipped files pass, and a table of the wrong size, with a NaN or with an impossible
/// medium is an error naming the file and the field (before, a wrong length surfaced as an
/// out-of-bounds lookup during rendering).
#[test]
fn table_files_are_checked_against_the_grid() {
    use tables::curvature::CurvatureTable;
    use tables::exit::TableFile;
    use tables::incidence::IncidenceTable;
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data");
    let read = |name: &str| std::fs::read_to_string(data.join(name)).unwrap();
    let exit = read("exit-g0-eta1.json");
    ExitTable::from_json(&exit, "exit-g0-eta1.json").unwrap();
    IncidenceTable::from_json(&read("incidence-g0-eta1.json"), "incidence.json").unwrap();
    CurvatureTable::from_json(&read("curvature-g0-eta1.json"), "curvature.json").unwrap();

    let mut v: serde_json::Value = serde_json::from_str(&exit).unwrap();
    let refused = |v: &serde_json::Value, field: &str| {
        let e = ExitTable::from_json(&v.to_string(), "damaged.json")
            .expect_err("a damaged table must be refused")
            .to_string();
        assert!(e.contains("damaged.json") && e.contains(field), "{e}");
    };
    v["f"].as_array_mut().unwrap().pop();
    refused(&v, "`f`");
    let mut v: serde_json::Value = serde_json::from_str(&exit).unwrap();
    v["escaped"][3] = serde_json::json!(1.5);
    refused(&v, "`escaped[3]`");
    let mut v: serde_json::Value = serde_json::from_str(&exit).unwrap();
    v["settings"]["eta"] = serde_json::json!(-1.0);
    refused(&v, "`settings.eta`");
    let e = ExitTable::from_json("{\"settings\": 1}", "junk.json")
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("junk.json") && e.contains("exit table"), "{e}");
}
