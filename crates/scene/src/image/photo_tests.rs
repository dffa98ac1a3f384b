//! Tests of photos as measurements: sRGB decoding against the standard's values, exposure,
//! 8/16-bit saturation, alpha, mask images, JPEG, EXR clipping levels, and the errors; and
//! dataset.json views with a photo, a mask and an exposure.

use std::path::Path;

use image::{GrayImage, Luma, Rgb, RgbImage, Rgba, RgbaImage};

use super::*;
use crate::dataset::Dataset;

fn read(path: &Path, transfer: Option<Transfer>, exposure: f32) -> Result<Photo, SceneError> {
    Photo::read(
        path,
        &PhotoSettings {
            transfer,
            exposure,
            saturation: None,
        },
    )
}

#[test]
fn srgb_decoding_follows_the_standard_and_inverts_the_previews() {
    assert_eq!(srgb_to_linear(0.0), 0.0);
    assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
    // The linear segment below 0.04045, the power law above (IEC 61966-2-1).
    assert!((srgb_to_linear(0.04045) - 0.04045 / 12.92).abs() < 1e-7);
    assert!((srgb_to_linear(0.5) - 0.214_041_14).abs() < 1e-6);
    // Every 8-bit code comes back through the previews' encoding.
    for c in 0..=255u8 {
        assert_eq!(to_srgb8(srgb_to_linear(c as f32 / 255.0)), c, "code {c}");
    }
}

#[test]
fn photos_decode_to_linear_radiance_with_exposure_and_saturation() {
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("photo.png");
    let mut img = RgbImage::from_pixel(4, 3, Rgb([188, 188, 188]));
    img.put_pixel(1, 0, Rgb([128, 64, 255]));
    img.put_pixel(2, 2, Rgb([0, 0, 0]));
    img.save(&p).unwrap();
    let ph = read(&p, None, 1.0).unwrap();
    assert_eq!((ph.image.width, ph.image.height), (4, 3));
    let want = srgb_to_linear(188.0 / 255.0);
    assert!((want - 0.502_886).abs() < 1e-5);
    assert!((ph.image.get(0, 0)[0] - want).abs() < 1e-6);
    assert_eq!(ph.image.get(2, 2), [0.0; 3]);
    // One channel at full scale: saturated, out of the measurement.
    assert_eq!(ph.saturated, 1);
    assert_eq!(ph.measured.count(), 11);
    assert!(!ph.measured.get(1, 0) && ph.measured.get(2, 2));
    // Exposure scales the linear value; a linear transfer reads the codes as they are.
    let twice = read(&p, None, 2.0).unwrap();
    assert!((twice.image.get(0, 0)[0] - 2.0 * want).abs() < 1e-6);
    let lin = read(&p, Some(Transfer::Linear), 1.0).unwrap();
    assert!((lin.image.get(1, 0)[0] - 128.0 / 255.0).abs() < 1e-6);
    // 16 bits: only 65535 is saturated.
    let p16 = d.path().join("photo16.png");
    let mut img16 = image::ImageBuffer::<Rgb<u16>, _>::from_pixel(2, 1, Rgb([32768, 0, 65534]));
    img16.put_pixel(1, 0, Rgb([65535, 1, 1]));
    img16.save(&p16).unwrap();
    let ph16 = read(&p16, Some(Transfer::Linear), 1.0).unwrap();
    assert!((ph16.image.get(0, 0)[0] - 32768.0 / 65535.0).abs() < 1e-7);
    assert_eq!(
        (ph16.saturated, ph16.measured.bits.clone()),
        (1, vec![true, false])
    );
}

#[test]
fn alpha_masks_and_jpeg() {
    let d = tempfile::tempdir().unwrap();
    // Alpha below half: transparent, out.
    let p = d.path().join("a.png");
    let mut img = RgbaImage::from_pixel(3, 1, Rgba([50, 60, 70, 255]));
    img.put_pixel(0, 0, Rgba([50, 60, 70, 127]));
    img.put_pixel(1, 0, Rgba([50, 60, 70, 128]));
    img.save(&p).unwrap();
    assert_eq!(
        read(&p, None, 1.0).unwrap().measured.bits,
        [false, true, true]
    );
    // A grey mask: measured from half of full scale up.
    let m = d.path().join("m.png");
    GrayImage::from_fn(3, 1, |x, _| Luma([[0, 127, 128][x as usize]]))
        .save(&m)
        .unwrap();
    assert_eq!(PixelMask::read(&m).unwrap().bits, [false, false, true]);
    // The mask written and read back.
    let mask = PixelMask {
        width: 2,
        height: 2,
        bits: vec![true, false, false, true],
    };
    mask.write_png(&d.path().join("w.png"), false).unwrap();
    assert_eq!(PixelMask::read(&d.path().join("w.png")).unwrap(), mask);
    assert!(mask.write_png(&d.path().join("w.png"), false).is_err());
    // JPEG: a flat colour decodes to its sRGB value within the codec's rounding.
    let j = d.path().join("j.jpg");
    RgbImage::from_pixel(16, 16, Rgb([200, 120, 40]))
        .save(&j)
        .unwrap();
    let ph = read(&j, None, 1.0).unwrap();
    for (c, code) in [200.0f32, 120.0, 40.0].into_iter().enumerate() {
        let (lo, hi) = (
            srgb_to_linear((code - 3.0) / 255.0),
            srgb_to_linear((code + 3.0) / 255.0),
        );
        let v = ph.image.get(8, 8)[c];
        assert!(v > lo && v < hi, "channel {c}: {v}");
    }
    assert_eq!(ph.saturated, 0);
}

#[test]
fn exr_clipping_levels_and_refusals() {
    let d = tempfile::tempdir().unwrap();
    let e = d.path().join("i.exr");
    let mut img = Image::new(3, 1);
    img.data = vec![[0.5, 0.5, 0.5], [0.9, 0.2, 3.0], [1.0, 1.0, 1.0]];
    img.write_exr(&e, false).unwrap();
    let clip = |level| PhotoSettings {
        transfer: None,
        exposure: 2.0,
        saturation: Some(level),
    };
    let ph = Photo::read(&e, &clip(1.0)).unwrap();
    assert_eq!(ph.measured.bits, [true, false, false]);
    assert_eq!(ph.image.get(0, 0), [1.0; 3]);
    let msg = |r: Result<Photo, SceneError>| r.unwrap_err().to_string();
    assert!(msg(Photo::read(&e, &clip(-1.0))).contains("clipping level -1"));
    let srgb = read(&e, Some(Transfer::Srgb), 1.0);
    assert!(msg(srgb).contains("linear (or leave it out)"));
    assert!(msg(read(&e, None, 0.0)).contains("exposure scale 0"));
    let p = d.path().join("p.png");
    RgbImage::new(1, 1).save(&p).unwrap();
    assert!(msg(Photo::read(&p, &clip(1.0))).contains("only for EXR"));
    let bad = d.path().join("bad.jpg");
    std::fs::write(&bad, b"not a jpeg at all").unwrap();
    let m = msg(read(&bad, None, 1.0));
    assert!(
        m.contains("bad.jpg") && m.contains("PNG (8/16-bit), a JPEG"),
        "{m}"
    );
}

/// A dataset.json view with a PNG photo, a mask and an exposure: the saturated and masked-out
/// pixels are out of the camera's measurement and zero in the image; errors name the field.
#[test]
fn dataset_views_take_photos_and_masks() {
    let d = tempfile::tempdir().unwrap();
    let ds = crate::dataset::tests::sample_dataset(d.path());
    ds.save(&d.path().join("ds"), false).unwrap();
    let dir = d.path().join("ds");
    let mut photo = RgbImage::from_pixel(12, 8, Rgb([100, 100, 100]));
    photo.put_pixel(0, 0, Rgb([255, 255, 255]));
    photo.save(dir.join("photo.png")).unwrap();
    let mut m = GrayImage::from_pixel(12, 8, Luma([255]));
    m.put_pixel(5, 5, Luma([0]));
    m.save(dir.join("m.png")).unwrap();
    let json_path = dir.join("dataset.json");
    let original = std::fs::read_to_string(&json_path).unwrap();
    let edit = |view: serde_json::Value| {
        let mut j: serde_json::Value = serde_json::from_str(&original).unwrap();
        for (k, v) in view.as_object().unwrap() {
            j["views"][1][k] = v.clone();
        }
        std::fs::write(&json_path, serde_json::to_string(&j).unwrap()).unwrap();
        Dataset::load(&dir)
    };
    let ds =
        edit(serde_json::json!({"image": "photo.png", "mask": "m.png", "exposure": 3})).unwrap();
    let v = &ds.views[1];
    assert_eq!(v.camera.mask.as_ref().unwrap().count(), 96 - 2);
    assert!(!v.camera.measures(0, 0) && !v.camera.measures(5, 5));
    let img = v.image.as_ref().unwrap();
    assert!((img.get(1, 1)[2] - 3.0 * srgb_to_linear(100.0 / 255.0)).abs() < 1e-6);
    assert_eq!((img.get(0, 0), img.get(5, 5)), ([0.0; 3], [0.0; 3]));
    assert!(ds.views[0].camera.mask.is_none());
    let err = |view| edit(view).unwrap_err().to_string();
    let e = err(serde_json::json!({"image": "photo.png", "transfer": "gamma"}));
    assert!(e.contains("gamma") && e.contains("srgb"), "{e}");
    let e = err(serde_json::json!({"image": "photo.png", "mask": "none.png"}));
    assert!(
        e.contains("views[1].mask") && e.contains("mask file not found"),
        "{e}"
    );
    GrayImage::new(12, 8).save(dir.join("black.png")).unwrap();
    let e = err(serde_json::json!({"image": "photo.png", "mask": "black.png"}));
    assert!(
        e.contains("views[1]") && e.contains("no pixel of this view"),
        "{e}"
    );
    GrayImage::new(6, 8).save(dir.join("small.png")).unwrap();
    let e = err(serde_json::json!({"image": "photo.png", "mask": "small.png"}));
    assert!(
        e.contains("small.png") && e.contains("6×8") && e.contains("12×8"),
        "{e}"
    );
}
