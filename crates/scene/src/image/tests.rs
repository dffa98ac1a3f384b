//! Tests of [`Image`]: EXR round trips and channel lookup, error messages, overwrite refusal,
//! PNG previews, downsampling, false-colour differences and the sRGB OETF.

use std::path::Path;

use super::*;
use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, SmallVec,
    WritableImage, f16,
};

fn ramp(w: u32, h: u32) -> Image {
    let mut img = Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            img.set(
                x,
                y,
                [
                    x as f32 * 0.1 + 0.01,
                    y as f32 * 0.2 + 0.02,
                    (x * y) as f32 * 0.3 + 1e-5,
                ],
            );
        }
    }
    img
}

fn write_channels(path: &Path, w: usize, h: usize, channels: Vec<AnyChannel<FlatSamples>>) {
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    exr::prelude::Image::from_layer(layer)
        .write()
        .to_file(path)
        .unwrap();
}

#[test]
fn exr_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.exr");
    let img = ramp(7, 5);
    img.write_exr(&p, false).unwrap();
    assert_eq!(Image::read_exr(&p).unwrap(), img);
    // No temporary files left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn exr_channels_are_found_by_name() {
    // Channels stored as A, B, G, R, Z (the crate sorts by name); G in f16, B in f32, R in f32.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("order.exr");
    let (w, h) = (3usize, 2usize);
    let n = w * h;
    let r: Vec<f32> = (0..n).map(|i| 1.0 + i as f32).collect();
    let g: Vec<f16> = (0..n).map(|i| f16::from_f32(100.0 + i as f32)).collect();
    let b: Vec<f32> = (0..n).map(|i| 1000.0 + i as f32).collect();
    write_channels(
        &p,
        w,
        h,
        vec![
            AnyChannel::new("Z", FlatSamples::F32(vec![-5.0; n])),
            AnyChannel::new("R", FlatSamples::F32(r)),
            AnyChannel::new("A", FlatSamples::F32(vec![1.0; n])),
            AnyChannel::new("G", FlatSamples::F16(g)),
            AnyChannel::new("B", FlatSamples::F32(b)),
        ],
    );
    let img = Image::read_exr(&p).unwrap();
    assert_eq!((img.width, img.height), (3, 2));
    assert_eq!(img.get(0, 0), [1.0, 100.0, 1000.0]);
    assert_eq!(img.get(2, 1), [6.0, 105.0, 1005.0]); // row-major, row 0 first
}

#[test]
fn exr_luminance_only_is_grey_and_missing_channels_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("y.exr");
    write_channels(
        &p,
        2,
        2,
        vec![AnyChannel::new(
            "Y",
            FlatSamples::F32(vec![0.5, 1.0, 1.5, 2.0]),
        )],
    );
    let img = Image::read_exr(&p).unwrap();
    assert_eq!(img.get(1, 1), [2.0; 3]);

    let p = dir.path().join("rg.exr");
    write_channels(
        &p,
        1,
        1,
        vec![
            AnyChannel::new("R", FlatSamples::F32(vec![1.0])),
            AnyChannel::new("G", FlatSamples::F32(vec![1.0])),
        ],
    );
    let msg = Image::read_exr(&p).unwrap_err().to_string();
    assert!(
        msg.contains("rg.exr")
            && msg.contains("no channel(s) named B")
            && msg.contains("found: G, R"),
        "{msg}"
    );
}

#[test]
fn exr_nan_pixel_is_rejected_with_its_position() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nan.exr");
    let mut img = ramp(4, 3);
    img.set(2, 1, [0.0, f32::NAN, 0.0]);
    img.write_exr(&p, false).unwrap();
    let msg = Image::read_exr(&p).unwrap_err().to_string();
    assert!(
        msg.contains("nan.exr") && msg.contains("pixel (x=2, y=1) channel G"),
        "{msg}"
    );
    img.set(2, 1, [0.0, 0.0, f32::INFINITY]);
    img.write_exr(&p, true).unwrap();
    let msg = Image::read_exr(&p).unwrap_err().to_string();
    assert!(
        msg.contains("pixel (x=2, y=1) channel B") && msg.contains("inf"),
        "{msg}"
    );
}

#[test]
fn exr_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.exr");
    assert!(
        Image::read_exr(&missing)
            .unwrap_err()
            .to_string()
            .contains("missing.exr")
    );
    let junk = dir.path().join("junk.exr");
    std::fs::write(&junk, b"definitely not an exr").unwrap();
    let msg = Image::read_exr(&junk).unwrap_err().to_string();
    assert!(msg.contains("junk.exr") && msg.contains("OpenEXR"), "{msg}");
}

/// A damaged data window (found by the mutation pass of `crates/fuzz`: a 4 × 3 image whose
/// header claimed billions of pixels made the EXR decoder allocate 11 GB) is an error naming the
/// file and the declared size, and nothing is allocated for it.
#[test]
fn exr_with_a_damaged_size_is_an_error_not_an_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.exr");
    ramp(4, 3).write_exr(&path, false).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let key = b"dataWindow\0box2i\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("a dataWindow attribute")
        + key.len()
        + 4;
    // box2i: x_min, y_min, x_max, y_max.
    bytes[at + 8..at + 12].copy_from_slice(&59_999i32.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&59_999i32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let msg = Image::read_exr(&path).unwrap_err().to_string();
    assert!(
        msg.contains("huge.exr") && msg.contains("60000×60000 pixels"),
        "{msg}"
    );
}

/// A tiled EXR whose tile claims a mip level the header does not have (found by AFL on the EXR
/// reader) trips an assertion inside the decoder in builds with debug assertions (the test
/// profile): the reader turns that panic into an error naming the file. Without debug
/// assertions the decoder reads the tile as if it were of level 0.
#[test]
fn exr_decoder_panics_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiles.exr");
    std::fs::write(&path, include_bytes!("testdata/tile-level-mismatch.exr")).unwrap();
    let result = Image::read_exr(&path);
    if cfg!(debug_assertions) {
        let msg = result.unwrap_err().to_string();
        assert!(
            msg.contains("tiles.exr") && msg.contains("decoder failed"),
            "{msg}"
        );
    }
}

/// A B44 block whose values underflow the decoder's arithmetic (found by AFL, minimised with
/// `afl-tmin`): with overflow checks (the test profile) the decoder panics. It used to panic
/// on the decoder's own thread pool, which aborts the process; the reader decodes on its own
/// thread, so the panic is an error naming the file.
#[test]
fn exr_b44_underflow_is_an_error_not_an_abort() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("b44.exr");
    std::fs::write(&path, include_bytes!("testdata/b44-underflow.exr")).unwrap();
    let result = Image::read_exr(&path);
    if cfg!(debug_assertions) {
        let msg = result.unwrap_err().to_string();
        assert!(
            msg.contains("b44.exr") && msg.contains("decoder failed"),
            "{msg}"
        );
    }
}

/// The same file minimised by `afl-tmin`, whose tile size became 0x30303030 pixels: the
/// decoder would reserve 808 MB for the first tile's declared byte count before finding the
/// file too short. The block size is checked against the file first.
#[test]
fn exr_with_huge_tiles_is_an_error_not_an_allocation() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiles.exr");
    std::fs::write(&path, include_bytes!("testdata/huge-tiles.exr")).unwrap();
    let msg = Image::read_exr(&path).unwrap_err().to_string();
    assert!(
        msg.contains("tiles.exr") && msg.contains("blocks of"),
        "{msg}"
    );
}

#[test]
fn overwrite_is_refused_unless_asked() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.exr");
    ramp(2, 2).write_exr(&p, false).unwrap();
    let err = ramp(3, 3).write_exr(&p, false).unwrap_err();
    assert!(matches!(err, SceneError::Exists { .. }), "{err}");
    assert!(
        err.to_string().contains("a.exr")
            && err.to_string().contains("pass overwrite to replace it")
    );
    assert_eq!(
        Image::read_exr(&p).unwrap().width,
        2,
        "the file is untouched"
    );
    ramp(3, 3).write_exr(&p, true).unwrap();
    assert_eq!(Image::read_exr(&p).unwrap().width, 3);
    let q = dir.path().join("a.png");
    ramp(2, 2).write_png(&q, 1.0, false).unwrap();
    assert!(matches!(
        ramp(2, 2).write_png(&q, 1.0, false),
        Err(SceneError::Exists { .. })
    ));
    ramp(2, 2).write_png(&q, 1.0, true).unwrap();
}

#[test]
fn png_preview_is_exposed_clamped_srgb() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("p.png");
    let mut img = Image::new(2, 1);
    img.set(0, 0, [0.25, 0.0, 2.0]);
    img.set(1, 0, [f32::NAN, -1.0, 0.001]);
    img.write_png(&p, 2.0, false).unwrap();
    let png = image::ImageReader::open(&p)
        .unwrap()
        .decode()
        .unwrap()
        .to_rgb8();
    assert_eq!(png.dimensions(), (2, 1));
    // 0.25·2 = 0.5 → sRGB 0.7354 → 188; 2·2 clamps to 255; 0.002 → 12.92·0.002·255 = 6.6 → 7.
    assert_eq!(png.get_pixel(0, 0).0, [188, 0, 255]);
    assert_eq!(png.get_pixel(1, 0).0, [0, 0, 7]);
    assert!(
        Image::new(0, 0)
            .write_png(&dir.path().join("e.png"), 1.0, false)
            .is_err()
    );
}

#[test]
fn downsample_and_scale() {
    let img = ramp(5, 4);
    let d = img.downsample(2).unwrap();
    assert_eq!((d.width, d.height), (2, 2));
    let expect = |x: u32, y: u32, c: usize| {
        (0..2)
            .flat_map(|j| (0..2).map(move |i| (i, j)))
            .map(|(i, j)| img.get(2 * x + i, 2 * y + j)[c] as f64)
            .sum::<f64>()
            / 4.0
    };
    for (x, y, c) in [(0, 0, 0), (1, 1, 2), (1, 0, 1)] {
        assert!((d.get(x, y)[c] as f64 - expect(x, y, c)).abs() < 1e-6);
    }
    assert_eq!(img.downsample(1).unwrap(), img);
    assert!(img.downsample(0).is_err());
    assert!(img.downsample(5).is_err());
    let s = img.scaled(2.0);
    assert_eq!(s.get(3, 2)[0], 2.0 * img.get(3, 2)[0]);
    let mut t = img.clone();
    t.scale(0.5);
    assert_eq!(t.mean()[1], 0.5 * img.mean()[1]);
}

#[test]
fn false_colour_diff_is_blue_white_red() {
    let a = Image::new(10, 10);
    let mut b = Image::new(10, 10);
    // b − a: one large outlier, the rest in ±0.1.
    for i in 0..100u32 {
        let v = if i < 50 { 0.1 } else { -0.05 };
        b.set(i % 10, i / 10, [v; 3]);
    }
    b.set(9, 9, [100.0; 3]);
    let (d, range) = Image::false_colour_diff_with_range(&a, &b, None).unwrap();
    assert!(
        (range - 0.1).abs() < 1e-6,
        "99th percentile, not the outlier: {range}"
    );
    // a − b = −0.1 → full blue; +0.05 → half red; outlier clamped.
    assert_eq!(d.get(0, 0), [0.0, 0.0, 1.0]);
    let half = d.get(0, 5);
    assert!(
        (half[0] - 1.0).abs() < 1e-6
            && (half[1] - 0.5).abs() < 1e-6
            && (half[2] - 0.5).abs() < 1e-6
    );
    assert_eq!(d.get(9, 9), [0.0, 0.0, 1.0]);
    assert_eq!(
        Image::false_colour_diff(&a, &a).unwrap().get(3, 3),
        [1.0; 3]
    );
    assert!(
        Image::false_colour_diff(&a, &Image::new(2, 2))
            .unwrap_err()
            .to_string()
            .contains("sizes differ")
    );
}

#[test]
fn srgb_oetf_endpoints() {
    assert_eq!(to_srgb8(0.0), 0);
    assert_eq!(to_srgb8(1.0), 255);
    assert_eq!(to_srgb8(0.5), 188);
    assert_eq!(to_srgb8(f32::NAN), 0);
    let mut im = Image::new(10, 1);
    im.set(0, 0, [4.0, 0.0, 0.0]);
    assert!((im.auto_exposure() - 0.25).abs() < 1e-6);
    assert_eq!(Image::new(3, 3).auto_exposure(), 1.0);
}

/// Tiles land where the grid puts them, gaps stay black, ragged rows leave the rest black.
#[test]
fn grid_tiles_rows_with_gaps() {
    let a = ramp(3, 2);
    let b = ramp(2, 3);
    let g = Image::grid(&[vec![&a, &b], vec![&b]], 1);
    assert_eq!((g.width, g.height), (3 + 1 + 2, 3 + 1 + 3));
    for y in 0..2 {
        for x in 0..3 {
            assert_eq!(g.get(x, y), a.get(x, y));
        }
    }
    for y in 0..3 {
        for x in 0..2 {
            assert_eq!(g.get(4 + x, y), b.get(x, y));
            assert_eq!(g.get(x, 4 + y), b.get(x, y));
        }
        assert_eq!(g.get(3, y), [0.0; 3], "gap column");
    }
    assert_eq!(g.get(0, 2), [0.0; 3], "below the shorter tile");
    assert_eq!(g.get(5, 5), [0.0; 3], "right of the shorter row");
}
