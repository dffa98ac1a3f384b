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

use std::io::Cursor;
use std::path::Path;

use crate::SceneError;
use crate::fsutil::{atomic_write, check_overwrite};

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

    /// Read an EXR (channels looked up by name R, G, B; f16/f32; any compression). Errors name the
    /// file and say which channel is missing; NaN/Inf pixels are an error naming the first pixel.
    pub fn read_exr(path: &Path) -> Result<Image, SceneError> {
        use exr::prelude::{AnyChannels, FlatSamples, Layer, Vec2};
        let file = exr::prelude::read_all_flat_layers_from_file(path).map_err(|e| match e {
            exr::error::Error::Io(source) => SceneError::Io {
                path: path.to_path_buf(),
                source,
            },
            other => SceneError::Parse {
                path: path.to_path_buf(),
                reason: format!(
                    "not a readable OpenEXR file ({other}); fix: write the image as a linear RGB \
                     OpenEXR (e.g. Mitsuba's default film output)"
                ),
            },
        })?;
        let find = |layer: &Layer<AnyChannels<FlatSamples>>, name: &str| {
            layer
                .channel_data
                .list
                .iter()
                .position(|c| c.name.to_string() == name)
        };
        // First layer with R, G, B; otherwise the first with a luminance channel Y.
        let mut chosen = None;
        for layer in &file.layer_data {
            let idx: Vec<Option<usize>> = CHANNEL_NAMES.iter().map(|n| find(layer, n)).collect();
            if idx.iter().all(Option::is_some) {
                chosen = Some((
                    layer,
                    [idx[0].unwrap(), idx[1].unwrap(), idx[2].unwrap()],
                    false,
                ));
                break;
            }
        }
        if chosen.is_none() {
            for layer in &file.layer_data {
                if let Some(y) = find(layer, "Y") {
                    chosen = Some((layer, [y, y, y], true));
                    break;
                }
            }
        }
        let Some((layer, idx, grey)) = chosen else {
            let mut names: Vec<String> = Vec::new();
            for layer in &file.layer_data {
                let prefix = layer
                    .attributes
                    .layer_name
                    .as_ref()
                    .map(|n| format!("{n}/"))
                    .unwrap_or_default();
                for c in &layer.channel_data.list {
                    names.push(format!("{prefix}{}", c.name));
                }
            }
            let missing: Vec<&str> = CHANNEL_NAMES
                .iter()
                .copied()
                .filter(|n| !names.iter().any(|m| m == n))
                .collect();
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                reason: format!(
                    "no channel(s) named {} (channels found: {}); fix: write the image with \
                     channels R, G, B",
                    missing.join(", "),
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            });
        };
        let (w, h) = (layer.size.width(), layer.size.height());
        let (Ok(wu), Ok(hu)) = (u32::try_from(w), u32::try_from(h)) else {
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                reason: format!("image of {w}×{h} pixels is too large"),
            });
        };
        let mut img = Image::new(wu, hu);
        for (c, &ci) in idx.iter().enumerate() {
            let ch = &layer.channel_data.list[ci];
            if ch.sampling != Vec2(1, 1) || ch.sample_data.len() != w * h {
                return Err(SceneError::Parse {
                    path: path.to_path_buf(),
                    reason: format!(
                        "channel {} is subsampled ({:?}); fix: write full-resolution channels",
                        ch.name, ch.sampling
                    ),
                });
            }
            for (i, v) in ch.sample_data.values_as_f32().enumerate() {
                img.data[i][c] = v;
            }
        }
        if let Some((x, y, c)) = img.first_non_finite() {
            let name = if grey { "Y" } else { CHANNEL_NAMES[c] };
            return Err(SceneError::Invalid {
                location: format!("{}: pixel (x={x}, y={y}) channel {name}", path.display()),
                reason: format!(
                    "value is {} (images must be finite); fix: re-render the image or repair \
                     that pixel",
                    img.get(x, y)[c]
                ),
            });
        }
        Ok(img)
    }

    /// Write a linear f32 RGB EXR atomically (temp file + rename). Refuses to overwrite an
    /// existing file unless `overwrite`.
    pub fn write_exr(&self, path: &Path, overwrite: bool) -> Result<(), SceneError> {
        use exr::prelude::{
            AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec,
            WritableImage,
        };
        check_overwrite(path, overwrite)?;
        self.check_size(path)?;
        let chan = |c: usize| {
            AnyChannel::new(
                CHANNEL_NAMES[c],
                FlatSamples::F32(self.data.iter().map(|p| p[c]).collect()),
            )
        };
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![chan(0), chan(1), chan(2)]));
        let layer = Layer::new(
            (self.width as usize, self.height as usize),
            LayerAttributes::default(),
            Encoding::SMALL_LOSSLESS,
            channels,
        );
        let mut buf = Cursor::new(Vec::new());
        exr::prelude::Image::from_layer(layer)
            .write()
            .to_buffered(&mut buf)
            .map_err(|e| SceneError::Parse {
                path: path.to_path_buf(),
                reason: format!("cannot encode EXR: {e}"),
            })?;
        atomic_write(path, buf.get_ref(), overwrite)
    }

    /// Write an sRGB PNG preview: clip(exposure · value), sRGB OETF, 8 bit.
    pub fn write_png(&self, path: &Path, exposure: f32, overwrite: bool) -> Result<(), SceneError> {
        use image::ImageEncoder;
        check_overwrite(path, overwrite)?;
        self.check_size(path)?;
        let bytes: Vec<u8> = self
            .data
            .iter()
            .flat_map(|p| p.map(|v| to_srgb8(v * exposure)))
            .collect();
        let mut buf = Vec::new();
        image::codecs::png::PngEncoder::new(&mut buf)
            .write_image(
                &bytes,
                self.width,
                self.height,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|e| SceneError::Parse {
                path: path.to_path_buf(),
                reason: format!("cannot encode PNG: {e}"),
            })?;
        atomic_write(path, &buf, overwrite)
    }

    fn check_size(&self, path: &Path) -> Result<(), SceneError> {
        if self.width == 0
            || self.height == 0
            || self.data.len() != self.width as usize * self.height as usize
        {
            return Err(SceneError::Invalid {
                location: format!("{}: image", path.display()),
                reason: format!(
                    "cannot write a {}×{} image holding {} pixels; fix: width and height must be \
                     > 0 and match the pixel data",
                    self.width,
                    self.height,
                    self.data.len()
                ),
            });
        }
        Ok(())
    }
}

/// Linear value → 8-bit sRGB (clamped to [0, 1] first; NaN → 0).
pub fn to_srgb8(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round().clamp(0.0, 255.0) as u8
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

#[cfg(test)]
#[allow(clippy::excessive_precision, clippy::type_complexity)] // numbers copied verbatim from Mitsuba's scene.json
mod tests {
    use super::*;
    use exr::prelude::{
        AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec,
        WritableImage, f16,
    };

    fn ramp(w: u32, h: u32) -> Image {
        let mut img = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                img.set(
                    x,
                    y,
                    [
                        x as f32 * 0.1 + 0.01,
                        y as f32 * 0.2 + 0.02,
                        (x * y) as f32 * 0.3 + 1e-5,
                    ],
                );
            }
        }
        img
    }

    fn write_channels(path: &Path, w: usize, h: usize, channels: Vec<AnyChannel<FlatSamples>>) {
        let layer = Layer::new(
            (w, h),
            LayerAttributes::default(),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(channels)),
        );
        exr::prelude::Image::from_layer(layer)
            .write()
            .to_file(path)
            .unwrap();
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        let img = ramp(7, 5);
        img.write_exr(&p, false).unwrap();
        assert_eq!(Image::read_exr(&p).unwrap(), img);
        // No temporary files left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn exr_channels_are_found_by_name() {
        // Channels stored as A, B, G, R, Z (the crate sorts by name); G in f16, B in f32, R in f32.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("order.exr");
        let (w, h) = (3usize, 2usize);
        let n = w * h;
        let r: Vec<f32> = (0..n).map(|i| 1.0 + i as f32).collect();
        let g: Vec<f16> = (0..n).map(|i| f16::from_f32(100.0 + i as f32)).collect();
        let b: Vec<f32> = (0..n).map(|i| 1000.0 + i as f32).collect();
        write_channels(
            &p,
            w,
            h,
            vec![
                AnyChannel::new("Z", FlatSamples::F32(vec![-5.0; n])),
                AnyChannel::new("R", FlatSamples::F32(r)),
                AnyChannel::new("A", FlatSamples::F32(vec![1.0; n])),
                AnyChannel::new("G", FlatSamples::F16(g)),
                AnyChannel::new("B", FlatSamples::F32(b)),
            ],
        );
        let img = Image::read_exr(&p).unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.get(0, 0), [1.0, 100.0, 1000.0]);
        assert_eq!(img.get(2, 1), [6.0, 105.0, 1005.0]); // row-major, row 0 first
    }

    #[test]
    fn exr_luminance_only_is_grey_and_missing_channels_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("y.exr");
        write_channels(
            &p,
            2,
            2,
            vec![AnyChannel::new(
                "Y",
                FlatSamples::F32(vec![0.5, 1.0, 1.5, 2.0]),
            )],
        );
        let img = Image::read_exr(&p).unwrap();
        assert_eq!(img.get(1, 1), [2.0; 3]);

        let p = dir.path().join("rg.exr");
        write_channels(
            &p,
            1,
            1,
            vec![
                AnyChannel::new("R", FlatSamples::F32(vec![1.0])),
                AnyChannel::new("G", FlatSamples::F32(vec![1.0])),
            ],
        );
        let msg = Image::read_exr(&p).unwrap_err().to_string();
        assert!(
            msg.contains("rg.exr")
                && msg.contains("no channel(s) named B")
                && msg.contains("found: G, R"),
            "{msg}"
        );
    }

    #[test]
    fn exr_nan_pixel_is_rejected_with_its_position() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("nan.exr");
        let mut img = ramp(4, 3);
        img.set(2, 1, [0.0, f32::NAN, 0.0]);
        img.write_exr(&p, false).unwrap();
        let msg = Image::read_exr(&p).unwrap_err().to_string();
        assert!(
            msg.contains("nan.exr") && msg.contains("pixel (x=2, y=1) channel G"),
            "{msg}"
        );
        img.set(2, 1, [0.0, 0.0, f32::INFINITY]);
        img.write_exr(&p, true).unwrap();
        let msg = Image::read_exr(&p).unwrap_err().to_string();
        assert!(
            msg.contains("pixel (x=2, y=1) channel B") && msg.contains("inf"),
            "{msg}"
        );
    }

    #[test]
    fn exr_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.exr");
        assert!(
            Image::read_exr(&missing)
                .unwrap_err()
                .to_string()
                .contains("missing.exr")
        );
        let junk = dir.path().join("junk.exr");
        std::fs::write(&junk, b"definitely not an exr").unwrap();
        let msg = Image::read_exr(&junk).unwrap_err().to_string();
        assert!(msg.contains("junk.exr") && msg.contains("OpenEXR"), "{msg}");
    }

    #[test]
    fn overwrite_is_refused_unless_asked() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        ramp(2, 2).write_exr(&p, false).unwrap();
        let err = ramp(3, 3).write_exr(&p, false).unwrap_err();
        assert!(matches!(err, SceneError::Exists { .. }), "{err}");
        assert!(err.to_string().contains("a.exr") && err.to_string().contains("--overwrite"));
        assert_eq!(
            Image::read_exr(&p).unwrap().width,
            2,
            "the file is untouched"
        );
        ramp(3, 3).write_exr(&p, true).unwrap();
        assert_eq!(Image::read_exr(&p).unwrap().width, 3);
        let q = dir.path().join("a.png");
        ramp(2, 2).write_png(&q, 1.0, false).unwrap();
        assert!(matches!(
            ramp(2, 2).write_png(&q, 1.0, false),
            Err(SceneError::Exists { .. })
        ));
        ramp(2, 2).write_png(&q, 1.0, true).unwrap();
    }

    #[test]
    fn png_preview_is_exposed_clamped_srgb() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("p.png");
        let mut img = Image::new(2, 1);
        img.set(0, 0, [0.25, 0.0, 2.0]);
        img.set(1, 0, [f32::NAN, -1.0, 0.001]);
        img.write_png(&p, 2.0, false).unwrap();
        let png = image::ImageReader::open(&p)
            .unwrap()
            .decode()
            .unwrap()
            .to_rgb8();
        assert_eq!(png.dimensions(), (2, 1));
        // 0.25·2 = 0.5 → sRGB 0.7354 → 188; 2·2 clamps to 255; 0.002 → 12.92·0.002·255 = 6.6 → 7.
        assert_eq!(png.get_pixel(0, 0).0, [188, 0, 255]);
        assert_eq!(png.get_pixel(1, 0).0, [0, 0, 7]);
        assert!(
            Image::new(0, 0)
                .write_png(&dir.path().join("e.png"), 1.0, false)
                .is_err()
        );
    }

    #[test]
    fn downsample_and_scale() {
        let img = ramp(5, 4);
        let d = img.downsample(2).unwrap();
        assert_eq!((d.width, d.height), (2, 2));
        let expect = |x: u32, y: u32, c: usize| {
            (0..2)
                .flat_map(|j| (0..2).map(move |i| (i, j)))
                .map(|(i, j)| img.get(2 * x + i, 2 * y + j)[c] as f64)
                .sum::<f64>()
                / 4.0
        };
        for (x, y, c) in [(0, 0, 0), (1, 1, 2), (1, 0, 1)] {
            assert!((d.get(x, y)[c] as f64 - expect(x, y, c)).abs() < 1e-6);
        }
        assert_eq!(img.downsample(1).unwrap(), img);
        assert!(img.downsample(0).is_err());
        assert!(img.downsample(5).is_err());
        let s = img.scaled(2.0);
        assert_eq!(s.get(3, 2)[0], 2.0 * img.get(3, 2)[0]);
        let mut t = img.clone();
        t.scale(0.5);
        assert_eq!(t.mean()[1], 0.5 * img.mean()[1]);
    }

    #[test]
    fn false_colour_diff_is_blue_white_red() {
        let a = Image::new(10, 10);
        let mut b = Image::new(10, 10);
        // b − a: one large outlier, the rest in ±0.1.
        for i in 0..100u32 {
            let v = if i < 50 { 0.1 } else { -0.05 };
            b.set(i % 10, i / 10, [v; 3]);
        }
        b.set(9, 9, [100.0; 3]);
        let (d, range) = Image::false_colour_diff_with_range(&a, &b, None).unwrap();
        assert!(
            (range - 0.1).abs() < 1e-6,
            "99th percentile, not the outlier: {range}"
        );
        // a − b = −0.1 → full blue; +0.05 → half red; outlier clamped.
        assert_eq!(d.get(0, 0), [0.0, 0.0, 1.0]);
        let half = d.get(0, 5);
        assert!(
            (half[0] - 1.0).abs() < 1e-6
                && (half[1] - 0.5).abs() < 1e-6
                && (half[2] - 0.5).abs() < 1e-6
        );
        assert_eq!(d.get(9, 9), [0.0, 0.0, 1.0]);
        assert_eq!(
            Image::false_colour_diff(&a, &a).unwrap().get(3, 3),
            [1.0; 3]
        );
        assert!(
            Image::false_colour_diff(&a, &Image::new(2, 2))
                .unwrap_err()
                .to_string()
                .contains("sizes differ")
        );
    }

    #[test]
    fn srgb_oetf_endpoints() {
        assert_eq!(to_srgb8(0.0), 0);
        assert_eq!(to_srgb8(1.0), 255);
        assert_eq!(to_srgb8(0.5), 188);
        assert_eq!(to_srgb8(f32::NAN), 0);
        let mut im = Image::new(10, 1);
        im.set(0, 0, [4.0, 0.0, 0.0]);
        assert!((im.auto_exposure() - 0.25).abs() < 1e-6);
        assert_eq!(Image::new(3, 3).auto_exposure(), 1.0);
    }
}
