//! Mesh file I/O: OBJ (tobj) and PLY (ply-rs-bw; ASCII and binary little/big endian, as Mitsuba
//! writes them: `x y z [nx ny nz] [s t]`, faces `vertex_indices` or `vertex_index`, list of
//! int/uint, polygons fan-triangulated).
//!
//! Readers never panic on bad input: every problem becomes a [`GeometryError`] naming the file and,
//! where there is one, the element (`face 3`, `vertex 17`, `property 'x'`). Loaded meshes go
//! through [`crate::mesh::validate`]. Writers write to a temporary file next to the target and
//! rename it into place, so a reader never sees a half-written file.
//!
//! This module holds the format dispatch of [`load_mesh`] and what the formats share (error
//! constructors, the panic guard around third-party parsers, the checks and atomic write of the
//! writers); `obj` and `ply` hold each format's reader and writer.

mod obj;
mod ply;

pub use obj::save_obj;
pub use ply::save_ply;

use obj::read_obj;
use ply::read_ply;

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::{Path, PathBuf};

use crate::{GeometryError, Mesh, MeshWarning};

/// Mesh file formats read by [`load_mesh`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// Stanford PLY (`.ply`), ASCII or binary.
    Ply,
}

impl MeshFormat {
    /// The format for a path's extension (case-insensitive), or `None` if it is not one we read.
    pub fn from_path(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "ply" => Some(MeshFormat::Ply),
            _ => None,
        }
    }
}

/// Read an OBJ or PLY file (by extension) and [`crate::mesh::validate`] it.
///
/// * `.obj` (case-insensitive): read with tobj, polygons triangulated, one index per vertex
///   (`single_index`), all objects/groups concatenated into one mesh; vertex normals kept when the
///   file has them (vertices without one get the area-weighted face normal). Materials are
///   ignored.
/// * `.ply`: ASCII, binary little endian or binary big endian. Element `vertex` with scalar
///   properties `x y z` (any numeric type, usually float or double) and optionally `nx ny nz`;
///   element `face` with a list property `vertex_indices` (or `vertex_index`) of any integer type.
///   Polygons with more than three corners are fan-triangulated `(v0, v_i, v_{i+1})`; faces with
///   fewer than three corners are an error naming the face. Other elements and properties
///   (texture coordinates, colours, edges, …) are skipped.
///
/// Returns the validated mesh and the warnings of [`crate::mesh::validate`].
pub fn load_mesh(path: &Path) -> Result<(Mesh, Vec<MeshWarning>), GeometryError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| GeometryError::UnsupportedFormat {
        path: path.to_path_buf(),
    })?;
    let file = File::open(path).map_err(|source| GeometryError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(GeometryError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a directory"),
        });
    }
    let mut reader = BufReader::new(file);
    let mut mesh = match format {
        MeshFormat::Obj => read_obj(&mut reader, path)?,
        MeshFormat::Ply => read_ply(&mut reader, path)?,
    };
    let warnings = crate::mesh::validate(&mut mesh, &path.display().to_string())?;
    Ok((mesh, warnings))
}

fn parse_error(path: &Path, format: &'static str, reason: impl Into<String>) -> GeometryError {
    GeometryError::Parse {
        path: path.to_path_buf(),
        format,
        reason: reason.into(),
    }
}

fn invalid(path: &Path, element: impl Into<String>, reason: impl Into<String>) -> GeometryError {
    GeometryError::Invalid {
        source_name: path.display().to_string(),
        element: element.into(),
        reason: reason.into(),
    }
}

/// Run a third-party parser so that a panic inside it (a bug triggered by hostile input) becomes
/// a parse error instead of taking the program down.
fn guard<T>(
    path: &Path,
    format: &'static str,
    f: impl FnOnce() -> Result<T, GeometryError>,
) -> Result<T, GeometryError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        Err(parse_error(
            path,
            format,
            format!("the {format} reader failed on this input ({what})"),
        ))
    })
}

// ---------------------------------------------------------------------------------------------
// Writers
// ---------------------------------------------------------------------------------------------

/// Check what a writer needs before creating any file.
fn check_writable(mesh: &Mesh, path: &Path) -> Result<(), GeometryError> {
    let n = mesh.positions.len();
    if let Some(normals) = &mesh.normals
        && normals.len() != n
    {
        return Err(invalid(
            path,
            "normals",
            format!("{} normals for {n} vertices; cannot write", normals.len()),
        ));
    }
    if let Some((f, &bad)) = mesh
        .indices
        .iter()
        .enumerate()
        .find_map(|(f, t)| t.iter().find(|&&i| i as usize >= n).map(|i| (f, i)))
    {
        return Err(invalid(
            path,
            format!("face {f}"),
            format!("vertex index {bad} is out of range ({n} vertices); cannot write"),
        ));
    }
    Ok(())
}

/// Write through `body` into a temporary file next to `path`, then rename it over `path`.
fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<(), GeometryError> {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let io_err = |source| GeometryError::Io {
        path: path.to_path_buf(),
        source,
    };
    let Some(name) = path.file_name() else {
        return Err(io_err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "the path has no file name",
        )));
    };
    let unique = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".{}.{unique}.tmp", std::process::id()));
    let tmp: PathBuf = path.with_file_name(tmp_name);

    let result = (|| {
        let file = File::options().write(true).create_new(true).open(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, file);
        body(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(io_err(e));
    }
    Ok(())
}
