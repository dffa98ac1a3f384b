//! Seeds of the capture readers: photos and masks, NeRF `transforms.json`.

use super::{Res, corpus};
use fuzz::readers::Reader;

/// Small photos and masks: 8-bit RGB and RGBA PNG, a 16-bit PNG, a grey mask and a JPEG.
pub fn photos() -> Res {
    use image::{GrayImage, ImageBuffer, Luma, Rgb, RgbImage, Rgba, RgbaImage};
    let r = Reader::Photo;
    RgbImage::from_fn(4, 3, |x, y| Rgb([(60 * x) as u8, (80 * y) as u8, 255]))
        .save(corpus(r, "rgb8.png"))?;
    RgbaImage::from_fn(3, 2, |x, _| Rgba([200, 100, 50, (120 * x) as u8]))
        .save(corpus(r, "rgba8.png"))?;
    ImageBuffer::<Rgb<u16>, _>::from_fn(2, 2, |x, y| Rgb([32768, 65535 * x as u16, y as u16]))
        .save(corpus(r, "rgb16.png"))?;
    GrayImage::from_fn(5, 2, |x, _| Luma([if x > 1 { 255 } else { 0 }]))
        .save(corpus(r, "mask.png"))?;
    RgbImage::from_fn(8, 8, |x, y| Rgb([(30 * x) as u8, (30 * y) as u8, 90]))
        .save_with_format(corpus(r, "rgb.jpg"), image::ImageFormat::Jpeg)?;
    Ok(())
}

/// Two `transforms.json`: Blender's layout (one field of view, names without extensions, a
/// light position per frame) and a calibrated one (fl_x/fl_y/cx/cy, a frame's own f_y, zero
/// distortion, a light as a matrix, 3-row poses).
pub fn transforms() -> Res {
    let r = Reader::NerfTransforms;
    let blender = r#"{
  "camera_angle_x": 0.6911112070083618,
  "frames": [
    {
      "file_path": "./train/r_0",
      "rotation": 0.012566370614359171,
      "transform_matrix": [
        [-0.9999021887779236, 0.004192245192825794, -0.013345719315111637, -0.05379832163453102],
        [-0.013988681137561798, -0.2996590733528137, 0.95394366979599, 3.845470428466797],
        [-4.656612873077393e-10, 0.9540371894836426, 0.29968830943107605, 1.2080823183059692],
        [0.0, 0.0, 0.0, 1.0]
      ],
      "light_position": [1.0, 4.0, 2.0]
    },
    {
      "file_path": "./train/r_1",
      "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]],
      "light_pos": [0.5, -1.5, 3.0]
    }
  ]
}
"#;
    let calibrated = r#"{
  "camera_model": "OPENCV",
  "fl_x": 1150.5, "fl_y": 1148.25, "cx": 511.5, "cy": 383.25, "w": 1024, "h": 768,
  "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0,
  "aabb_scale": 16, "scale": 0.33, "offset": [0.5, 0.5, 0.5],
  "frames": [
    {"file_path": "images/frame_00001.jpg", "fl_y": 1149.0,
     "transform_matrix": [[0, 0, 1, 3], [1, 0, 0, 0], [0, 1, 0, 0.5]],
     "light_transform": [[1, 0, 0, 0.25], [0, 1, 0, 2], [0, 0, 1, -1], [0, 0, 0, 1]]}
  ]
}
"#;
    std::fs::write(corpus(r, "blender.json"), blender)?;
    std::fs::write(corpus(r, "calibrated.json"), calibrated)?;
    Ok(())
}
