//! Small file-system helpers: the overwrite policy and atomic writes (temp file + rename).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::SceneError;

/// `Exists` error if `path` exists and `overwrite` is false.
pub fn check_overwrite(path: &Path, overwrite: bool) -> Result<(), SceneError> {
    if !overwrite && path.exists() {
        return Err(SceneError::Exists {
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

/// Write `bytes` to `path` through a temporary file in the same folder, renamed into place, so a
/// reader never sees a half-written file. Refuses to replace an existing file unless `overwrite`.
pub fn atomic_write(path: &Path, bytes: &[u8], overwrite: bool) -> Result<(), SceneError> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    check_overwrite(path, overwrite)?;
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| SceneError::Io { path: p, source }
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if name.is_empty() {
        return Err(SceneError::Invalid {
            location: path.display().to_string(),
            reason: "not a file path; fix: give a file name".into(),
        });
    }
    let tmp = dir.join(format!(
        ".{name}.tmp-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp).map_err(io(&tmp))?;
        f.write_all(bytes).map_err(io(&tmp))?;
        f.sync_all().map_err(io(&tmp))?;
        drop(f);
        // Re-check just before the rename: the window for a race is as small as we can make it.
        check_overwrite(path, overwrite)?;
        std::fs::rename(&tmp, path).map_err(io(path))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}
