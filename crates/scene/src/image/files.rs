//! Image files: EXR reading (channels looked up by name, f16/f32/u32 samples, any compression,
//! NaN/Inf rejected with the pixel named), atomic linear f32 EXR writing, and tone-mapped sRGB
//! PNG previews.

use std::io::Cursor;
use std::path::Path;

use super::{CHANNEL_NAMES, Image};
use crate::SceneError;
use crate::fsutil::{atomic_write, check_overwrite};

impl Image {
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
