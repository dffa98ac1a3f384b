//! The ways a real capture is wrong ([`Perturbation`]), each applied to a dataset whose images
//! are the true object's: what the recovery is told (cameras, lights, mesh) departs from what
//! made the images, or the images carry what a camera adds (8-bit sRGB quantisation, sensor
//! noise).
//!
//! Random draws come from counter-based streams of the experiment's seed, one per view and
//! purpose, so a perturbed dataset is the same whatever order it is made in.

use glam::{Mat3, Vec3};
use scene::image::{srgb_to_linear, to_srgb8};
use scene::{Dataset, Image};
use volpath::rng::Sampler;

/// One capture error of the experiment's table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Perturbation {
    /// The dataset as rendered: the row every other is compared with.
    None,
    /// Each camera turned by this angle (degrees) about a random axis through its centre.
    CameraRotation { degrees: f32 },
    /// Each camera moved by this fraction of its distance to the object, in a random direction.
    CameraPosition { fraction: f32 },
    /// Each light moved by this fraction of its distance to the object, in a random direction;
    /// a light shared by every view (a fixed lamp) is moved once.
    LightPosition { fraction: f32 },
    /// Every light's stated intensity times this factor (the images were made with 1).
    LightIntensity { factor: f32 },
    /// Every light's stated red and blue intensity times these factors, green as made: a
    /// camera's white balance that the capture does not know.
    WhiteBalance { red: f32, blue: f32 },
    /// The mesh decimated to 1/factor of its triangles ([`geometry::remesh::decimate`]).
    Decimated { factor: f32 },
    /// The mesh's vertices moved along their normals by Gaussian noise of this standard
    /// deviation, as a fraction of the bounding-box diagonal.
    ScanNoise { fraction: f32 },
    /// The mesh smoothed by this many Taubin passes ([`geometry::remesh::taubin_smooth`]): a
    /// reconstruction's lost detail.
    ScanSmoothed { passes: u32 },
    /// The images as 8-bit sRGB photos, exposed so that the brightest pixel of all views is
    /// full scale, decoded back to linear.
    Srgb8,
    /// Poisson–Gaussian sensor noise: the brightest pixel of all views collects `full_well`
    /// electrons, each pixel's count is Poisson, plus Gaussian read noise of `read_noise`
    /// electrons. `iso` names the level in the table.
    SensorNoise {
        iso: u32,
        full_well: f32,
        read_noise: f32,
    },
}

/// The experiment's perturbations, in its table's order: each error at two levels, about what
/// a careful and a hurried capture leave.
pub fn all() -> Vec<Perturbation> {
    use Perturbation::*;
    vec![
        None,
        CameraRotation { degrees: 0.1 },
        CameraRotation { degrees: 0.5 },
        CameraPosition { fraction: 0.005 },
        CameraPosition { fraction: 0.02 },
        LightPosition { fraction: 0.01 },
        LightPosition { fraction: 0.05 },
        LightIntensity { factor: 1.05 },
        LightIntensity { factor: 0.95 },
        LightIntensity { factor: 1.10 },
        LightIntensity { factor: 0.90 },
        WhiteBalance {
            red: 1.10,
            blue: 0.90,
        },
        Decimated { factor: 10.0 },
        Decimated { factor: 50.0 },
        ScanNoise { fraction: 0.002 },
        ScanSmoothed { passes: 10 },
        Srgb8,
        // A full-frame sensor at base ISO (a large well, little read noise), and at ISO 3200,
        // the well 32× smaller in the image's units.
        SensorNoise {
            iso: 100,
            full_well: 20000.0,
            read_noise: 3.0,
        },
        SensorNoise {
            iso: 3200,
            full_well: 625.0,
            read_noise: 2.0,
        },
    ]
}

impl Perturbation {
    /// Its name in folder names, the table and the selection setting.
    pub fn name(&self) -> String {
        match *self {
            Perturbation::None => "none".into(),
            Perturbation::CameraRotation { degrees } => format!("camera-rotation-{degrees}deg"),
            Perturbation::CameraPosition { fraction } => {
                format!("camera-position-{}pct", 100.0 * fraction)
            }
            Perturbation::LightPosition { fraction } => {
                format!("light-position-{}pct", 100.0 * fraction)
            }
            Perturbation::LightIntensity { factor } => {
                format!("light-intensity-x{factor}")
            }
            Perturbation::WhiteBalance { red, blue } => format!("white-balance-r{red}-b{blue}"),
            Perturbation::Decimated { factor } => format!("mesh-decimated-x{factor}"),
            Perturbation::ScanNoise { fraction } => format!("mesh-noise-{}pct", 100.0 * fraction),
            Perturbation::ScanSmoothed { passes } => format!("mesh-smoothed-{passes}"),
            Perturbation::Srgb8 => "srgb-8bit".into(),
            Perturbation::SensorNoise { iso, .. } => format!("sensor-noise-iso{iso}"),
        }
    }

    /// What it does, for the table.
    pub fn describe(&self) -> String {
        match *self {
            Perturbation::None => "none (the dataset as rendered)".into(),
            Perturbation::CameraRotation { degrees } => format!("camera rotation {degrees}°"),
            Perturbation::CameraPosition { fraction } => {
                format!("camera position {} % of the distance", 100.0 * fraction)
            }
            Perturbation::LightPosition { fraction } => {
                format!("light position {} % of the distance", 100.0 * fraction)
            }
            Perturbation::LightIntensity { factor } => {
                format!("light intensity {:+.0} %", 100.0 * (factor - 1.0))
            }
            Perturbation::WhiteBalance { red, blue } => format!(
                "white balance R {:+.0} %, B {:+.0} %",
                100.0 * (red - 1.0),
                100.0 * (blue - 1.0)
            ),
            Perturbation::Decimated { factor } => format!("mesh decimated ×{factor}"),
            Perturbation::ScanNoise { fraction } => {
                format!("mesh noise {} % of the size", 100.0 * fraction)
            }
            Perturbation::ScanSmoothed { passes } => format!("mesh smoothed ({passes} passes)"),
            Perturbation::Srgb8 => "8-bit sRGB".into(),
            Perturbation::SensorNoise {
                iso,
                full_well,
                read_noise,
            } => format!("sensor noise ISO {iso} ({full_well} e⁻ full, {read_noise} e⁻ read)"),
        }
    }

    /// The factor per channel on the stated lights that gives the lights that made the images:
    /// 1/factor for an intensity or white-balance error, 1 for every other.
    pub fn true_light_scale(&self) -> [f64; 3] {
        self.stated_factor().map(|f| 1.0 / f as f64)
    }

    /// The factor per channel on the lights that made the images which the dataset states.
    fn stated_factor(&self) -> [f32; 3] {
        match *self {
            Perturbation::LightIntensity { factor } => [factor; 3],
            Perturbation::WhiteBalance { red, blue } => [red, 1.0, blue],
            _ => [1.0; 3],
        }
    }

    /// Whether it changes the mesh.
    pub fn changes_mesh(&self) -> bool {
        matches!(
            self,
            Perturbation::Decimated { .. }
                | Perturbation::ScanNoise { .. }
                | Perturbation::ScanSmoothed { .. }
        )
    }

    /// The perturbed mesh (the mesh itself for the perturbations that leave it).
    pub fn mesh(&self, mesh: &geometry::Mesh, seed: u64) -> geometry::Mesh {
        match *self {
            Perturbation::Decimated { factor } => geometry::remesh::decimate(mesh, factor),
            Perturbation::ScanNoise { fraction } => {
                let mut s = Sampler::new(seed, KEY, 0, 7);
                geometry::remesh::normal_noise(mesh, fraction, || normal(&mut s))
            }
            Perturbation::ScanSmoothed { passes } => geometry::remesh::taubin_smooth(mesh, passes),
            _ => mesh.clone(),
        }
    }

    /// Applies the perturbation's cameras, lights and images to `ds` (its mesh: [`Self::mesh`]).
    pub fn apply(&self, ds: &mut Dataset, seed: u64) {
        let centre = Vec3::ZERO;
        match *self {
            Perturbation::CameraRotation { degrees } => {
                for (i, v) in ds.views.iter_mut().enumerate() {
                    let mut s = Sampler::new(seed, KEY, i as u64, 1);
                    let turn = Mat3::from_axis_angle(unit(&mut s), degrees.to_radians());
                    v.camera.rotation = turn * v.camera.rotation;
                }
            }
            Perturbation::CameraPosition { fraction } => {
                for (i, v) in ds.views.iter_mut().enumerate() {
                    let mut s = Sampler::new(seed, KEY, i as u64, 2);
                    let d = (v.camera.origin - centre).length();
                    v.camera.origin += unit(&mut s) * (fraction * d);
                }
            }
            Perturbation::LightPosition { fraction } => {
                let shared = ds
                    .views
                    .windows(2)
                    .all(|w| w[0].light.position == w[1].light.position);
                for (i, v) in ds.views.iter_mut().enumerate() {
                    let stream = if shared { 0 } else { i as u64 };
                    let mut s = Sampler::new(seed, KEY, stream, 3);
                    let d = (v.light.position - centre).length();
                    v.light.position += unit(&mut s) * (fraction * d);
                }
            }
            Perturbation::LightIntensity { .. } | Perturbation::WhiteBalance { .. } => {
                let f = self.stated_factor();
                for v in &mut ds.views {
                    v.light.intensity = std::array::from_fn(|c| v.light.intensity[c] * f[c]);
                }
            }
            Perturbation::Srgb8 => {
                let scale = brightest(ds);
                for v in &mut ds.views {
                    if let Some(img) = &mut v.image {
                        for x in img.data.iter_mut().flatten() {
                            let code = to_srgb8((*x / scale).min(1.0));
                            *x = srgb_to_linear(code as f32 / 255.0) * scale;
                        }
                    }
                }
            }
            Perturbation::SensorNoise {
                full_well,
                read_noise,
                ..
            } => {
                let per_electron = brightest(ds) / full_well;
                for (i, v) in ds.views.iter_mut().enumerate() {
                    let mut s = Sampler::new(seed, KEY, i as u64, 4);
                    if let Some(img) = &mut v.image {
                        for x in img.data.iter_mut().flatten() {
                            let electrons = poisson(&mut s, (*x / per_electron).max(0.0))
                                + read_noise * normal(&mut s);
                            *x = electrons * per_electron;
                        }
                    }
                }
            }
            _ => {}
        }
    }
}

/// The random streams' key.
const KEY: u64 = 0xCA97_0E55;

/// The brightest pixel value over every view's image.
fn brightest(ds: &Dataset) -> f32 {
    let m = ds
        .views
        .iter()
        .filter_map(|v| v.image.as_ref())
        .flat_map(|img: &Image| img.data.iter().flatten().copied())
        .fold(0.0f32, f32::max);
    if m > 0.0 { m } else { 1.0 }
}

/// A standard normal number (Box–Muller).
fn normal(s: &mut Sampler) -> f32 {
    let u1 = s.next_f32().max(1e-7);
    let u2 = s.next_f32();
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

/// A uniformly distributed unit vector.
fn unit(s: &mut Sampler) -> Vec3 {
    let z = 2.0 * s.next_f32() - 1.0;
    let phi = std::f32::consts::TAU * s.next_f32();
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A Poisson count of mean `mean`: by inversion below 64, above by the normal approximation
/// N(mean, mean) (its skewness 1/√mean < 0.13 there, far below what a recovery notices).
fn poisson(s: &mut Sampler, mean: f32) -> f32 {
    if mean >= 64.0 {
        return (mean + mean.sqrt() * normal(s)).max(0.0);
    }
    let u = s.next_f32();
    let (mut k, mut p) = (0u32, (-mean).exp());
    let mut cdf = p;
    while u > cdf && k < 1000 {
        k += 1;
        p *= mean / k as f32;
        cdf += p;
    }
    k as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Poisson draws have their mean and variance (both λ) within four standard errors,
    /// below and above the switch to the normal approximation.
    #[test]
    fn poisson_draws_have_their_mean_and_variance() {
        for mean in [0.5f32, 7.0, 200.0] {
            let mut s = Sampler::new(1, KEY, 0, 9);
            let n = 40_000;
            let xs: Vec<f64> = (0..n).map(|_| poisson(&mut s, mean) as f64).collect();
            let m = xs.iter().sum::<f64>() / n as f64;
            let var = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1) as f64;
            let lam = mean as f64;
            // Standard errors of the sample mean and variance of a Poisson(λ) sample.
            let se_m = (lam / n as f64).sqrt();
            let se_v = ((lam + 2.0 * lam * lam) / n as f64).sqrt();
            assert!((m - lam).abs() < 4.0 * se_m, "λ {lam}: mean {m}");
            assert!((var - lam).abs() < 4.0 * se_v, "λ {lam}: variance {var}");
        }
    }

    /// Every perturbation has its own name; a rotation keeps the camera's frame orthonormal and
    /// turns it by its angle; a position error has its size; an intensity error scales every
    /// light; the images' perturbations leave the geometry alone.
    #[test]
    fn perturbations_do_what_they_say() {
        let names: std::collections::HashSet<String> = all().iter().map(|p| p.name()).collect();
        assert_eq!(names.len(), all().len());
        let desc = scene::SceneDesc {
            mesh: scene::MeshSource::Shape(geometry::Shape::from_name("blob").unwrap()),
            medium: scene::Medium {
                sigma_t: [50.0; 3],
                albedo: [0.9; 3],
                g: scene::Anisotropy::uniform(0.0),
                eta: 1.0,
                roughness: 0.0,
            },
            views: scene::rig::paper_rig(4, 8).build(),
            render: Default::default(),
            path: "dataset.json".into(),
            length_unit: None,
        };
        let mut ds = Dataset::from_scene(&desc);
        for v in &mut ds.views {
            let mut img = Image::new(8, 8);
            img.data.fill([0.3; 3]);
            v.image = Some(img);
        }
        let perturbed = |p: Perturbation| {
            let mut d = ds.clone();
            p.apply(&mut d, 5);
            d
        };
        let r = perturbed(Perturbation::CameraRotation { degrees: 0.5 });
        for (a, b) in ds.views.iter().zip(&r.views) {
            let (ra, rb) = (a.camera.rotation, b.camera.rotation);
            let angle = ra.z_axis.angle_between(rb.z_axis).to_degrees();
            assert!(angle <= 0.5 + 1e-3, "{angle}");
            assert!((rb.determinant() - 1.0).abs() < 1e-5);
            assert_eq!(a.camera.origin, b.camera.origin);
        }
        let p = perturbed(Perturbation::CameraPosition { fraction: 0.02 });
        for (a, b) in ds.views.iter().zip(&p.views) {
            let d = a.camera.origin.length();
            let moved = (b.camera.origin - a.camera.origin).length();
            assert!((moved / d - 0.02).abs() < 1e-4, "{}", moved / d);
        }
        let k = perturbed(Perturbation::LightIntensity { factor: 0.9 });
        for (a, b) in ds.views.iter().zip(&k.views) {
            assert_eq!(b.light.intensity, a.light.intensity.map(|x| x * 0.9));
        }
        let wb = Perturbation::WhiteBalance {
            red: 1.1,
            blue: 0.9,
        };
        for (a, b) in ds.views.iter().zip(&perturbed(wb).views) {
            let [r, g, bl] = a.light.intensity;
            assert_eq!(b.light.intensity, [r * 1.1, g, bl * 0.9]);
        }
        assert_eq!(wb.true_light_scale()[1], 1.0);
        assert!((wb.true_light_scale()[0] * 1.1 - 1.0).abs() < 1e-7);
        let q = perturbed(Perturbation::Srgb8);
        let x = q.views[0].image.as_ref().unwrap().data[0][0];
        assert_eq!(x, 0.3, "the brightest pixel is full scale: exact");
        assert_eq!(q.views[0].camera.origin, ds.views[0].camera.origin);
        let n = perturbed(*all().last().unwrap());
        let img = n.views[0].image.as_ref().unwrap();
        let values: Vec<f32> = img.data.iter().flatten().copied().collect();
        let m = values.iter().sum::<f32>() / values.len() as f32;
        // 625 electrons at full scale: the mean within 5 standard errors of 192 values.
        let se = 0.3 * (1.0 / 625.0f32).sqrt() / (values.len() as f32).sqrt();
        assert!((m - 0.3).abs() < 5.0 * se, "{m}");
    }
}
