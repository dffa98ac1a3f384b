//! Mesh file I/O: OBJ (tobj) and PLY (ply-rs-bw; ASCII and binary little/big endian, as Mitsuba
//! writes them: `x y z [nx ny nz] [s t]`, faces `vertex_indices` or `vertex_index`, list of
//! int/uint, polygons fan-triangulated).
//!
//! Readers never panic on bad input: every problem becomes a [`GeometryError`] naming the file and,
//! where there is one, the element (`face 3`, `vertex 17`, `property 'x'`). Loaded meshes go
//! through [`crate::mesh::validate`]. Writers write to a temporary file next to the target and
//! rename it into place, so a reader never sees a half-written file.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use glam::Vec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    BeginList, ElementDef, Encoding, Header, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};

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
// OBJ
// ---------------------------------------------------------------------------------------------

/// tobj's float type is f32 or f64 depending on a feature flag; accept both.
fn tobj_f32(x: impl Into<f64>) -> f32 {
    x.into() as f32
}

fn read_obj(reader: &mut impl BufRead, path: &Path) -> Result<Mesh, GeometryError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let models = guard(path, "OBJ", || {
        // Materials are irrelevant here: refuse to load any .mtl file.
        tobj::load_obj_buf(reader, &options, |_| Err(tobj::LoadError::GenericFailure))
            .map(|(models, _materials)| models)
            .map_err(|e| {
                let reason = match e {
                    tobj::LoadError::ReadError => {
                        "read error (I/O failure, or the file is not UTF-8 text)".to_string()
                    }
                    tobj::LoadError::FaceVertexOutOfBounds => {
                        "a face refers to a vertex that does not exist (index out of range)"
                            .to_string()
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

// ---------------------------------------------------------------------------------------------
// PLY
// ---------------------------------------------------------------------------------------------

/// One PLY vertex as read: position in f64 (PLY may store doubles), optional normal.
#[derive(Default)]
struct PlyVertex {
    p: [f64; 3],
    n: [f64; 3],
}

impl PlyVertex {
    fn set(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        let slot = match name {
            "x" => &mut self.p[0],
            "y" => &mut self.p[1],
            "z" => &mut self.p[2],
            "nx" => &mut self.n[0],
            "ny" => &mut self.n[1],
            "nz" => &mut self.n[2],
            _ => return PropertyAccessResult::Ignored,
        };
        *slot = v;
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        Self::default()
    }
    fn set_char(&mut self, name: &str, v: i8) -> PropertyAccessResult {
        self.set(name, f64::from(v))
    }
    fn set_uchar(&mut self, name: &str, v: u8) -> PropertyAccessResult {
        self.set(name, f64::from(v))
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.set(name, f64::from(v))
    }
    fn set_ushort(&mut self, name: &str, v: u16) -> PropertyAccessResult {
        self.set(name, f64::from(v))
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        self.set(name, f64::from(v))
    }
    fn set_uint(&mut self, name: &str, v: u32) -> PropertyAccessResult {
        self.set(name, f64::from(v))
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.set(name, f64::from(v))
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.set(name, v)
    }
}

/// One PLY face as read: its corner indices in whatever integer type the file uses.
#[derive(Default)]
enum FaceList {
    #[default]
    Missing,
    I32(Vec<i32>),
    U32(Vec<u32>),
    Wide(Vec<i64>),
}

#[derive(Default)]
struct PlyFace {
    list: FaceList,
}

fn is_face_list(name: &str) -> bool {
    name == "vertex_indices" || name == "vertex_index"
}

impl PlyFace {
    fn set_wide(&mut self, name: &str, v: impl Iterator<Item = i64>) -> PropertyAccessResult {
        if is_face_list(name) {
            self.list = FaceList::Wide(v.collect());
            PropertyAccessResult::Set
        } else {
            PropertyAccessResult::Ignored
        }
    }

    /// Corner indices, or the first offending value.
    fn corners(&self) -> Result<Vec<u32>, i64> {
        match &self.list {
            FaceList::Missing => Ok(Vec::new()),
            FaceList::U32(v) => Ok(v.clone()),
            FaceList::I32(v) => v
                .iter()
                .map(|&i| u32::try_from(i).map_err(|_| i64::from(i)))
                .collect(),
            FaceList::Wide(v) => v.iter().map(|&i| u32::try_from(i).map_err(|_| i)).collect(),
        }
    }
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        Self::default()
    }
    fn set_list_char(&mut self, name: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.set_wide(name, v.into_iter().map(i64::from))
    }
    fn set_list_uchar(&mut self, name: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.set_wide(name, v.into_iter().map(i64::from))
    }
    fn set_list_short(&mut self, name: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.set_wide(name, v.into_iter().map(i64::from))
    }
    fn set_list_ushort(&mut self, name: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.set_wide(name, v.into_iter().map(i64::from))
    }
    fn set_list_int(&mut self, name: &str, v: Vec<i32>) -> PropertyAccessResult {
        self.set_wide(name, v.into_iter().map(i64::from))
    }
    fn set_list_uint(&mut self, name: &str, v: Vec<u32>) -> PropertyAccessResult {
        self.set_wide(name, v.into_iter().map(i64::from))
    }
    // Fast paths for the common index types: the parser fills our vector directly.
    fn begin_list_int(&mut self, name: &str, _len: usize) -> BeginList<'_, i32> {
        if !is_face_list(name) {
            return BeginList::UseSetter;
        }
        self.list = FaceList::I32(Vec::new());
        match &mut self.list {
            FaceList::I32(v) => BeginList::Fill(v),
            _ => BeginList::UseSetter,
        }
    }
    fn begin_list_uint(&mut self, name: &str, _len: usize) -> BeginList<'_, u32> {
        if !is_face_list(name) {
            return BeginList::UseSetter;
        }
        self.list = FaceList::U32(Vec::new());
        match &mut self.list {
            FaceList::U32(v) => BeginList::Fill(v),
            _ => BeginList::UseSetter,
        }
    }
}

/// Skips the payload of elements we do not use.
struct PlyIgnore;

impl PropertyAccess for PlyIgnore {
    fn new() -> Self {
        PlyIgnore
    }
}

fn is_integer(t: &ScalarType) -> bool {
    !matches!(t, ScalarType::Float | ScalarType::Double)
}

/// What the header promises, checked before reading the payload.
struct PlyLayout {
    has_normals: bool,
}

fn check_ply_header(header: &Header, path: &Path) -> Result<PlyLayout, GeometryError> {
    let elements: Vec<&str> = header.elements.keys().map(String::as_str).collect();
    let Some(vertex) = header.elements.get("vertex") else {
        return Err(parse_error(
            path,
            "PLY",
            format!(
                "the header declares no 'vertex' element (elements: [{}])",
                elements.join(", ")
            ),
        ));
    };
    let Some(face) = header.elements.get("face") else {
        return Err(parse_error(
            path,
            "PLY",
            format!(
                "the header declares no 'face' element (elements: [{}]); point clouds are not \
                 supported, a mesh needs faces",
                elements.join(", ")
            ),
        ));
    };
    let scalar = |name: &str| -> Result<bool, GeometryError> {
        match vertex.properties.get(name).map(|p| &p.data_type) {
            None => Ok(false),
            Some(PropertyType::Scalar(_)) => Ok(true),
            Some(PropertyType::List(..)) => Err(parse_error(
                path,
                "PLY",
                format!("property '{name}' of element 'vertex' is a list, expected a number"),
            )),
        }
    };
    let missing: Vec<&str> = ["x", "y", "z"]
        .into_iter()
        .map(|n| scalar(n).map(|ok| (n, ok)))
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .filter(|(_, ok)| !ok)
        .map(|(n, _)| n)
        .collect();
    if !missing.is_empty() {
        let present: Vec<&str> = vertex.properties.keys().map(String::as_str).collect();
        return Err(parse_error(
            path,
            "PLY",
            format!(
                "element 'vertex' lacks the position propert{} {} (it has: [{}])",
                if missing.len() == 1 { "y" } else { "ies" },
                missing
                    .iter()
                    .map(|n| format!("'{n}'"))
                    .collect::<Vec<_>>()
                    .join(", "),
                present.join(", ")
            ),
        ));
    }
    let normal_flags = [scalar("nx")?, scalar("ny")?, scalar("nz")?];
    let has_normals = normal_flags.iter().all(|&b| b);
    if !has_normals && normal_flags.iter().any(|&b| b) {
        tracing::warn!(
            "{}: element 'vertex' has only some of nx, ny, nz; ignoring the normals",
            path.display()
        );
    }
    let list = ["vertex_indices", "vertex_index"]
        .iter()
        .find_map(|n| face.properties.get(*n));
    match list.map(|p| (&p.name, &p.data_type)) {
        None => {
            let present: Vec<&str> = face.properties.keys().map(String::as_str).collect();
            return Err(parse_error(
                path,
                "PLY",
                format!(
                    "element 'face' has no list property 'vertex_indices' (or 'vertex_index') \
                     (it has: [{}])",
                    present.join(", ")
                ),
            ));
        }
        Some((name, PropertyType::List(_, item))) if !is_integer(item) => {
            return Err(parse_error(
                path,
                "PLY",
                format!(
                    "property '{name}' of element 'face' is a list of {item:?}, expected an \
                     integer type"
                ),
            ));
        }
        Some((name, PropertyType::Scalar(_))) => {
            return Err(parse_error(
                path,
                "PLY",
                format!("property '{name}' of element 'face' is a scalar, expected a list"),
            ));
        }
        Some(_) => {}
    }
    Ok(PlyLayout { has_normals })
}

fn read_ply<R: BufRead>(reader: R, path: &Path) -> Result<Mesh, GeometryError> {
    guard(path, "PLY", || read_ply_inner(reader, path))
}

fn read_ply_inner<R: BufRead>(reader: R, path: &Path) -> Result<Mesh, GeometryError> {
    let ply_err = |e: ply_rs_bw::parser::ParseError| {
        parse_error(path, "PLY", e.to_string().replace("\n\t", "; "))
    };
    let mut reader = Reader::new(reader);
    let header = Parser::<PlyIgnore>::new()
        .read_header(&mut reader)
        .map_err(ply_err)?;
    let layout = check_ply_header(&header, path)?;

    let mut vertices: Vec<PlyVertex> = Vec::new();
    let mut faces: Vec<PlyFace> = Vec::new();
    for element in header.elements.values() {
        let with_context = |e: ply_rs_bw::parser::ParseError| {
            let encoding = match header.encoding {
                Encoding::Ascii => "ASCII",
                Encoding::BinaryBigEndian => "binary big-endian",
                Encoding::BinaryLittleEndian => "binary little-endian",
            };
            parse_error(
                path,
                "PLY",
                format!(
                    "{encoding} payload of element '{}' ({} declared): {} (is the file truncated?)",
                    element.name,
                    element.count,
                    e.to_string().replace("\n\t", "; ")
                ),
            )
        };
        match element.name.as_str() {
            "vertex" => {
                vertices = read_element(&mut reader, element, &header).map_err(with_context)?
            }
            "face" => faces = read_element(&mut reader, element, &header).map_err(with_context)?,
            _ => {
                // Skip, but still consume the bytes.
                read_element::<PlyIgnore, _>(&mut reader, element, &header)
                    .map_err(with_context)?;
            }
        }
    }

    let n_vertices = vertices.len();
    if n_vertices > u32::MAX as usize {
        return Err(parse_error(path, "PLY", "more than 2³² vertices"));
    }
    let mut mesh = Mesh {
        positions: Vec::with_capacity(n_vertices),
        normals: None,
        indices: Vec::with_capacity(faces.len()),
    };
    // Positions are converted to f32; a finite double too large for f32 becomes infinite and is
    // reported by `validate` with its vertex index.
    mesh.positions.extend(
        vertices
            .iter()
            .map(|v| Vec3::new(v.p[0] as f32, v.p[1] as f32, v.p[2] as f32)),
    );
    if layout.has_normals {
        mesh.normals = Some(
            vertices
                .iter()
                .map(|v| Vec3::new(v.n[0] as f32, v.n[1] as f32, v.n[2] as f32))
                .collect(),
        );
    }
    for (f, face) in faces.iter().enumerate() {
        let corners = face.corners().map_err(|bad| {
            invalid(
                path,
                format!("face {f}"),
                format!("vertex index {bad} is negative or too large"),
            )
        })?;
        if corners.len() < 3 {
            return Err(invalid(
                path,
                format!("face {f}"),
                format!(
                    "has {} vertex ind{}, a face needs at least 3",
                    corners.len(),
                    if corners.len() == 1 { "ex" } else { "ices" }
                ),
            ));
        }
        if let Some(&bad) = corners.iter().find(|&&i| i as usize >= n_vertices) {
            return Err(invalid(
                path,
                format!("face {f}"),
                format!(
                    "vertex index {bad} is out of range (the file has {n_vertices} vertices, \
                     valid indices are 0..{n_vertices})"
                ),
            ));
        }
        // Fan triangulation (v0, v_i, v_{i+1}), exact for convex polygons.
        for i in 1..corners.len() - 1 {
            mesh.indices.push([corners[0], corners[i], corners[i + 1]]);
        }
    }
    Ok(mesh)
}

fn read_element<E: PropertyAccess, R: BufRead>(
    reader: &mut Reader<R>,
    element: &ElementDef,
    header: &Header,
) -> Result<Vec<E>, ply_rs_bw::parser::ParseError> {
    Parser::<E>::new().read_payload_for_element(reader, element, header)
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

/// Write a binary little-endian PLY (float x y z [nx ny nz], uchar/int faces).
///
/// Header: `element vertex N` with `property float x|y|z` (and `nx ny nz` when the mesh has
/// normals), `element face F` with `property list uchar int vertex_indices`. The file is written
/// to a temporary file in the same directory and renamed into place (atomic on POSIX).
pub fn save_ply(mesh: &Mesh, path: &Path) -> Result<(), GeometryError> {
    check_writable(mesh, path)?;
    if mesh.positions.len() > i32::MAX as usize {
        return Err(invalid(
            path,
            "mesh",
            "more than 2³¹ − 1 vertices do not fit PLY 'int' indices",
        ));
    }
    write_atomic(path, |w| {
        let mut header = String::new();
        header.push_str("ply\nformat binary_little_endian 1.0\n");
        header.push_str("comment written by translucent (triangles CCW seen from outside)\n");
        header.push_str(&format!("element vertex {}\n", mesh.positions.len()));
        header.push_str("property float x\nproperty float y\nproperty float z\n");
        if mesh.normals.is_some() {
            header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
        }
        header.push_str(&format!("element face {}\n", mesh.indices.len()));
        header.push_str("property list uchar int vertex_indices\nend_header\n");
        w.write_all(header.as_bytes())?;
        for (i, p) in mesh.positions.iter().enumerate() {
            for c in p.to_array() {
                w.write_all(&c.to_le_bytes())?;
            }
            if let Some(normals) = &mesh.normals {
                for c in normals[i].to_array() {
                    w.write_all(&c.to_le_bytes())?;
                }
            }
        }
        for t in &mesh.indices {
            w.write_all(&[3u8])?;
            for &i in t {
                // Checked above: every index < positions.len() ≤ i32::MAX.
                w.write_all(&(i as i32).to_le_bytes())?;
            }
        }
        Ok(())
    })
}

/// Write a Wavefront OBJ (v, vn, f).
///
/// Coordinates use Rust's shortest round-trip formatting, so reading the file back gives the same
/// f32 values. With normals, faces are written `f a//a b//b c//c` (1-based). Written to a
/// temporary file and renamed into place, like [`save_ply`].
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
