//! Small file-system helpers: the overwrite policy, atomic writes (temp file + rename) and the
//! lock that keeps two runs out of one output folder.

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

/// The name of the lock file [`lock_folder`] keeps in an output folder.
pub const LOCK_FILE: &str = ".translucent.lock";

/// An output folder claimed by this process until the value is dropped ([`lock_folder`]).
#[derive(Debug)]
pub struct FolderLock {
    _file: std::fs::File,
}

/// Claim the output folder `dir` (created if needed) for one run: `dir/.translucent.lock` is
/// locked with the operating system's advisory file lock (`flock` on Unix, `LockFileEx` on
/// Windows) and holds the owner's process id. A second run on the same folder, in this process
/// or another, gets [`SceneError::Busy`] naming the owner. The lock goes with its process, so a
/// run that crashed or was killed (`kill -9`) leaves the file behind but never a stuck lock.
pub fn lock_folder(dir: &Path) -> Result<FolderLock, SceneError> {
    let (file, path) = open_lock_file(dir)?;
    match file.try_lock() {
        Ok(()) => claimed(file, &path),
        Err(std::fs::TryLockError::WouldBlock) => {
            let owner = std::fs::read_to_string(&path).unwrap_or_default();
            Err(SceneError::Busy {
                dir: dir.to_path_buf(),
                owner: owner.trim().to_string(),
            })
        }
        Err(std::fs::TryLockError::Error(source)) => Err(SceneError::Io { path, source }),
    }
}

/// [`lock_folder`], waiting while another process (or another claim in this one) holds the
/// folder, instead of failing with [`SceneError::Busy`]: for inputs that several jobs make or
/// read in turn.
pub fn lock_folder_waiting(dir: &Path) -> Result<FolderLock, SceneError> {
    let (file, path) = open_lock_file(dir)?;
    file.lock().map_err(|source| SceneError::Io {
        path: path.clone(),
        source,
    })?;
    claimed(file, &path)
}

/// `dir` (created if needed) and its lock file, opened.
fn open_lock_file(dir: &Path) -> Result<(std::fs::File, std::path::PathBuf), SceneError> {
    std::fs::create_dir_all(dir).map_err(|source| SceneError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(|source| SceneError::Io {
            path: path.clone(),
            source,
        })?;
    Ok((file, path))
}

/// A lock file just locked by this process: it now holds our process id.
fn claimed(mut file: std::fs::File, path: &Path) -> Result<FolderLock, SceneError> {
    let io = |source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    };
    file.set_len(0).map_err(io)?;
    write!(file, "{}", std::process::id()).map_err(io)?;
    file.flush().map_err(io)?;
    Ok(FolderLock { _file: file })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_locked_folder_refuses_a_second_claim_until_released() {
        let d = tempfile::tempdir().unwrap();
        let dir = d.path().join("run");
        let first = lock_folder(&dir).unwrap();
        let second = lock_folder(&dir).unwrap_err();
        let msg = second.to_string();
        assert!(matches!(second, SceneError::Busy { .. }), "{msg}");
        assert!(msg.contains(&std::process::id().to_string()), "{msg}");
        assert!(msg.contains("run"), "{msg}");
        drop(first);
        let _again = lock_folder(&dir).unwrap();
        assert!(dir.join(LOCK_FILE).exists());
    }

    /// The waiting claim gets the folder once its holder lets go (here: another thread).
    #[test]
    fn a_waiting_claim_gets_the_folder_when_it_is_released() {
        let d = tempfile::tempdir().unwrap();
        let dir = d.path().join("shared");
        let first = lock_folder(&dir).unwrap();
        let waiter = {
            let dir = dir.clone();
            std::thread::spawn(move || lock_folder_waiting(&dir).map(|_| ()))
        };
        std::thread::sleep(std::time::Duration::from_millis(50));
        assert!(
            !waiter.is_finished(),
            "the claim waits while the folder is held"
        );
        drop(first);
        waiter.join().unwrap().unwrap();
        let _free = lock_folder(&dir).unwrap();
    }
}
