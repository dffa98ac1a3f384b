//! A medium, and a whole scene, written as Mitsuba 3 XML, so that a recovered medium drops into
//! the user's renderer. The scene is the one [`super::parse`] reads back: the object's mesh
//! (written beside the scene as `object.ply`, already placed in the world) inside its boundary
//! (`null`, `dielectric` or GGX `roughdielectric`, η as `int_ior` with `ext_ior` 1) around a
//! `homogeneous` interior (RGB σ_t stored as σ_t/s with `scale` s = max σ_t, since Mitsuba reads
//! `rgb` values in [0, 1]; `hg` phase function), one `perspective` sensor per view (fov along x,
//! box filter, `independent` sampler at `$spp`) and the point light. Views lit from different
//! positions cannot share one Mitsuba scene: each such view is a scene file of its own.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::fsutil::atomic_write;
use crate::scene_file::{SceneDesc, ViewDesc};
use crate::{Medium, PointLight, SceneError};

/// The object's `<bsdf>` and interior `<medium>` for `m`, to place inside a `<shape>`. Mitsuba
/// 3's `hg` has one g for every channel: a g per channel is written as the channels' mean, with
/// a comment that says so (the scene export writes a scene per channel, [`MitsubaExport::of`]).
pub fn medium_snippet(m: &Medium) -> String {
    let mut s = String::new();
    let f = |v: f32| format!("{v}");
    if m.eta == 1.0 {
        s.push_str("<bsdf type=\"null\"/>\n");
    } else if m.roughness == 0.0 {
        let _ = writeln!(
            s,
            "<bsdf type=\"dielectric\">\n    <float name=\"int_ior\" value=\"{}\"/>\n    \
             <float name=\"ext_ior\" value=\"1\"/>\n</bsdf>",
            f(m.eta)
        );
    } else {
        let _ = writeln!(
            s,
            "<bsdf type=\"roughdielectric\">\n    <string name=\"distribution\" value=\"ggx\"/>\n    \
             <float name=\"alpha\" value=\"{}\"/>\n    <float name=\"int_ior\" value=\"{}\"/>\n    \
             <float name=\"ext_ior\" value=\"1\"/>\n</bsdf>",
            f(m.roughness),
            f(m.eta)
        );
    }
    if !m.g.is_uniform() {
        let _ = writeln!(
            s,
            "<!-- The medium's g per channel is {}; Mitsuba 3's hg phase function has one g, \
             so the channels' mean is written. -->",
            m.g
        );
    }
    let scale = m.sigma_t.iter().fold(0.0f32, |a, &b| a.max(b));
    let rgb = |v: [f32; 3]| format!("{}, {}, {}", f(v[0]), f(v[1]), f(v[2]));
    let _ = writeln!(
        s,
        "<medium type=\"homogeneous\" name=\"interior\">\n    \
         <rgb name=\"sigma_t\" value=\"{}\"/>\n    <float name=\"scale\" value=\"{}\"/>\n    \
         <rgb name=\"albedo\" value=\"{}\"/>\n    <phase type=\"hg\">\n        \
         <float name=\"g\" value=\"{}\"/>\n    </phase>\n</medium>",
        rgb(m.sigma_t.map(|v| v / scale)),
        f(scale),
        rgb(m.albedo),
        f(m.g.mean())
    );
    s
}

/// A scene as Mitsuba 3 scene files: (file name, XML) in order, and the mesh they refer to.
#[derive(Clone, Debug)]
pub struct MitsubaExport {
    pub files: Vec<(String, String)>,
    mesh: geometry::Mesh,
}

impl MitsubaExport {
    /// The scene `desc` with its medium, at `spp` samples per pixel and `max_depth` (Mitsuba
    /// `volpath` semantics). Fails on a view with a cropped camera (Mitsuba would render the
    /// whole film) and when the mesh does not load. A medium with a g per channel is one scene
    /// per channel (`scene_r.xml`, `scene_g.xml`, `scene_b.xml`, or `view_XXX_r.xml` …), each at
    /// that channel's g: channel c of the object's images is channel c of its scene's.
    pub fn of(desc: &SceneDesc, spp: u32, max_depth: u32) -> Result<Self, SceneError> {
        if let Some(i) = desc.views.iter().position(|v| v.camera.crop.is_some()) {
            return Err(SceneError::Invalid {
                location: format!("{}: view {i}", desc.path.display()),
                reason: "a cropped camera has no Mitsuba scene of its own; fix: export the \
                         full views"
                    .into(),
            });
        }
        if let Some(i) = desc
            .views
            .iter()
            .position(|v| v.camera.pinhole.is_some_and(|p| p.aspect != 1.0))
        {
            return Err(SceneError::Invalid {
                location: format!("{}: view {i}", desc.path.display()),
                reason: "a camera whose focal lengths differ along x and y (non-square pixels) \
                         has no Mitsuba perspective sensor; fix: resample the images to square \
                         pixels"
                    .into(),
            });
        }
        let (mesh, _) = desc.mesh.load()?;
        let shared = desc.views.iter().all(|v| v.light == desc.views[0].light);
        // Mitsuba 3's hg has one g for every channel: a medium with a g per channel is written
        // as one scene per channel (`_r`, `_g`, `_b`), each at that channel's g, whose channel
        // of the images is the medium's.
        let media: Vec<(&str, Medium)> = match desc.medium.g.as_uniform() {
            Some(_) => vec![("", desc.medium)],
            None => ["_r", "_g", "_b"]
                .into_iter()
                .zip(desc.medium.g.channels())
                .map(|(suffix, g)| {
                    let m = Medium {
                        g: crate::Anisotropy::uniform(g),
                        ..desc.medium
                    };
                    (suffix, m)
                })
                .collect(),
        };
        let mut files = Vec::new();
        for (suffix, m) in &media {
            if shared {
                let xml = scene_xml(m, &desc.views, desc.views[0].light, spp, max_depth);
                files.push((format!("scene{suffix}.xml"), xml));
            } else {
                for (i, v) in desc.views.iter().enumerate() {
                    let xml = scene_xml(m, std::slice::from_ref(v), v.light, spp, max_depth);
                    files.push((format!("view_{i:03}{suffix}.xml"), xml));
                }
            }
        }
        Ok(Self { files, mesh })
    }

    /// Writes the scene files, `object.ply` and `medium.xml` (the snippet) into `dir`; the
    /// paths written.
    pub fn write(
        &self,
        dir: &Path,
        medium: &Medium,
        overwrite: bool,
    ) -> Result<Vec<PathBuf>, SceneError> {
        std::fs::create_dir_all(dir).map_err(|source| SceneError::Io {
            path: dir.to_path_buf(),
            source,
        })?;
        let mut written = Vec::new();
        let snippet = format!(
            "<!-- The recovered object's boundary and interior medium (Mitsuba 3): paste them \
             inside the object's <shape>. -->\n{}",
            medium_snippet(medium)
        );
        for (name, text) in self
            .files
            .iter()
            .map(|(n, t)| (n.as_str(), t.as_str()))
            .chain([("medium.xml", snippet.as_str())])
        {
            let p = dir.join(name);
            atomic_write(&p, text.as_bytes(), overwrite)?;
            written.push(p);
        }
        let ply = dir.join("object.ply");
        if !overwrite && ply.exists() {
            return Err(SceneError::Exists { path: ply });
        }
        geometry::io::save_ply(&self.mesh, &ply)?;
        written.push(ply);
        Ok(written)
    }
}

/// One Mitsuba scene: `views`' sensors lit by `light`.
fn scene_xml(m: &Medium, views: &[ViewDesc], light: PointLight, spp: u32, depth: u32) -> String {
    let mut s = String::from("<scene version=\"3.0.0\">\n");
    let _ = writeln!(s, "    <default name=\"spp\" value=\"{spp}\"/>");
    let _ = writeln!(
        s,
        "    <integrator type=\"volpath\">\n        <integer name=\"max_depth\" \
         value=\"{depth}\"/>\n    </integrator>"
    );
    for v in views {
        let c = &v.camera;
        let rows: Vec<String> = c
            .to_world_rows()
            .iter()
            .flatten()
            .map(|x| format!("{x}"))
            .collect();
        // Mitsuba's principal-point offsets are fractions of the film: the optical axis meets
        // it at (1/2 − offset) of its size.
        let k = c.intrinsics();
        let offsets = match c.pinhole {
            None => String::new(),
            Some(_) => format!(
                "        <float name=\"principal_point_offset_x\" value=\"{}\"/>\n        \
                 <float name=\"principal_point_offset_y\" value=\"{}\"/>\n",
                0.5 - k.cx / c.width as f32,
                0.5 - k.cy / c.height as f32
            ),
        };
        let _ = writeln!(
            s,
            "    <sensor type=\"perspective\">\n        <float name=\"fov\" value=\"{}\"/>\n{offsets}        \
             <string name=\"fov_axis\" value=\"x\"/>\n        <transform name=\"to_world\">\n            \
             <matrix value=\"{}\"/>\n        </transform>\n        <sampler type=\"independent\">\n            \
             <integer name=\"sample_count\" value=\"$spp\"/>\n        </sampler>\n        \
             <film type=\"hdrfilm\">\n            <integer name=\"width\" value=\"{}\"/>\n            \
             <integer name=\"height\" value=\"{}\"/>\n            <string name=\"pixel_format\" value=\"rgb\"/>\n            \
             <rfilter type=\"box\"/>\n        </film>\n    </sensor>",
            c.fov_x_deg,
            rows.join(" "),
            c.width,
            c.height
        );
    }
    let p = light.position;
    let i = light.intensity;
    let _ = writeln!(
        s,
        "    <emitter type=\"point\">\n        <point name=\"position\" x=\"{}\" y=\"{}\" z=\"{}\"/>\n        \
         <rgb name=\"intensity\" value=\"{}, {}, {}\"/>\n    </emitter>",
        p.x, p.y, p.z, i[0], i[1], i[2]
    );
    s.push_str(
        "    <shape type=\"ply\">\n        <string name=\"filename\" value=\"object.ply\"/>\n",
    );
    for line in medium_snippet(m).lines() {
        let _ = writeln!(s, "        {line}");
    }
    s.push_str("    </shape>\n</scene>\n");
    s
}
