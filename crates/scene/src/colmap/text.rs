//! COLMAP's text format: `cameras.txt` (CAMERA_ID MODEL WIDTH HEIGHT PARAMS…, one line per
//! camera) and `images.txt` (two lines per image: IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME,
//! then the image's 2D points, which are not needed). `#` starts a comment line.

use std::collections::BTreeMap;
use std::path::Path;

use super::{ColmapCamera, ColmapImage, checked_camera};
use crate::SceneError;

/// The file's text, or an error naming it.
fn read(path: &Path) -> Result<String, SceneError> {
    std::fs::read_to_string(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// `what` of line `n` of `path` parsed, or an error naming the line and the field.
fn field<T: std::str::FromStr>(
    path: &Path,
    n: usize,
    what: &str,
    word: Option<&str>,
) -> Result<T, SceneError> {
    let word = word.ok_or_else(|| SceneError::Invalid {
        location: format!("{}:{n}", path.display()),
        reason: format!("{what} is missing; fix: write the line as COLMAP does"),
    })?;
    word.parse().map_err(|_| SceneError::Invalid {
        location: format!("{}:{n}", path.display()),
        reason: format!("{what} {word:?} is not a number of the right kind"),
    })
}

/// The cameras of `cameras.txt`, by id.
pub(super) fn cameras(path: &Path) -> Result<BTreeMap<u32, ColmapCamera>, SceneError> {
    let text = read(path)?;
    let mut out = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let n = i + 1;
        let mut w = line.split_whitespace();
        let id: u32 = field(path, n, "CAMERA_ID", w.next())?;
        let model = w.next().unwrap_or_default().to_string();
        let width: u64 = field(path, n, "WIDTH", w.next())?;
        let height: u64 = field(path, n, "HEIGHT", w.next())?;
        let params = w
            .map(|p| field(path, n, "a parameter", Some(p)))
            .collect::<Result<Vec<f64>, _>>()?;
        let at = format!("{}:{n}", path.display());
        let cam = checked_camera(&at, model, width, height, params)?;
        if out.insert(id, cam).is_some() {
            return Err(SceneError::Invalid {
                location: at,
                reason: format!("camera {id} is defined twice"),
            });
        }
    }
    Ok(out)
}

/// The images of `images.txt`, in the file's order.
pub(super) fn images(path: &Path) -> Result<Vec<ColmapImage>, SceneError> {
    let text = read(path)?;
    let mut out = Vec::new();
    // Each image is a pose line followed by its points line (which may be empty).
    let mut points_line_next = false;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with('#') {
            continue;
        }
        if points_line_next {
            points_line_next = false;
            continue;
        }
        if line.trim().is_empty() {
            continue;
        }
        let n = i + 1;
        let mut w = line.split_whitespace();
        let id: u32 = field(path, n, "IMAGE_ID", w.next())?;
        let mut q = [0.0; 4];
        for (k, name) in ["QW", "QX", "QY", "QZ"].iter().enumerate() {
            q[k] = field(path, n, name, w.next())?;
        }
        let mut t = [0.0; 3];
        for (k, name) in ["TX", "TY", "TZ"].iter().enumerate() {
            t[k] = field(path, n, name, w.next())?;
        }
        let camera_id: u32 = field(path, n, "CAMERA_ID", w.next())?;
        // A name may hold spaces: the rest of the line.
        let name = w.collect::<Vec<_>>().join(" ");
        if name.is_empty() {
            return Err(SceneError::Invalid {
                location: format!("{}:{n}", path.display()),
                reason: "NAME is missing; fix: write the line as COLMAP does".into(),
            });
        }
        out.push(ColmapImage {
            id,
            q,
            t,
            camera_id,
            name,
        });
        points_line_next = true;
    }
    Ok(out)
}
