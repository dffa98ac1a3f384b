//! Mesh file I/O: OBJ (tobj) and PLY (ply-rs-bw; ASCII and binary little/big endian, as Mitsuba
//! writes them: `x y z [nx ny nz] [s t]`, faces `vertex_indices` or `vertex_index`, list of
//! int/uint, polygons fan-triangulated).
//!
//! SKELETON: helper H1 owns this file.

use std::path::Path;

use crate::{GeometryError, Mesh, MeshWarning};

/// Read an OBJ or PLY file (by extension) and [`crate::mesh::validate`] it.
pub fn load_mesh(path: &Path) -> Result<(Mesh, Vec<MeshWarning>), GeometryError> {
    todo!()
}

/// Write a binary little-endian PLY (float x y z [nx ny nz], uchar/int faces).
pub fn save_ply(mesh: &Mesh, path: &Path) -> Result<(), GeometryError> {
    todo!()
}

/// Write a Wavefront OBJ (v, vn, f).
pub fn save_obj(mesh: &Mesh, path: &Path) -> Result<(), GeometryError> {
    todo!()
}
