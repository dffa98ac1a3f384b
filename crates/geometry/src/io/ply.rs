//! Stanford PLY: the reader (through ply-rs-bw; ASCII and binary little/big endian, as Mitsuba
//! writes them) and the binary little-endian writer [`save_ply`].

use std::io::{BufRead, Write};
use std::path::Path;

use glam::Vec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    BeginList, ElementDef, Encoding, Header, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};

use super::{check_writable, guard, invalid, parse_error, write_atomic};
use crate::{GeometryError, Mesh};

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

pub(super) fn read_ply<R: BufRead>(reader: R, path: &Path) -> Result<Mesh, GeometryError> {
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
