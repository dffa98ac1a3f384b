//! The values of a Mitsuba 3 scene file: properties (`<float name="…" value="…"/>`, `rgb`,
//! `spectrum`, `point`, `string`, `integer`, `boolean`), `$name` substitution from `<default>`,
//! transforms (`translate`, `scale`, `rotate`, `matrix`, `lookat`, composed in the order written:
//! M = op_n ⋯ op_1, as Mitsuba's loader does) and the named indices of refraction of Mitsuba's
//! `dielectric` plugin.

use std::collections::HashMap;

use glam::{DMat4, DVec3};
use roxmltree::Node;

use crate::SceneError;

/// A scene file being read: its path and its `<default>` values.
pub(super) struct Doc {
    pub(super) file: String,
    pub(super) defaults: HashMap<String, String>,
}

impl Doc {
    /// "file.xml:LINE <tag name="…">" of a node.
    pub(super) fn at(&self, n: Node) -> String {
        let pos = n.document().text_pos_at(n.range().start);
        let name = n
            .attribute("name")
            .map(|v| format!(" name=\"{v}\""))
            .unwrap_or_default();
        format!("{}:{} <{}{name}>", self.file, pos.row, n.tag_name().name())
    }

    /// An error at `n`.
    pub(super) fn err(&self, n: Node, reason: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            location: self.at(n),
            reason: reason.into(),
        }
    }

    /// Attribute `key` of `n` with `$name` replaced by the `<default>` values.
    pub(super) fn attr(&self, n: Node, key: &str) -> Result<Option<String>, SceneError> {
        let Some(raw) = n.attribute(key) else {
            return Ok(None);
        };
        let mut out = String::with_capacity(raw.len());
        let mut rest = raw;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let len = tail
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(tail.len());
            let name = &tail[..len];
            let Some(v) = self.defaults.get(name) else {
                return Err(self.err(
                    n,
                    format!(
                        "{key}=\"{raw}\" names ${name}, which no <default name=\"{name}\" \
                         value=\"…\"/> declares; fix: declare it at the top of the scene"
                    ),
                ));
            };
            out.push_str(v);
            rest = &tail[len..];
        }
        out.push_str(rest);
        Ok(Some(out))
    }

    /// A required attribute.
    pub(super) fn req(&self, n: Node, key: &str) -> Result<String, SceneError> {
        self.attr(n, key)?
            .ok_or_else(|| self.err(n, format!("the attribute {key}=\"…\" is missing")))
    }

    /// Numbers separated by commas or spaces.
    pub(super) fn numbers(&self, n: Node, key: &str, text: &str) -> Result<Vec<f64>, SceneError> {
        text.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| {
                s.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| {
                        self.err(n, format!("{key}=\"{text}\": '{s}' is not a finite number"))
                    })
            })
            .collect()
    }

    /// One finite number in attribute `key`.
    pub(super) fn number(&self, n: Node, key: &str) -> Result<f64, SceneError> {
        let t = self.req(n, key)?;
        match self.numbers(n, key, &t)?.as_slice() {
            [v] => Ok(*v),
            _ => Err(self.err(n, format!("{key}=\"{t}\" must be one number"))),
        }
    }

    /// The value of a `float` or `integer` property.
    pub(super) fn float(&self, n: Node) -> Result<f64, SceneError> {
        match n.tag_name().name() {
            "float" | "integer" => self.number(n, "value"),
            t => Err(self.err(n, format!("expected a <float>, found <{t}>"))),
        }
    }

    /// The value of an `integer` property.
    pub(super) fn integer(&self, n: Node) -> Result<i64, SceneError> {
        let v = self.float(n)?;
        if v.fract() != 0.0 || v.abs() > 1e15 {
            return Err(self.err(n, format!("value {v} must be an integer")));
        }
        Ok(v as i64)
    }

    /// The value of a `string` property.
    pub(super) fn string(&self, n: Node) -> Result<String, SceneError> {
        match n.tag_name().name() {
            "string" => self.req(n, "value"),
            t => Err(self.err(n, format!("expected a <string>, found <{t}>"))),
        }
    }

    /// An RGB value: `<rgb value="r, g, b"/>` (or one value for all three), a constant
    /// `<spectrum value="v"/>`, or a `<float>`.
    pub(super) fn rgb(&self, n: Node) -> Result<[f64; 3], SceneError> {
        let name = n.tag_name().name();
        if !matches!(name, "rgb" | "spectrum" | "float" | "integer") {
            return Err(self.err(
                n,
                format!("expected an <rgb>, a constant <spectrum> or a <float>, found <{name}>"),
            ));
        }
        if name == "spectrum" && n.attribute("filename").is_some() {
            return Err(self.err(
                n,
                "a spectrum from a file is not read; fix: give its RGB value as <rgb value=\"r, g, b\"/>",
            ));
        }
        let t = self.req(n, "value")?;
        if name == "spectrum" && t.contains(':') {
            return Err(self.err(
                n,
                format!(
                    "value=\"{t}\": a sampled spectrum (wavelength:value pairs) is not read; the \
                     tracer renders RGB; fix: give its RGB value as <rgb value=\"r, g, b\"/>"
                ),
            ));
        }
        match self.numbers(n, "value", &t)?.as_slice() {
            [v] => Ok([*v; 3]),
            [r, g, b] if name == "rgb" => Ok([*r, *g, *b]),
            _ => Err(self.err(
                n,
                format!("value=\"{t}\" must be one number or three (r, g, b)"),
            )),
        }
    }

    /// A `point` or `vector`: `x="…" y="…" z="…"` (each defaulting to 0) or `value="x, y, z"`.
    pub(super) fn point(&self, n: Node) -> Result<DVec3, SceneError> {
        match n.tag_name().name() {
            "point" | "vector" => self.xyz(n, 0.0),
            t => Err(self.err(n, format!("expected a <point>, found <{t}>"))),
        }
    }

    /// `x`, `y`, `z` attributes (each `default` when absent) or `value="x, y, z"`.
    fn xyz(&self, n: Node, default: f64) -> Result<DVec3, SceneError> {
        if let Some(t) = self.attr(n, "value")? {
            return match self.numbers(n, "value", &t)?.as_slice() {
                [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                _ => Err(self.err(n, format!("value=\"{t}\" must be three numbers x, y, z"))),
            };
        }
        let c = |k: &str| -> Result<f64, SceneError> {
            match self.attr(n, k)? {
                Some(_) => self.number(n, k),
                None => Ok(default),
            }
        };
        Ok(DVec3::new(c("x")?, c("y")?, c("z")?))
    }

    /// A `<transform>`: its operations composed in the order written.
    pub(super) fn transform(&self, n: Node) -> Result<DMat4, SceneError> {
        if n.tag_name().name() != "transform" {
            return Err(self.err(
                n,
                format!("expected a <transform>, found <{}>", n.tag_name().name()),
            ));
        }
        let mut m = DMat4::IDENTITY;
        for op in n.children().filter(Node::is_element) {
            m = self.operation(op)? * m;
        }
        if !m.is_finite() {
            return Err(self.err(n, "the transform is not finite"));
        }
        Ok(m)
    }

    /// One operation of a `<transform>`.
    fn operation(&self, op: Node) -> Result<DMat4, SceneError> {
        Ok(match op.tag_name().name() {
            "translate" => DMat4::from_translation(self.xyz(op, 0.0)?),
            "scale" => {
                let uniform = self
                    .attr(op, "value")?
                    .map(|t| self.numbers(op, "value", &t))
                    .transpose()?;
                let s = match uniform.as_deref() {
                    Some([s]) => DVec3::splat(*s),
                    _ => self.xyz(op, 1.0)?,
                };
                DMat4::from_scale(s)
            }
            "rotate" => {
                let axis = self.xyz(op, 0.0)?;
                if axis.length_squared() == 0.0 {
                    return Err(self.err(op, "the rotation axis is zero; fix: e.g. y=\"1\""));
                }
                let angle = self.number(op, "angle")?;
                DMat4::from_axis_angle(axis.normalize(), angle.to_radians())
            }
            "matrix" => {
                let t = self.req(op, "value")?;
                match self.numbers(op, "value", &t)?.as_slice() {
                    v if v.len() == 16 => {
                        DMat4::from_cols_array(&std::array::from_fn(|i| v[(i % 4) * 4 + i / 4]))
                    }
                    v if v.len() == 9 => {
                        DMat4::from_mat3(glam::DMat3::from_cols_array(&std::array::from_fn(|i| {
                            v[(i % 3) * 3 + i / 3]
                        })))
                    }
                    _ => {
                        return Err(
                            self.err(op, "a matrix has 16 numbers (4×4, row by row) or 9 (3×3)")
                        );
                    }
                }
            }
            "lookat" => {
                let p = |k: &str| -> Result<DVec3, SceneError> {
                    let t = self.req(op, k)?;
                    match self.numbers(op, k, &t)?.as_slice() {
                        [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                        _ => Err(self.err(op, format!("{k}=\"{t}\" must be three numbers"))),
                    }
                };
                let (origin, target, up) = (p("origin")?, p("target")?, p("up")?);
                let dir = (target - origin).normalize_or_zero();
                let left = up.cross(dir).normalize_or_zero();
                if dir == DVec3::ZERO || left == DVec3::ZERO {
                    return Err(self.err(
                        op,
                        "origin equals target, or up is parallel to the view direction; fix: \
                         choose another up",
                    ));
                }
                let new_up = dir.cross(left);
                DMat4::from_cols(
                    left.extend(0.0),
                    new_up.extend(0.0),
                    dir.extend(0.0),
                    origin.extend(1.0),
                )
            }
            t => {
                return Err(self.err(
                    op,
                    format!(
                        "<{t}> is not a transform operation (translate, scale, rotate, matrix, \
                         lookat)"
                    ),
                ));
            }
        })
    }

    /// An index of refraction: a number, or one of the names Mitsuba's `dielectric` knows.
    pub(super) fn ior(&self, n: Node) -> Result<f64, SceneError> {
        let v = match n.tag_name().name() {
            "string" => {
                let name = self.req(n, "value")?;
                named_ior(&name).ok_or_else(|| {
                    self.err(
                        n,
                        format!(
                            "\"{name}\" is not an index of refraction Mitsuba names ({}); fix: \
                             give it as <float name=\"…\" value=\"1.5\"/>",
                            NAMED_IOR.map(|(k, _)| k).join(", ")
                        ),
                    )
                })?
            }
            _ => self.float(n)?,
        };
        if !(v.is_finite() && v >= 1.0) {
            return Err(self.err(n, format!("index of refraction {v} must be ≥ 1")));
        }
        Ok(v)
    }
}

/// Mitsuba 3's named indices of refraction (its `ior.h`, at 589 nm).
const NAMED_IOR: [(&str, f64); 23] = [
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

/// The index of a Mitsuba material name.
pub(super) fn named_ior(name: &str) -> Option<f64> {
    NAMED_IOR
        .iter()
        .find(|(k, _)| k.eq_ignore_ascii_case(name.trim()))
        .map(|&(_, v)| v)
}
