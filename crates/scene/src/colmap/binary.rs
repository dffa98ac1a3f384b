//! COLMAP's binary format (little-endian): `cameras.bin` (u64 count; per camera i32 id, i32
//! model id, u64 width, u64 height, f64 parameters) and `images.bin` (u64 count; per image
//! u32 id, f64 q_w q_x q_y q_z, f64 t_x t_y t_z, u32 camera id, the name NUL-terminated, u64
//! point count, per point f64 x, f64 y, i64 3D point id).

use std::collections::BTreeMap;
use std::path::Path;

use super::{ColmapCamera, ColmapImage, MODELS, checked_camera};
use crate::SceneError;

/// A cursor over a file's bytes that names the file and the offset in its errors.
struct Bytes<'a> {
    path: &'a Path,
    data: Vec<u8>,
    at: usize,
}

impl<'a> Bytes<'a> {
    fn open(path: &'a Path) -> Result<Self, SceneError> {
        let data = std::fs::read(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(Bytes { path, data, at: 0 })
    }

    fn err(&self, reason: String) -> SceneError {
        SceneError::Invalid {
            location: format!("{} (byte {})", self.path.display(), self.at),
            reason,
        }
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N], SceneError> {
        let end = self.at.checked_add(N).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(self.err(format!(
                "the file ends inside {what}; fix: re-export the model (it is truncated)"
            )));
        };
        let b = self.data[self.at..end].try_into().expect("N bytes");
        self.at = end;
        Ok(b)
    }

    fn u32(&mut self, what: &str) -> Result<u32, SceneError> {
        self.take::<4>(what).map(u32::from_le_bytes)
    }

    fn u64(&mut self, what: &str) -> Result<u64, SceneError> {
        self.take::<8>(what).map(u64::from_le_bytes)
    }

    fn f64(&mut self, what: &str) -> Result<f64, SceneError> {
        self.take::<8>(what).map(f64::from_le_bytes)
    }

    /// A count of records of at least `size` bytes each, checked against what is left.
    fn count(&mut self, what: &str, size: usize) -> Result<usize, SceneError> {
        let n = self.u64(what)?;
        let left = (self.data.len() - self.at) / size.max(1);
        usize::try_from(n)
            .ok()
            .filter(|&n| n <= left)
            .ok_or_else(|| self.err(format!("{what} = {n} does not fit in the file's size")))
    }

    /// A NUL-terminated UTF-8 string.
    fn name(&mut self) -> Result<String, SceneError> {
        let rest = &self.data[self.at..];
        let Some(len) = rest.iter().position(|&b| b == 0) else {
            return Err(self.err("an image name has no terminating NUL byte".into()));
        };
        let s = std::str::from_utf8(&rest[..len])
            .map_err(|_| self.err("an image name is not UTF-8".into()))?
            .to_string();
        self.at += len + 1;
        Ok(s)
    }
}

/// The cameras of `cameras.bin`, by id.
pub(super) fn cameras(path: &Path) -> Result<BTreeMap<u32, ColmapCamera>, SceneError> {
    let mut b = Bytes::open(path)?;
    let n = b.count("the number of cameras", 24)?;
    let mut out = BTreeMap::new();
    for _ in 0..n {
        let at = format!("{} (byte {})", path.display(), b.at);
        let id = b.u32("a camera id")?;
        let model_id = b.u32("a camera model id")?;
        let (width, height) = (b.u64("a width")?, b.u64("a height")?);
        let Some((model, k)) = MODELS.get(model_id as usize) else {
            return Err(b.err(format!(
                "camera model id {model_id} is not one of COLMAP's (0…{})",
                MODELS.len() - 1
            )));
        };
        let params = (0..*k)
            .map(|_| b.f64("a camera parameter"))
            .collect::<Result<Vec<_>, _>>()?;
        let cam = checked_camera(&at, model.to_string(), width, height, params)?;
        if out.insert(id, cam).is_some() {
            return Err(b.err(format!("camera {id} is defined twice")));
        }
    }
    Ok(out)
}

/// The images of `images.bin`, in the file's order.
pub(super) fn images(path: &Path) -> Result<Vec<ColmapImage>, SceneError> {
    let mut b = Bytes::open(path)?;
    let n = b.count("the number of images", 73)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let id = b.u32("an image id")?;
        let mut q = [0.0; 4];
        for v in &mut q {
            *v = b.f64("a rotation")?;
        }
        let mut t = [0.0; 3];
        for v in &mut t {
            *v = b.f64("a translation")?;
        }
        let camera_id = b.u32("a camera id")?;
        let name = b.name()?;
        let points = b.count("the number of 2D points", 24)?;
        b.at += 24 * points;
        out.push(ColmapImage {
            id,
            q,
            t,
            camera_id,
            name,
        });
    }
    Ok(out)
}
