//! Which pixels of a view measure the object ([`PixelMask`]): a pixel whose bit is clear leaves
//! the measurement. Every renderer leaves such a pixel black, with zero derivatives, and the
//! target is zero there, so it adds nothing to any loss, gradient, interval or check: the loss
//! over a view is Σ over its measured pixels only.

use std::path::Path;

use super::Image;
use super::decode::{decode, is_photo_file};
use super::files::{Encoding, write_8bit};
use crate::SceneError;
use crate::fsutil::check_overwrite;
use image::ExtendedColorType;

/// One bit per pixel of a film, row-major, row 0 = top: set where the pixel measures the object.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PixelMask {
    pub width: u32,
    pub height: u32,
    pub bits: Vec<bool>,
}

impl PixelMask {
    /// Every pixel measured.
    pub fn all(width: u32, height: u32) -> Self {
        PixelMask {
            width,
            height,
            bits: vec![true; width as usize * height as usize],
        }
    }

    /// Whether pixel (x, y) is measured (false outside the film).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> bool {
        x < self.width
            && y < self.height
            && self.bits[y as usize * self.width as usize + x as usize]
    }

    /// How many pixels are measured.
    pub fn count(&self) -> usize {
        self.bits.iter().filter(|&&b| b).count()
    }

    /// Whether every pixel is measured.
    pub fn is_full(&self) -> bool {
        self.bits.iter().all(|&b| b)
    }

    /// The pixels measured in both.
    pub fn and(&self, other: &PixelMask) -> PixelMask {
        PixelMask {
            bits: self
                .bits
                .iter()
                .zip(&other.bits)
                .map(|(a, b)| *a && *b)
                .collect(),
            ..self.clone()
        }
    }

    /// A mask image (PNG, JPEG or EXR): a pixel is measured where the image's first channel is at
    /// least half of full scale (0.5 in an EXR) and, where it has alpha, its alpha too.
    pub fn read(path: &Path) -> Result<PixelMask, SceneError> {
        if is_photo_file(path) {
            let img = decode(path)?;
            let has_alpha = img.color().has_alpha();
            let rgba = img.to_rgba16();
            let (w, h) = rgba.dimensions();
            let bits = rgba
                .pixels()
                .map(|p| p.0[0] >= 32768 && (!has_alpha || p.0[3] >= 32768))
                .collect();
            return Ok(PixelMask {
                width: w,
                height: h,
                bits,
            });
        }
        let img = Image::read_exr(path)?;
        Ok(PixelMask {
            width: img.width,
            height: img.height,
            bits: img.data.iter().map(|p| p[0] >= 0.5).collect(),
        })
    }

    /// Write the mask as an 8-bit grey PNG (255 measured, 0 not), atomically.
    pub fn write_png(&self, path: &Path, overwrite: bool) -> Result<(), SceneError> {
        check_overwrite(path, overwrite)?;
        let bytes: Vec<u8> = self.bits.iter().map(|&b| if b { 255 } else { 0 }).collect();
        let size = (self.width, self.height);
        write_8bit(
            path,
            &bytes,
            size,
            ExtendedColorType::L8,
            Encoding::Png,
            overwrite,
        )
    }
}

impl Image {
    /// Zero every pixel the mask leaves out (the mask must have this image's size).
    pub fn apply_mask(&mut self, mask: &PixelMask) {
        debug_assert_eq!((mask.width, mask.height), (self.width, self.height));
        for (p, &m) in self.data.iter_mut().zip(&mask.bits) {
            if !m {
                *p = [0.0; 3];
            }
        }
    }
}
