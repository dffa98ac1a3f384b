//! Line charts as PNG (and SVG) for training curves and convergence plots.
//!
//! A [`Figure`] is a grid of [`Panel`]s; a panel holds line [`Series`] (x, y), shaded
//! [`Band`]s (x, lo, hi) under them (an interval, a mean ± s.d.) and optional horizontal
//! reference lines (e.g. the ground truth of a parameter). PNGs are drawn into an RGB
//! buffer with plotters' bitmap backend and encoded with `image` (no system libraries); text uses
//! the embedded DejaVu Sans (licence in `assets/DejaVuSans-LICENSE.txt`). Files are written
//! atomically and never replace an existing file unless asked.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;

/// Errors of plotting.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Drawing failed (plotters backend error).
    #[error("cannot draw {path}: {reason}")]
    Draw {
        /// Output file.
        path: PathBuf,
        /// Backend message.
        reason: String,
    },
    /// Writing the file failed.
    #[error(transparent)]
    Write(#[from] scene::SceneError),
    /// Nothing to plot or a bad layout.
    #[error("cannot plot {path}: {reason}")]
    Invalid {
        /// Output file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// One line of a panel.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points (x, y); non-finite points are skipped.
    pub points: Vec<(f64, f64)>,
    /// Drawn thin and pale, behind the other lines (e.g. raw values under their running mean).
    pub faint: bool,
}

impl Series {
    /// A series from its label and points.
    pub fn new(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            points,
            faint: false,
        }
    }

    /// A faint series: thin and pale, drawn before the others.
    pub fn faint(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            faint: true,
            ..Self::new(label, points)
        }
    }
}

/// A shaded range under a panel's lines: between `lo` and `hi` at each `x`.
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    /// Legend label.
    pub label: String,
    /// Points (x, lo, hi), in order of x; non-finite points are skipped.
    pub points: Vec<(f64, f64, f64)>,
    /// Palette index of its colour: the colour of the series with that index.
    pub colour: usize,
}

impl Band {
    /// A band of constant `[lo, hi]` from `x0` to `x1` (e.g. a 95 % interval).
    pub fn constant(label: impl Into<String>, x0: f64, x1: f64, lo: f64, hi: f64) -> Self {
        Self {
            label: label.into(),
            points: vec![(x0, lo, hi), (x1, lo, hi)],
            colour: 0,
        }
    }

    /// The same band in the colour of series `colour`.
    pub fn coloured(self, colour: usize) -> Self {
        Self { colour, ..self }
    }
}

/// One chart of a figure.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic y axis (non-positive values are skipped).
    pub log_y: bool,
    /// Lines.
    pub series: Vec<Series>,
    /// Horizontal dashed reference lines (label, y).
    pub reference_lines: Vec<(String, f64)>,
    /// Shaded ranges, drawn under the lines.
    pub bands: Vec<Band>,
}

/// A grid of panels.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Panels, filled row by row.
    pub panels: Vec<Panel>,
    /// Number of columns of the grid.
    pub columns: usize,
    /// Size of one panel in pixels.
    pub panel_size: (u32, u32),
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let font: &'static [u8] = include_bytes!("../assets/DejaVuSans.ttf");
        // The embedded font is known to parse; registration only fails on a corrupt font.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, font);
    });
}

impl Figure {
    /// A figure of `panels` in `columns` columns with 640×400 panels.
    pub fn new(panels: Vec<Panel>, columns: usize) -> Self {
        Self {
            panels,
            columns: columns.max(1),
            panel_size: (640, 400),
        }
    }

    /// Total size in pixels.
    pub fn size(&self) -> (u32, u32) {
        let cols = self.columns.min(self.panels.len()).max(1) as u32;
        let rows = self.panels.len().div_ceil(self.columns.max(1)).max(1) as u32;
        (self.panel_size.0 * cols, self.panel_size.1 * rows)
    }

    /// Draws the figure as a PNG at `path` (atomically; an existing file is replaced only if
    /// `overwrite`).
    pub fn write_png(&self, path: &Path, overwrite: bool) -> Result<(), PlotError> {
        if self.panels.is_empty() {
            return Err(PlotError::Invalid {
                path: path.to_path_buf(),
                reason: "the figure has no panels".into(),
            });
        }
        scene::fsutil::check_overwrite(path, overwrite)?;
        register_font();
        let (w, h) = self.size();
        let mut buf = vec![255u8; (w * h * 3) as usize];
        self.draw_and_present(
            BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area(),
            path,
        )?;
        let img = image::RgbImage::from_raw(w, h, buf).ok_or_else(|| PlotError::Invalid {
            path: path.to_path_buf(),
            reason: "internal buffer size mismatch".into(),
        })?;
        let mut bytes = Vec::new();
        img.write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .map_err(|e| PlotError::Draw {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        scene::fsutil::atomic_write(path, &bytes, overwrite)?;
        Ok(())
    }

    /// Draws the figure as an SVG at `path`.
    pub fn write_svg(&self, path: &Path, overwrite: bool) -> Result<(), PlotError> {
        scene::fsutil::check_overwrite(path, overwrite)?;
        register_font();
        let mut text = String::new();
        self.draw_and_present(
            SVGBackend::with_string(&mut text, self.size()).into_drawing_area(),
            path,
        )?;
        scene::fsutil::atomic_write(path, text.as_bytes(), overwrite)?;
        Ok(())
    }

    /// Draws into `root` and flushes it; errors name `path`.
    fn draw_and_present<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
        path: &Path,
    ) -> Result<(), PlotError> {
        let err = |reason: String| PlotError::Draw {
            path: path.to_path_buf(),
            reason,
        };
        self.draw(&root).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let rows = self.panels.len().div_ceil(self.columns);
        let cols = self.columns.min(self.panels.len());
        let areas = root.split_evenly((rows, cols));
        for (panel, area) in self.panels.iter().zip(areas.iter()) {
            draw_panel(panel, area).map_err(|e| format!("panel '{}': {e}", panel.title))?;
        }
        Ok(())
    }
}

/// Data range of a panel: (x_min, x_max, y_min, y_max) over finite (and, for log axes,
/// positive) values, widened when degenerate.
fn ranges(panel: &Panel) -> Option<(f64, f64, f64, f64)> {
    let ok_y = |y: f64| y.is_finite() && (!panel.log_y || y > 0.0);
    let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
    let mut ys = (f64::INFINITY, f64::NEG_INFINITY);
    for s in &panel.series {
        for &(x, y) in &s.points {
            if x.is_finite() && ok_y(y) {
                xs = (xs.0.min(x), xs.1.max(x));
                ys = (ys.0.min(y), ys.1.max(y));
            }
        }
    }
    for &(_, y) in &panel.reference_lines {
        if ok_y(y) {
            ys = (ys.0.min(y), ys.1.max(y));
        }
    }
    for b in &panel.bands {
        for &(x, lo, hi) in &b.points {
            if x.is_finite() && ok_y(lo) && ok_y(hi) {
                xs = (xs.0.min(x), xs.1.max(x));
                ys = (ys.0.min(lo.min(hi)), ys.1.max(lo.max(hi)));
            }
        }
    }
    if !(xs.0.is_finite() && ys.0.is_finite()) {
        return None;
    }
    if xs.1 <= xs.0 {
        xs = (xs.0 - 0.5, xs.0 + 0.5);
    }
    if panel.log_y {
        if ys.1 <= ys.0 {
            ys = (ys.0 / 2.0, ys.0 * 2.0);
        }
        ys = (ys.0 / 1.2, ys.1 * 1.2);
    } else {
        let pad = if ys.1 > ys.0 {
            0.05 * (ys.1 - ys.0)
        } else {
            0.5 * ys.0.abs().max(1e-3)
        };
        ys = (ys.0 - pad, ys.1 + pad);
    }
    Some((xs.0, xs.1, ys.0, ys.1))
}

/// The body of a panel, drawn into `$chart` (an `x0..x1` chart, linear or logarithmic in y,
/// whose coordinate types differ; hence a macro rather than a function): the mesh, the bands,
/// the series (faint ones first), the reference lines and the legend. `$ok` says which y values
/// the axis can show. Returns early from the caller with the drawing error as a string.
macro_rules! draw_body {
    ($chart:expr, $panel:expr, $x0:expr, $x1:expr, $ok:expr) => {{
        let (panel, x0, x1): (&Panel, f64, f64) = ($panel, $x0, $x1);
        let mut chart = $chart;
        chart
            .configure_mesh()
            .x_desc(&panel.x_label)
            .y_desc(&panel.y_label)
            .label_style(("sans-serif", 13))
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .draw()
            .map_err(|e| e.to_string())?;
        for b in &panel.bands {
            let colour = PALETTE[b.colour % PALETTE.len()];
            let pts: Vec<(f64, f64, f64)> = b
                .points
                .iter()
                .copied()
                .filter(|&(x, lo, hi)| x.is_finite() && $ok(lo) && $ok(hi))
                .collect();
            if pts.len() < 2 {
                continue;
            }
            let outline: Vec<(f64, f64)> = pts
                .iter()
                .map(|&(x, lo, _)| (x, lo))
                .chain(pts.iter().rev().map(|&(x, _, hi)| (x, hi)))
                .collect();
            chart
                .draw_series(std::iter::once(Polygon::new(
                    outline,
                    colour.mix(0.18).filled(),
                )))
                .map_err(|e| e.to_string())?
                .label(&b.label)
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 18, y + 5)], colour.mix(0.18).filled())
                });
        }
        // Faint series first, so that the others are drawn over them.
        let order = panel
            .series
            .iter()
            .enumerate()
            .filter(|(_, s)| s.faint)
            .chain(panel.series.iter().enumerate().filter(|(_, s)| !s.faint));
        for (i, s) in order {
            let colour = PALETTE[i % PALETTE.len()];
            let style = if s.faint {
                colour.mix(0.3).stroke_width(1)
            } else {
                colour.stroke_width(2)
            };
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|&(x, y)| x.is_finite() && $ok(y))
                .collect();
            chart
                .draw_series(LineSeries::new(pts, style))
                .map_err(|e| e.to_string())?
                .label(&s.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], style));
        }
        // Reference line k is dashed in the colour of series k (e.g. the truth of channel k
        // next to its estimate); black when there are more lines than series.
        for (k, (label, y)) in panel.reference_lines.iter().enumerate() {
            let y = *y;
            if !$ok(y) {
                continue;
            }
            let colour = if k < panel.series.len() {
                PALETTE[k % PALETTE.len()]
            } else {
                BLACK
            };
            let dashes = dashed_segments(x0, x1, 60);
            chart
                .draw_series(
                    dashes.into_iter().map(|(a, b)| {
                        PathElement::new(vec![(a, y), (b, y)], colour.stroke_width(1))
                    }),
                )
                .map_err(|e| e.to_string())?
                .label(label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 6, y)], colour));
        }
        if !panel.series.is_empty() || !panel.reference_lines.is_empty() || !panel.bands.is_empty()
        {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .draw()
                .map_err(|e| e.to_string())?;
        }
    }};
}

fn draw_panel<DB: DrawingBackend>(
    panel: &Panel,
    area: &DrawingArea<DB, plotters::coord::Shift>,
) -> Result<(), String> {
    let Some((x0, x1, y0, y1)) = ranges(panel) else {
        area.titled(&format!("{} (no data)", panel.title), ("sans-serif", 18))
            .map_err(|e| e.to_string())?;
        return Ok(());
    };
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&panel.title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70);
    if panel.log_y {
        let chart = builder
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(|e| e.to_string())?;
        draw_body!(chart, panel, x0, x1, |y: f64| y.is_finite() && y > 0.0);
    } else {
        let chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        draw_body!(chart, panel, x0, x1, |y: f64| y.is_finite());
    }
    Ok(())
}

/// Short tick labels: plain for moderate magnitudes, scientific otherwise.
fn tick(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&a) {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.1e}")
    }
}

/// `n` dash segments (every other piece of a `2n`-way split) covering `[x0, x1]`.
fn dashed_segments(x0: f64, x1: f64, n: usize) -> Vec<(f64, f64)> {
    let step = (x1 - x0) / (2 * n) as f64;
    (0..n)
        .map(|i| {
            let a = x0 + 2.0 * i as f64 * step;
            (a, a + step)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figure() -> Figure {
        let curve: Vec<(f64, f64)> = (0..50)
            .map(|i| (i as f64, 1.0 / (1.0 + i as f64)))
            .collect();
        Figure::new(
            vec![
                Panel {
                    title: "loss".into(),
                    x_label: "step".into(),
                    y_label: "loss".into(),
                    log_y: true,
                    series: vec![Series::new("train", curve.clone())],
                    reference_lines: vec![],
                    bands: Vec::new(),
                },
                Panel {
                    title: "sigma_t".into(),
                    x_label: "iteration".into(),
                    y_label: "σ_t".into(),
                    log_y: false,
                    series: vec![
                        Series::faint("raw", curve.clone()),
                        Series::new("estimate", curve),
                    ],
                    reference_lines: vec![("truth".into(), 0.5)],
                    bands: vec![Band::constant("interval", 0.0, 49.0, 0.4, 0.6).coloured(1)],
                },
                Panel {
                    title: "empty".into(),
                    ..Default::default()
                },
            ],
            2,
        )
    }

    #[test]
    fn png_and_svg_are_written_and_not_overwritten() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("f.png");
        let fig = figure();
        fig.write_png(&png, false).unwrap();
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), fig.size());
        // Something other than the white background was drawn.
        assert!(img.to_rgb8().pixels().any(|p| p.0 != [255, 255, 255]));
        assert!(matches!(
            fig.write_png(&png, false),
            Err(PlotError::Write(_))
        ));
        fig.write_png(&png, true).unwrap();
        let svg = dir.path().join("f.svg");
        fig.write_svg(&svg, false).unwrap();
        assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(2000.0), "2000");
        assert_eq!(tick(0.25), "0.25");
        assert_eq!(tick(4e-10), "4.0e-10");
        assert_eq!(tick(1.5e6), "1.5e6");
    }

    #[test]
    fn empty_figure_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let fig = Figure::new(vec![], 1);
        assert!(matches!(
            fig.write_png(&dir.path().join("x.png"), false),
            Err(PlotError::Invalid { .. })
        ));
    }

    #[test]
    fn log_ranges_skip_non_positive_values() {
        let p = Panel {
            log_y: true,
            series: vec![Series::new(
                "a",
                vec![(0.0, -1.0), (1.0, 0.0), (2.0, 4.0), (3.0, f64::NAN)],
            )],
            ..Default::default()
        };
        let (x0, x1, y0, y1) = ranges(&p).unwrap();
        assert_eq!((x0, x1), (1.5, 2.5));
        assert!(y0 > 0.0 && y0 < 4.0 && y1 > 4.0);
    }

    #[test]
    fn bands_widen_the_ranges() {
        let p = Panel {
            series: vec![Series::new("a", vec![(0.0, 1.0), (1.0, 2.0)])],
            bands: vec![Band::constant("b", -1.0, 3.0, 0.0, 5.0)],
            ..Default::default()
        };
        let (x0, x1, y0, y1) = ranges(&p).unwrap();
        assert_eq!((x0, x1), (-1.0, 3.0));
        assert!(y0 < 0.0 && y1 > 5.0, "{y0} {y1}");
    }
}
