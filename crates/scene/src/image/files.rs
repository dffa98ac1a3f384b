//! Image files: EXR reading (channels looked up by name, f16/f32/u32 samples, any compression,
//! declared sizes checked against the file before decoding, decoder panics turned into errors,
//! NaN/Inf rejected with the pixel named), atomic linear f32 EXR writing, and tone-mapped sRGB
//! PNG previews.

use std::io::Cursor;

use image::ExtendedColorType::{self, Rgb8};
use std::path::Path;

use super::{CHANNEL_NAMES, Image};
use crate::SceneError;
use crate::fsutil::{atomic_write, check_overwrite};

impl Image {
    /// Read an EXR (channels looked up by name R, G, B; f16/f32; any compression). Errors name the
    /// file and say which channel is missing; NaN/Inf pixels are an error naming the first pixel.
    ///
    /// Before any pixel is decoded, the sizes the headers declare are checked against what the
    /// file can hold ([`check_exr_size`]), so that a damaged size field is an error and not an
    /// allocation of gigabytes; a panic inside the decoder is an error naming the file.
    pub fn read_exr(path: &Path) -> Result<Image, SceneError> {
        use exr::prelude::Vec2;
        let file = decode_exr(path)?;
        let (layer, idx, grey) = rgb_layer(&file, path)?;
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
        check_overwrite(path, overwrite)?;
        self.check_size(path)?;
        let (w, h) = (self.width, self.height);
        write_8bit(
            path,
            &self.srgb8(exposure),
            (w, h),
            Rgb8,
            Encoding::Png,
            overwrite,
        )
    }

    /// The pixels as 8-bit sRGB: clip(exposure · value), sRGB OETF, R, G, B per pixel.
    pub(super) fn srgb8(&self, exposure: f32) -> Vec<u8> {
        self.data
            .iter()
            .flat_map(|p| p.map(|v| to_srgb8(v * exposure)))
            .collect()
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

/// No lossless EXR compression packs more than this many bytes of samples into one byte of file
/// (deflate, used by ZIP and ZIPS, reaches about 1032:1; RLE 64:1; PIZ and PXR24 less).
const EXR_MAX_EXPANSION: u64 = 1032;
/// Decoded bytes allowed whatever the file's size (small files, lossy codecs).
const EXR_MIN_BUDGET: u64 = 64 << 20;

/// Checks that the layers an EXR's headers declare fit in what the file can hold: the decoded
/// samples of all layers (each channel at its own sampling rate and sample size) plus the
/// 12 bytes per pixel of the [`Image`] made from them, and each layer's block (a tile or a
/// group of scan lines, which the decoder reserves per chunk), at most
/// max([`EXR_MIN_BUDGET`], [`EXR_MAX_EXPANSION`] × file size). A header whose data window was
/// damaged to 60000 × 60000 pixels is then an error naming the layer and its size, instead of
/// an attempt to allocate tens of gigabytes before the missing data is noticed.
pub fn check_exr_size(
    meta: &exr::meta::MetaData,
    file_len: u64,
    path: &Path,
) -> Result<(), SceneError> {
    let budget = EXR_MIN_BUDGET.max(EXR_MAX_EXPANSION.saturating_mul(file_len));
    let mut total: u64 = 0;
    for (i, header) in meta.headers.iter().enumerate() {
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        let pixels = (w as u64).saturating_mul(h as u64);
        let mut bytes = pixels.saturating_mul(12);
        for c in &header.channels.list {
            let (sx, sy) = (c.sampling.x().max(1), c.sampling.y().max(1));
            let samples = ((w / sx) as u64).saturating_mul((h / sy) as u64);
            bytes = bytes
                .saturating_add(samples.saturating_mul(c.sample_type.bytes_per_sample() as u64));
        }
        // The decoder reserves up to one block's bytes (a tile, or a group of scan lines) for
        // each chunk it reads, before it knows whether the file holds them.
        let bytes_per_pixel: u64 = header
            .channels
            .list
            .iter()
            .map(|c| c.sample_type.bytes_per_sample() as u64)
            .sum();
        let block_pixels = match header.blocks {
            exr::meta::BlockDescription::Tiles(t) => {
                (t.tile_size.width() as u64).saturating_mul(t.tile_size.height() as u64)
            }
            exr::meta::BlockDescription::ScanLines => {
                (header.compression.scan_lines_per_block() as u64).saturating_mul(w as u64)
            }
        };
        let block = block_pixels.saturating_mul(bytes_per_pixel);
        if block > budget {
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                reason: format!(
                    "layer {i} declares blocks of {block} bytes ({block_pixels} pixels of \
                     {bytes_per_pixel} bytes), more than a file of {file_len} bytes can hold; \
                     fix: the header is damaged, write the image again"
                ),
            });
        }
        total = total.saturating_add(bytes);
        if total > budget {
            let name = layer_name(&header.own_attributes)
                .map(|n| format!(" '{n}'"))
                .unwrap_or_default();
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                reason: format!(
                    "layer {i}{name} declares {w}×{h} pixels in {} channel(s), {total} bytes \
                     decoded, more than a file of {file_len} bytes can hold; fix: the header is \
                     damaged or the file truncated, write the image again",
                    header.channels.list.len()
                ),
            });
        }
    }
    Ok(())
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

/// A decoded EXR file: flat samples of every channel of every layer.
type ExrFile =
    exr::image::Image<exr::image::Layers<exr::image::AnyChannels<exr::image::FlatSamples>>>;
/// One layer of an [`ExrFile`].
type ExrLayer = exr::image::Layer<exr::image::AnyChannels<exr::image::FlatSamples>>;

/// The EXR's layers, decoded sequentially after [`check_exr_size`]; errors and decoder panics
/// are errors naming `path`.
fn decode_exr(path: &Path) -> Result<ExrFile, SceneError> {
    use exr::prelude::{ReadChannels, ReadLayers};
    let exr_err = |e: exr::error::Error| match e {
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
    };
    let file_len = std::fs::metadata(path)
        .map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    // The decoder asserts its own invariants, and some of those a damaged file can break
    // (a tile of a mip level in an image without levels trips a debug assertion): a panic
    // inside it is an error about this file, not a crash.
    let decoded = std::panic::catch_unwind(|| {
        let meta = exr::meta::MetaData::read_from_file(path, false).map_err(exr_err)?;
        check_exr_size(&meta, file_len, path)?;
        // `read_all_flat_layers_from_file` with sequential decompression: the parallel
        // decoder runs on a thread pool whose panics abort the process, out of reach of
        // this guard.
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .non_parallel()
            .from_file(path)
            .map_err(exr_err)
    });
    let file = decoded.unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        Err(SceneError::Parse {
            path: path.to_path_buf(),
            reason: format!(
                "the OpenEXR decoder failed on this file ({what}); the file is damaged, \
                 write the image again"
            ),
        })
    })?;
    Ok(file)
}

/// A layer's name, if it has one.
fn layer_name(attributes: &exr::meta::header::LayerAttributes) -> Option<String> {
    attributes.layer_name.as_ref().map(|n| n.to_string())
}

/// The first layer with channels R, G, B (their indices), else the first with a luminance
/// channel Y (`grey`); an error naming the channels found otherwise.
fn rgb_layer<'f>(
    file: &'f ExrFile,
    path: &Path,
) -> Result<(&'f ExrLayer, [usize; 3], bool), SceneError> {
    let find = |layer: &ExrLayer, name: &str| {
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
            let prefix = layer_name(&layer.attributes)
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
    Ok((layer, idx, grey))
}

/// An 8-bit file format images and masks are written in.
#[derive(Clone, Copy, Debug)]
pub(super) enum Encoding {
    Png,
    /// JPEG of this quality, 1–100.
    Jpeg(u8),
}

/// Encodes 8-bit pixels (`color`: RGB or grey) of a `size` = (width, height) image as `format`
/// and writes them to `path` atomically, refusing to replace a file unless `overwrite`.
pub(super) fn write_8bit(
    path: &Path,
    bytes: &[u8],
    size: (u32, u32),
    color: ExtendedColorType,
    format: Encoding,
    overwrite: bool,
) -> Result<(), SceneError> {
    use image::ImageEncoder;
    let mut buf = Vec::new();
    let (w, h) = size;
    let (result, name) = match format {
        Encoding::Png => (
            image::codecs::png::PngEncoder::new(&mut buf).write_image(bytes, w, h, color),
            "PNG",
        ),
        Encoding::Jpeg(q) => (
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, q.clamp(1, 100))
                .write_image(bytes, w, h, color),
            "JPEG",
        ),
    };
    result.map_err(|e| SceneError::Parse {
        path: path.to_path_buf(),
        reason: format!("cannot encode {name}: {e}"),
    })?;
    atomic_write(path, &buf, overwrite)
}
