//! Decoding 8/16-bit photo files (PNG, JPEG) within a size limit, for photos and masks alike.

use std::path::Path;

use image::{DynamicImage, ImageReader};

use crate::SceneError;

/// Whether `path` names an 8/16-bit photo format (by its extension: PNG, JPEG).
pub fn is_photo_file(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
}

/// The most a photo's decoded pixels may take: 256 MiB, a 48-megapixel 8-bit RGB photo with
/// room to spare (its linear image then takes 4× that). A larger one is refused before it is
/// decoded, so that a damaged size field is an error and not gigabytes.
pub const PHOTO_MAX_BYTES: u64 = 256 << 20;

/// Decode a PNG or JPEG within [`PHOTO_MAX_BYTES`].
pub fn decode(path: &Path) -> Result<DynamicImage, SceneError> {
    let parse = |reason: String| SceneError::Parse {
        path: path.to_path_buf(),
        reason,
    };
    let mut reader = ImageReader::open(path)
        .map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .with_guessed_format()
        .map_err(|e| parse(format!("cannot read: {e}")))?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(PHOTO_MAX_BYTES);
    reader.limits(limits);
    reader.decode().map_err(|e| match e {
        image::ImageError::Limits(_) => parse(format!(
            "the image is larger than the {} MiB of pixels a view may take; fix: downscale the \
             photos (and their cameras' intrinsics) to a few megapixels",
            PHOTO_MAX_BYTES >> 20
        )),
        e => parse(format!(
            "cannot decode ({e}); fix: give a PNG (8/16-bit), a JPEG or a linear EXR"
        )),
    })
}
