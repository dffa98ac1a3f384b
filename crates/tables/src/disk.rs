//! Tables simulated at run time, kept on disk between processes. A medium other than the shipped
//! one (g = 0, η = 1) costs a simulation of its exit and incidence tables (and at g ≠ 0 its
//! curvature table) at the first render of each run: 35.6 s on 2 cores at η 1.4, 103 s at g 0.3
//! behind a rough surface (docs/notes/test-time.md). The same medium in the next run, or in
//! another process, reads them back instead.
//!
//! Where: `$TRANSLUCENT_CACHE_DIR/tables` if that variable is set (set and empty: nothing is
//! kept), else `$XDG_CACHE_HOME/translucent/tables`, else `$HOME/.cache/translucent/tables`.
//! A file is named by the table's kind, its settings (g, η, roughness, walks or collisions, seed) and the
//! fingerprint of the code that simulates it (a hash of this crate's and the base crate's
//! sources, made at build time), so a file is only ever read by a build that would simulate
//! the same numbers: what is read back equals, bit for bit, what the simulation gives. A file
//! that does not read, or whose settings differ, is simulated again and replaced; a folder that
//! cannot be written leaves the table in memory only. Files are written whole (a temporary
//! file, then a rename), so processes running side by side never read half a table.

use std::path::{Path, PathBuf};

use crate::curvature::{CurvatureSettings, CurvatureTable};
use crate::exit::ExitTableSettings;
use crate::table::{TableFile, WalkTable};

/// The fingerprint of the simulating code (build.rs).
const SOURCE_HASH: &str = env!("TABLES_SOURCE_HASH");

/// The folder the tables are kept in (module docs), or `None` where nothing is kept.
pub fn folder() -> Option<PathBuf> {
    let env = |k: &str| std::env::var_os(k);
    if let Some(d) = env("TRANSLUCENT_CACHE_DIR") {
        return (!d.is_empty()).then(|| PathBuf::from(d).join("tables"));
    }
    let base = env("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            env("HOME")
                .filter(|d| !d.is_empty())
                .map(|h| PathBuf::from(h).join(".cache"))
        })?;
    Some(base.join("translucent").join("tables"))
}

/// A table that can be kept: it records the settings it was simulated with.
pub(crate) trait Kept: TableFile + serde::Serialize {
    type Settings: PartialEq + Copy;
    /// The settings the table records.
    fn kept_settings(&self) -> &Self::Settings;
    /// Simulate the table.
    fn simulate_kept(s: Self::Settings) -> Self;
    /// The settings in the file's name (every one of them).
    fn stem(s: &Self::Settings) -> String;
}

impl<T: WalkTable> Kept for T {
    type Settings = ExitTableSettings;
    fn kept_settings(&self) -> &ExitTableSettings {
        self.settings()
    }
    fn simulate_kept(s: ExitTableSettings) -> Self {
        T::simulate(s)
    }
    fn stem(s: &ExitTableSettings) -> String {
        format!(
            "g{}-eta{}-r{}-w{}-s{}",
            s.g, s.eta, s.roughness, s.walks, s.seed
        )
    }
}

impl Kept for CurvatureTable {
    type Settings = CurvatureSettings;
    fn kept_settings(&self) -> &CurvatureSettings {
        &self.settings
    }
    fn simulate_kept(s: CurvatureSettings) -> Self {
        CurvatureTable::generate(s)
    }
    fn stem(s: &CurvatureSettings) -> String {
        format!("g{}-c{}-s{}", s.g, s.collisions, s.seed)
    }
}

/// The file of a table of kind `T` with settings `s`.
pub(crate) fn file_name<T: Kept>(s: &T::Settings) -> String {
    format!("{}-{}-{SOURCE_HASH}.json", T::KIND, T::stem(s))
}

/// The table with settings `s`: read from `folder` when a file of this build holds it, else
/// simulated and written there (module docs).
pub(crate) fn load_or_simulate<T: Kept>(folder: Option<&Path>, s: T::Settings) -> T {
    let Some(folder) = folder else {
        return T::simulate_kept(s);
    };
    let path = folder.join(file_name::<T>(&s));
    let name = path.display().to_string();
    let read = std::fs::read_to_string(&path)
        .ok()
        .and_then(|text| T::from_json(&text, &name).ok())
        .filter(|t| *t.kept_settings() == s);
    if let Some(t) = read {
        return t;
    }
    let t = T::simulate_kept(s);
    // A folder that cannot be written only costs the next process the simulation.
    let _ = write(folder, &path, &t);
    t
}

/// Writes `t` to `path` whole: a temporary file in `folder`, then a rename.
fn write<T: serde::Serialize>(folder: &Path, path: &Path, t: &T) -> std::io::Result<()> {
    std::fs::create_dir_all(folder)?;
    let text = serde_json::to_string(t).map_err(std::io::Error::other)?;
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let tmp = folder.join(format!(
        ".{}.{}-{nanos}.tmp",
        path.file_name().and_then(|n| n.to_str()).unwrap_or("table"),
        std::process::id()
    ));
    std::fs::write(&tmp, text)?;
    std::fs::rename(&tmp, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exit::ExitTable;
    use crate::incidence::IncidenceTable;

    fn settings() -> ExitTableSettings {
        ExitTableSettings {
            g: 0.3,
            eta: 1.4,
            roughness: 0.1,
            walks: 64,
            seed: 0,
        }
    }

    /// The first process simulates and writes; the next reads the file back, the same table bit
    /// for bit; and what it returns is the file's (an edited value comes back edited).
    #[test]
    fn a_kept_table_reads_back_as_simulated() {
        let dir = tempfile::tempdir().unwrap();
        let s = settings();
        let first: ExitTable = load_or_simulate(Some(dir.path()), s);
        let path = dir.path().join(file_name::<ExitTable>(&s));
        assert!(path.is_file(), "{}", path.display());
        assert_eq!(load_or_simulate::<ExitTable>(Some(dir.path()), s), first);
        assert_eq!(ExitTable::simulate(s), first);
        let mut edited = first.clone();
        edited.f[0] *= 0.5;
        std::fs::write(&path, serde_json::to_string(&edited).unwrap()).unwrap();
        assert_eq!(load_or_simulate::<ExitTable>(Some(dir.path()), s), edited);
        // No temporary file is left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().collect();
        assert_eq!(names.len(), 1, "{names:?}");
    }

    /// A damaged file, or one holding another medium's table under this name, is simulated again
    /// and replaced; a folder that cannot be written still gives the table.
    #[test]
    fn a_damaged_or_foreign_file_is_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let s = settings();
        let path = dir.path().join(file_name::<IncidenceTable>(&s));
        let truth = IncidenceTable::simulate(s);
        std::fs::write(&path, "{\"settings\": ").unwrap();
        assert_eq!(
            load_or_simulate::<IncidenceTable>(Some(dir.path()), s),
            truth
        );
        let other = IncidenceTable::simulate(ExitTableSettings { g: 0.5, ..s });
        std::fs::write(&path, serde_json::to_string(&other).unwrap()).unwrap();
        assert_eq!(
            load_or_simulate::<IncidenceTable>(Some(dir.path()), s),
            truth
        );
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(IncidenceTable::from_json(&text, "kept").unwrap(), truth);
        let blocked = dir.path().join("a-file");
        std::fs::write(&blocked, "").unwrap();
        assert_eq!(load_or_simulate::<IncidenceTable>(Some(&blocked), s), truth);
    }

    /// The name holds every setting and the code's fingerprint.
    #[test]
    fn the_name_says_what_the_table_is() {
        let name = file_name::<ExitTable>(&settings());
        assert_eq!(
            name,
            format!("exit-g0.3-eta1.4-r0.1-w64-s0-{SOURCE_HASH}.json")
        );
        let c = CurvatureSettings {
            g: 0.6,
            collisions: 1000,
            seed: 0,
        };
        assert_eq!(
            file_name::<CurvatureTable>(&c),
            format!("curvature-g0.6-c1000-s0-{SOURCE_HASH}.json")
        );
        assert_eq!(SOURCE_HASH.len(), 16);
    }
}
