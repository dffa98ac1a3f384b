//! The fingerprint of the code that simulates the tables: a hash of this crate's sources and
//! data and of the base crate's (the walks' phase function, Fresnel and microfacet code), so
//! that a table kept on disk ([`tables::disk`]) by another build of different code is never
//! read back as this build's.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let dirs = [
        root.join("src"),
        root.join("data"),
        root.join("../base/src"),
    ];
    let mut paths = Vec::new();
    for d in &dirs {
        println!("cargo:rerun-if-changed={}", d.display());
        files(d, &mut paths);
    }
    paths.sort();
    // FNV-1a over each file's path (relative to the crate) and bytes.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for p in &paths {
        let rel = p.strip_prefix(&root).unwrap_or(p);
        eat(rel.to_string_lossy().as_bytes());
        eat(&std::fs::read(p).unwrap_or_default());
    }
    println!("cargo:rustc-env=TABLES_SOURCE_HASH={h:016x}");
}
