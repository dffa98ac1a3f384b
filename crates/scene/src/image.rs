//! RGB float images: linear f32 EXR (the data format) and tone-mapped sRGB PNG previews.
//!
//! * EXR reading looks channels up **by name** (`R`, `G`, `B`; the exr crate stores channels
//!   sorted by name, so positions mean nothing). f16, f32 and u32 samples and every compression
//!   the exr crate knows are accepted; a file with a single luminance channel `Y` is read as grey.
//!   NaN/Inf samples are an error naming the file, the pixel and the channel.
//! * EXR writing: linear f32 `R`, `G`, `B`, ZIP compression, scan lines, written to a temporary file
//!   in the same folder and renamed into place (atomic), refusing to replace an existing file
//!   unless asked to.
//! * PNG previews: `clamp(exposure · value, 0, 1)`, sRGB OETF, 8 bit.
//!
//! This module holds [`Image`] and its pixel operations (crop, mean, scale, box downsampling,
//! false-colour differences, auto exposure); the file formats are in `image/files.rs`.

use crate::SceneError;

mod decode;
mod files;
mod mask;
mod photo;
#[cfg(test)]
mod photo_tests;
mod stats;
#[cfg(test)]
// Numbers copied verbatim from Mitsuba's scene.json.
#[allow(clippy::excessive_precision, clippy::type_complexity)]
mod tests;

pub use decode::{PHOTO_MAX_BYTES, is_photo_file};
pub use files::to_srgb8;
pub use mask::PixelMask;
pub use photo::{Photo, PhotoSettings, Transfer, srgb_to_linear};
pub use stats::{PairStats, pair_stats};

/// A linear RGB float image, row-major, row 0 = top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub data: Vec<[f32; 3]>,
}

const CHANNEL_NAMES: [&str; 3] = ["R", "G", "B"];

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image {
            width,
            height,
            data: vec![[0.0; 3]; width as usize * height as usize],
        }
    }
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.data[y as usize * self.width as usize + x as usize]
    }
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, v: [f32; 3]) {
        self.data[y as usize * self.width as usize + x as usize] = v;
    }
    /// The `width × height` pixels from (x0, y0) (must lie inside the image; see
    /// [`Camera::cropped`](crate::Camera::cropped), which checks the same window).
    pub fn crop(&self, x0: u32, y0: u32, width: u32, height: u32) -> Image {
        assert!(
            x0 + width <= self.width && y0 + height <= self.height,
            "crop outside the image"
        );
        let mut out = Image::new(width, height);
        for y in 0..height {
            let src = (y0 + y) as usize * self.width as usize + x0 as usize;
            out.data[(y * width) as usize..((y + 1) * width) as usize]
                .copy_from_slice(&self.data[src..src + width as usize]);
        }
        out
    }

    /// The images of `rows` tiled row by row (each row left to right), `gap` black pixels
    /// between tiles; every tile keeps its size and the grid is as large as its largest row
    /// and its rows' tallest tiles.
    pub fn grid(rows: &[Vec<&Image>], gap: u32) -> Image {
        let row_w = |r: &Vec<&Image>| {
            r.iter().map(|i| i.width).sum::<u32>() + gap * r.len().saturating_sub(1) as u32
        };
        let row_h = |r: &Vec<&Image>| r.iter().map(|i| i.height).max().unwrap_or(0);
        let width = rows.iter().map(row_w).max().unwrap_or(0);
        let height =
            rows.iter().map(row_h).sum::<u32>() + gap * rows.len().saturating_sub(1) as u32;
        let mut out = Image::new(width, height);
        let mut y0 = 0;
        for r in rows {
            let mut x0 = 0;
            for img in r {
                for y in 0..img.height {
                    let dst = (y0 + y) as usize * width as usize + x0 as usize;
                    let src = y as usize * img.width as usize;
                    out.data[dst..dst + img.width as usize]
                        .copy_from_slice(&img.data[src..src + img.width as usize]);
                }
                x0 += img.width + gap;
            }
            y0 += row_h(r) + gap;
        }
        out
    }

    /// Per-channel mean.
    pub fn mean(&self) -> [f64; 3] {
        let mut m = [0.0f64; 3];
        for p in &self.data {
            for c in 0..3 {
                m[c] += p[c] as f64;
            }
        }
        let n = self.data.len().max(1) as f64;
        m.map(|v| v / n)
    }

    /// The first pixel (x, y, channel index) holding NaN or ±Inf, scanning rows top to bottom.
    pub fn first_non_finite(&self) -> Option<(u32, u32, usize)> {
        let w = self.width.max(1) as usize;
        self.data.iter().enumerate().find_map(|(i, p)| {
            p.iter()
                .position(|v| !v.is_finite())
                .map(|c| ((i % w) as u32, (i / w) as u32, c))
        })
    }

    /// Error if any pixel is NaN/Inf; `what` names the image in the message (file or view).
    pub fn check_finite(&self, what: &str) -> Result<(), SceneError> {
        match self.first_non_finite() {
            None => Ok(()),
            Some((x, y, c)) => Err(SceneError::Invalid {
                location: format!("{what}: pixel (x={x}, y={y}) channel {}", CHANNEL_NAMES[c]),
                reason: format!(
                    "value is {} (images must be finite); fix: re-render the image or repair \
                     that pixel",
                    self.get(x, y)[c]
                ),
            }),
        }
    }

    /// Multiply every value by `s` in place.
    pub fn scale(&mut self, s: f32) {
        for p in &mut self.data {
            *p = p.map(|v| v * s);
        }
    }

    /// A copy with every value multiplied by `s`.
    pub fn scaled(&self, s: f32) -> Image {
        let mut out = self.clone();
        out.scale(s);
        out
    }

    /// Box-filter downsampling by an integer `factor`: each output pixel is the mean of a
    /// `factor × factor` block. Output size is `floor(W/factor) × floor(H/factor)`; rightmost
    /// columns / bottom rows that do not fill a whole block are dropped.
    pub fn downsample(&self, factor: u32) -> Result<Image, SceneError> {
        if factor == 0 || factor > self.width || factor > self.height {
            return Err(SceneError::Invalid {
                location: format!("downsample factor = {factor}"),
                reason: format!(
                    "must be between 1 and the smaller image side ({}×{} image); fix: choose a \
                     factor in that range",
                    self.width, self.height
                ),
            });
        }
        if factor == 1 {
            return Ok(self.clone());
        }
        let (w, h) = (self.width / factor, self.height / factor);
        let mut out = Image::new(w, h);
        let norm = 1.0 / (factor as f64 * factor as f64);
        for oy in 0..h {
            for ox in 0..w {
                let mut acc = [0.0f64; 3];
                for y in oy * factor..(oy + 1) * factor {
                    for x in ox * factor..(ox + 1) * factor {
                        let p = self.get(x, y);
                        for c in 0..3 {
                            acc[c] += p[c] as f64;
                        }
                    }
                }
                out.set(ox, oy, acc.map(|v| (v * norm) as f32));
            }
        }
        Ok(out)
    }

    /// Signed difference `a − b` (mean over the RGB channels) shown blue–white–red: white = 0,
    /// red where `a > b`, blue where `a < b`, full colour at ± the 99th percentile of |a − b|.
    /// The result is meant for [`Image::write_png`] with exposure 1.
    pub fn false_colour_diff(a: &Image, b: &Image) -> Result<Image, SceneError> {
        Self::false_colour_diff_with_range(a, b, None).map(|(img, _)| img)
    }

    /// [`Image::false_colour_diff`] with an explicit symmetric range (`Some(r)`: ±r maps to full
    /// blue/red, e.g. to give several views the same scale) or the automatic one (`None`). Returns
    /// the image and the range used.
    pub fn false_colour_diff_with_range(
        a: &Image,
        b: &Image,
        range: Option<f32>,
    ) -> Result<(Image, f32), SceneError> {
        if a.width != b.width || a.height != b.height {
            return Err(SceneError::Invalid {
                location: "difference image".into(),
                reason: format!(
                    "image sizes differ ({}×{} vs {}×{}); fix: compare images of the same \
                     resolution (downsample the larger one)",
                    a.width, a.height, b.width, b.height
                ),
            });
        }
        let diff: Vec<f32> = a
            .data
            .iter()
            .zip(&b.data)
            .map(|(p, q)| {
                let d = ((p[0] - q[0]) + (p[1] - q[1]) + (p[2] - q[2])) / 3.0;
                if d.is_finite() { d } else { 0.0 }
            })
            .collect();
        let range = match range {
            Some(r) if r.is_finite() && r > 0.0 => r,
            Some(r) => {
                return Err(SceneError::Invalid {
                    location: format!("difference range = {r}"),
                    reason: "must be > 0 and finite; fix: pass a positive range or none for \
                             automatic"
                        .into(),
                });
            }
            None => {
                let mut abs: Vec<f32> = diff.iter().map(|d| d.abs()).collect();
                let mut r = percentile(&mut abs, 0.99);
                if r <= 0.0 {
                    r = abs.iter().copied().fold(0.0, f32::max);
                }
                if r <= 0.0 { 1.0 } else { r }
            }
        };
        let mut out = Image::new(a.width, a.height);
        for (o, d) in out.data.iter_mut().zip(&diff) {
            let t = (d / range).clamp(-1.0, 1.0);
            *o = if t >= 0.0 {
                [1.0, 1.0 - t, 1.0 - t]
            } else {
                [1.0 + t, 1.0 + t, 1.0]
            };
        }
        Ok((out, range))
    }

    /// An exposure that maps the 99.5th percentile of the per-pixel maximum channel to 1 (1 for
    /// an all-black image). Used for previews.
    pub fn auto_exposure(&self) -> f32 {
        auto_exposure(std::slice::from_ref(self))
    }
}

/// One exposure shared by several images: maps the 99.5th percentile of the per-pixel maximum
/// channel over all of them to 1; 1 when they are all black.
pub fn auto_exposure(images: &[Image]) -> f32 {
    let mut v: Vec<f32> = images
        .iter()
        .flat_map(|im| im.data.iter().map(|p| p[0].max(p[1]).max(p[2])))
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if v.is_empty() {
        return 1.0;
    }
    let p = percentile(&mut v, 0.995);
    if p > 0.0 && p.is_finite() {
        1.0 / p
    } else {
        1.0
    }
}

/// The `q`-quantile (0..=1, nearest rank) of `values` (reordered in place); 0 for an empty slice.
fn percentile(values: &mut [f32], q: f64) -> f32 {
    if values.is_empty() {
        return 0.0;
    }
    let k = ((q * values.len() as f64).ceil() as usize).clamp(1, values.len()) - 1;
    let (_, v, _) = values.select_nth_unstable_by(k, f32::total_cmp);
    *v
}
