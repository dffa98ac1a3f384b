//! The Henyey–Greenstein anisotropy g of a medium, one value per RGB channel.
//!
//! g is the mean cosine of the scattering angle, in (−1, 1) (0 = isotropic, > 0 = forward
//! scattering). Real media's g depends on the wavelength: a milk's fat droplets scatter blue
//! light more isotropically than red (Narasimhan et al. 2006, Table 1 lists g per channel), so a
//! medium may state one g for all channels or one per channel.
//!
//! In files g is either one number (`"g": 0.7`, every channel) or three (`"g": [0.7, 0.75,
//! 0.8]`, red, green, blue); it is written back as one number when the three are equal, so a
//! medium of one g reads and writes exactly as before g could be chromatic.

use std::fmt;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::scene_file::Rgb;

/// The Henyey–Greenstein g of each RGB channel ([module docs](self)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Anisotropy(pub [f32; 3]);

impl Anisotropy {
    /// Isotropic scattering in every channel (g = 0).
    pub const ISOTROPIC: Anisotropy = Anisotropy([0.0; 3]);

    /// One g for every channel.
    pub const fn uniform(g: f32) -> Self {
        Anisotropy([g; 3])
    }

    /// The g of each channel.
    #[inline]
    pub fn channels(&self) -> [f32; 3] {
        self.0
    }

    /// The one g of every channel, or `None` when the channels differ (a chromatic medium).
    #[inline]
    pub fn as_uniform(&self) -> Option<f32> {
        let [r, g, b] = self.0;
        (r == g && g == b).then_some(r)
    }

    /// Whether the channels share one g.
    #[inline]
    pub fn is_uniform(&self) -> bool {
        self.as_uniform().is_some()
    }

    /// Whether every channel scatters isotropically.
    #[inline]
    pub fn is_isotropic(&self) -> bool {
        self.0 == [0.0; 3]
    }

    /// The channels' mean g: the one g of a uniform medium, and what a model that renders one g
    /// for all channels renders a chromatic one with (it says so: the models' physics gaps).
    #[inline]
    pub fn mean(&self) -> f32 {
        let [r, g, b] = self.0;
        if r == g && g == b {
            r
        } else {
            (r + g + b) / 3.0
        }
    }

    /// The first channel whose g is outside (−1, 1) or not finite, with its value.
    pub fn out_of_range(&self) -> Option<(usize, f32)> {
        (0..3)
            .map(|c| (c, self.0[c]))
            .find(|&(_, g)| !(g.is_finite() && g > -1.0 && g < 1.0))
    }

    /// The field name of channel `c` in errors: `g` for a uniform g, `g[c]` otherwise.
    pub fn field(&self, c: usize) -> String {
        if self.is_uniform() {
            "g".into()
        } else {
            format!("g[{c}]")
        }
    }
}

impl From<f32> for Anisotropy {
    fn from(g: f32) -> Self {
        Anisotropy::uniform(g)
    }
}

impl fmt::Display for Anisotropy {
    /// `0.3` for a uniform g, `(0.7, 0.75, 0.8)` for a chromatic one.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.as_uniform() {
            Some(g) => write!(f, "{g}"),
            None => write!(f, "({}, {}, {})", self.0[0], self.0[1], self.0[2]),
        }
    }
}

impl Serialize for Anisotropy {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.as_uniform() {
            Some(g) => g.serialize(s),
            None => self.0.serialize(s),
        }
    }
}

impl<'de> Deserialize<'de> for Anisotropy {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Rgb::deserialize(d).map(|rgb| Anisotropy(rgb.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_number_or_three_read_and_write_back() {
        let one: Anisotropy = serde_json::from_str("0.7").unwrap();
        assert_eq!(one, Anisotropy::uniform(0.7));
        assert_eq!(serde_json::to_string(&one).unwrap(), "0.7");
        let three: Anisotropy = serde_json::from_str("[0.7, 0.75, 0.8]").unwrap();
        assert_eq!(three.channels(), [0.7, 0.75, 0.8]);
        assert_eq!(three.as_uniform(), None);
        assert_eq!(serde_json::to_string(&three).unwrap(), "[0.7,0.75,0.8]");
        let same: Anisotropy = serde_json::from_str("[0.3, 0.3, 0.3]").unwrap();
        assert_eq!(serde_json::to_string(&same).unwrap(), "0.3");
        assert!(serde_json::from_str::<Anisotropy>("[0.1, 0.2]").is_err());
        assert!(serde_json::from_str::<Anisotropy>("\"0.1\"").is_err());
    }

    #[test]
    fn ranges_means_and_names() {
        assert_eq!(Anisotropy([0.1, 1.0, 0.2]).out_of_range(), Some((1, 1.0)));
        assert_eq!(Anisotropy::uniform(-0.99).out_of_range(), None);
        assert!(Anisotropy([0.0, f32::NAN, 0.0]).out_of_range().is_some());
        assert_eq!(Anisotropy::uniform(0.4).mean(), 0.4);
        assert!((Anisotropy([0.6, 0.7, 0.8]).mean() - 0.7).abs() < 1e-6);
        assert_eq!(Anisotropy([0.6, 0.7, 0.8]).field(2), "g[2]");
        assert_eq!(Anisotropy::uniform(0.6).field(2), "g");
        assert_eq!(Anisotropy([0.6, 0.7, 0.8]).to_string(), "(0.6, 0.7, 0.8)");
        assert_eq!(Anisotropy::uniform(0.6).to_string(), "0.6");
        assert!(Anisotropy::ISOTROPIC.is_isotropic());
    }
}
