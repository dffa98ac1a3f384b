//! Training history as CSV and loss curves as PNG.

use std::fmt::Write as _;
use std::path::Path;

use plot::{Figure, Panel, Series};

use crate::train::{HistoryRow, TrainError};

/// Writes `history.csv` and `loss.png` into `dir` (replacing them if `overwrite`).
///
/// Columns: step, learning rate, mean training loss since the previous row, validation total
/// loss, its position / KL / absorption terms, the validation position MSE (units of σ_n²) and
/// absorption RMSE, training seconds, then the energy objective's weighted term and its
/// unweighted energy score (units of σ_n; 0 under the CVAE objective).
pub fn write_history(
    history: &[HistoryRow],
    dir: &Path,
    overwrite: bool,
) -> Result<(), TrainError> {
    let mut csv = String::from(
        "step,lr,train_loss,val_loss,val_position_term,val_kl_term,val_absorption_term,\
         val_position_mse,val_absorption_rmse,seconds,val_energy_term,val_energy_score\n",
    );
    for r in history {
        let _ = writeln!(
            csv,
            "{},{:e},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.2},{:.6},{:.6}",
            r.step,
            r.lr,
            r.train_loss.unwrap_or(f64::NAN),
            r.val.total,
            r.val.position,
            r.val.kl,
            r.val.absorption,
            r.val.position_mse,
            r.val.absorption_mse.sqrt(),
            r.seconds,
            r.val.energy,
            r.val.energy_score
        );
    }
    scene::fsutil::atomic_write(&dir.join("history.csv"), csv.as_bytes(), overwrite)?;
    let pts = |f: &dyn Fn(&HistoryRow) -> f64| -> Vec<(f64, f64)> {
        history.iter().map(|r| (r.step as f64, f(r))).collect()
    };
    let fig = Figure::new(
        vec![
            Panel {
                title: "loss (docs/model.md §6)".into(),
                x_label: "step".into(),
                y_label: "loss".into(),
                log_y: true,
                series: vec![
                    Series::new(
                        "train (running mean)",
                        pts(&|r| r.train_loss.unwrap_or(f64::NAN)),
                    ),
                    Series::new("validation", pts(&|r| r.val.total)),
                ],
                reference_lines: vec![],
                bands: Vec::new(),
            },
            Panel {
                title: "validation terms".into(),
                x_label: "step".into(),
                y_label: "loss term".into(),
                log_y: true,
                series: vec![
                    Series::new("position", pts(&|r| r.val.position)),
                    Series::new("KL", pts(&|r| r.val.kl)),
                    Series::new("absorption", pts(&|r| r.val.absorption)),
                    Series::new("energy score", pts(&|r| r.val.energy)),
                ],
                reference_lines: vec![],
                bands: Vec::new(),
            },
            Panel {
                title: "validation absorption RMSE".into(),
                x_label: "step".into(),
                y_label: "RMSE".into(),
                log_y: true,
                series: vec![Series::new(
                    "|Absorb − p_abs|",
                    pts(&|r| r.val.absorption_mse.sqrt()),
                )],
                reference_lines: vec![],
                bands: Vec::new(),
            },
            Panel {
                title: "learning rate".into(),
                x_label: "step".into(),
                y_label: "lr".into(),
                log_y: true,
                series: vec![Series::new("lr", pts(&|r| r.lr as f64))],
                reference_lines: vec![],
                bands: Vec::new(),
            },
        ],
        2,
    );
    fig.write_png(&dir.join("loss.png"), overwrite)
        .map_err(|e| TrainError::Data(format!("cannot draw the loss curves: {e}")))?;
    Ok(())
}
