//! The estimate in real units, where the dataset states what its length unit is: σ_t and its
//! 95 % intervals in mm⁻¹, the reduced coefficients σ_s' = σ_t α (1 − g) and σ_a = σ_t (1 − α)
//! in mm⁻¹ (what published measurements tabulate), and the nearest measured media
//! ([`scene::measured::nearest`]).

use serde_json::json;

use inverse::params::Params;
use inverse::uncertainty::Uncertainty;
use scene::measured::{LengthUnit, nearest, reduced_per_mm};

/// How many measured media the report names.
const NEAREST: usize = 3;

/// The lines printed and the `real_units` block of result.json, for the estimate `est` (with the
/// object's `g` where the run does not recover it) in datasets of length unit `unit`.
pub fn real_units(
    est: &Params,
    u: Option<&Uncertainty>,
    g: scene::Anisotropy,
    unit: LengthUnit,
) -> (Vec<String>, serde_json::Value) {
    let g = est.g_or(g);
    let per_mm = est.sigma_t.map(|s| s / unit.mm());
    let (s, a) = reduced_per_mm(est.sigma_t, est.albedo, g.channels().map(f64::from), unit);
    let near = nearest(s, a, NEAREST);
    let fmt3 = |v: [f64; 3]| format!("({:.4}, {:.4}, {:.4})", v[0], v[1], v[2]);
    let intervals: Vec<Option<[f64; 2]>> = (0..3)
        .map(|c| {
            u.and_then(|u| u.sigma_t[c])
                .map(|[lo, hi]| [lo, hi].map(|x| x / unit.mm()))
        })
        .collect();
    let mut sigma_t = fmt3(per_mm);
    if intervals.iter().all(Option::is_some) {
        let iv: Vec<String> = intervals
            .iter()
            .flatten()
            .map(|[lo, hi]| format!("[{lo:.4}, {hi:.4}]"))
            .collect();
        sigma_t = format!("{sigma_t}, 95 %: {}", iv.join(", "));
    }
    let lines = vec![
        format!(
            "in real units (lengths in {}): σ_t = {sigma_t} mm⁻¹; reduced scattering σ_s' = {} \
             mm⁻¹, absorption σ_a = {} mm⁻¹ (g = {g})",
            unit.name(),
            fmt3(s),
            fmt3(a)
        ),
        format!(
            "nearest measured media (σ_s' and σ_a within a typical factor): {}",
            near.iter()
                .map(|(m, d)| format!("{} ({}, {:.2}×)", m.name, m.source.citation, d.exp()))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    ];
    let json = json!({
        "length_unit": unit.name(),
        "sigma_t_per_mm": per_mm,
        "sigma_t_per_mm_95": intervals,
        "reduced_scattering_per_mm": s,
        "absorption_per_mm": a,
        "g": g,
        "nearest_measured": near.iter().map(|(m, d)| json!({
            "name": m.name,
            "source": m.source.citation,
            "convention": m.source.convention,
            "reduced_scattering_per_mm": m.reduced_scattering,
            "absorption_per_mm": m.absorption,
            "typical_factor": d.exp(),
        })).collect::<Vec<_>>(),
    });
    (lines, json)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::measured::MeasuredMedium;

    /// Marble rendered in cm at g = 0.3 reads back as marble, in mm⁻¹.
    #[test]
    fn a_marble_estimate_in_centimetres_names_marble() {
        let (t, a) = MeasuredMedium::find("marble")
            .unwrap()
            .medium(0.3, LengthUnit::Cm);
        let est = Params {
            sigma_t: t.map(f64::from),
            albedo: a.map(f64::from),
            g: None,
            light_scale: None,
        };
        let (lines, json) = real_units(&est, None, scene::Anisotropy::uniform(0.3), LengthUnit::Cm);
        assert!(
            lines[0].contains("lengths in cm") && lines[0].contains("(2.1900, 2.6200, 3.0000)"),
            "{}",
            lines[0]
        );
        assert!(
            lines[1].contains("marble (Jensen et al. 2001, 1.00×)"),
            "{}",
            lines[1]
        );
        let per_mm = json["sigma_t_per_mm"][0].as_f64().unwrap();
        assert!((per_mm - (2.19 / 0.7 + 0.0021)).abs() < 1e-4, "{per_mm}");
        assert_eq!(json["nearest_measured"][0]["name"], "marble");
    }
}
