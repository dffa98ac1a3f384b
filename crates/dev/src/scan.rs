//! `translucent-dev loss-scan`: where the learned renderer's loss has its minimum, without an
//! optimiser.
//!
//! For a dataset with a known medium (its truth), the learned renderer draws the first `--views`
//! views at the truth with σ_t scaled by each `--scales` factor (all channels, α at the truth),
//! with the polynomial features fitted at that medium, twice with independent random numbers
//! (seeds `seed` and `seed + 1`). Per channel it reports
//!
//! * the decorrelated loss L = Σ (I₁ − T)(I₂ − T) over the views' pixels, an unbiased estimate
//!   of Σ (E\[I\] − T)²: a plain L2 of one render adds the render's own variance, which grows as
//!   σ_t falls and would put the minimum at the truth by itself
//!   (docs/notes/learned-model-bias.md, "The model's own loss minimum on the torus, and the
//!   descriptor's refit");
//! * the brightness ratio Σ ½(I₁ + I₂) / Σ T.
//!
//! A renderer that agrees with the targets has its minimum at scale 1. `--entry-sampler walks`
//! replaces the decoder by the walks it imitates ([`bssrdf::render::EntrySampler`]), so the two
//! scans separate the decoder's share of the error from the rest of the model
//! (docs/notes/decoder-training.md, "The decoder is the cause").
//! Writes `OUT/loss-scan.csv`.
//!
//! **Where the error lives.** `--grazing-cos C` sorts every pixel by the surface point its
//! camera ray meets first (at the pixel centre; [`pixel_classes`]): `rim` (the camera looks
//! along the surface, |cos| < C), `lit` (the light shines on it, unoccluded, at cos ≥ C),
//! `terminator` (the light grazes it) and `unlit` (facing away from the light or in the object's
//! own shadow: all its light crossed the medium); pixels whose ray misses the mesh count in none.
//! The scan then reports the decorrelated loss of each class, so a minimum away from the truth
//! can be traced to where on the object it comes from.
//!
//! `OUT/loss-scan-views.csv` holds the loss and brightness of every view at every scale with its
//! phase angle (light–object–camera, at the bounding-box centre), and the scan prints the
//! brightness ratio Σ render / Σ target per phase-angle bin: a model whose error depends on the
//! lighting direction shows a trend across the bins that no albedo can remove.
//!
//! `--cosine-table` bins the pixels by the camera and light cosines at the visible point instead
//! and prints the brightness ratio per bin ([`cosines`]; `OUT/loss-scan-cosines.csv`).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use scene::scene_file::ViewDesc;
use scene::{Dataset, Image, Medium};

use cmdline::{LearnedArgs, by_rows};
use inverse::forward::ModelSpec;
use inverse::views::build_accel;

mod cosines;
use cosines::{CosineBrightness, pixel_geometry};

#[derive(Args)]
#[command(mut_arg("out", cmdline::groups::default("out/bench-loss-scan")))]
#[command(mut_arg(
    "seed",
    cmdline::groups::help("Seed of the first render (the second uses seed + 1)")
))]
#[command(mut_arg(
    "views",
    cmdline::groups::default_and_help("12", "Number of views used (the first ones)")
))]
#[command(mut_arg(
    "spp",
    cmdline::groups::default_and_help("32", "Samples per pixel of each of the two renders")
))]
pub struct LossScanArgs {
    /// Dataset folder (ours or a Mitsuba reference folder) whose medium is known.
    #[arg(long)]
    pub dataset: PathBuf,
    /// Factors applied to the true σ_t (all channels).
    #[arg(long, value_delimiter = ',', default_value = "0.8,0.9,1,1.1,1.2")]
    pub scales: Vec<f32>,
    #[command(flatten)]
    pub views: cmdline::Views,
    #[command(flatten)]
    pub spp: cmdline::Spp,
    #[command(flatten)]
    pub learned: LearnedArgs,
    #[command(flatten)]
    pub out: cmdline::Output,
    #[command(flatten)]
    pub seed: cmdline::Seed,
    /// Also report the loss of rim pixels (|cos| between camera ray and surface normal below
    /// this) and of the other pixels separately.
    #[arg(long)]
    pub grazing_cos: Option<f32>,
    /// Also print the brightness ratio by the camera and light cosines at the visible point
    /// (`bench_scan::cosines`) and write it to `OUT/loss-scan-cosines.csv`.
    #[arg(long)]
    pub cosine_table: bool,
    #[command(flatten)]
    pub overwrite: cmdline::Overwrite,
}

/// Per channel: Σ (a − t)(b − t) and Σ ½(a + b) / Σ t over the pixels of every image triple.
pub fn decorrelated_loss(a: &[Image], b: &[Image], t: &[Image]) -> ([f64; 3], [f64; 3]) {
    let (mut l, mut s, mut st) = ([0.0f64; 3], [0.0f64; 3], [0.0f64; 3]);
    for ((ia, ib), it) in a.iter().zip(b).zip(t) {
        for ((pa, pb), pt) in ia.data.iter().zip(&ib.data).zip(&it.data) {
            for c in 0..3 {
                let (x, y, z) = (pa[c] as f64, pb[c] as f64, pt[c] as f64);
                l[c] += (x - z) * (y - z);
                s[c] += 0.5 * (x + y);
                st[c] += z;
            }
        }
    }
    (l, std::array::from_fn(|c| s[c] / st[c]))
}

/// The phase angle of a view in degrees: the angle at `centre` (the object's bounding-box
/// centre) between the directions to the camera and to the light. 0° lights the object from the
/// camera, 180° from behind it.
pub fn phase_angle_deg(centre: glam::Vec3, camera: glam::Vec3, light: glam::Vec3) -> f32 {
    let (c, l) = ((camera - centre).normalize(), (light - centre).normalize());
    c.dot(l).clamp(-1.0, 1.0).acos().to_degrees()
}

/// Phase-angle bins of the brightness summary (degrees, upper bounds).
const PHASE_BINS: [f32; 4] = [45.0, 90.0, 135.0, 180.01];

fn phase_bin(p: f32) -> usize {
    PHASE_BINS
        .iter()
        .position(|&b| p < b)
        .unwrap_or(PHASE_BINS.len() - 1)
}

/// Σ render and Σ target per phase-angle bin and channel, at one σ_t scale.
#[derive(Default)]
struct PhaseBrightness {
    render: [[f64; 3]; PHASE_BINS.len()],
    target: [[f64; 3]; PHASE_BINS.len()],
}

impl PhaseBrightness {
    /// Adds a view of phase angle `phase` with target sums `target` and brightness ratios `ratio`.
    fn add(&mut self, phase: f32, target: [f64; 3], ratio: [f64; 3]) {
        let k = phase_bin(phase);
        for c in 0..3 {
            self.target[k][c] += target[c];
            self.render[k][c] += ratio[c] * target[c];
        }
    }

    /// The bin's brightness ratios as text ("-" for a bin without light).
    fn row(&self, k: usize) -> String {
        let r: Vec<String> = (0..3)
            .map(|c| match self.target[k][c] {
                t if t > 0.0 => format!("{:.3}", self.render[k][c] / t),
                _ => "  -  ".into(),
            })
            .collect();
        r.join(" ")
    }
}

/// Prints the brightness ratio per phase-angle bin (rows: σ_t scales).
fn print_phase_table(phase: &[f32], rows: &[(f32, PhaseBrightness)]) {
    println!("brightness (render / target, R G B) by phase angle (light–object–camera):");
    print!("{:>7} |", "σ_t ×");
    let mut lo = 0.0;
    for (k, hi) in PHASE_BINS.iter().enumerate() {
        let count = phase.iter().filter(|&&p| phase_bin(p) == k).count();
        print!(" {lo:>4.0}–{:<3.0}° ({count:>2} views) |", hi.floor());
        lo = *hi;
    }
    println!();
    for (s, b) in rows {
        print!("{s:>7.3} |");
        for k in 0..PHASE_BINS.len() {
            print!(" {} |", b.row(k));
        }
        println!();
    }
}

/// Names of the pixel classes of [`pixel_classes`] (class k + 1 is `CLASS_NAMES[k]`).
pub const CLASS_NAMES: [&str; 4] = ["lit", "terminator", "unlit", "rim"];

/// Pixel classes of one view, from the first surface point x of the ray through the pixel
/// centre, its shading normal n, the camera direction d and the light direction l (c =
/// `grazing_cos`): 0 = the ray misses the mesh; 4 `rim` = |n·d| < c; otherwise 1 `lit` = n·l ≥ c
/// and the light visible from x, 2 `terminator` = |n·l| < c, 3 `unlit` = facing away from the
/// light or shadowed by the object.
pub fn pixel_classes(
    accel: &geometry::Accel,
    camera: &scene::Camera,
    light: glam::Vec3,
    grazing_cos: f32,
) -> Vec<u8> {
    pixel_geometry(accel, camera, light)
        .into_iter()
        .map(|g| match g {
            None => 0,
            Some(g) if g.cos_cam < grazing_cos => 4,
            Some(g) if g.cos_light.abs() < grazing_cos => 2,
            Some(g) if !g.visible => 3,
            Some(_) => 1,
        })
        .collect()
}

/// Per pixel class and channel (`classes[i]` of pixel i; 0 is skipped, class k counts in
/// row k − 1): Σ (a − t)(b − t).
pub fn decorrelated_loss_by_class(
    a: &Image,
    b: &Image,
    t: &Image,
    classes: &[u8],
) -> [[f64; 3]; CLASS_NAMES.len()] {
    let mut l = [[0.0f64; 3]; CLASS_NAMES.len()];
    for (((pa, pb), pt), &k) in a.data.iter().zip(&b.data).zip(&t.data).zip(classes) {
        if k == 0 {
            continue;
        }
        for c in 0..3 {
            let (x, y, z) = (pa[c] as f64, pb[c] as f64, pt[c] as f64);
            l[k as usize - 1][c] += (x - z) * (y - z);
        }
    }
    l
}

/// What the scan reads from its dataset: the truth, the first `--views` targets and views, and
/// the mesh's BVH.
struct Scanned {
    truth: Medium,
    targets: Vec<Image>,
    views: Vec<ViewDesc>,
    accel: geometry::Accel,
}

fn load(a: &LossScanArgs) -> Result<Scanned> {
    let ds = Dataset::load(&a.dataset)?;
    let Some(truth) = ds.truth else {
        bail!(
            "{}: the dataset records no medium (truth); the scan needs one",
            a.dataset.display()
        )
    };
    let n = a.views.min(ds.views.len());
    anyhow::ensure!(n > 0, "--views must be at least 1");
    let mut targets = Vec::with_capacity(n);
    for (i, v) in ds.views.iter().take(n).enumerate() {
        let Some(img) = &v.image else {
            bail!("{}: view {i} has no image", a.dataset.display())
        };
        targets.push(img.clone());
    }
    let views: Vec<_> = ds.views.iter().take(n).map(|v| v.desc()).collect();
    let (mesh, warnings) = ds
        .load_mesh()
        .with_context(|| format!("loading the mesh of {}", a.dataset.display()))?;
    let accel = build_accel(mesh, &warnings, &ds.mesh.describe());
    Ok(Scanned {
        truth,
        targets,
        views,
        accel,
    })
}

/// How many pixels of each class the views hold (printed).
fn print_class_counts(classes: &[Vec<u8>], grazing_cos: f32) {
    let count = |k: u8| classes.iter().flatten().filter(|&&x| x == k).count();
    let counts: Vec<String> = (1..=CLASS_NAMES.len() as u8)
        .map(|k| format!("{} {}", count(k), CLASS_NAMES[k as usize - 1]))
        .collect();
    println!(
        "pixels (grazing below |cos| {grazing_cos}): {}, {} background",
        counts.join(", "),
        count(0)
    );
}

/// The header of `loss-scan.csv` (with the per-class columns when the pixels are classed).
fn csv_header(by_class: bool) -> String {
    let mut csv = String::from("scale,loss_r,loss_g,loss_b,brightness_r,brightness_g,brightness_b");
    if by_class {
        for name in CLASS_NAMES {
            csv.push_str(&format!(",{name}_r,{name}_g,{name}_b"));
        }
    }
    csv.push('\n');
    csv
}

/// The decorrelated loss of two renders (`pair`) per pixel class, summed over the views:
/// printed and appended to the CSV row.
fn class_losses(classes: &[Vec<u8>], pair: [&[Image]; 2], targets: &[Image], csv: &mut String) {
    let mut by = [[0.0f64; 3]; CLASS_NAMES.len()];
    for (i, k) in classes.iter().enumerate() {
        let v = decorrelated_loss_by_class(&pair[0][i], &pair[1][i], &targets[i], k);
        for (acc, x) in by.iter_mut().zip(v) {
            (0..3).for_each(|c| acc[c] += x[c]);
        }
    }
    for (name, v) in CLASS_NAMES.iter().zip(&by) {
        println!(
            "        | {name:>10} {:>9.2} {:>9.2} {:>9.2}",
            v[0], v[1], v[2]
        );
    }
    for v in by {
        csv.push_str(&format!(",{},{},{}", v[0], v[1], v[2]));
    }
}

/// Each view's decorrelated loss and brightness at σ_t scale `s` (rows of the views' CSV),
/// and the brightness by phase angle.
fn view_losses(
    s: f32,
    phase: &[f32],
    pair: [&[Image]; 2],
    targets: &[Image],
    views_csv: &mut String,
) -> PhaseBrightness {
    let mut bright = PhaseBrightness::default();
    for (i, t) in targets.iter().enumerate() {
        let (l, b) = decorrelated_loss(
            std::slice::from_ref(&pair[0][i]),
            std::slice::from_ref(&pair[1][i]),
            std::slice::from_ref(t),
        );
        views_csv.push_str(&format!(
            "{s},{i},{:.2},{},{},{},{},{},{}\n",
            phase[i], l[0], l[1], l[2], b[0], b[1], b[2]
        ));
        let sum = std::array::from_fn(|c| t.data.iter().map(|p| p[c] as f64).sum());
        bright.add(phase[i], sum, b);
    }
    bright
}

pub fn run(a: &LossScanArgs) -> Result<()> {
    anyhow::ensure!(*a.spp > 0, "--spp must be at least 1");
    anyhow::ensure!(
        a.scales.iter().all(|s| s.is_finite() && *s > 0.0),
        "--scales must be positive factors of the true σ_t"
    );
    let (path, vpath, cpath) = (
        a.out.join("loss-scan.csv"),
        a.out.join("loss-scan-views.csv"),
        a.out.join("loss-scan-cosines.csv"),
    );
    for p in [&path, &vpath, &cpath] {
        scene::fsutil::check_overwrite(p, *a.overwrite)?;
    }
    let Scanned {
        truth,
        targets,
        views,
        accel,
    } = load(a)?;
    let n = views.len();
    let model = a.learned.load_model()?;
    if let Some(c) = a.grazing_cos {
        anyhow::ensure!(
            c > 0.0 && c < 1.0,
            "--grazing-cos must lie in (0, 1) (a cosine); got {c}"
        );
    }
    let classes: Option<Vec<Vec<u8>>> = a.grazing_cos.map(|c| {
        views
            .iter()
            .map(|v| pixel_classes(&accel, &v.camera, v.light.position, c))
            .collect()
    });
    let geometry: Option<Vec<_>> = a.cosine_table.then(|| {
        views
            .iter()
            .map(|v| pixel_geometry(&accel, &v.camera, v.light.position))
            .collect()
    });
    let mut cosines_csv = String::from(
        "scale,light_bin,camera_bin,share_r,share_g,share_b,brightness_r,brightness_g,brightness_b\n",
    );
    if let Some(cl) = &classes {
        print_class_counts(cl, a.grazing_cos.unwrap_or_default());
    }
    println!("{}; {n} views, 2 × {} spp", a.learned.describe(), *a.spp);
    println!(
        "{:>7} | {:>30} | {:>24}",
        "σ_t ×", "decorrelated loss (R, G, B)", "brightness (R, G, B)"
    );
    let mut csv = csv_header(classes.is_some());
    let mut views_csv = String::from(
        "scale,view,phase_deg,loss_r,loss_g,loss_b,brightness_r,brightness_g,brightness_b\n",
    );
    let (lo, hi) = accel.mesh().bounds();
    let centre = 0.5 * (lo + hi);
    let phase: Vec<f32> = views
        .iter()
        .map(|v| phase_angle_deg(centre, v.camera.origin, v.light.position))
        .collect();
    let mut by_phase: Vec<(f32, PhaseBrightness)> = Vec::new();
    for &s in &a.scales {
        let mut m = truth;
        m.sigma_t = m.sigma_t.map(|v| v * s);
        let render = |seed| {
            by_rows(&views, "learned", |pb| {
                inverse::views::render(
                    ModelSpec::learned(&model, a.learned.settings(), seed),
                    &inverse::views::Job {
                        accel: &accel,
                        medium: &m,
                        views: &views,
                        spp: *a.spp,
                        seed,
                    },
                    false,
                    pb,
                )
            })
        };
        let (r1, r2) = (render(*a.seed)?, render(*a.seed + 1)?);
        let (l, b) = decorrelated_loss(&r1.images, &r2.images, &targets);
        println!(
            "{s:>7.3} | {:>9.2} {:>9.2} {:>9.2} | {:>7.4} {:>7.4} {:>7.4}",
            l[0], l[1], l[2], b[0], b[1], b[2]
        );
        csv.push_str(&format!(
            "{s},{},{},{},{},{},{}",
            l[0], l[1], l[2], b[0], b[1], b[2]
        ));
        let pair = [&r1.images[..], &r2.images[..]];
        if let Some(cl) = &classes {
            class_losses(cl, pair, &targets, &mut csv);
        }
        csv.push('\n');
        by_phase.push((s, view_losses(s, &phase, pair, &targets, &mut views_csv)));
        if let Some(g) = &geometry {
            let mut cb = CosineBrightness::default();
            for i in 0..n {
                cb.add(&r1.images[i], &r2.images[i], &targets[i], &g[i]);
            }
            cb.print(s, s == a.scales[0]);
            cosines_csv.push_str(&cb.csv_rows(s));
        }
    }
    print_phase_table(&phase, &by_phase);
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    scene::fsutil::atomic_write(&path, csv.as_bytes(), *a.overwrite)?;
    scene::fsutil::atomic_write(&vpath, views_csv.as_bytes(), *a.overwrite)?;
    if geometry.is_some() {
        scene::fsutil::atomic_write(&cpath, cosines_csv.as_bytes(), *a.overwrite)?;
        println!("wrote {}", cpath.display());
    }
    println!("wrote {} and {}", path.display(), vpath.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(v: [f32; 3]) -> Image {
        let mut im = Image::new(2, 1);
        im.data.iter_mut().for_each(|p| *p = v);
        im
    }

    /// Two renders with opposite noise around the target-plus-bias: the cross term keeps the
    /// bias² and cancels the noise; identical renders give the plain squared error.
    #[test]
    fn decorrelated_loss_removes_independent_noise() {
        let t = [image([1.0, 2.0, 4.0])];
        let a = [image([1.5, 2.0, 4.25])];
        let b = [image([1.1, 2.0, 3.75])];
        let (l, bright) = decorrelated_loss(&a, &b, &t);
        // (0.5)(0.1)·2 pixels, 0, (0.25)(−0.25)·2.
        assert!((l[0] - 0.1).abs() < 1e-6 && l[1] == 0.0 && (l[2] + 0.125).abs() < 1e-6);
        assert!((bright[0] - 1.3).abs() < 1e-6 && (bright[2] - 1.0).abs() < 1e-6);
        let (l2, _) = decorrelated_loss(&a, &a, &t);
        assert!((l2[0] - 0.5).abs() < 1e-6);
    }

    /// A sphere seen head-on from +z: with the light at the camera the centre is `lit`, a ring at
    /// the silhouette is `rim` and the corners miss; with the light behind the sphere the centre
    /// is `unlit`; with the light to the side (+x) the centre column is `terminator`, the +x side
    /// `lit` and the −x side `unlit`.
    #[test]
    fn pixel_classes_follow_camera_and_light() {
        use glam::Vec3;
        let mesh = geometry::shapes::Shape::Sphere {
            radius: 0.5,
            subdivisions: 4,
        }
        .build()
        .unwrap();
        let accel = geometry::Accel::new(mesh);
        let eye = Vec3::new(0.0, 0.0, 3.0);
        let cam = scene::Camera::look_at(eye, Vec3::ZERO, Vec3::Y, 25.0, 33, 33);
        let at = |cl: &[u8], x: u32, y: u32| cl[(y * 33 + x) as usize];
        let front = pixel_classes(&accel, &cam, eye, 0.3);
        assert_eq!(at(&front, 16, 16), 1);
        assert_eq!(at(&front, 0, 0), 0);
        let rim = front.iter().filter(|&&k| k == 4).count();
        let lit = front.iter().filter(|&&k| k == 1).count();
        assert!(rim > 0 && lit > 4 * rim, "lit {lit}, rim {rim}");
        assert!(!front.contains(&2) && !front.contains(&3));
        let back = pixel_classes(&accel, &cam, Vec3::new(0.0, 0.0, -3.0), 0.3);
        assert_eq!(at(&back, 16, 16), 3);
        assert!(!back.contains(&1));
        let side = pixel_classes(&accel, &cam, Vec3::new(30.0, 0.0, 0.0), 0.3);
        assert_eq!(at(&side, 16, 16), 2);
        // Camera x points to image left (Mitsuba), so world +x is the image's left half.
        let (left, right) = (at(&side, 11, 16), at(&side, 21, 16));
        assert_eq!((left.min(right), left.max(right)), (1, 3), "{left} {right}");
    }

    /// The classes' losses add up to the loss of all pixels that hit the mesh.
    #[test]
    fn class_losses_partition_the_loss() {
        let mut t = Image::new(5, 1);
        let (mut a, mut b) = (t.clone(), t.clone());
        for i in 0..5 {
            t.data[i] = [1.0, 2.0, 3.0];
            a.data[i] = [1.0 + i as f32, 2.5, 3.0];
            b.data[i] = [2.0, 2.0 + i as f32, 1.0];
        }
        let classes = [0u8, 1, 2, 3, 4];
        let by = decorrelated_loss_by_class(&a, &b, &t, &classes);
        let (all, _) = decorrelated_loss(
            std::slice::from_ref(&a),
            std::slice::from_ref(&b),
            std::slice::from_ref(&t),
        );
        for c in 0..3 {
            let pixel0 =
                (a.data[0][c] - t.data[0][c]) as f64 * (b.data[0][c] - t.data[0][c]) as f64;
            let sum: f64 = by.iter().map(|r| r[c]).sum();
            assert!((sum + pixel0 - all[c]).abs() < 1e-9, "channel {c}");
        }
        // Pixel 2 (class 2) alone: R (3 − 1)(2 − 1) = 2.
        assert!((by[1][0] - 2.0).abs() < 1e-9);
    }

    #[test]
    fn phase_angle_of_front_side_and_back_light() {
        use glam::Vec3;
        let (o, cam) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 5.0));
        assert!(phase_angle_deg(o, cam, Vec3::new(1.0, 0.0, 9.0)).abs() < 1e-3);
        assert!((phase_angle_deg(o, cam, Vec3::new(4.0, 0.0, 0.0)) - 90.0).abs() < 1e-3);
        assert!((phase_angle_deg(o, cam, Vec3::new(1.0, 0.0, -2.0)) - 180.0).abs() < 1e-3);
    }
}
