//! Mitsuba reference-render folders (`scene.json` + mesh + `view_XXX.exr`, as written by
//! `render_reference.py`): a small JSON navigator whose errors name the file and the field, and
//! [`load_reference_folder`].

use std::path::Path;

use glam::Vec3;
use serde_json::Value;

use super::{Dataset, DatasetKind, DatasetMetadata, REFERENCE_FILE, View, load_view_image};
use crate::camera::camera_from_matrix;
use crate::rig::check_intensity;
use crate::scene_file::{RenderInfo, check_finite3, look_at_checked, resolve_mesh_path};
use crate::{Camera, Medium, MeshSource, Object, PointLight, SceneError};

/// Navigation in a JSON document with errors naming the file and the field path.
struct Doc<'a> {
    file: &'a str,
}

impl Doc<'_> {
    fn err(&self, path: &str, reason: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            location: format!("{}: {path}", self.file),
            reason: reason.into(),
        }
    }
    fn get<'v>(&self, v: &'v Value, path: &str) -> Option<&'v Value> {
        let mut cur = v;
        for key in path.split('.') {
            cur = cur.get(key)?;
        }
        if cur.is_null() { None } else { Some(cur) }
    }
    fn req<'v>(&self, v: &'v Value, path: &str, full: &str) -> Result<&'v Value, SceneError> {
        self.get(v, path).ok_or_else(|| {
            self.err(
                full,
                "missing; fix: add it (see DATASET.md, reference folders)",
            )
        })
    }
    fn num(&self, v: &Value, full: &str) -> Result<f64, SceneError> {
        v.as_f64()
            .ok_or_else(|| self.err(full, format!("= {v}: expected a number")))
    }
    fn uint(&self, v: &Value, full: &str) -> Result<u32, SceneError> {
        v.as_u64()
            .and_then(|u| u32::try_from(u).ok())
            .ok_or_else(|| self.err(full, format!("= {v}: expected a non-negative integer")))
    }
    fn str<'v>(&self, v: &'v Value, full: &str) -> Result<&'v str, SceneError> {
        v.as_str()
            .ok_or_else(|| self.err(full, format!("= {v}: expected a string")))
    }
    fn arr<const N: usize>(&self, v: &Value, full: &str) -> Result<[f64; N], SceneError> {
        let a = v
            .as_array()
            .filter(|a| a.len() == N)
            .ok_or_else(|| self.err(full, format!("= {v}: expected an array of {N} numbers")))?;
        let mut out = [0.0; N];
        for (i, x) in a.iter().enumerate() {
            out[i] = self.num(x, &format!("{full}[{i}]"))?;
        }
        Ok(out)
    }
    fn f3(&self, v: &Value, full: &str) -> Result<[f32; 3], SceneError> {
        // One number is accepted for all three channels, like scene files.
        if let Some(x) = v.as_f64() {
            return Ok([x as f32; 3]);
        }
        Ok(self.arr::<3>(v, full)?.map(|x| x as f32))
    }
    fn mat4(&self, v: &Value, full: &str) -> Result<[[f64; 4]; 4], SceneError> {
        let rows = v.as_array().filter(|a| a.len() == 4).ok_or_else(|| {
            self.err(
                full,
                "expected a 4×4 matrix as 4 rows of 4 numbers (row-major)",
            )
        })?;
        let mut m = [[0.0; 4]; 4];
        for (r, row) in rows.iter().enumerate() {
            m[r] = self.arr::<4>(row, &format!("{full}[{r}]"))?;
        }
        Ok(m)
    }
}

/// Read a Mitsuba reference-render folder (`scene.json` + mesh + `view_XXX.exr`, as written by
/// `render_reference.py`) into a [`Dataset`] of kind [`DatasetKind::MitsubaReference`].
///
/// Fields read (others are ignored): `shape.mesh_file`; `medium.sigma_t`, `medium.albedo`,
/// `medium.phase.g` (default 0); `boundary.bsdf` (`"null"` → η = 1; `"dielectric"` with
/// `int_ior`/`ext_ior` → η = int/ext); `light.intensity_rgb` (or `light.intensity`) and
/// `light.position` (default for views without `light_position`); `camera.fov_deg`,
/// `camera.fov_axis` (default "x"; y/diagonal/smaller/larger are converted), `camera.width`,
/// `camera.height`; per view `to_world` (4×4 row-major, columns x, y, z, origin; used as is) or
/// `origin`/`target`/`up`, `light_position`, `file_exr`, `mean_rgb` (optional, checked against
/// the image with a warning); `integrator.max_depth`; `render.spp`, `render.seed`.
pub fn load_reference_folder(dir: &Path) -> Result<Dataset, SceneError> {
    let file = dir.join(REFERENCE_FILE);
    let name = file.display().to_string();
    let text = std::fs::read_to_string(&file).map_err(|source| SceneError::Io {
        path: file.clone(),
        source,
    })?;
    let doc: Value = serde_json::from_str(&text).map_err(|e| SceneError::Parse {
        path: file.clone(),
        reason: format!("not valid JSON: {e}"),
    })?;
    let d = Doc { file: &name };

    // Mesh.
    let mesh_rel = d.str(
        d.req(&doc, "shape.mesh_file", "shape.mesh_file")?,
        "shape.mesh_file",
    )?;
    let mesh = MeshSource::File(resolve_mesh_path(
        Path::new(mesh_rel),
        dir,
        &format!("{name}: shape.mesh_file"),
    )?);

    let truth = medium_of(&d, &doc, &name)?;
    let (intensity, default_light) = light_of(&d, &doc, &name)?;
    let (fov_x, width, height) = camera_of(&d, &doc, &name)?;
    let views_v = d
        .req(&doc, "views", "views")?
        .as_array()
        .ok_or_else(|| d.err("views", "expected an array of views"))?;
    if views_v.is_empty() {
        return Err(d.err("views", "no views; fix: add at least one view"));
    }
    let mut views = Vec::with_capacity(views_v.len());
    let mut warnings = Vec::new();
    for (i, v) in views_v.iter().enumerate() {
        let lights = (intensity, default_light);
        let (view, warning) = view_of(&d, v, i, dir, lights, (fov_x, width, height))?;
        views.push(view);
        warnings.extend(warning);
    }
    let (render, metadata) = render_of(&d, &doc, &name)?;
    Ok(Dataset {
        views,
        mesh,
        object: Some(Object::of(&truth)),
        truth: Some(truth),
        render,
        metadata,
        root: dir.to_path_buf(),
        kind: DatasetKind::MitsubaReference,
        warnings,
    })
}

/// The medium of `scene.json`: `medium.*` (homogeneous; σ_t, α, the phase function's g) and the
/// index of refraction from `boundary.*`.
fn medium_of(d: &Doc, doc: &Value, name: &str) -> Result<Medium, SceneError> {
    if let Some(t) = d.get(doc, "medium.type") {
        let t = d.str(t, "medium.type")?;
        if t != "homogeneous" {
            return Err(d.err(
                &format!("medium.type = \"{t}\""),
                "only homogeneous media are supported",
            ));
        }
    }
    let sigma_t = d.f3(
        d.req(doc, "medium.sigma_t", "medium.sigma_t")?,
        "medium.sigma_t",
    )?;
    let albedo = d.f3(
        d.req(doc, "medium.albedo", "medium.albedo")?,
        "medium.albedo",
    )?;
    let g = phase_of(d, doc)?;
    let (eta, roughness) = boundary_of(d, doc)?;
    let truth = Medium {
        sigma_t,
        albedo,
        g: g.into(),
        eta,
        roughness,
    };
    truth.validate(&format!("{name}: medium"))?;
    Ok(truth)
}

/// The Henyey–Greenstein g of `scene.json`'s `medium.phase`: `{"type": "hg", "g": …}`,
/// `{"type": "isotropic"}`, or absent (isotropic).
fn phase_of(d: &Doc, doc: &Value) -> Result<f32, SceneError> {
    let kind = d
        .get(doc, "medium.phase.type")
        .map(|v| d.str(v, "medium.phase.type"))
        .transpose()?;
    let g = d
        .get(doc, "medium.phase.g")
        .map(|v| d.num(v, "medium.phase.g"))
        .transpose()?;
    match (kind, g) {
        (None | Some("hg"), Some(g)) => Ok(g as f32),
        (None | Some("isotropic"), None) => Ok(0.0),
        (Some("isotropic"), Some(0.0)) => Ok(0.0),
        (Some("isotropic"), Some(g)) => Err(d.err(
            &format!("medium.phase.g = {g}"),
            "an isotropic phase function has g = 0; fix: type \"hg\" for an anisotropic medium",
        )),
        (Some("hg"), None) => Err(d.err(
            "medium.phase.g",
            "missing for the Henyey–Greenstein phase function; fix: add g, in (−1, 1)",
        )),
        (Some(other), _) => Err(d.err(
            &format!("medium.phase.type = \"{other}\""),
            "only the Henyey–Greenstein (\"hg\") and isotropic phase functions are modelled; \
             fix: render the reference with one of them",
        )),
    }
}

/// The boundary of `scene.json` as (η, GGX α): `boundary.bsdf` `"null"` (or absent),
/// `"dielectric"` or `"roughdielectric"` (Mitsuba 3's plugins: `int_ior`, `ext_ior` (default
/// 1.000277), `distribution` (default `"beckmann"`), `alpha` (default 0.1)).
fn boundary_of(d: &Doc, doc: &Value) -> Result<(f32, f32), SceneError> {
    let bsdf = d
        .get(doc, "boundary.bsdf")
        .map(|v| d.str(v, "boundary.bsdf"))
        .transpose()?;
    let Some(bsdf @ ("dielectric" | "roughdielectric")) = bsdf else {
        return match bsdf {
            None | Some("null") => Ok((1.0, 0.0)),
            Some(other) => Err(d.err(
                &format!("boundary.bsdf = \"{other}\""),
                "unsupported boundary; fix: \"null\" (index-matched), \"dielectric\" or \
                 \"roughdielectric\" with int_ior/ext_ior",
            )),
        };
    };
    let int = d.num(
        d.req(doc, "boundary.int_ior", "boundary.int_ior")?,
        "boundary.int_ior",
    )?;
    let ext = match d.get(doc, "boundary.ext_ior") {
        Some(v) => d.num(v, "boundary.ext_ior")?,
        None => 1.000_277,
    };
    if !(int.is_finite() && ext.is_finite() && int > 0.0 && ext > 0.0 && int > ext) {
        return Err(d.err(
            &format!("boundary.int_ior = {int}, boundary.ext_ior = {ext}"),
            "the object must be optically denser than its surroundings (int_ior > ext_ior > 0); \
             fix: e.g. int_ior 1.5, ext_ior 1",
        ));
    }
    if bsdf == "dielectric" {
        if let Some(v) = d.get(doc, "boundary.alpha")
            && d.num(v, "boundary.alpha")? != 0.0
        {
            return Err(d.err(
                "boundary.alpha",
                "a smooth \"dielectric\" has no roughness; fix: \"roughdielectric\" for a \
                 rough surface, or drop alpha",
            ));
        }
        return Ok(((int / ext) as f32, 0.0));
    }
    let distribution = match d.get(doc, "boundary.distribution") {
        Some(v) => d.str(v, "boundary.distribution")?,
        None => "beckmann",
    };
    if distribution != "ggx" {
        return Err(d.err(
            &format!("boundary.distribution = \"{distribution}\""),
            "only GGX microfacets are modelled (Mitsuba's roughdielectric defaults to \
             \"beckmann\"); fix: render the reference with distribution \"ggx\"",
        ));
    }
    if d.get(doc, "boundary.alpha_u").is_some() || d.get(doc, "boundary.alpha_v").is_some() {
        return Err(d.err(
            "boundary.alpha_u",
            "anisotropic roughness is not modelled; fix: one isotropic alpha",
        ));
    }
    // Mitsuba's roughdielectric defaults to α = 0.1.
    let alpha = match d.get(doc, "boundary.alpha") {
        Some(v) => d.num(v, "boundary.alpha")?,
        None => 0.1,
    };
    if !(alpha.is_finite() && (0.0..=1.0).contains(&alpha)) {
        return Err(d.err(
            &format!("boundary.alpha = {alpha}"),
            "the GGX α of the surface must be in [0, 1]; fix: e.g. 0.1 (polished) to 0.3 (matte)",
        ));
    }
    Ok(((int / ext) as f32, alpha as f32))
}

/// The light of `scene.json`: its intensity per channel and its default position.
fn light_of(d: &Doc, doc: &Value, name: &str) -> Result<([f32; 3], Option<[f32; 3]>), SceneError> {
    let intensity = match (
        d.get(doc, "light.intensity_rgb"),
        d.get(doc, "light.intensity"),
    ) {
        (Some(v), _) => d.f3(v, "light.intensity_rgb")?,
        (None, Some(v)) => d.f3(v, "light.intensity")?,
        (None, None) => {
            return Err(d.err(
                "light.intensity_rgb",
                "missing; fix: add the radiant intensity per channel [W/sr]",
            ));
        }
    };
    check_intensity(&intensity, &format!("{name}: light.intensity_rgb"))?;
    if let Some(t) = d.get(doc, "light.type") {
        let t = d.str(t, "light.type")?;
        if t != "point" {
            return Err(d.err(
                &format!("light.type = \"{t}\""),
                "only point lights are supported",
            ));
        }
    }
    let default_light = d
        .get(doc, "light.position")
        .map(|v| d.f3(v, "light.position"))
        .transpose()?;
    Ok((intensity, default_light))
}

/// The camera intrinsics of `scene.json`: the horizontal field of view (converted from
/// `camera.fov_axis`), width and height.
fn camera_of(d: &Doc, doc: &Value, name: &str) -> Result<(f32, u32, u32), SceneError> {
    let fov = d.num(
        d.req(doc, "camera.fov_deg", "camera.fov_deg")?,
        "camera.fov_deg",
    )?;
    let width = d.uint(d.req(doc, "camera.width", "camera.width")?, "camera.width")?;
    let height = d.uint(
        d.req(doc, "camera.height", "camera.height")?,
        "camera.height",
    )?;
    let axis = match d.get(doc, "camera.fov_axis") {
        Some(v) => d.str(v, "camera.fov_axis")?,
        None => "x",
    };
    if !(fov.is_finite() && fov > 0.0 && fov < 180.0) {
        return Err(d.err(
            &format!("camera.fov_deg = {fov}"),
            "field of view must be in (0, 180) degrees",
        ));
    }
    let (w, h) = (width as f64, height as f64);
    let t = (0.5 * fov.to_radians()).tan();
    let tx = match axis {
        "x" => t,
        "y" => t * w / h.max(1.0),
        "diagonal" => t * w / (w * w + h * h).sqrt().max(1.0),
        "smaller" if width <= height => t,
        "smaller" => t * w / h.max(1.0),
        "larger" if width >= height => t,
        "larger" => t * w / h.max(1.0),
        other => {
            return Err(d.err(
                &format!("camera.fov_axis = \"{other}\""),
                "unknown fov axis; fix: use x, y, diagonal, smaller or larger",
            ));
        }
    };
    let fov_x = (2.0 * tx.atan()).to_degrees() as f32;
    let probe = Camera {
        origin: Vec3::ZERO,
        rotation: glam::Mat3::IDENTITY,
        fov_x_deg: fov_x,
        width,
        height,
        crop: None,
        pinhole: None,
        mask: None,
    };
    probe.validate_named(&format!("{name}: camera"), "fov_deg")?;
    Ok((fov_x, width, height))
}

/// View `i` of `scene.json` (`v`): its camera, its light (`lights`: the intensity and the
/// default position), its image; a warning when the image's mean differs from `mean_rgb`.
fn view_of(
    d: &Doc,
    v: &Value,
    i: usize,
    dir: &Path,
    (intensity, default_light): ([f32; 3], Option<[f32; 3]>),
    (fov_x, width, height): (f32, u32, u32),
) -> Result<(View, Option<String>), SceneError> {
    let name = d.file;
    let mut warning = None;
    let p = format!("views[{i}]");
    let ctx = format!("{name}: {p}");
    let camera = if let Some(m) = d.get(v, "to_world") {
        let m = d.mat4(m, &format!("{p}.to_world"))?;
        camera_from_matrix(&m, fov_x, width, height, &ctx)?
    } else {
        let o = d.f3(
            d.req(v, "origin", &format!("{p}.origin"))?,
            &format!("{p}.origin"),
        )?;
        let tg = d.f3(
            d.req(v, "target", &format!("{p}.target"))?,
            &format!("{p}.target"),
        )?;
        let up = match d.get(v, "up") {
            Some(u) => d.f3(u, &format!("{p}.up"))?,
            None => [0.0, 1.0, 0.0],
        };
        look_at_checked(&ctx, o, tg, up, fov_x, "fov_deg", width, height)?
    };
    let light_pos = match d.get(v, "light_position") {
        Some(lp) => d.f3(lp, &format!("{p}.light_position"))?,
        None => default_light.ok_or_else(|| {
            d.err(
                &format!("{p}.light_position"),
                "missing, and there is no light.position to fall back on; fix: add it",
            )
        })?,
    };
    let position = check_finite3(light_pos, &format!("{ctx}.light_position"))?;
    let exr = d.str(
        d.req(v, "file_exr", &format!("{p}.file_exr"))?,
        &format!("{p}.file_exr"),
    )?;
    let (image, image_path) = load_view_image(dir, exr, &format!("{ctx}.file_exr"), &camera)?;
    let expected_mean = match d.get(v, "mean_rgb") {
        Some(m) => Some(d.arr::<3>(m, &format!("{p}.mean_rgb"))?),
        None => None,
    };
    if let Some(e) = expected_mean {
        let got = image.mean();
        let off = (0..3).any(|c| (got[c] - e[c]).abs() > 1e-4 * e[c].abs().max(1e-3));
        if off {
            let msg = format!(
                "{ctx}: image mean {got:?} differs from mean_rgb {e:?} recorded in scene.json \
                 (the image may not be the one described)"
            );
            tracing::warn!("{msg}");
            warning = Some(msg);
        }
    }
    let view = View {
        camera,
        light: PointLight {
            position,
            intensity,
        },
        image: Some(image),
        image_path: Some(image_path),
        expected_mean,
    };
    Ok((view, warning))
}

/// The render settings (`integrator.max_depth`, `render.spp`, `render.seed`, the renderer) and
/// the metadata of `scene.json` (informational).
fn render_of(
    d: &Doc,
    doc: &Value,
    name: &str,
) -> Result<(RenderInfo, DatasetMetadata), SceneError> {
    let opt_u = |path: &str| -> Result<Option<u64>, SceneError> {
        d.get(doc, path)
            .map(|v| {
                v.as_u64()
                    .ok_or_else(|| d.err(path, format!("= {v}: expected a non-negative integer")))
            })
            .transpose()
    };
    let max_depth = opt_u("integrator.max_depth")?.map(|v| v.min(u32::MAX as u64) as u32);
    let spp = opt_u("render.spp")?.map(|v| v.min(u32::MAX as u64) as u32);
    let seed = opt_u("render.seed")?;
    let version = d
        .get(doc, "software.mitsuba_version")
        .and_then(Value::as_str);
    let integrator = d
        .get(doc, "integrator.type")
        .and_then(Value::as_str)
        .unwrap_or("volpath");
    let renderer = Some(match version {
        Some(v) => format!("mitsuba {v} {integrator}"),
        None => format!("mitsuba {integrator}"),
    });
    let render = RenderInfo {
        spp,
        max_depth,
        seed,
        renderer,
    };
    render.validate(&format!("{name}: integrator"))?;
    let text_of = |path: &str| d.get(doc, path).and_then(Value::as_str).map(str::to_string);
    let metadata = DatasetMetadata {
        units: text_of("units"),
        conventions: text_of("coordinate_system"),
        generator: text_of("generator"),
        notes: d.get(doc, "command").cloned(),
        length_unit: None,
    };
    Ok((render, metadata))
}
