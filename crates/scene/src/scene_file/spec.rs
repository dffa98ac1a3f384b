//! Building blocks of scene files shared with dataset.json: [`Rgb`] (three numbers or one for
//! all three), [`MediumSpec`] (the medium as written) and [`ShapeSpec`] (a built-in shape as
//! written), each converted to the validated value with errors naming the field.

use std::fmt;

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use crate::{Medium, SceneError};

/// Three numbers given either as `[a, b, c]` or as one number used for all three.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rgb(pub [f32; 3]);

impl Serialize for Rgb {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

impl<'de> Deserialize<'de> for Rgb {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Rgb;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of 3 numbers [r, g, b]")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Rgb, E> {
                Ok(Rgb([v as f32; 3]))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Rgb, E> {
                Ok(Rgb([v as f32; 3]))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Rgb, E> {
                Ok(Rgb([v as f32; 3]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Rgb, A::Error> {
                let mut out = [0.0f32; 3];
                for (i, o) in out.iter_mut().enumerate() {
                    *o = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(Rgb(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// The medium as written in files: `sigma_t`, `albedo` and `g` (default 0) per channel or one
/// number, `eta` (default 1) and the boundary's `roughness` (GGX α, default 0: smooth).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MediumSpec {
    pub sigma_t: Rgb,
    pub albedo: Rgb,
    #[serde(default)]
    pub g: crate::Anisotropy,
    #[serde(default = "crate::medium::one")]
    pub eta: f32,
    #[serde(default, skip_serializing_if = "crate::medium::is_zero")]
    pub roughness: f32,
}

impl MediumSpec {
    /// The validated medium; `context` is e.g. "scene.toml: medium".
    pub fn to_medium(&self, context: &str) -> Result<Medium, SceneError> {
        let m = Medium {
            sigma_t: self.sigma_t.0,
            albedo: self.albedo.0,
            g: self.g,
            eta: self.eta,
            roughness: self.roughness,
        };
        m.validate(context)?;
        Ok(m)
    }
}

impl From<&Medium> for MediumSpec {
    fn from(m: &Medium) -> Self {
        MediumSpec {
            sigma_t: Rgb(m.sigma_t),
            albedo: Rgb(m.albedo),
            g: m.g,
            eta: m.eta,
            roughness: m.roughness,
        }
    }
}

/// A built-in shape as written in files: `{ name = "blob", scale = 0.5, radius = …, … }`.
/// Parameters not given keep the shape's defaults ([`geometry::Shape::from_name`]); `scale`
/// (default 1) then multiplies every length. Which parameters exist depends on the shape:
///
/// | name | parameters |
/// |---|---|
/// | sphere | radius, subdivisions |
/// | cone | height, radius, tip_radius, segments |
/// | torus | major, minor, segments |
/// | rounded-box | size (`[x, y, z]` or one number), radius, segments |
/// | blob | radius, amplitude, bumps, seed, subdivisions |
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeSpec {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subdivisions: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tip_radius: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segments: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub major: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub minor: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<Rgb>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bumps: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

impl ShapeSpec {
    /// The shape described (parameters applied, then scaled). `context` is e.g.
    /// "scene.toml: shape". Errors on an unknown name, a parameter the shape does not have, and
    /// non-finite numbers; the geometry crate checks the remaining ranges when building.
    pub fn to_shape(&self, context: &str) -> Result<geometry::Shape, SceneError> {
        use geometry::Shape;
        let mut shape = Shape::from_name(&self.name).map_err(|e| SceneError::Invalid {
            location: format!("{context}.name = \"{}\"", self.name),
            reason: e.to_string(),
        })?;
        self.check_finite(context)?;
        let allowed = self.apply(&mut shape);
        let given = [
            ("radius", self.radius.is_some()),
            ("subdivisions", self.subdivisions.is_some()),
            ("height", self.height.is_some()),
            ("tip_radius", self.tip_radius.is_some()),
            ("segments", self.segments.is_some()),
            ("major", self.major.is_some()),
            ("minor", self.minor.is_some()),
            ("size", self.size.is_some()),
            ("amplitude", self.amplitude.is_some()),
            ("bumps", self.bumps.is_some()),
            ("seed", self.seed.is_some()),
        ];
        for (name, is_given) in given {
            if is_given && !allowed.contains(&name) {
                return Err(SceneError::Invalid {
                    location: format!("{context}.{name}"),
                    reason: format!(
                        "shape '{}' has no parameter '{name}'; fix: remove it (its parameters: \
                         scale, {})",
                        self.name,
                        allowed.join(", ")
                    ),
                });
            }
        }
        if let Some(s) = self.scale {
            if s <= 0.0 {
                return Err(SceneError::Invalid {
                    location: format!("{context}.scale = {s}"),
                    reason: "scale must be > 0; fix: use e.g. 0.25 for an object about 0.25 \
                             units across"
                        .into(),
                });
            }
            shape = shape.scaled(s);
        }
        Ok(shape)
    }

    /// The given numbers are finite (`context` names the table).
    fn check_finite(&self, context: &str) -> Result<(), SceneError> {
        let floats = [
            ("scale", self.scale),
            ("radius", self.radius),
            ("height", self.height),
            ("tip_radius", self.tip_radius),
            ("major", self.major),
            ("minor", self.minor),
            ("amplitude", self.amplitude),
        ];
        for (name, v) in floats {
            if let Some(v) = v
                && !v.is_finite()
            {
                return Err(SceneError::Invalid {
                    location: format!("{context}.{name} = {v}"),
                    reason: "must be a finite number".into(),
                });
            }
        }
        if let Some(Rgb(s)) = self.size
            && s.iter().any(|v| !v.is_finite())
        {
            return Err(SceneError::Invalid {
                location: format!("{context}.size = {s:?}"),
                reason: "must be finite".into(),
            });
        }
        Ok(())
    }

    /// Sets the given parameters on `shape`; the names of the parameters it has.
    fn apply(&self, shape: &mut geometry::Shape) -> &'static [&'static str] {
        use geometry::Shape;
        fn set<T: Copy>(dst: &mut T, src: Option<T>) {
            if let Some(v) = src {
                *dst = v;
            }
        }
        match shape {
            Shape::Sphere {
                radius,
                subdivisions,
            } => {
                set(radius, self.radius);
                set(subdivisions, self.subdivisions);
                &["radius", "subdivisions"]
            }
            Shape::Cone {
                height,
                radius,
                tip_radius,
                segments,
            } => {
                set(height, self.height);
                set(radius, self.radius);
                set(tip_radius, self.tip_radius);
                set(segments, self.segments);
                &["height", "radius", "tip_radius", "segments"]
            }
            Shape::Torus {
                major,
                minor,
                segments,
            } => {
                set(major, self.major);
                set(minor, self.minor);
                set(segments, self.segments);
                &["major", "minor", "segments"]
            }
            Shape::RoundedBox {
                size,
                radius,
                segments,
            } => {
                set(size, self.size.map(|s| s.0));
                set(radius, self.radius);
                set(segments, self.segments);
                &["size", "radius", "segments"]
            }
            Shape::Blob {
                radius,
                amplitude,
                bumps,
                seed,
                subdivisions,
            } => {
                set(radius, self.radius);
                set(amplitude, self.amplitude);
                set(bumps, self.bumps);
                set(seed, self.seed);
                set(subdivisions, self.subdivisions);
                &["radius", "amplitude", "bumps", "seed", "subdivisions"]
            }
        }
    }

    /// Parse the compact command-line form `NAME[:KEY=VALUE]…`, e.g. `blob:amplitude=0.05:bumps=6`
    /// (the keys and meanings of the scene file's `shape` table; `size` takes one number here).
    /// `context` names the option in errors, e.g. "--shapes". [`Self::to_shape`] then checks the
    /// parameters against the shape.
    pub fn parse_compact(text: &str, context: &str) -> Result<ShapeSpec, SceneError> {
        let invalid = |reason: String| SceneError::Invalid {
            location: format!("{context} \"{text}\""),
            reason,
        };
        let mut parts = text.split(':');
        let name = parts.next().unwrap_or_default().trim();
        if name.is_empty() {
            return Err(invalid(
                "names no shape; fix: write NAME[:KEY=VALUE]…, e.g. blob:amplitude=0.05".into(),
            ));
        }
        let mut toml_text = format!("name = {name:?}\n");
        for part in parts {
            let Some((key, value)) = part.split_once('=') else {
                return Err(invalid(format!(
                    "'{part}' is not KEY=VALUE; fix: e.g. {name}:radius=0.4"
                )));
            };
            let (key, value) = (key.trim(), value.trim());
            if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                return Err(invalid(format!("'{key}' is not a parameter name")));
            }
            toml_text.push_str(&format!("{key} = {value}\n"));
        }
        toml::from_str(&toml_text).map_err(|e| invalid(e.message().to_string()))
    }

    /// The spec that reproduces `shape` exactly (every parameter written, no scale).
    pub fn from_shape(shape: &geometry::Shape) -> ShapeSpec {
        use geometry::Shape;
        let mut s = ShapeSpec {
            name: shape.name().to_string(),
            ..Default::default()
        };
        match *shape {
            Shape::Sphere {
                radius,
                subdivisions,
            } => {
                s.radius = Some(radius);
                s.subdivisions = Some(subdivisions);
            }
            Shape::Cone {
                height,
                radius,
                tip_radius,
                segments,
            } => {
                s.height = Some(height);
                s.radius = Some(radius);
                s.tip_radius = Some(tip_radius);
                s.segments = Some(segments);
            }
            Shape::Torus {
                major,
                minor,
                segments,
            } => {
                s.major = Some(major);
                s.minor = Some(minor);
                s.segments = Some(segments);
            }
            Shape::RoundedBox {
                size,
                radius,
                segments,
            } => {
                s.size = Some(Rgb(size));
                s.radius = Some(radius);
                s.segments = Some(segments);
            }
            Shape::Blob {
                radius,
                amplitude,
                bumps,
                seed,
                subdivisions,
            } => {
                s.radius = Some(radius);
                s.amplitude = Some(amplitude);
                s.bumps = Some(bumps);
                s.seed = Some(seed);
                s.subdivisions = Some(subdivisions);
            }
        }
        s
    }
}
