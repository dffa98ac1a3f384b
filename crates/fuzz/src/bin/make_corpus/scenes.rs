//! Seeds of the scene-file readers: TOML and JSON scene files (listed views, rigs, a measured
//! medium in millimetres) and Mitsuba 3 XML scenes.

use super::{Res, corpus};
use fuzz::readers::Reader;

const SCENE_VIEWS_TOML: &str = r#"mesh = "mesh.ply"

[medium]
sigma_t = 60.0
albedo = [0.95, 0.90, 0.85]
g = 0.2
eta = 1.3

[[views]]
camera = { origin = [0.0, 0.5, 2.0], target = [0.0, 0.0, 0.0], up = [0.0, 1.0, 0.0], fov = 40.0, width = 16, height = 12 }
light = { position = [1.0, 1.5, 0.5], intensity = [4.0, 4.0, 4.0] }

[[views]]
camera = { origin = [2.0, 0.0, 0.0], target = [0.0, 0.0, 0.0], width = 16, height = 12 }
light = { position = [2.0, 0.2, 0.0], intensity = 4.0 }

[render]
spp = 4
max_depth = 8
seed = 3
"#;

const SCENE_RIG_TOML: &str = r#"shape = { name = "torus", major = 0.4, minor = 0.1, segments = 16, scale = 0.5 }

[medium]
sigma_t = [30.0, 40.0, 50.0]
albedo = 0.9

[rig]
views = 3
radius = 2.5
fov = 30.0
width = 8
height = 8
light = "attached"
light_offset = [0.5, 0.5, 0.0]
intensity = [1.0, 2.0, 3.0]
"#;

const SCENE_MEASURED_TOML: &str = r#"length_unit = "mm"
shape = { name = "sphere", radius = 15, subdivisions = 2 }

[medium]
measured = "marble"
g = 0.3
eta = 1.5

[rig]
views = 2
radius = 60.0
width = 8
height = 8
light = "attached"
intensity = 1000.0
"#;

const SCENE_VIEWS_JSON: &str = r#"{
  "mesh": "mesh.ply",
  "medium": { "sigma_t": 60.0, "albedo": [0.95, 0.90, 0.85], "g": 0.0, "eta": 1.0 },
  "views": [
    { "camera": { "origin": [0.0, 0.5, 2.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 1.0, 0.0],
                  "fov": 40.0, "width": 16, "height": 12 },
      "light": { "position": [1.0, 1.5, 0.5], "intensity": [4.0, 4.0, 4.0] } },
    { "camera": { "origin": [2.0, 0.0, 0.0], "target": [0.0, 0.0, 0.0], "width": 16, "height": 12 },
      "light": { "position": [2.0, 0.2, 0.0], "intensity": 4.0 } }
  ],
  "render": { "spp": 16, "max_depth": 32, "seed": 1, "renderer": "translucent volpath" }
}
"#;

const SCENE_RIG_JSON: &str = r#"{
  "shape": { "name": "box", "size": [0.8, 0.6, 0.7], "radius": 0.1, "segments": 8 },
  "medium": { "sigma_t": [50.0, 60.0, 70.0], "albedo": 0.8 },
  "rig": { "views": 4, "radius": 2.0, "target": [0.0, 0.1, 0.0], "fov": 45.0, "width": 8,
           "height": 6, "light": "fixed", "light_position": [1.0, 1.5, 0.5], "intensity": 2.0,
           "elevation": [-30.0, 60.0] }
}
"#;

const SCENE_XML_ROUGH: &str = r#"<scene version="3.0.0">
    <integrator type="volpath"><integer name="max_depth" value="32"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0.5, 2" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
    </sensor>
    <emitter type="point">
        <point name="position" x="1" y="1.5" z="0.5"/>
        <rgb name="intensity" value="4, 4, 4"/>
    </emitter>
    <shape type="ply">
        <string name="filename" value="mesh.ply"/>
        <transform name="to_world"><rotate y="1" angle="30"/><scale value="0.5"/></transform>
        <bsdf type="roughdielectric">
            <string name="distribution" value="ggx"/>
            <float name="alpha" value="0.3"/>
            <float name="int_ior" value="1.4"/>
            <float name="ext_ior" value="1"/>
        </bsdf>
        <medium type="homogeneous" name="interior">
            <rgb name="sigma_t" value="0.5, 0.6, 0.7"/>
            <float name="scale" value="100"/>
            <rgb name="albedo" value="0.95, 0.9, 0.85"/>
            <phase type="hg"><float name="g" value="0.6"/></phase>
        </medium>
    </shape>
</scene>
"#;

const SCENE_XML_REFS: &str = r#"<scene version="3.0.0">
    <default name="res" value="8"/>
    <default name="ior" value="water"/>
    <bsdf type="dielectric" id="surface"><string name="int_ior" value="$ior"/></bsdf>
    <medium type="homogeneous" id="milk">
        <float name="sigma_t" value="60"/>
        <spectrum name="albedo" value="0.9"/>
    </medium>
    <sensor type="perspective">
        <string name="focal_length" value="35mm"/>
        <transform name="to_world">
            <matrix value="1 0 0 0  0 1 0 0  0 0 1 -2  0 0 0 1"/>
        </transform>
        <film type="hdrfilm"><integer name="width" value="$res"/><integer name="height" value="$res"/></film>
    </sensor>
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <string name="fov_axis" value="smaller"/>
        <transform name="to_world"><lookat origin="2, 0, 0" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
    </sensor>
    <emitter type="point">
        <transform name="to_world"><translate value="0.5, 1, -1.5"/></transform>
        <spectrum name="intensity" value="3"/>
    </emitter>
    <shape type="ply">
        <string name="filename" value="mesh.ply"/>
        <ref id="surface"/>
        <ref name="interior" id="milk"/>
    </shape>
</scene>
"#;

pub fn scenes() -> Res {
    let small_example = scene::scene_file::EXAMPLE_SCENE_TOML
        .replace("width = 128", "width = 8")
        .replace("height = 128", "height = 8");
    for (r, name, text) in [
        (Reader::SceneToml, "example.toml", small_example.as_str()),
        (Reader::SceneToml, "views-mesh.toml", SCENE_VIEWS_TOML),
        (Reader::SceneToml, "rig-torus.toml", SCENE_RIG_TOML),
        (Reader::SceneToml, "rig-measured.toml", SCENE_MEASURED_TOML),
        (Reader::SceneJson, "views-mesh.json", SCENE_VIEWS_JSON),
        (Reader::SceneJson, "rig-box.json", SCENE_RIG_JSON),
        (Reader::SceneXml, "rough-hg.xml", SCENE_XML_ROUGH),
        (Reader::SceneXml, "refs-defaults.xml", SCENE_XML_REFS),
    ] {
        std::fs::write(corpus(r, name), text)?;
    }
    Ok(())
}
