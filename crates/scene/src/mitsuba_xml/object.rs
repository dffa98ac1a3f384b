//! The translucent object of a Mitsuba 3 scene: its mesh shape (placed by `to_world`), its
//! boundary (`null`, `dielectric`, GGX `roughdielectric`: η = int_ior/ext_ior and the roughness)
//! and its `homogeneous` interior medium with its phase function.

use std::path::Path;

use glam::DMat4;
use roxmltree::Node;

use super::values::Doc;
use super::{elements, plugin_type, props, unknown};
use crate::scene_file::desc::MeshSource;
use crate::{Medium, SceneError};

/// The translucent object: a mesh shape, its boundary and its interior medium.
pub(super) fn shape(doc: &Doc, root: Node, n: Node) -> Result<(MeshSource, Medium), SceneError> {
    let t = plugin_type(doc, n)?;
    let mut file = None;
    let mut to_world = DMat4::IDENTITY;
    let (mut boundary, mut interior) = (None, None);
    for c in elements(n) {
        let tag = c.tag_name().name();
        let node = if tag == "ref" {
            resolve(doc, root, c)?
        } else {
            c
        };
        match (node.tag_name().name(), c.attribute("name")) {
            ("bsdf", _) => boundary = Some(node),
            ("medium", Some("interior")) => interior = Some(medium(doc, node)?),
            ("medium", Some(k)) => {
                return Err(doc.err(
                    c,
                    format!("a medium '{k}': only the object's interior medium is modelled (the outside is vacuum)"),
                ));
            }
            (_, Some("filename")) => file = Some(doc.string(c)?),
            (_, Some("to_world")) => to_world = doc.transform(c)?,
            _ => unknown(doc, n, c, &["face_normals", "id"])?,
        }
    }
    let Some(medium) = interior else {
        return Err(doc.err(
            n,
            "a shape without an interior medium: translucent renders one object and nothing \
             else; fix: remove the other shapes, or give this one its homogeneous interior",
        ));
    };
    if !matches!(t.as_str(), "ply" | "obj") {
        return Err(doc.err(
            n,
            format!("shape type \"{t}\": the object must be a mesh; fix: export it as PLY or OBJ"),
        ));
    }
    let Some(file) = file else {
        return Err(doc.err(n, "the mesh has no filename"));
    };
    let boundary = boundary.ok_or_else(|| {
        doc.err(
            n,
            "no BSDF (Mitsuba's default is diffuse, which a translucent object does not have); \
             fix: <bsdf type=\"roughdielectric\"> (or dielectric, or null for an index-matched \
             surface)",
        )
    })?;
    let (eta, roughness) = bsdf(doc, boundary)?;
    let medium = Medium {
        eta: eta as f32,
        roughness: roughness as f32,
        ..medium
    };
    let base = crate::scene_file::parse::base_dir(Path::new(&doc.file));
    let path = crate::scene_file::parse::resolve_mesh_path(Path::new(&file), &base, &doc.at(n))?;
    let mesh = if to_world == DMat4::IDENTITY {
        MeshSource::File(path)
    } else {
        MeshSource::Placed {
            path,
            to_world: to_world.as_mat4(),
        }
    };
    Ok((mesh, medium))
}

/// The declaration a `<ref id="…"/>` names.
fn resolve<'a, 'i>(
    doc: &Doc,
    root: Node<'a, 'i>,
    r: Node<'a, 'i>,
) -> Result<Node<'a, 'i>, SceneError> {
    let id = doc.req(r, "id")?;
    elements(root)
        .find(|d| d.attribute("id") == Some(id.as_str()))
        .ok_or_else(|| doc.err(r, format!("no top-level declaration has id=\"{id}\"")))
}

/// The boundary: (η, GGX α).
fn bsdf(doc: &Doc, n: Node) -> Result<(f64, f64), SceneError> {
    let t = plugin_type(doc, n)?;
    let (mut int, mut ext, mut alpha, mut dist) = (1.5046, 1.000277, 0.1, "beckmann".to_string());
    match t.as_str() {
        "null" => {
            for c in elements(n) {
                unknown(doc, n, c, &["id"])?;
            }
            return Ok((1.0, 0.0));
        }
        "dielectric" | "roughdielectric" => {}
        _ => {
            return Err(doc.err(
                n,
                format!(
                    "bsdf type \"{t}\": the object's surface is null, dielectric or \
                     roughdielectric (GGX)"
                ),
            ));
        }
    }
    for (k, p) in props(n) {
        match k {
            "int_ior" => int = doc.ior(p)?,
            "ext_ior" => ext = doc.ior(p)?,
            "alpha" if t == "roughdielectric" => alpha = doc.float(p)?,
            "distribution" if t == "roughdielectric" => dist = doc.string(p)?,
            "alpha_u" | "alpha_v" => {
                return Err(doc.err(
                    p,
                    "anisotropic roughness is not modelled; fix: one isotropic alpha",
                ));
            }
            "specular_reflectance" | "specular_transmittance" => {
                if doc.rgb(p)? != [1.0; 3] {
                    return Err(doc.err(
                        p,
                        format!(
                            "{k} other than 1 is not physical for a dielectric and is not modelled"
                        ),
                    ));
                }
            }
            _ => unknown(doc, n, p, &["sample_visible", "id"])?,
        }
    }
    if t == "roughdielectric" && dist != "ggx" {
        return Err(doc.err(
            n,
            format!(
                "distribution \"{dist}\" (Mitsuba's default is beckmann): the rough boundary is \
                 GGX; fix: <string name=\"distribution\" value=\"ggx\"/>"
            ),
        ));
    }
    if int <= ext {
        return Err(doc.err(
            n,
            format!(
                "int_ior {int} ≤ ext_ior {ext}: the object must be optically denser than its \
                 surroundings"
            ),
        ));
    }
    if !(0.0..=1.0).contains(&alpha) {
        return Err(doc.err(n, format!("alpha {alpha} must lie in [0, 1]")));
    }
    let rough = if t == "roughdielectric" { alpha } else { 0.0 };
    Ok((int / ext, rough))
}

/// A `homogeneous` medium (η and roughness filled in from the boundary).
fn medium(doc: &Doc, n: Node) -> Result<Medium, SceneError> {
    let t = plugin_type(doc, n)?;
    if t != "homogeneous" {
        return Err(doc.err(
            n,
            format!("medium type \"{t}\": only a homogeneous medium is modelled"),
        ));
    }
    let (mut sigma_t, mut albedo, mut scale, mut g) = ([1.0; 3], [0.75; 3], 1.0, 0.0);
    for c in elements(n) {
        match (c.tag_name().name(), c.attribute("name")) {
            ("phase", _) => g = phase(doc, c)?,
            (_, Some("sigma_t")) => sigma_t = doc.rgb(c)?,
            (_, Some("albedo")) => albedo = doc.rgb(c)?,
            (_, Some("scale")) => scale = doc.float(c)?,
            _ => unknown(doc, n, c, &["sample_emitters", "id"])?,
        }
    }
    Ok(Medium {
        sigma_t: sigma_t.map(|s| (s * scale) as f32),
        albedo: albedo.map(|a| a as f32),
        g: (g as f32).into(),
        eta: 1.0,
        roughness: 0.0,
    })
}

/// The phase function's g.
fn phase(doc: &Doc, n: Node) -> Result<f64, SceneError> {
    match plugin_type(doc, n)?.as_str() {
        "isotropic" => Ok(0.0),
        "hg" => {
            let mut g = 0.8;
            for (k, p) in props(n) {
                match k {
                    "g" => g = doc.float(p)?,
                    _ => unknown(doc, n, p, &["id"])?,
                }
            }
            if !(g > -1.0 && g < 1.0) {
                return Err(doc.err(n, format!("g {g} must lie in (−1, 1)")));
            }
            Ok(g)
        }
        t => Err(doc.err(
            n,
            format!("phase type \"{t}\": the phase function is isotropic or hg"),
        )),
    }
}
