//! Mitsuba 3 scene files (`.xml`) read as a [`SceneDesc`]: the scene a Mitsuba user already has,
//! rendered and recovered as it is written, or refused with the line and the fix.
//!
//! What is read (Mitsuba 3's plugins and their defaults):
//! - **the object**: one `ply` or `obj` shape (`filename` relative to the scene file, `to_world`
//!   applied to the mesh) with an `interior` `homogeneous` medium (`sigma_t` × `scale`,
//!   `albedo`; defaults 1 and 0.75) whose phase function is `isotropic` (the default) or `hg`
//!   (`g`, default 0.8), inside a `null`, `dielectric` or `roughdielectric` BSDF (`int_ior`,
//!   `ext_ior` as numbers or Mitsuba's names, defaults `bk7` and `air`, η = int/ext;
//!   `distribution` `ggx` with one `alpha`, default 0.1). BSDFs and media may be given inline
//!   or by `<ref id="…"/>` to a top-level declaration.
//! - **the cameras**: every `perspective` sensor is a view: `to_world` (`lookat`, `matrix`, …),
//!   `fov` along `fov_axis` (`x`, `y`, `diagonal`, `smaller`, `larger`) or `focal_length`
//!   (35 mm equivalent, default 50mm), `principal_point_offset_x`/`_y` (fractions of the film:
//!   the optical axis meets it at ½ − offset of its size), `hdrfilm` `width` × `height`
//!   (default 768 × 576); the first sensor's `sample_count` becomes the render's samples per
//!   pixel.
//! - **the light**: one `point` emitter (`position` or a `to_world` translation; `intensity` in
//!   W/sr), lighting every view (a capture with a light per image is one scene file per view).
//! - the integrator's `max_depth` (−1, Mitsuba's unbounded, leaves the tracer's default), and
//!   `<default name value>` declarations with `$name` substitution in any attribute.
//!
//! Refused with a message: other shapes beside the object (a floor, a backdrop), other emitters,
//! an `exterior` medium, spectra from files or by wavelength, anisotropic or Beckmann roughness,
//! film crops, `<include>`, and any property of these plugins that
//! would change the physics and is not listed above. Ignored, because they do not change the
//! image the tracer computes: `near_clip`, `far_clip`, the film's `rfilter` and pixel format, the
//! sampler's type, `rr_depth`, `hide_emitters`, `sample_emitters`, `sample_visible`,
//! `face_normals` and `id`s.

use std::path::Path;

use glam::{DMat4, DVec3};
use roxmltree::{Document, Node};

use crate::scene_file::desc::{MeshSource, RenderInfo, SceneDesc, ViewDesc};
use crate::{Camera, Medium, PointLight, SceneError};

mod object;
#[cfg(test)]
mod tests;
mod values;
mod write;

use values::Doc;
pub use write::{MitsubaExport, medium_snippet};

/// Reads a Mitsuba 3 scene file as a scene.
pub fn load(path: &Path) -> Result<SceneDesc, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text, path)
}

/// Parses Mitsuba 3 scene text as if read from `path` (relative mesh paths resolve from its
/// folder).
pub fn parse(text: &str, path: &Path) -> Result<SceneDesc, SceneError> {
    let xml = Document::parse(text).map_err(|e| SceneError::Parse {
        path: path.to_path_buf(),
        reason: format!("not well-formed XML: {e}"),
    })?;
    let root = xml.root_element();
    let mut doc = Doc {
        file: path.display().to_string(),
        defaults: Default::default(),
    };
    if root.tag_name().name() != "scene" {
        return Err(doc.err(root, "the root element must be <scene version=\"3.0.0\">"));
    }
    match root.attribute("version") {
        Some(v) if v.starts_with("2.") || v.starts_with("3.") => {}
        v => {
            return Err(doc.err(
                root,
                format!(
                    "version {v:?}: only Mitsuba 2 and 3 scenes are read (their camera and \
                     transform conventions); fix: convert the scene with Mitsuba 3 and write \
                     version=\"3.0.0\""
                ),
            ));
        }
    }
    for d in elements(root).filter(|n| n.tag_name().name() == "default") {
        let name = doc.req(d, "name")?;
        let value = doc.req(d, "value")?;
        doc.defaults.insert(name, value);
    }
    let mut scene = Parts::default();
    for n in elements(root) {
        scene.add(&doc, root, n)?;
    }
    scene.finish(&doc, root, path)
}

/// The element children of a node.
fn elements<'a, 'i>(n: Node<'a, 'i>) -> impl Iterator<Item = Node<'a, 'i>> {
    n.children().filter(Node::is_element)
}

/// What the scene's top-level elements give.
#[derive(Default)]
struct Parts {
    object: Option<(MeshSource, Medium)>,
    cameras: Vec<Camera>,
    spp: Option<u32>,
    lights: Vec<PointLight>,
    max_depth: Option<u32>,
}

impl Parts {
    fn add(&mut self, doc: &Doc, root: Node, n: Node) -> Result<(), SceneError> {
        match n.tag_name().name() {
            "default" => {}
            // Declarations that shapes refer to by id.
            "bsdf" | "medium" | "texture" if n.attribute("id").is_some() => {}
            "integrator" => self.max_depth = integrator_depth(doc, n)?,
            "sensor" => {
                let (camera, spp) = sensor(doc, n)?;
                self.spp = self.spp.or(spp);
                self.cameras.push(camera);
            }
            "emitter" => self.lights.push(emitter(doc, n)?),
            "shape" => {
                let object = object::shape(doc, root, n)?;
                if self.object.is_some() {
                    return Err(doc.err(
                        n,
                        "a second shape with an interior medium; fix: one translucent object \
                         per scene",
                    ));
                }
                self.object = Some(object);
            }
            "include" => {
                return Err(doc.err(
                    n,
                    "<include> is not followed; fix: paste the included file's content in place",
                ));
            }
            t => {
                return Err(doc.err(
                    n,
                    format!(
                        "<{t}> is not read here (a scene holds default, integrator, sensor, \
                         emitter, shape, and bsdf or medium declarations with an id)"
                    ),
                ));
            }
        }
        Ok(())
    }

    fn finish(self, doc: &Doc, root: Node, path: &Path) -> Result<SceneDesc, SceneError> {
        let Some((mesh, medium)) = self.object else {
            return Err(doc.err(
                root,
                "no shape with an interior medium; fix: give the object \
                 <medium type=\"homogeneous\" name=\"interior\">…</medium>",
            ));
        };
        if self.cameras.is_empty() {
            return Err(doc.err(
                root,
                "no <sensor type=\"perspective\">; fix: add one per view",
            ));
        }
        let light = match self.lights.as_slice() {
            [l] => *l,
            [] => return Err(doc.err(root, "no <emitter type=\"point\">; fix: add the light")),
            ls => {
                return Err(doc.err(
                    root,
                    format!(
                        "{} point emitters: each view is lit by one point light; fix: one \
                         emitter per scene file (a capture with a light per image is one scene \
                         file per view)",
                        ls.len()
                    ),
                ));
            }
        };
        let file = path.display().to_string();
        medium.validate(&format!("{file}: interior medium"))?;
        for (i, c) in self.cameras.iter().enumerate() {
            c.validate(&format!("{file}: sensor {i}"))?;
        }
        let render = RenderInfo {
            spp: self.spp,
            max_depth: self.max_depth,
            seed: None,
            renderer: None,
        };
        render.validate(&format!("{file}: render"))?;
        Ok(SceneDesc {
            mesh,
            medium,
            views: self
                .cameras
                .into_iter()
                .map(|camera| ViewDesc { camera, light })
                .collect(),
            render,
            path: path.to_path_buf(),
            length_unit: None,
        })
    }
}

/// The named properties of a plugin node (children with a `name` attribute).
fn props<'a, 'i>(n: Node<'a, 'i>) -> impl Iterator<Item = (&'a str, Node<'a, 'i>)> {
    elements(n).filter_map(|c| c.attribute("name").map(|k| (k, c)))
}

/// Refuses a property that this reader does not read and that is not known to leave the image
/// unchanged.
fn unknown(doc: &Doc, plugin: Node, prop: Node, ignored: &[&str]) -> Result<(), SceneError> {
    let name = prop.attribute("name").unwrap_or_default();
    if ignored.contains(&name) {
        return Ok(());
    }
    Err(doc.err(
        prop,
        format!(
            "the property '{name}' of <{} type=\"{}\"> is not modelled; fix: remove it (the \
             reader follows what changes the image, and refuses what it cannot honour)",
            plugin.tag_name().name(),
            plugin.attribute("type").unwrap_or_default()
        ),
    ))
}

fn integrator_depth(doc: &Doc, n: Node) -> Result<Option<u32>, SceneError> {
    let mut depth = None;
    for (k, p) in props(n) {
        if k == "max_depth" {
            let d = doc.integer(p)?;
            depth = match d {
                -1 => None,
                1..=100_000 => Some(d as u32),
                _ => return Err(doc.err(p, format!("max_depth {d} must be ≥ 1 (or −1)"))),
            };
        }
    }
    Ok(depth)
}

fn plugin_type(doc: &Doc, n: Node) -> Result<String, SceneError> {
    doc.attr(n, "type")?
        .ok_or_else(|| doc.err(n, "the attribute type=\"…\" is missing"))
}

/// A `perspective` sensor: its camera and its sampler's `sample_count`.
fn sensor(doc: &Doc, n: Node) -> Result<(Camera, Option<u32>), SceneError> {
    let t = plugin_type(doc, n)?;
    if t != "perspective" {
        return Err(doc.err(
            n,
            format!("sensor type \"{t}\": only the pinhole \"perspective\" camera is modelled"),
        ));
    }
    let (mut fov, mut axis, mut focal) = (None, "x".to_string(), None);
    let mut offset = [0.0f64; 2];
    let mut to_world = DMat4::IDENTITY;
    let (mut width, mut height, mut spp) = (768u32, 576u32, None);
    for c in elements(n) {
        match (c.tag_name().name(), c.attribute("name")) {
            ("film", _) => (width, height) = film(doc, c)?,
            ("sampler", _) => spp = sampler(doc, c)?,
            (_, Some("fov")) => fov = Some(doc.float(c)?),
            (_, Some("fov_axis")) => axis = doc.string(c)?,
            (_, Some("focal_length")) => focal = Some(focal_length(doc, c)?),
            (_, Some("to_world")) => to_world = doc.transform(c)?,
            (_, Some("principal_point_offset_x")) => offset[0] = doc.float(c)?,
            (_, Some("principal_point_offset_y")) => offset[1] = doc.float(c)?,
            _ => unknown(doc, n, c, &["near_clip", "far_clip", "srf", "id"])?,
        }
    }
    let (w, h) = (width as f64, height as f64);
    let (fov, axis) = match (fov, focal) {
        (Some(f), _) => (f, axis.as_str()),
        // Mitsuba: a 35 mm equivalent focal length spans the 36 × 24 mm frame's diagonal.
        (None, f) => {
            let f = f.unwrap_or(50.0);
            (
                (36f64.hypot(24.0) / (2.0 * f)).atan().to_degrees() * 2.0,
                "diagonal",
            )
        }
    };
    if !(fov > 0.0 && fov < 180.0) {
        return Err(doc.err(n, format!("fov {fov}° must lie in (0, 180)")));
    }
    let t = (fov.to_radians() / 2.0).tan();
    let tan_x = match axis {
        "x" => t,
        "y" => t * w / h,
        "diagonal" => t * w / w.hypot(h),
        "smaller" if w <= h => t,
        "smaller" => t * w / h,
        "larger" if w >= h => t,
        "larger" => t * w / h,
        a => {
            return Err(doc.err(
                n,
                format!("fov_axis \"{a}\": one of x, y, diagonal, smaller, larger"),
            ));
        }
    };
    let rows = to_world.transpose().to_cols_array_2d();
    let fov_x = (2.0 * tan_x.atan()).to_degrees() as f32;
    let cam = crate::camera::camera_from_matrix(&rows, fov_x, width, height, &doc.at(n))?;
    if offset == [0.0; 2] {
        return Ok((cam, spp));
    }
    // Mitsuba adds the offsets (fractions of the film) to the film position a ray is sampled
    // at: the optical axis meets the film at (1/2 − offset) of its size.
    let k = cam.intrinsics();
    let cam = cam.with_intrinsics(&crate::camera::Intrinsics {
        cx: ((0.5 - offset[0]) * w) as f32,
        cy: ((0.5 - offset[1]) * h) as f32,
        ..k
    });
    if let Some(p) = &cam.pinhole {
        p.validate(&doc.at(n), width, height)?;
    }
    Ok((cam, spp))
}

/// A focal length "50mm" (35 mm equivalent).
fn focal_length(doc: &Doc, n: Node) -> Result<f64, SceneError> {
    let s = doc.string(n)?;
    s.trim()
        .trim_end_matches("mm")
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|f| f.is_finite() && *f > 0.0)
        .ok_or_else(|| doc.err(n, format!("focal_length \"{s}\": write e.g. \"50mm\"")))
}

fn film(doc: &Doc, n: Node) -> Result<(u32, u32), SceneError> {
    let (mut w, mut h) = (768, 576);
    for c in elements(n) {
        match c.attribute("name") {
            Some(k @ ("width" | "height")) => {
                let v = doc.integer(c)?;
                if !(1..=65536).contains(&v) {
                    return Err(doc.err(c, format!("{k} {v} must lie in 1…65536")));
                }
                if k == "width" {
                    w = v as u32
                } else {
                    h = v as u32
                }
            }
            Some(k) if k.starts_with("crop_") => {
                return Err(doc.err(c, "a film crop is not modelled; fix: render the full film"));
            }
            _ if c.tag_name().name() == "rfilter" => {}
            _ => unknown(
                doc,
                n,
                c,
                &[
                    "pixel_format",
                    "component_format",
                    "file_format",
                    "sample_border",
                    "compensate",
                ],
            )?,
        }
    }
    Ok((w, h))
}

fn sampler(doc: &Doc, n: Node) -> Result<Option<u32>, SceneError> {
    for (k, p) in props(n) {
        if k == "sample_count" {
            let v = doc.integer(p)?;
            if !(1..=1 << 24).contains(&v) {
                return Err(doc.err(p, format!("sample_count {v} must be ≥ 1")));
            }
            return Ok(Some(v as u32));
        }
    }
    Ok(None)
}

/// A `point` emitter.
fn emitter(doc: &Doc, n: Node) -> Result<PointLight, SceneError> {
    let t = plugin_type(doc, n)?;
    if t != "point" {
        return Err(doc.err(
            n,
            format!(
                "emitter type \"{t}\": only a point light is modelled; fix: remove it (the \
                 images must be lit by the one point light)"
            ),
        ));
    }
    let mut position = None;
    let mut intensity = [1.0; 3];
    for (k, p) in props(n) {
        match k {
            "position" => position = Some(doc.point(p)?),
            "to_world" => {
                let m = doc.transform(p)?;
                position = Some(m.transform_point3(DVec3::ZERO));
            }
            "intensity" => intensity = doc.rgb(p)?,
            _ => unknown(doc, n, p, &["id"])?,
        }
    }
    if intensity.iter().any(|&v| v < 0.0) {
        return Err(doc.err(n, format!("intensity {intensity:?} must be ≥ 0")));
    }
    Ok(PointLight {
        position: position.unwrap_or(DVec3::ZERO).as_vec3(),
        intensity: intensity.map(|v| v as f32),
    })
}
