//! Real units and published measurements of real media.
//!
//! [`LengthUnit`]: what one scene unit is (mm, cm, m): σ[1/unit] = σ[1/mm] × (mm per unit).
//!
//! [`MEASURED`]: named media from two sources, each with its convention stored beside the numbers
//! ([`Source`]). Both tabulate the **reduced** scattering coefficient σ_s' = σ_s (1 − g) and the
//! absorption σ_a in mm⁻¹ per RGB channel, not σ_s and g: the diffuse appearance fixes only
//! σ_s'. A medium of Henyey–Greenstein g with the same σ_s' and σ_a has
//! σ_s = σ_s'/(1 − g), σ_t = σ_s + σ_a, α = σ_s/σ_t ([`MeasuredMedium::medium`]); at g = 0 it is the
//! isotropic medium of the similarity relation.
//!
//! [`nearest`]: the measured media closest to an estimate, by the root mean square over the
//! channels of the log-ratios of σ_s' and of σ_a (each with 10⁻³ mm⁻¹ added, below which a
//! centimetre-sized object shows no difference).

use serde::{Deserialize, Serialize};

use crate::SceneError;

mod table;

/// What one scene unit is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum LengthUnit {
    Mm,
    Cm,
    M,
}

impl LengthUnit {
    /// Millimetres per unit.
    pub fn mm(self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::Cm => 10.0,
            LengthUnit::M => 1000.0,
        }
    }

    /// The unit's symbol.
    pub fn name(self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::Cm => "cm",
            LengthUnit::M => "m",
        }
    }
}

/// Where a measurement comes from and what its numbers mean.
#[derive(Debug, PartialEq, Eq)]
pub struct Source {
    /// A short citation.
    pub citation: &'static str,
    /// The convention of its numbers.
    pub convention: &'static str,
}

/// Jensen, Marschner, Levoy, Hanrahan, "A Practical Model for Subsurface Light Transport",
/// SIGGRAPH 2001, Figure 5.
pub const JENSEN_2001: &Source = &Source {
    citation: "Jensen et al. 2001",
    convention: "reduced scattering σ_s' and absorption σ_a in mm⁻¹, fitted to the diffuse \
                 reflectance of the material itself (g not measured)",
};

/// Narasimhan, Gupta, Donner, Ramamoorthi, Nayar, Jensen, "Acquiring Scattering Properties of
/// Participating Media by Dilution", SIGGRAPH 2006, Table 1.
pub const NARASIMHAN_2006: &Source = &Source {
    citation: "Narasimhan et al. 2006",
    convention: "σ_s (1 − g) with the g measured, and σ_a, in mm⁻¹, at the concentration the \
                 paper measured (liquids diluted in water: the undiluted medium scatters more)",
};

/// One measured medium.
#[derive(Debug, PartialEq)]
pub struct MeasuredMedium {
    /// Lower case, words joined by `-` (`marble`, `regular-milk`).
    pub name: &'static str,
    pub source: &'static Source,
    /// σ_s' = σ_s (1 − g) in mm⁻¹, R, G, B.
    pub reduced_scattering: [f64; 3],
    /// σ_a in mm⁻¹, R, G, B.
    pub absorption: [f64; 3],
}

/// Every measured medium.
pub const MEASURED: &[MeasuredMedium] = &table::TABLE;

impl MeasuredMedium {
    /// The medium of HG anisotropy `g` with these reduced coefficients, as (σ_t in 1/`unit`, α)
    /// per channel: σ_s = σ_s'/(1 − g), σ_t = σ_s + σ_a, α = σ_s/σ_t.
    pub fn medium(&self, g: f64, unit: LengthUnit) -> ([f32; 3], [f32; 3]) {
        self.medium_rgb([g; 3], unit)
    }

    /// [`MeasuredMedium::medium`] with a g per channel (σ_s = σ_s'/(1 − g_c) in channel c).
    pub fn medium_rgb(&self, g: [f64; 3], unit: LengthUnit) -> ([f32; 3], [f32; 3]) {
        let mut sigma_t = [0.0; 3];
        let mut albedo = [0.0; 3];
        for c in 0..3 {
            let s = self.reduced_scattering[c] / (1.0 - g[c]);
            let t = s + self.absorption[c];
            sigma_t[c] = (t * unit.mm()) as f32;
            albedo[c] = if t > 0.0 { (s / t) as f32 } else { 0.0 };
        }
        (sigma_t, albedo)
    }

    /// The measured medium called `name` (case, spaces and `-`/`_` ignored); an error listing
    /// the names where there is none.
    pub fn find(name: &str) -> Result<&'static MeasuredMedium, SceneError> {
        let key = |s: &str| {
            s.chars()
                .filter(|c| c.is_alphanumeric())
                .collect::<String>()
                .to_lowercase()
        };
        MEASURED
            .iter()
            .find(|m| key(m.name) == key(name))
            .ok_or_else(|| SceneError::Invalid {
                location: format!("measured medium {name:?}"),
                reason: format!(
                    "no such measured medium; the names: {}",
                    MEASURED
                        .iter()
                        .map(|m| m.name)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            })
    }
}

/// A typical real material's σ_t in 1/`unit` for HG anisotropy `g`: the geometric mean over
/// Jensen et al. 2001's twelve materials and their three channels of σ_t = σ_s'/(1 − g) + σ_a
/// ([`MeasuredMedium::medium`]); 1.50 mm⁻¹ at g = 0, the materials spanning 0.17–20 mm⁻¹.
/// (Narasimhan et al. 2006's media are left out: they were measured diluted.)
pub fn typical_sigma_t(g: f64, unit: LengthUnit) -> f64 {
    let sigma_t: Vec<f64> = MEASURED
        .iter()
        .filter(|m| m.source == JENSEN_2001)
        .flat_map(|m| m.medium(g, unit).0)
        .map(f64::from)
        .collect();
    (sigma_t.iter().map(|s| s.ln()).sum::<f64>() / sigma_t.len() as f64).exp()
}

/// The reduced coefficients (σ_s', σ_a) in mm⁻¹ of a medium of σ_t in 1/`unit`, α and g per channel.
pub fn reduced_per_mm(
    sigma_t: [f64; 3],
    albedo: [f64; 3],
    g: [f64; 3],
    unit: LengthUnit,
) -> ([f64; 3], [f64; 3]) {
    let t = sigma_t.map(|s| s / unit.mm());
    (
        std::array::from_fn(|c| t[c] * albedo[c] * (1.0 - g[c])),
        std::array::from_fn(|c| t[c] * (1.0 - albedo[c])),
    )
}

/// The `k` measured media nearest to reduced coefficients (σ_s', σ_a) in mm⁻¹, nearest first,
/// each with its distance: the RMS over the six log-ratios ln((x + ε)/(x_ref + ε)), ε = 10⁻³.
pub fn nearest(
    reduced_scattering: [f64; 3],
    absorption: [f64; 3],
    k: usize,
) -> Vec<(&'static MeasuredMedium, f64)> {
    const EPS: f64 = 1e-3;
    let d = |m: &MeasuredMedium| {
        let sq = |a: f64, b: f64| ((a + EPS) / (b + EPS)).ln().powi(2);
        let s: f64 = (0..3)
            .map(|c| {
                sq(reduced_scattering[c], m.reduced_scattering[c])
                    + sq(absorption[c], m.absorption[c])
            })
            .sum();
        (s / 6.0).sqrt()
    };
    let mut all: Vec<_> = MEASURED.iter().map(|m| (m, d(m))).collect();
    all.sort_by(|a, b| a.1.total_cmp(&b.1));
    all.truncate(k);
    all
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The typical material: 1.50 mm⁻¹ at g = 0, in the unit asked, and σ_s'/(1 − g) larger
    /// with g (σ_a is small beside σ_s' in these materials).
    #[test]
    fn the_typical_material_is_the_geometric_mean_of_jensens() {
        let mm = typical_sigma_t(0.0, LengthUnit::Mm);
        assert!((mm - 1.5009).abs() < 1e-3, "{mm}");
        let cm = typical_sigma_t(0.0, LengthUnit::Cm);
        assert!((cm / mm - 10.0).abs() < 1e-5, "{cm}");
        let g = typical_sigma_t(0.8, LengthUnit::Mm);
        assert!(g > 4.0 * mm && g < 5.0 * mm, "{g}");
    }

    #[test]
    fn a_measured_medium_in_scene_units_keeps_its_reduced_coefficients() {
        let marble = MeasuredMedium::find("Marble").unwrap();
        assert_eq!(marble.source, JENSEN_2001);
        for g in [0.0, 0.3, 0.8] {
            for unit in [LengthUnit::Mm, LengthUnit::Cm, LengthUnit::M] {
                let (t, a) = marble.medium(g, unit);
                let (s, ab) = reduced_per_mm(t.map(f64::from), a.map(f64::from), [g; 3], unit);
                for c in 0..3 {
                    let rel = |x: f64, y: f64| ((x - y) / y).abs();
                    assert!(
                        rel(s[c], marble.reduced_scattering[c]) < 1e-5,
                        "{g} {unit:?}"
                    );
                    assert!(rel(ab[c], marble.absorption[c]) < 1e-4, "{g} {unit:?}");
                }
            }
        }
        // Marble at g = 0: σ_t ≈ 2.2–3.0 mm⁻¹, 22–30 cm⁻¹.
        let (t, a) = marble.medium(0.0, LengthUnit::Cm);
        assert!((t[0] - 21.921).abs() < 1e-3 && (a[2] - 3.0 / 3.0071).abs() < 1e-6);
        // Forward scattering: the same σ_s' means 5× the σ_s at g = 0.8.
        assert!((marble.medium(0.8, LengthUnit::Mm).0[1] - (2.62 * 5.0 + 0.0041)).abs() < 1e-5);
    }

    #[test]
    fn names_are_found_loosely_and_unknown_ones_listed() {
        assert_eq!(
            MeasuredMedium::find("regular milk").unwrap().name,
            "regular-milk"
        );
        assert_eq!(
            MeasuredMedium::find("Regular_Milk").unwrap().source,
            NARASIMHAN_2006
        );
        assert_eq!(
            MeasuredMedium::find("HEAD & SHOULDERS shampoo")
                .unwrap()
                .name,
            "head-shoulders-shampoo"
        );
        let e = MeasuredMedium::find("jade").unwrap_err().to_string();
        assert!(
            e.contains("\"jade\"") && e.contains("marble") && e.contains("skin1"),
            "{e}"
        );
        let mut names: Vec<_> = MEASURED.iter().map(|m| m.name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), 47);
    }

    #[test]
    fn each_measured_medium_is_its_own_nearest() {
        for m in MEASURED {
            let n = nearest(m.reduced_scattering, m.absorption, 2);
            assert_eq!(n[0].0.name, m.name);
            assert!(n[0].1 == 0.0 && n[1].1 > 0.0);
        }
        // A marble-like estimate, 10 % off: marble first.
        let s = MeasuredMedium::find("marble")
            .unwrap()
            .reduced_scattering
            .map(|x| x * 1.1);
        let a = [0.0019, 0.0045, 0.0065];
        assert_eq!(nearest(s, a, 3)[0].0.name, "marble");
    }
}
