//! The optimised medium parameters and their parameterisation (Son et al. 2024 §5;
//! docs/model.md §8.3, A12–A13).
//!
//! The optimiser sees six unconstrained numbers u = (u_σ,R, u_σ,G, u_σ,B, u_α,R, u_α,G, u_α,B):
//!
//! * σ_t = 100·u_σ ([`Parameterisation::Scaled`], the paper's release: σ_t/100), or
//!   σ_t = exp(u_σ) ([`Parameterisation::Log`]); chain rule ∂ℓ/∂u_σ = ∂ℓ/∂σ_t · dσ_t/du_σ with
//!   dσ_t/du_σ = 100 or σ_t;
//! * α = u_α;
//!
//! * g = u_g, a seventh variable when the run recovers the phase function's g
//!   ([`ParamSpec::free_g`]; one g for all channels), or three, g_R, g_G, g_B, with
//!   [`ParamSpec::g_per_channel`] (a chromatic medium). Channel c's image depends on g_c alone,
//!   so ∂ℓ/∂g_c is channel c's term of ∂ℓ/∂g, and a shared g's derivative their sum;
//! * k = exp(u_k), the factor on every light's stated intensity, the next variable when the run
//!   recovers the light's strength ([`ParamSpec::free_light_scale`]): one factor for all lights
//!   and channels, or one per channel with [`ParamSpec::light_scale_per_channel`] (an unknown
//!   white balance: three variables, k_R, k_G, k_B). The images are linear in it, I_c(k) =
//!   k_c·I_c(1), so ∂I_c/∂ln k_c = I_c, and a shared k's derivative is the sum over the channels;
//!
//! then clamped after every step: α ∈ [ALBEDO_MIN, ALBEDO_MAX] (the paper's (0, 0.99995)),
//! σ_t ≥ SIGMA_T_MIN, g ∈ [−G_MAX, G_MAX], k ∈ [LIGHT_SCALE_MIN, LIGHT_SCALE_MAX]. A monochrome run shares one value per kind over the
//! channels (the gradient is the channel mean, docs/model.md A13); a fixed parameter keeps its
//! value (zero gradient). Without a free g, g is the object's ([`Params::medium`]'s `base`).

use scene::Medium;
use serde::{Deserialize, Serialize};

/// Smallest albedo after clamping.
pub const ALBEDO_MIN: f64 = 1e-4;
/// Largest albedo after clamping (Son et al.'s clamp).
pub const ALBEDO_MAX: f64 = 0.99995;
/// Smallest extinction after clamping (1/unit).
pub const SIGMA_T_MIN: f64 = 1e-3;
/// Largest |g| after clamping: HG lobes narrower than this are beyond what a recovery's
/// images resolve, and g → ±1 is a delta.
pub const G_MAX: f64 = 0.95;
/// Smallest light scale after clamping.
pub const LIGHT_SCALE_MIN: f64 = 1e-3;
/// Largest light scale after clamping.
pub const LIGHT_SCALE_MAX: f64 = 1e3;

/// How σ_t is represented for the optimiser.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Parameterisation {
    /// u = σ_t/100.
    #[default]
    Scaled,
    /// u = ln σ_t.
    Log,
}

/// Which parameters move and how.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamSpec {
    /// σ_t representation.
    pub parameterisation: Parameterisation,
    /// One σ_t and one α shared by the channels.
    pub monochrome: bool,
    /// Keep σ_t at its initial value.
    pub fix_sigma_t: bool,
    /// Keep α at its initial value.
    pub fix_albedo: bool,
    /// Recover the phase function's g (one value for all channels) as a seventh variable.
    /// (Left out of the JSON when off, so runs written before the option compare equal.)
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub free_g: bool,
    /// With a free g, one g per channel (a chromatic medium): three variables, g_R, g_G, g_B.
    /// (Left out of the JSON when off.)
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub g_per_channel: bool,
    /// Recover a factor on every light's stated intensity (one for all lights and channels) as
    /// the last variable. (Left out of the JSON when off.)
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub free_light_scale: bool,
    /// With a free light scale, one factor per channel (the camera's white balance unknown as
    /// well as the light's strength): the last three variables. (Left out of the JSON when off.)
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub light_scale_per_channel: bool,
}

/// One value for every channel, or one per channel: a recovered light scale, its gradient or
/// its interval. Written to JSON as the value, or as an array of three.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum OneOrRgb<T> {
    /// One value shared by the channels.
    One(T),
    /// One value per channel (R, G, B).
    Rgb([T; 3]),
}

impl<T: Copy> OneOrRgb<T> {
    /// The value of channel `c`.
    pub fn channel(&self, c: usize) -> T {
        match self {
            OneOrRgb::One(v) => *v,
            OneOrRgb::Rgb(v) => v[c],
        }
    }

    /// The values: one, or three.
    pub fn values(&self) -> &[T] {
        match self {
            OneOrRgb::One(v) => std::slice::from_ref(v),
            OneOrRgb::Rgb(v) => v,
        }
    }

    /// Each value through `f`, keeping the shape.
    pub fn map<U>(self, mut f: impl FnMut(T) -> U) -> OneOrRgb<U> {
        match self {
            OneOrRgb::One(v) => OneOrRgb::One(f(v)),
            OneOrRgb::Rgb(v) => OneOrRgb::Rgb(v.map(f)),
        }
    }

    /// `f` of this and `other` value by value: one where both are one, per channel otherwise.
    pub fn zip_with<U: Copy, V>(self, other: OneOrRgb<U>, f: impl Fn(T, U) -> V) -> OneOrRgb<V> {
        match (self, other) {
            (OneOrRgb::One(a), OneOrRgb::One(b)) => OneOrRgb::One(f(a, b)),
            _ => OneOrRgb::Rgb(std::array::from_fn(|c| {
                f(self.channel(c), other.channel(c))
            })),
        }
    }
}

impl Default for ParamSpec {
    fn default() -> Self {
        Self {
            parameterisation: Parameterisation::Scaled,
            monochrome: false,
            fix_sigma_t: false,
            fix_albedo: false,
            free_g: false,
            g_per_channel: false,
            free_light_scale: false,
            light_scale_per_channel: false,
        }
    }
}

/// σ_t and α per channel, and g where the run recovers it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Params {
    /// Extinction per channel (1/unit).
    pub sigma_t: [f64; 3],
    /// Single-scattering albedo per channel.
    pub albedo: [f64; 3],
    /// The Henyey–Greenstein g, one or one per channel, where the run recovers it
    /// ([`ParamSpec::free_g`]); `None`: the object's own. (Left out of the JSON when `None`.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g: Option<OneOrRgb<f64>>,
    /// The factor on every light's stated intensity, one or one per channel, where the run
    /// recovers it ([`ParamSpec::free_light_scale`]); `None`: the lights as stated. (Left out of
    /// the JSON when `None`.)
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub light_scale: Option<OneOrRgb<f64>>,
}

impl Params {
    /// σ_t and α per channel, with the object's g.
    pub fn new(sigma_t: [f64; 3], albedo: [f64; 3]) -> Self {
        Self {
            sigma_t,
            albedo,
            g: None,
            light_scale: None,
        }
    }

    /// `light` with its intensity times the recovered light scale, channel by channel (as
    /// stated without one).
    pub fn light(&self, light: &scene::PointLight) -> scene::PointLight {
        scene::PointLight {
            intensity: std::array::from_fn(|c| light.intensity[c] * self.light_scale_of(c) as f32),
            ..*light
        }
    }

    /// The light scale of channel `c` (1 where the run does not recover one).
    pub fn light_scale_of(&self, c: usize) -> f64 {
        self.light_scale.map_or(1.0, |k| k.channel(c))
    }

    /// The g of every channel: the recovered one where the run recovers it, `stated` (the
    /// object's) otherwise.
    pub fn g_or(&self, stated: scene::Anisotropy) -> scene::Anisotropy {
        match self.g {
            Some(g) => scene::Anisotropy(std::array::from_fn(|c| g.channel(c) as f32)),
            None => stated,
        }
    }

    /// The parameters of a medium (its g is the object's, not a parameter).
    pub fn of(m: &Medium) -> Self {
        Self::new(m.sigma_t.map(|v| v as f64), m.albedo.map(|v| v as f64))
    }

    /// A medium with these parameters, this g where it has one, and `base`'s g otherwise,
    /// η and roughness.
    pub fn medium(&self, base: &Medium) -> Medium {
        Medium {
            sigma_t: self.sigma_t.map(|v| v as f32),
            albedo: self.albedo.map(|v| v as f32),
            g: self.g_or(base.g),
            eta: base.eta,
            roughness: base.roughness,
        }
    }
}

/// One value, or `[r, g, b]`, each with the formatter's precision.
impl OneOrRgb<f64> {
    /// A per-channel quantity as a variable that is one value or one per channel has it
    /// (`per_channel`): the three values, or their sum (the gradient of one shared value).
    pub fn summed(per_channel: bool, d: [f64; 3]) -> Self {
        if per_channel {
            OneOrRgb::Rgb(d)
        } else {
            OneOrRgb::One(d.iter().sum())
        }
    }
}

impl<T: std::fmt::Display> std::fmt::Display for OneOrRgb<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OneOrRgb::One(v) => v.fmt(f),
            OneOrRgb::Rgb([r, g, b]) => {
                f.write_str("[")?;
                r.fmt(f)?;
                f.write_str(", ")?;
                g.fmt(f)?;
                f.write_str(", ")?;
                b.fmt(f)?;
                f.write_str("]")
            }
        }
    }
}

impl ParamSpec {
    /// The number of the optimiser's variables: six, one or three for a free g, and one or
    /// three for a free light scale.
    pub fn len(&self) -> usize {
        6 + self.g_count() + self.light_scale_count()
    }

    /// The number of g variables: 0 (the object's g), 1, or 3 (per channel).
    pub fn g_count(&self) -> usize {
        match (self.free_g, self.g_per_channel) {
            (false, _) => 0,
            (true, false) => 1,
            (true, true) => 3,
        }
    }

    /// The indices of the g variables (empty where g is the object's).
    pub fn g_indices(&self) -> std::ops::Range<usize> {
        6..6 + self.g_count()
    }

    /// The number of light-scale variables: 0 (the lights as stated), 1, or 3 (per channel).
    pub fn light_scale_count(&self) -> usize {
        match (self.free_light_scale, self.light_scale_per_channel) {
            (false, _) => 0,
            (true, false) => 1,
            (true, true) => 3,
        }
    }

    /// The index of the (first) g among the variables, where it is free (the others, per
    /// channel, follow it).
    pub fn g_index(&self) -> Option<usize> {
        self.free_g.then_some(6)
    }

    /// The index of the first ln k among the variables, where the light scale is free (the
    /// others, per channel, follow it).
    pub fn light_scale_index(&self) -> Option<usize> {
        self.free_light_scale.then_some(6 + self.g_count())
    }

    /// The indices of the ln k variables (empty where the light scale is fixed).
    pub fn light_scale_indices(&self) -> std::ops::Range<usize> {
        let i = 6 + self.g_count();
        i..i + self.light_scale_count()
    }

    /// Always false: the optimiser has at least six variables.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The optimiser's vector for `p` (a free g that `p` lacks starts at 0, a free light scale
    /// at 1; one g from per-channel ones is their mean).
    pub fn encode(&self, p: &Params) -> Vec<f32> {
        let mut u = Vec::with_capacity(self.len());
        for &s in &p.sigma_t {
            u.push(match self.parameterisation {
                Parameterisation::Scaled => (s / 100.0) as f32,
                Parameterisation::Log => s.ln() as f32,
            });
        }
        u.extend(p.albedo.iter().map(|&a| a as f32));
        let g_of = |c: usize| p.g.map_or(0.0, |g| g.channel(c));
        match self.g_count() {
            0 => {}
            1 => u.push(((0..3).map(g_of).sum::<f64>() / 3.0) as f32),
            _ => u.extend((0..3).map(|c| g_of(c) as f32)),
        }
        match self.light_scale_count() {
            0 => {}
            // One factor from per-channel ones: their geometric mean.
            1 => u.push(((0..3).map(|c| p.light_scale_of(c).ln()).sum::<f64>() / 3.0) as f32),
            _ => u.extend((0..3).map(|c| p.light_scale_of(c).ln() as f32)),
        }
        u
    }

    /// The parameters of the optimiser's vector (clamped).
    pub fn decode(&self, u: &[f32]) -> Params {
        let sigma = |v: f32| match self.parameterisation {
            Parameterisation::Scaled => 100.0 * v as f64,
            Parameterisation::Log => (v as f64).exp(),
        };
        Params {
            sigma_t: std::array::from_fn(|c| sigma(u[c]).max(SIGMA_T_MIN)),
            albedo: std::array::from_fn(|c| (u[3 + c] as f64).clamp(ALBEDO_MIN, ALBEDO_MAX)),
            g: {
                let g = |i: usize| (u[i] as f64).clamp(-G_MAX, G_MAX);
                match self.g_count() {
                    0 => None,
                    1 => Some(OneOrRgb::One(g(6))),
                    _ => Some(OneOrRgb::Rgb(std::array::from_fn(|c| g(6 + c)))),
                }
            },
            light_scale: {
                let k = |i: usize| (u[i] as f64).exp().clamp(LIGHT_SCALE_MIN, LIGHT_SCALE_MAX);
                let i = self.light_scale_indices().start;
                match self.light_scale_count() {
                    0 => None,
                    1 => Some(OneOrRgb::One(k(i))),
                    _ => Some(OneOrRgb::Rgb(std::array::from_fn(|c| k(i + c)))),
                }
            },
        }
    }

    /// Clamps `u` in place to the representable range (after an optimiser step).
    pub fn clamp(&self, u: &mut [f32]) {
        let p = self.decode(u);
        let e = self.encode(&p);
        u.copy_from_slice(&e);
    }

    /// ∂ℓ/∂u from ∂ℓ/∂σ_t and ∂ℓ/∂α (monochrome averaging and fixed parameters applied),
    /// channel c's term ∂ℓ/∂g_c of a free g and ∂ℓ/∂ln k_c of a free light scale: for one g
    /// (one factor) their sum, for one per channel each.
    pub fn chain(
        &self,
        p: &Params,
        d_sigma_t: [f64; 3],
        d_albedo: [f64; 3],
        d_g: [f64; 3],
        d_ln_k: [f64; 3],
    ) -> Vec<f32> {
        let mut gs: [f64; 3] = std::array::from_fn(|c| {
            d_sigma_t[c]
                * match self.parameterisation {
                    Parameterisation::Scaled => 100.0,
                    Parameterisation::Log => p.sigma_t[c],
                }
        });
        let mut ga = d_albedo;
        if self.monochrome {
            let m = gs.iter().sum::<f64>() / 3.0;
            gs = [m; 3];
            let m = ga.iter().sum::<f64>() / 3.0;
            ga = [m; 3];
        }
        if self.fix_sigma_t {
            gs = [0.0; 3];
        }
        if self.fix_albedo {
            ga = [0.0; 3];
        }
        let dg: Vec<f64> = match self.g_count() {
            0 => Vec::new(),
            1 => vec![d_g.iter().sum()],
            _ => d_g.to_vec(),
        };
        let dk: Vec<f64> = match self.light_scale_count() {
            0 => Vec::new(),
            1 => vec![d_ln_k.iter().sum()],
            _ => d_ln_k.to_vec(),
        };
        gs.iter()
            .chain(&ga)
            .chain(&dg)
            .chain(&dk)
            .map(|&g| g as f32)
            .collect()
    }
}

#[cfg(test)]
mod tests;
