//! The printed intervals of a recovery: each estimate with its 95 % interval (in words where it
//! spans orders of magnitude), and in plain words what the images leave open and which capture
//! would settle it.

use inverse::params::{OneOrRgb, Params};
use inverse::uncertainty::{SharedUncertainty, Uncertainty};

use super::CHANNELS;

/// A σ_t interval reaching this factor beyond the estimate on a side is printed in words.
const WIDE: f64 = 100.0;

/// `v` with `p` decimals, or in scientific notation where `p` decimals cannot show it: an
/// interval of a flat valley can span many decades.
fn num(v: f64, p: usize) -> String {
    if v != 0.0 && (v.abs() >= 1e5 || v.abs() < 0.1f64.powi(p as i32)) {
        format!("{v:.1e}")
    } else {
        format!("{v:.p$}")
    }
}

/// `v` and its interval `i` (`fixed`: a parameter the run kept).
fn fmt(v: f64, i: Option<[f64; 2]>, fixed: bool, p: usize) -> String {
    match i {
        _ if fixed => format!("{v:.p$} (fixed)"),
        Some([lo, hi]) => format!("{v:.p$} [{}, {}]", num(lo, p), num(hi, p)),
        None => format!("{v:.p$} [no finite interval]"),
    }
}

/// The lines of an unknown recovered as one value or one per channel, with its intervals:
/// `one` (with `{}` for the value and its interval) for one value, else `heading` and a line
/// per channel `{name} = …`, at `digits` decimals.
fn one_or_rgb_lines(
    (est, u): (Option<OneOrRgb<f64>>, Option<OneOrRgb<SharedUncertainty>>),
    one: &str,
    heading: &str,
    name: &str,
    digits: usize,
    out: &mut Vec<String>,
) {
    match (u, est) {
        (Some(OneOrRgb::One(u)), Some(v)) => {
            out.push(one.replace("{}", &fmt(v.channel(0), u.interval, false, digits)));
        }
        (Some(OneOrRgb::Rgb(u)), Some(v)) => {
            out.push(heading.into());
            for c in 0..3 {
                let v = fmt(v.channel(c), u[c].interval, false, digits);
                out.push(format!("    {}: {name} = {v}", CHANNELS[c]));
            }
        }
        _ => {}
    }
}

/// The printed intervals: `σ_t = 72.1 [65.0, 80.2]` per channel (in words where it spans orders
/// of magnitude: `anything above 20.0 fits these images`), and in plain words what the images
/// leave open and which capture would settle it.
pub fn interval_lines(est: &Params, u: &Uncertainty) -> Vec<String> {
    const CH: [&str; 3] = CHANNELS;
    // An interval of σ_t that reaches orders of magnitude beyond the estimate says no more than
    // which side the images bound: it is printed as that, in words.
    let sigma_t = |v: f64, i: Option<[f64; 2]>| match i {
        Some([lo, hi]) if !u.fixed[0] && (hi >= WIDE * v || lo <= v / WIDE) => {
            match (lo <= v / WIDE, hi >= WIDE * v) {
                (true, true) => format!("{v:.1} [not determined: any value fits these images]"),
                (false, _) => format!(
                    "{v:.1} [not determined: anything above {} fits these images]",
                    num(lo, 1)
                ),
                (true, false) => format!(
                    "{v:.1} [not determined: anything below {} fits these images]",
                    num(hi, 1)
                ),
            }
        }
        _ => fmt(v, i, u.fixed[0], 1),
    };
    let mut out = vec![match u.mesh_error {
        Some(f) => format!(
            "95 % intervals (from the images, and a mesh error of {} % of its diagonal):",
            num(100.0 * f, 2)
        ),
        None => "95 % intervals (from the images):".to_string(),
    }];
    for c in 0..3 {
        out.push(format!(
            "  {}: σ_t = {}  α = {}",
            CH[c],
            sigma_t(est.sigma_t[c], u.sigma_t[c]),
            fmt(est.albedo[c], u.albedo[c], u.fixed[1], 4)
        ));
    }
    one_or_rgb_lines(
        (est.g, u.g),
        "  g = {}",
        "  phase function g per channel:",
        "g",
        3,
        &mut out,
    );
    one_or_rgb_lines(
        (est.light_scale, u.light_scale),
        "  light scale k = {} (the lights' stated intensity times k)",
        "  light scale per channel (the lights' stated intensity times k_c):",
        "k",
        4,
        &mut out,
    );
    let open_t: Vec<&str> = (0..3)
        .filter(|&c| !u.fixed[0] && !u.determined_sigma_t[c])
        .map(|c| CH[c])
        .collect();
    let open_a: Vec<&str> = (0..3)
        .filter(|&c| !u.fixed[1] && !u.determined_albedo[c])
        .map(|c| CH[c])
        .collect();
    if !open_t.is_empty() && u.fixed[1] {
        out.push(format!(
            "σ_t is NOT determined by these images in {} (with α fixed, its interval from the \
             images alone spans more than ±{:.0} %): more views, more samples per iteration, or \
             views with the light beside or behind the object narrow it.",
            open_t.join(", "),
            50.0 * (inverse::uncertainty::DETERMINED_SIGMA_T_RATIO - 1.0)
        ));
    } else if !open_t.is_empty() {
        out.push(format!(
            "σ_t is NOT determined by these images in {} (from the images alone its interval \
             spans more than ±{:.0} %): their brightness trades σ_t against α. Views with the \
             light beside or behind the object (light that crossed it) constrain σ_t most; a \
             light at the camera barely does, however many views. More views, or more samples \
             per iteration, narrow the interval of any capture.",
            open_t.join(", "),
            50.0 * (inverse::uncertainty::DETERMINED_SIGMA_T_RATIO - 1.0)
        ));
    }
    if !open_a.is_empty() {
        out.push(format!(
            "α is NOT determined by these images in {} (its interval is wider than ±{}).",
            open_a.join(", "),
            inverse::uncertainty::DETERMINED_ALBEDO_HALF_WIDTH
        ));
    }
    let open_k: Vec<usize> = u.light_scale.map_or(vec![], |k| {
        (0..k.values().len())
            .filter(|&i| !k.values()[i].determined)
            .collect()
    });
    if !open_k.is_empty() {
        let which = match u.light_scale {
            Some(OneOrRgb::Rgb(_)) => format!(
                " in {}",
                open_k.iter().map(|&c| CH[c]).collect::<Vec<_>>().join(", ")
            ),
            _ => String::new(),
        };
        out.push(format!(
            "The light's strength is NOT determined by these images{which} (its interval spans \
             more than ±{:.0} %): a brighter light trades against α (and σ_t). A calibrated \
             light, or a reference of known reflectance in the images, settles it.",
            50.0 * (inverse::uncertainty::DETERMINED_SIGMA_T_RATIO - 1.0)
        ));
    }
    let g_open: Vec<&str> = (0..3)
        .filter(|&c| u.g.is_some_and(|g| !g.channel(c).determined))
        .map(|c| CH[c])
        .collect();
    if !g_open.is_empty() {
        let which = match u.g {
            Some(OneOrRgb::Rgb(_)) => format!(" in {}", g_open.join(", ")),
            _ => String::new(),
        };
        out.push(format!(
            "g is NOT determined by these images{which} (its interval is wider than ±{}): where light \
             scatters many times only the reduced scattering σ_t·α·(1 − g) shows, so g trades \
             against σ_t and α. Views whose light crossed little of the object (thin parts, \
             grazing or back light) carry the single scattering that sets g.",
            inverse::uncertainty::DETERMINED_G_HALF_WIDTH
        ));
    }
    out
}
