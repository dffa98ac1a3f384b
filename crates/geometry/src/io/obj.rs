//! Wavefront OBJ: the reader (through tobj) and the writer [`save_obj`].

use std::io::{BufRead, Write};
use std::path::Path;

use glam::Vec3;

use super::{check_writable, guard, invalid, parse_error, write_atomic};
use crate::{GeometryError, Mesh};

/// tobj's float type is f32 or f64 depending on a feature flag; accept both.
fn tobj_f32(x: impl Into<f64>) -> f32 {
    x.into() as f32
}

/// The elements face corners index, in the order of a corner `v/vt/vn`.
const CORNER_PARTS: [(&str, &str, &str); 3] = [
    ("v", "vertex", "vertices"),
    ("vt", "texture coordinate", "texture coordinates"),
    ("vn", "normal", "normals"),
];

/// Checks every face corner index of an OBJ text before tobj resolves it: index 0, a relative
/// (negative) index reaching before the first element, and a vertex index past the file's
/// vertices are errors naming the line. tobj computes `3·index` unchecked: a normal index of
/// 6148914691236517207 wrapped around to a small offset, so a damaged file read silently with
/// another vertex's normal (and an overflow panic in builds with overflow checks). Texture
/// coordinate and normal indices are checked only when the file has such elements (tobj ignores
/// them otherwise); tokens that are not integers are left to tobj's own error.
fn check_face_indices(text: &str, path: &Path) -> Result<(), GeometryError> {
    let mut totals = [0usize; 3];
    for line in text.lines() {
        if let Some(k) = line
            .split_whitespace()
            .next()
            .and_then(|t| CORNER_PARTS.iter().position(|(tag, ..)| *tag == t))
        {
            totals[k] += 1;
        }
    }
    let mut so_far = [0usize; 3];
    for (n, line) in text.lines().enumerate() {
        let mut tokens = line.split_whitespace();
        let tag = tokens.next();
        if let Some(k) = tag.and_then(|t| CORNER_PARTS.iter().position(|(tag, ..)| *tag == t)) {
            so_far[k] += 1;
            continue;
        }
        if tag != Some("f") {
            continue;
        }
        for corner in tokens {
            for (k, part) in corner.split('/').enumerate().take(3) {
                let Ok(i) = part.parse::<i64>() else {
                    continue;
                };
                let (_, what, whats) = CORNER_PARTS[k];
                if k > 0 && totals[k] == 0 {
                    continue;
                }
                let problem = if i == 0 {
                    Some(format!("{what} index 0 (OBJ indices start at 1)"))
                } else if i < 0 && i.unsigned_abs() > so_far[k] as u64 {
                    Some(format!(
                        "relative {what} index {i} reaches before the first {what} ({} so far)",
                        so_far[k]
                    ))
                } else if i > 0 && i as u64 > totals[k] as u64 {
                    Some(format!(
                        "{what} index {i} is out of range (the file has {} {})",
                        totals[k],
                        if totals[k] == 1 { what } else { whats }
                    ))
                } else {
                    None
                };
                if let Some(p) = problem {
                    return Err(parse_error(path, "OBJ", format!("line {}: {p}", n + 1)));
                }
            }
        }
    }
    Ok(())
}

pub(super) fn read_obj(reader: &mut impl BufRead, path: &Path) -> Result<Mesh, GeometryError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|source| GeometryError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    // Text that is not UTF-8 is left to tobj, which reports it.
    if let Ok(text) = std::str::from_utf8(&bytes) {
        check_face_indices(text, path)?;
    }
    let mut reader = bytes.as_slice();
    let models = guard(path, "OBJ", || {
        // Materials are irrelevant here: refuse to load any .mtl file.
        tobj::load_obj_buf(&mut reader, &options, |_| {
            Err(tobj::LoadError::GenericFailure)
        })
        .map(|(models, _materials)| models)
        .map_err(|e| {
            let reason = match e {
                tobj::LoadError::ReadError => {
                    "read error (I/O failure, or the file is not UTF-8 text)".to_string()
                }
                tobj::LoadError::FaceVertexOutOfBounds => {
                    "a face refers to a vertex that does not exist (index out of range)".to_string()
                }
                other => other.to_string(),
            };
            parse_error(path, "OBJ", reason)
        })
    })?;

    let mut mesh = Mesh::default();
    // Per vertex: was a normal given in the file?
    let mut normals: Vec<Option<Vec3>> = Vec::new();
    let mut any_normals = false;
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len();
        let count = m.positions.len() / 3;
        if base + count > u32::MAX as usize {
            return Err(parse_error(path, "OBJ", "more than 2³² vertices"));
        }
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(tobj_f32(p[0]), tobj_f32(p[1]), tobj_f32(p[2]))),
        );
        let has_normals = !m.normals.is_empty() && m.normals.len() == m.positions.len();
        if has_normals {
            any_normals = true;
            normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|n| Some(Vec3::new(tobj_f32(n[0]), tobj_f32(n[1]), tobj_f32(n[2])))),
            );
        } else {
            if !m.normals.is_empty() {
                tracing::warn!(
                    "{}: object '{}': only some vertices have normals; using face normals there",
                    path.display(),
                    model.name
                );
            }
            normals.extend(std::iter::repeat_n(None, count));
        }
        for (f, tri) in m.indices.chunks(3).enumerate() {
            if tri.len() != 3 {
                return Err(invalid(
                    path,
                    format!("object '{}', face {f}", model.name),
                    "has fewer than 3 vertices after triangulation",
                ));
            }
            // tobj has checked the indices against its own vertex arrays.
            mesh.indices.push([
                tri[0] + base as u32,
                tri[1] + base as u32,
                tri[2] + base as u32,
            ]);
        }
    }
    if any_normals {
        let computed = if normals.iter().any(Option::is_none) {
            mesh.compute_vertex_normals()
        } else {
            Vec::new()
        };
        mesh.normals = Some(
            normals
                .iter()
                .enumerate()
                .map(|(i, n)| n.unwrap_or_else(|| computed[i]))
                .collect(),
        );
    }
    Ok(mesh)
}

/// Write a Wavefront OBJ (v, vn, f).
///
/// Coordinates use Rust's shortest round-trip formatting, so reading the file back gives the same
/// f32 values. With normals, faces are written `f a//a b//b c//c` (1-based). Written to a
/// temporary file and renamed into place, like [`save_ply`](super::save_ply).
pub fn save_obj(mesh: &Mesh, path: &Path) -> Result<(), GeometryError> {
    check_writable(mesh, path)?;
    write_atomic(path, |w| {
        writeln!(
            w,
            "# written by translucent (triangles CCW seen from outside)"
        )?;
        writeln!(
            w,
            "# {} vertices, {} triangles",
            mesh.positions.len(),
            mesh.indices.len()
        )?;
        for p in &mesh.positions {
            writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
        }
        if let Some(normals) = &mesh.normals {
            for n in normals {
                writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
            }
        }
        for t in &mesh.indices {
            let [a, b, c] = t.map(|i| u64::from(i) + 1);
            if mesh.normals.is_some() {
                writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?;
            } else {
                writeln!(w, "f {a} {b} {c}")?;
            }
        }
        Ok(())
    })
}
