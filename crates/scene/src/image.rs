//! RGB float images: linear f32 EXR (the data format) and tone-mapped sRGB PNG previews.
//!
//! SKELETON: helper H3 owns this file.

use std::path::Path;

use crate::SceneError;

/// A linear RGB float image, row-major, row 0 = top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub data: Vec<[f32; 3]>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image { width, height, data: vec![[0.0; 3]; (width * height) as usize] }
    }
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.data[(y * self.width + x) as usize]
    }
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, v: [f32; 3]) {
        self.data[(y * self.width + x) as usize] = v;
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
    /// Read an EXR (channels looked up by name R, G, B; f16/f32; any compression). Errors name the
    /// file and say which channel is missing; NaN/Inf pixels are an error naming the first pixel.
    pub fn read_exr(path: &Path) -> Result<Image, SceneError> {
        todo!()
    }
    /// Write a linear f32 RGB EXR atomically (temp file + rename). Refuses to overwrite an
    /// existing file unless `overwrite`.
    pub fn write_exr(&self, path: &Path, overwrite: bool) -> Result<(), SceneError> {
        todo!()
    }
    /// Write an sRGB PNG preview: clip(exposure · value), sRGB OETF, 8 bit.
    pub fn write_png(&self, path: &Path, exposure: f32, overwrite: bool) -> Result<(), SceneError> {
        todo!()
    }
}
