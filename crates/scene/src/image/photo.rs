//! Photographs as measurements: 8/16-bit PNG and JPEG (or linear EXR) decoded to linear
//! radiance, with the pixels that measure nothing marked ([`PixelMask`]).
//!
//! A pixel value v ∈ [0, 1] (the code value over its full scale, 255 or 65535) becomes linear
//! radiance L = k · f⁻¹(v), where f is the stated transfer function and k the image's exposure
//! scale:
//! - sRGB (IEC 61966-2-1, the default for PNG and JPEG): f⁻¹(v) = v/12.92 for v ≤ 0.04045, else
//!   ((v + 0.055)/1.055)^2.4;
//! - linear: f⁻¹(v) = v (a RAW developed without a tone curve, or an EXR, which is always
//!   linear).
//!
//! A pixel leaves the measurement (its [`PixelMask`] bit is clear) where
//! - any of its colour channels is saturated: at full scale in an 8/16-bit file, or at or above
//!   the stated clipping level of an EXR (before the exposure scale);
//! - its alpha (PNG with alpha) is below half of full scale;
//! - a mask image's value there is below half of full scale ([`PixelMask::read`]).

use std::path::Path;

use image::DynamicImage;
use serde::{Deserialize, Serialize};

use super::Image;
use super::decode::{decode, is_photo_file};
use super::files::{Encoding, write_8bit};
use super::mask::PixelMask;
use crate::SceneError;

/// How a photo's code values map to linear radiance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Transfer {
    /// The sRGB curve (IEC 61966-2-1): what cameras and editors write to PNG and JPEG.
    Srgb,
    /// Linear code values (RAW developed without a tone curve; EXR).
    Linear,
}

impl Transfer {
    /// The name in files.
    pub fn name(self) -> &'static str {
        match self {
            Transfer::Srgb => "srgb",
            Transfer::Linear => "linear",
        }
    }
}

/// How to read one photo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotoSettings {
    /// The transfer function; `None`: sRGB for PNG and JPEG, linear for EXR.
    pub transfer: Option<Transfer>,
    /// The exposure scale k: linear radiance = k · f⁻¹(v).
    pub exposure: f32,
    /// An EXR's clipping level (raw values at or above it are saturated); `None`: none.
    pub saturation: Option<f32>,
}

impl Default for PhotoSettings {
    fn default() -> Self {
        PhotoSettings {
            transfer: None,
            exposure: 1.0,
            saturation: None,
        }
    }
}

/// A decoded photo: its linear image and the pixels that measure the object.
#[derive(Clone, Debug, PartialEq)]
pub struct Photo {
    pub image: Image,
    /// Clear where the pixel is saturated or transparent.
    pub measured: PixelMask,
    /// How many pixels are saturated.
    pub saturated: usize,
}

/// The sRGB decoding f⁻¹(v) of a value v ∈ [0, 1] (IEC 61966-2-1).
#[inline]
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

impl Photo {
    /// Read a photo (PNG, JPEG or EXR, by its extension) as linear radiance with its measured
    /// pixels. Errors name the file and the fix.
    pub fn read(path: &Path, settings: &PhotoSettings) -> Result<Photo, SceneError> {
        check_exposure(settings.exposure, path)?;
        if is_photo_file(path) {
            if settings.saturation.is_some() {
                return Err(invalid(
                    path,
                    "a clipping level is stated for an 8/16-bit photo, whose saturated pixels \
                     are those at full scale; fix: state the saturation only for EXR images",
                ));
            }
            return Ok(Self::from_decoded(
                &decode(path)?,
                settings.transfer.unwrap_or(Transfer::Srgb),
                settings.exposure,
            ));
        }
        if settings.transfer == Some(Transfer::Srgb) {
            return Err(invalid(
                path,
                "sRGB is stated for an EXR, whose values are linear; fix: state the transfer \
                 as linear (or leave it out) for EXR images",
            ));
        }
        let mut image = Image::read_exr(path)?;
        let mut measured = PixelMask::all(image.width, image.height);
        let mut saturated = 0;
        if let Some(level) = settings.saturation {
            if !(level.is_finite() && level > 0.0) {
                return Err(invalid(
                    path,
                    &format!("the clipping level {level} must be a positive number"),
                ));
            }
            for (i, p) in image.data.iter().enumerate() {
                if p.iter().any(|&v| v >= level) {
                    measured.bits[i] = false;
                    saturated += 1;
                }
            }
        }
        image.scale(settings.exposure);
        Ok(Photo {
            image,
            measured,
            saturated,
        })
    }

    /// A decoded 8/16-bit image as linear radiance (every format goes through 16 bits per
    /// channel: an 8-bit code c becomes 257·c, so full scale stays full scale).
    pub fn from_decoded(img: &DynamicImage, transfer: Transfer, exposure: f32) -> Photo {
        let has_alpha = img.color().has_alpha();
        let rgba = img.to_rgba16();
        let (w, h) = rgba.dimensions();
        let mut image = Image::new(w, h);
        let mut measured = PixelMask::all(w, h);
        let mut saturated = 0;
        let decode = |c: u16| {
            let v = c as f32 / 65535.0;
            exposure
                * match transfer {
                    Transfer::Srgb => srgb_to_linear(v),
                    Transfer::Linear => v,
                }
        };
        for (i, p) in rgba.pixels().enumerate() {
            let [r, g, b, a] = p.0;
            image.data[i] = [decode(r), decode(g), decode(b)];
            let clipped = [r, g, b].contains(&u16::MAX);
            saturated += clipped as usize;
            measured.bits[i] = !clipped && (!has_alpha || a >= 32768);
        }
        Photo {
            image,
            measured,
            saturated,
        }
    }
}

impl Image {
    /// Write a photo as a camera would: the linear values times `exposure`, clipped to [0, 1],
    /// sRGB-encoded to 8 bits, as a JPEG of `quality` (1–100); atomic, refusing to replace a file
    /// unless `overwrite`. Returns how many pixels it saturates (a channel at or above 1).
    pub fn write_jpeg(
        &self,
        path: &Path,
        exposure: f32,
        quality: u8,
        overwrite: bool,
    ) -> Result<usize, SceneError> {
        crate::fsutil::check_overwrite(path, overwrite)?;
        let bytes = self.srgb8(exposure);
        let saturated = self
            .data
            .iter()
            .filter(|p| p.iter().any(|&v| v * exposure >= 1.0))
            .count();
        let (size, color) = ((self.width, self.height), image::ExtendedColorType::Rgb8);
        write_8bit(
            path,
            &bytes,
            size,
            color,
            Encoding::Jpeg(quality),
            overwrite,
        )?;
        Ok(saturated)
    }
}

fn check_exposure(k: f32, path: &Path) -> Result<(), SceneError> {
    if k.is_finite() && k > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            path,
            &format!("the exposure scale {k} must be a positive number (1: as recorded)"),
        ))
    }
}

fn invalid(path: &Path, reason: &str) -> SceneError {
    SceneError::Invalid {
        location: path.display().to_string(),
        reason: reason.to_string(),
    }
}
