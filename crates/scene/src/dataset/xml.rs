//! A Mitsuba 3 scene folder as a dataset: `scene.xml` ([`crate::mitsuba_xml`]) and one image per
//! sensor, `view_000.exr`, `view_001.exr`, … in the order of the sensors (a capture posed and lit
//! as the scene file says). The scene's boundary and phase function are what the dataset states
//! about the object; the σ_t and α written in its interior medium are not read as a truth (they
//! are what the images are for).

use std::path::Path;

use super::{Dataset, DatasetKind, DatasetMetadata, MITSUBA_SCENE_FILE, View, load_view_image};
use crate::{Object, SceneError};

/// Loads the scene folder `dir` (see the module docs).
pub(super) fn load_scene_folder(dir: &Path) -> Result<Dataset, SceneError> {
    let file = dir.join(MITSUBA_SCENE_FILE);
    let desc = crate::mitsuba_xml::load(&file)?;
    let mut views = Vec::with_capacity(desc.views.len());
    for (i, v) in desc.views.iter().enumerate() {
        let name = format!("view_{i:03}.exr");
        let location = format!("{}: sensor {i}'s image", file.display());
        let (img, path) = load_view_image(dir, &name, &location, &v.camera)?;
        views.push(View {
            camera: v.camera.clone(),
            light: v.light,
            image: Some(img),
            image_path: Some(path),
            expected_mean: None,
        });
    }
    Ok(Dataset {
        views,
        mesh: desc.mesh,
        object: Some(Object::of(&desc.medium)),
        truth: None,
        render: desc.render,
        metadata: DatasetMetadata {
            units: Some(super::UNITS_NOTE.into()),
            conventions: Some(super::CONVENTIONS_NOTE.into()),
            generator: Some(format!("Mitsuba 3 scene file {}", file.display())),
            notes: None,
            length_unit: None,
        },
        root: dir.to_path_buf(),
        kind: DatasetKind::MitsubaScene,
        warnings: Vec::new(),
    })
}
