//! Time to an accurate answer: the first iteration of a run after which its estimate stays
//! within a band around the truth, and the loop's seconds until then.
//!
//! The band is σ_t within [`SIGMA_T_BAND`] (relative) and α within [`ALBEDO_BAND`] (absolute),
//! per channel (channel c of the images depends on channel c's parameters alone). The trajectory is the run's `iterations.csv` (the parameters each iteration
//! started from, and its seconds) followed by the run's final estimate (the parameters after the
//! last step; before any bias correction). A run settles at iteration k when the parameters at
//! k and at every later point lie in the band; its time to accuracy is the seconds of
//! iterations 0 … k − 1 (the loop reached those parameters then), against the loop's total.

use std::path::Path;

use crate::error::{Context, Result};

/// σ_t's half-width of the band, relative to the truth.
pub const SIGMA_T_BAND: f64 = 0.05;
/// α's half-width of the band.
pub const ALBEDO_BAND: f64 = 0.01;

/// When a run's estimate entered the band for good.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settled {
    /// The first iteration whose parameters, and every later one's, lie in the band (the run's
    /// iteration count when only the final estimate does).
    pub iteration: usize,
    /// The loop's seconds until then.
    pub seconds: f64,
}

/// Per channel, the run's time to accuracy against the truth `sigma_t`, `albedo` from its
/// trajectory `params` (σ_t, α per iteration, the final estimate last) and the seconds of each
/// iteration (one fewer than `params`): `None` where even the final estimate lies outside the
/// band.
pub fn settled(
    params: &[([f64; 3], [f64; 3])],
    seconds: &[f64],
    sigma_t: [f64; 3],
    albedo: [f64; 3],
) -> [Option<Settled>; 3] {
    std::array::from_fn(|c| settled_channel(params, seconds, sigma_t[c], albedo[c], c))
}

fn settled_channel(
    params: &[([f64; 3], [f64; 3])],
    seconds: &[f64],
    sigma_t: f64,
    albedo: f64,
    c: usize,
) -> Option<Settled> {
    let inside = |(s, a): &([f64; 3], [f64; 3])| {
        (s[c] / sigma_t - 1.0).abs() <= SIGMA_T_BAND && (a[c] - albedo).abs() <= ALBEDO_BAND
    };
    let outside_after = params.iter().rposition(|p| !inside(p));
    let iteration = match outside_after {
        None => 0,
        Some(k) if k + 1 < params.len() => k + 1,
        Some(_) => return None,
    };
    Some(Settled {
        iteration,
        seconds: seconds[..iteration.min(seconds.len())].iter().sum(),
    })
}

/// A run's trajectory from its `iterations.csv` (columns by name): the parameters of each
/// row and its seconds.
type Trajectory = (Vec<([f64; 3], [f64; 3])>, Vec<f64>);

fn read_trajectory(csv: &Path) -> Result<Trajectory> {
    let text = std::fs::read_to_string(csv).context(format!("reading {}", csv.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .context(format!("{}: no column `{name}`", csv.display()))
    };
    let cols = |n: [&str; 3]| -> Result<[usize; 3]> { Ok([col(n[0])?, col(n[1])?, col(n[2])?]) };
    let st = cols(["sigma_t_r", "sigma_t_g", "sigma_t_b"])?;
    let al = cols(["albedo_r", "albedo_g", "albedo_b"])?;
    let sec = col("seconds")?;
    let mut params = Vec::new();
    let mut seconds = Vec::new();
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let num = |k: usize| -> Result<f64> {
            f.get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .context(format!("{}: row {}, column {k}", csv.display(), i + 2))
        };
        params.push((
            [num(st[0])?, num(st[1])?, num(st[2])?],
            [num(al[0])?, num(al[1])?, num(al[2])?],
        ));
        seconds.push(num(sec)?);
    }
    Ok((params, seconds))
}

/// What a run's `iterations.csv` leaves out of its trajectory.
#[derive(Clone, Copy, Debug)]
pub enum Rows {
    /// Rows of the parameters each iteration started from (ours): the final estimate follows.
    Before(([f64; 3], [f64; 3])),
    /// Rows of the parameters *after* each iteration's step (Mitsuba 3's PRB baseline,
    /// `tools/mitsuba/prb_optimize.py`): the start precedes them, the last row is the estimate.
    After(([f64; 3], [f64; 3])),
}

/// [`settled`] for the run whose `iterations.csv` is `csv`, its rows completed by `rows`, and
/// the loop's total seconds; `None`s when the file holds no iterations.
pub fn settled_from_csv(
    csv: &Path,
    rows: Rows,
    sigma_t: [f64; 3],
    albedo: [f64; 3],
) -> Result<([Option<Settled>; 3], f64)> {
    let (mut params, seconds) = read_trajectory(csv)?;
    let total = seconds.iter().sum();
    if params.is_empty() {
        return Ok(([None; 3], total));
    }
    match rows {
        Rows::Before(estimate) => params.push(estimate),
        Rows::After(start) => params.insert(0, start),
    }
    Ok((settled(&params, &seconds, sigma_t, albedo), total))
}

/// [`settled_from_csv`] for the run whose `result.json` is `result` (read as `v`), of the
/// medium `truth`: its `iterations.csv` beside it and its final estimate before any bias
/// correction; `None`s without a trajectory.
pub fn of_run(
    truth: &scene::Medium,
    v: &serde_json::Value,
    result: &Path,
) -> Result<([Option<Settled>; 3], f64)> {
    let csv = result.with_file_name("iterations.csv");
    let end = if v["estimate_uncorrected"].is_object() {
        &v["estimate_uncorrected"]
    } else {
        &v["estimate"]
    };
    if !csv.exists() || !end.is_object() {
        return Ok(([None; 3], f64::NAN));
    }
    let rgb = |x: &serde_json::Value| -> [f64; 3] {
        std::array::from_fn(|c| x[c].as_f64().unwrap_or(f64::NAN))
    };
    settled_from_csv(
        &csv,
        Rows::Before((rgb(&end["sigma_t"]), rgb(&end["albedo"]))),
        truth.sigma_t.map(f64::from),
        truth.albedo.map(f64::from),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: [f64; 3] = [50.0, 60.0, 70.0];
    const A: [f64; 3] = [0.9, 0.8, 0.7];

    fn at(f: f64, da: f64) -> ([f64; 3], [f64; 3]) {
        (S.map(|s| s * f), A.map(|a| a + da))
    }

    /// The run settles where it enters the band for the last time, its time is the seconds of
    /// the iterations before, and a run that leaves the band again settles later.
    #[test]
    fn settles_where_the_band_holds_for_good() {
        let secs = [1.0, 2.0, 3.0, 4.0];
        let path = [
            at(2.0, 0.0),
            at(1.01, 0.0),
            at(1.2, 0.0),
            at(1.04, 0.005),
            at(0.97, -0.009),
        ];
        let s = settled(&path, &secs, S, A);
        for c in s {
            let c = c.expect("settles");
            assert_eq!((c.iteration, c.seconds), (3, 6.0));
        }
        // α off by more than 0.01 in channel 2 at the end: that channel never settles.
        let mut off = path;
        off[4].1[2] += 0.02;
        let s = settled(&off, &secs, S, A);
        assert_eq!((s[0].map(|c| c.iteration), s[2]), (Some(3), None));
        // In the band from the start.
        let s = settled(&[at(1.0, 0.0), at(1.0, 0.0)], &[5.0], S, A);
        assert_eq!(s[1].map(|c| (c.iteration, c.seconds)), Some((0, 0.0)));
    }

    /// The CSV reader takes the columns by name and appends the final estimate.
    #[test]
    fn reads_the_trajectory_of_a_run() {
        let dir = tempfile::tempdir().expect("tmp");
        let csv = dir.path().join("iterations.csv");
        std::fs::write(
            &csv,
            "iteration,loss,sigma_t_r,sigma_t_g,sigma_t_b,albedo_r,albedo_g,albedo_b,seconds\n\
             0,1,100,120,140,0.9,0.8,0.7,0.5\n\
             1,1,51,61,71,0.9,0.8,0.7,0.25\n",
        )
        .expect("write");
        let (s, total) = settled_from_csv(&csv, Rows::Before(at(1.0, 0.0)), S, A).expect("read");
        assert_eq!(total, 0.75);
        assert_eq!(s[0].map(|s| (s.iteration, s.seconds)), Some((1, 0.5)));
        // The same rows as the parameters after each step, from a start far off: the
        // trajectory is the start, then the rows.
        let (s, _) = settled_from_csv(&csv, Rows::After(at(2.0, 0.0)), S, A).expect("read");
        assert_eq!(s[0].map(|s| (s.iteration, s.seconds)), Some((2, 0.75)));
        std::fs::write(&csv, "iteration,loss\n0,1\n").expect("write");
        let e = settled_from_csv(&csv, Rows::Before(at(1.0, 0.0)), S, A).unwrap_err();
        assert!(format!("{e:#}").contains("sigma_t_r"), "{e:#}");
    }
}
