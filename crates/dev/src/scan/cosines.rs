//! `translucent-dev loss-scan --cosine-table`: the learned renderer's brightness against the targets,
//! binned by the two cosines at the visible point.
//!
//! For every pixel the ray through its centre meets the surface at x_o with shading normal n;
//! μ_c = |n·d| is the camera cosine (d the ray direction) and μ_l = n·l the light cosine (l the
//! unit direction from x_o to the light), with the light's visibility from x_o. A pixel counts in
//! the bin of (μ_l, μ_c); light bin 0 holds the pixels whose light crossed the medium (μ_l < 0 or
//! the light occluded). Per bin and channel the scan sums the render ½(I₁ + I₂) and the target T,
//! and prints Σ render / Σ T.
//!
//! In a half-space lit by a distant light the image does not depend on σ_t at all (the medium is
//! scale-free), and for isotropic scattering the reflected radiance depends only on α, μ_c and
//! μ_l (Chandrasekhar's H-function solution). So on a smooth shape whose curvature is small
//! against the kernel, the ratios away from light bin 0 and the smallest μ_l test the model's
//! albedo and angular dependence, while the bins near the terminator (small μ_l, light bin 0) and
//! the rim (small μ_c) hold the σ_t signal. A model whose ratio varies across the bins has an error
//! that no single albedo removes, and the joint fit trades it against σ_t.

use scene::Image;

/// The two cosines and the light's visibility at the surface point seen through one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelGeometry {
    /// |n·d|, n the shading normal, d the camera ray direction.
    pub cos_cam: f32,
    /// n·l, l the unit direction to the light.
    pub cos_light: f32,
    /// The light is unoccluded from x_o (only tested where `cos_light > 0`).
    pub visible: bool,
}

/// [`PixelGeometry`] of every pixel of `camera` (row-major, pixel centres); `None` where the ray
/// misses the mesh.
pub fn pixel_geometry(
    accel: &geometry::Accel,
    camera: &scene::Camera,
    light: glam::Vec3,
) -> Vec<Option<PixelGeometry>> {
    let rays = camera.ray_gen();
    let (w, h) = (camera.width, camera.height);
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (o, d) = rays.ray(x as f32 + 0.5, y as f32 + 0.5);
            out.push(accel.closest(o, d, 0.0, f32::INFINITY).map(|hit| {
                let to_l = light - hit.p;
                let dist = to_l.length();
                let l = to_l / dist;
                let cos_light = hit.ns.dot(l);
                let visible = cos_light > 0.0 && {
                    let origin = geometry::bvh::offset_origin(hit.p, hit.ng, l);
                    !accel.occluded(origin, l, 0.0, dist * (1.0 - 1e-4))
                };
                PixelGeometry {
                    cos_cam: hit.ns.dot(d).abs(),
                    cos_light,
                    visible,
                }
            }));
        }
    }
    out
}

/// Upper bounds of the light-cosine bins 1.. (bin 0: light through the medium).
pub const LIGHT_BINS: [f32; 5] = [0.1, 0.25, 0.5, 0.75, 1.0001];
/// Upper bounds of the camera-cosine bins.
pub const CAMERA_BINS: [f32; 4] = [0.25, 0.5, 0.75, 1.0001];
/// Number of (light, camera) bins.
pub const BINS: usize = (LIGHT_BINS.len() + 1) * CAMERA_BINS.len();

fn bin_of(bounds: &[f32], v: f32) -> usize {
    bounds
        .iter()
        .position(|&b| v < b)
        .unwrap_or(bounds.len() - 1)
}

/// The (light, camera) bin of a pixel, as light_bin · [`CAMERA_BINS`].len() + camera_bin.
pub fn cosine_bin(g: &PixelGeometry) -> usize {
    let light = if g.visible {
        1 + bin_of(&LIGHT_BINS, g.cos_light)
    } else {
        0
    };
    light * CAMERA_BINS.len() + bin_of(&CAMERA_BINS, g.cos_cam)
}

/// Σ render and Σ target per (light, camera) bin and channel.
#[derive(Clone, Debug)]
pub struct CosineBrightness {
    pub render: [[f64; 3]; BINS],
    pub target: [[f64; 3]; BINS],
}

impl Default for CosineBrightness {
    fn default() -> Self {
        Self {
            render: [[0.0; 3]; BINS],
            target: [[0.0; 3]; BINS],
        }
    }
}

impl CosineBrightness {
    /// Adds the pixels of one view: renders `a`, `b` (their mean counts), target `t`, geometry `g`.
    pub fn add(&mut self, a: &Image, b: &Image, t: &Image, g: &[Option<PixelGeometry>]) {
        for (((pa, pb), pt), g) in a.data.iter().zip(&b.data).zip(&t.data).zip(g) {
            let Some(g) = g else { continue };
            let k = cosine_bin(g);
            for c in 0..3 {
                self.render[k][c] += 0.5 * (pa[c] as f64 + pb[c] as f64);
                self.target[k][c] += pt[c] as f64;
            }
        }
    }

    /// Σ render / Σ target of bin `k`, channel `c` (None without target light).
    pub fn ratio(&self, k: usize, c: usize) -> Option<f64> {
        (self.target[k][c] > 0.0).then(|| self.render[k][c] / self.target[k][c])
    }

    /// The CSV rows of this scale: scale, light bin, camera bin, target share and ratio per channel.
    pub fn csv_rows(&self, scale: f32) -> String {
        let total: [f64; 3] = std::array::from_fn(|c| self.target.iter().map(|t| t[c]).sum());
        let mut s = String::new();
        for k in 0..BINS {
            let (li, ci) = (k / CAMERA_BINS.len(), k % CAMERA_BINS.len());
            s.push_str(&format!("{scale},{li},{ci}"));
            for (c, tot) in total.iter().enumerate() {
                s.push_str(&format!(
                    ",{}",
                    self.target[k][c] / tot.max(f64::MIN_POSITIVE)
                ));
            }
            for c in 0..3 {
                s.push_str(&format!(",{}", self.ratio(k, c).unwrap_or(f64::NAN)));
            }
            s.push('\n');
        }
        s
    }

    /// Prints the table of one scale: rows light bins, columns camera bins, cells the R G B
    /// ratios; with `shares`, a second table of each bin's share of the target light (R).
    pub fn print(&self, scale: f32, shares: bool) {
        let head = |title: &str| {
            print!("{title:>16} |");
            let mut lo = 0.0;
            for hi in CAMERA_BINS {
                print!("   μ_c {lo:.2}–{:.2}    |", hi.min(1.0));
                lo = hi;
            }
            println!();
        };
        let label = |li: usize| match li {
            0 => "through medium".to_string(),
            _ => {
                let lo = if li == 1 { 0.0 } else { LIGHT_BINS[li - 2] };
                format!("μ_l {lo:.2}–{:.2}", LIGHT_BINS[li - 1].min(1.0))
            }
        };
        head(&format!("σ_t × {scale:.3}"));
        for li in 0..=LIGHT_BINS.len() {
            print!("{:>16} |", label(li));
            for ci in 0..CAMERA_BINS.len() {
                let k = li * CAMERA_BINS.len() + ci;
                let cell: Vec<String> = (0..3)
                    .map(|c| {
                        self.ratio(k, c)
                            .map_or("  -  ".into(), |r| format!("{r:.3}"))
                    })
                    .collect();
                print!(" {} |", cell.join(" "));
            }
            println!();
        }
        if shares {
            let total: f64 = self.target.iter().map(|t| t[0]).sum();
            head("share of T (R)");
            for li in 0..=LIGHT_BINS.len() {
                print!("{:>16} |", label(li));
                for ci in 0..CAMERA_BINS.len() {
                    let t = self.target[li * CAMERA_BINS.len() + ci][0];
                    print!(
                        "       {:>6.2} %       |",
                        100.0 * t / total.max(f64::MIN_POSITIVE)
                    );
                }
                println!();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bins follow the cosines; an occluded or back-lit point goes to light bin 0.
    #[test]
    fn cosine_bins_follow_the_cosines() {
        let g = |cos_cam, cos_light, visible| PixelGeometry {
            cos_cam,
            cos_light,
            visible,
        };
        let n = CAMERA_BINS.len();
        assert_eq!(cosine_bin(&g(0.9, 0.9, true)), 5 * n + 3);
        assert_eq!(cosine_bin(&g(1.0, 1.0, true)), 5 * n + 3);
        assert_eq!(cosine_bin(&g(0.1, 0.05, true)), n);
        assert_eq!(cosine_bin(&g(0.6, 0.3, true)), 3 * n + 2);
        assert_eq!(cosine_bin(&g(0.6, 0.3, false)), 2);
        assert_eq!(cosine_bin(&g(0.3, -0.5, false)), 1);
    }

    /// The sums partition the image: Σ over bins equals the sums over all hit pixels, and the
    /// ratio of a bin is its render over its target.
    #[test]
    fn brightness_sums_partition_the_pixels() {
        let (mut t, mut a) = (Image::new(3, 1), Image::new(3, 1));
        t.data = vec![[1.0, 2.0, 4.0], [2.0, 2.0, 2.0], [5.0, 5.0, 5.0]];
        a.data = vec![[2.0, 2.0, 2.0], [1.0, 1.0, 1.0], [9.0, 9.0, 9.0]];
        let b = a.clone();
        let lit = PixelGeometry {
            cos_cam: 0.9,
            cos_light: 0.9,
            visible: true,
        };
        let dark = PixelGeometry {
            cos_light: -0.2,
            visible: false,
            ..lit
        };
        let mut cb = CosineBrightness::default();
        cb.add(&a, &b, &t, &[Some(lit), Some(dark), None]);
        let k = cosine_bin(&lit);
        assert_eq!(cb.ratio(k, 0), Some(2.0));
        assert_eq!(cb.ratio(k, 2), Some(0.5));
        assert_eq!(cb.ratio(cosine_bin(&dark), 1), Some(0.5));
        let total: f64 = cb.target.iter().map(|x| x[0]).sum();
        assert_eq!(total, 3.0);
        assert_eq!(cb.ratio(0, 0), None);
        assert_eq!(cb.csv_rows(1.0).lines().count(), BINS);
    }
}
