//! Every reader of outside data behind one interface: [`Target::read`] writes the input where the
//! reader expects its file and calls the reader as the command line does.

use std::path::{Path, PathBuf};

use bssrdf::curvature::CurvatureTable;
use bssrdf::exit::{ExitTable, TableFile};
use bssrdf::incidence::IncidenceTable;
use inverse::optimize::Checkpoint;
use learn::sample::Sample;
use learn::train::{Prepared, Trainer};

use crate::fuzz_dir;
use crate::mutate::Layout;

/// A reader of outside data.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reader {
    /// Stanford PLY meshes, ASCII and binary (`geometry::io::load_mesh`).
    Ply,
    /// Wavefront OBJ meshes (`geometry::io::load_mesh`).
    Obj,
    /// Scene files in TOML (`scene::SceneDesc::load`).
    SceneToml,
    /// Scene files in JSON (`scene::SceneDesc::load`).
    SceneJson,
    /// Mitsuba 3 scene files (`scene::SceneDesc::load` of a `.xml`).
    SceneXml,
    /// `dataset.json` of a dataset folder, with its views' EXRs (`scene::Dataset::load`).
    Dataset,
    /// `scene.json` of a Mitsuba reference-render folder (`scene::Dataset::load_reference`).
    Reference,
    /// OpenEXR images (`scene::Image::read_exr`).
    Exr,
    /// Model files, safetensors with JSON metadata (`bssrdf::model::load`).
    Model,
    /// Checkpoints of an optimisation (`inverse::optimize::Checkpoint::read`).
    OptimizeCheckpoint,
    /// Checkpoints of a training run (`learn::train::Trainer::resume` on the data it was made
    /// with).
    TrainCheckpoint,
    /// Training sample files (`learn::samplefile::read_samples`).
    Samples,
    /// The exit, incidence and curvature tables (`bssrdf::exit::TableFile::from_json`, the
    /// reader of the shipped `crates/tables/data/*.json`).
    Tables,
    /// Tensors of the reference weights of Son et al. (`bssrdf::son24::read_bin`).
    Son24Bin,
    /// COLMAP's `cameras.txt`, beside a fixed `images.txt` (`scene::colmap::ColmapModel::read`
    /// and every image's camera).
    ColmapCamerasTxt,
    /// COLMAP's `images.txt`, beside a fixed `cameras.txt`.
    ColmapImagesTxt,
    /// COLMAP's `cameras.bin`, beside a fixed `images.bin`.
    ColmapCamerasBin,
    /// COLMAP's `images.bin`, beside a fixed `cameras.bin`.
    ColmapImagesBin,
    /// NeRF-style `transforms.json` (`scene::nerf::NerfTransforms::read`, every frame's camera
    /// and the lights).
    NerfTransforms,
    /// Photos and masks, PNG or JPEG by their content (`scene::image::Photo::read`,
    /// `scene::image::PixelMask::read`).
    Photo,
}

impl Reader {
    /// All readers.
    pub const ALL: [Reader; 20] = [
        Reader::Ply,
        Reader::Obj,
        Reader::SceneToml,
        Reader::SceneJson,
        Reader::SceneXml,
        Reader::Dataset,
        Reader::Reference,
        Reader::Exr,
        Reader::Model,
        Reader::OptimizeCheckpoint,
        Reader::TrainCheckpoint,
        Reader::Samples,
        Reader::Tables,
        Reader::Son24Bin,
        Reader::ColmapCamerasTxt,
        Reader::ColmapImagesTxt,
        Reader::ColmapCamerasBin,
        Reader::ColmapImagesBin,
        Reader::NerfTransforms,
        Reader::Photo,
    ];

    /// The reader's name: its corpus is `fuzz/corpus/<name>/`, its fixed companion files
    /// `fuzz/support/<name>/`.
    pub fn name(self) -> &'static str {
        match self {
            Reader::Ply => "ply",
            Reader::Obj => "obj",
            Reader::SceneToml => "scene-toml",
            Reader::SceneJson => "scene-json",
            Reader::SceneXml => "scene-xml",
            Reader::Dataset => "dataset",
            Reader::Reference => "reference",
            Reader::Exr => "exr",
            Reader::Model => "model",
            Reader::OptimizeCheckpoint => "optimize-checkpoint",
            Reader::TrainCheckpoint => "train-checkpoint",
            Reader::Samples => "samples",
            Reader::Tables => "tables",
            Reader::Son24Bin => "son24-bin",
            Reader::ColmapCamerasTxt => "colmap-cameras-txt",
            Reader::ColmapImagesTxt => "colmap-images-txt",
            Reader::ColmapCamerasBin => "colmap-cameras-bin",
            Reader::ColmapImagesBin => "colmap-images-bin",
            Reader::NerfTransforms => "transforms-json",
            Reader::Photo => "photo",
        }
    }

    /// The reader called `name`.
    pub fn from_name(name: &str) -> Option<Reader> {
        Reader::ALL.into_iter().find(|r| r.name() == name)
    }

    /// The file name an input is written to (the name the reader looks for, or one with the
    /// extension it needs).
    pub fn input_name(self) -> &'static str {
        match self {
            Reader::Ply => "mesh.ply",
            Reader::Obj => "mesh.obj",
            Reader::SceneToml => "scene.toml",
            Reader::SceneJson => "scene.json",
            Reader::SceneXml => "scene.xml",
            Reader::Dataset => "dataset.json",
            Reader::Reference => "scene.json",
            Reader::Exr => "image.exr",
            Reader::Model => "model.safetensors",
            Reader::OptimizeCheckpoint => "checkpoint.json",
            Reader::TrainCheckpoint => "checkpoint.bin",
            Reader::Samples => "train.samples",
            Reader::Tables => "table.json",
            Reader::Son24Bin => "tensor.bin",
            Reader::ColmapCamerasTxt => "cameras.txt",
            Reader::ColmapImagesTxt => "images.txt",
            Reader::ColmapCamerasBin => "cameras.bin",
            Reader::ColmapImagesBin => "images.bin",
            Reader::NerfTransforms => "transforms.json",
            Reader::Photo => "photo.png",
        }
    }

    /// How the reader's files are laid out (for the mutator).
    pub fn layout(self) -> Layout {
        match self {
            Reader::Ply
            | Reader::Exr
            | Reader::Son24Bin
            | Reader::ColmapCamerasBin
            | Reader::ColmapImagesBin
            | Reader::Photo => Layout::Binary,
            // safetensors: u64 header length, then the JSON header.
            Reader::Model => Layout::PrefixedJson {
                len_at: 0,
                len_bytes: 8,
                json_at: 8,
            },
            // magic, u32 version, u32 header length, JSON header.
            Reader::Samples => Layout::PrefixedJson {
                len_at: 12,
                len_bytes: 4,
                json_at: 16,
            },
            // magic, u64 header length, JSON header.
            Reader::TrainCheckpoint => Layout::PrefixedJson {
                len_at: 8,
                len_bytes: 8,
                json_at: 16,
            },
            _ => Layout::Text,
        }
    }

    /// The corpus folder: `fuzz/corpus/<name>/`, except for the tables, whose corpus is the
    /// folder of the shipped tables themselves (`crates/tables/data/`, 700 KB not worth a copy
    /// that could go stale).
    pub fn corpus_dir(self) -> PathBuf {
        match self {
            Reader::Tables => fuzz_dir().join("../crates/tables/data"),
            _ => fuzz_dir().join("corpus").join(self.name()),
        }
    }

    /// The folder of fixed companion files (images of a dataset, the samples a training
    /// checkpoint was made on); may not exist.
    pub fn support_dir(self) -> PathBuf {
        fuzz_dir().join("support").join(self.name())
    }

    /// The corpus files, sorted by name.
    pub fn corpus(self) -> std::io::Result<Vec<(PathBuf, Vec<u8>)>> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(self.corpus_dir())?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        files
            .into_iter()
            .map(|p| std::fs::read(&p).map(|b| (p, b)))
            .collect()
    }
}

/// The training and validation rows of a samples file as the train-checkpoint corpus was made:
/// normalisation over all samples, the first three quarters to train on, the rest to validate.
pub fn train_data(
    samples: &[Sample],
) -> Result<(bssrdf::nn::Normalisation, Prepared, Prepared), learn::train::TrainError> {
    let norm = learn::train::normalisation_of(samples)?;
    let cut = (samples.len() * 3 / 4).max(1).min(samples.len());
    let train = learn::train::prepare(&samples[..cut], &norm)?;
    let val = learn::train::prepare(&samples[cut..], &norm)?;
    Ok((norm, train, val))
}

/// Which table a text holds, by its first data key (`"f"` exit, `"a"` incidence, `"c"`
/// curvature); exit when none is found (the reader then reports the missing field).
fn table_kind(text: &str) -> &'static str {
    [
        ("\"f\"", "exit"),
        ("\"a\"", "incidence"),
        ("\"c\"", "curvature"),
    ]
    .into_iter()
    .filter_map(|(key, kind)| text.find(key).map(|i| (i, kind)))
    .min()
    .map_or("exit", |(_, kind)| kind)
}

/// One reader set up in a scratch folder.
pub struct Target {
    reader: Reader,
    dir: PathBuf,
    input: PathBuf,
    train: Option<(Prepared, Prepared)>,
}

impl Target {
    /// The reader `reader` reading from the folder `dir` (created if needed; its support files
    /// are copied in).
    pub fn new(reader: Reader, dir: &Path) -> Result<Target, String> {
        let fail =
            |what: &str, e: &dyn std::fmt::Display| format!("{}: {what}: {e}", reader.name());
        std::fs::create_dir_all(dir).map_err(|e| fail("scratch folder", &e))?;
        let support = reader.support_dir();
        if support.is_dir() {
            for entry in std::fs::read_dir(&support).map_err(|e| fail("support folder", &e))? {
                let path = entry.map_err(|e| fail("support folder", &e))?.path();
                if let Some(name) = path.file_name() {
                    std::fs::copy(&path, dir.join(name)).map_err(|e| fail("support file", &e))?;
                }
            }
        }
        let train = if reader == Reader::TrainCheckpoint {
            let (_, samples) = learn::samplefile::read_samples(&dir.join("train.samples"))
                .map_err(|e| fail("support samples", &e))?;
            let (_, train, val) = train_data(&samples).map_err(|e| fail("support samples", &e))?;
            Some((train, val))
        } else {
            None
        };
        Ok(Target {
            reader,
            dir: dir.to_path_buf(),
            input: dir.join(reader.input_name()),
            train,
        })
    }

    /// The reader.
    pub fn reader(&self) -> Reader {
        self.reader
    }

    /// The file inputs are written to.
    pub fn input(&self) -> &Path {
        &self.input
    }

    /// Writes `bytes` as the input file and reads it: `Ok` when the reader accepts it, else the
    /// reader's error message.
    pub fn read(&self, bytes: &[u8]) -> Result<(), String> {
        // A new file each time: rewriting a truncated file in place makes ext4 flush it on
        // close (auto_da_alloc), which costs milliseconds per input.
        let _ = std::fs::remove_file(&self.input);
        std::fs::write(&self.input, bytes)
            .unwrap_or_else(|e| panic!("cannot write {}: {e}", self.input.display()));
        self.read_input()
    }

    /// Reads the input file as the command line does.
    pub fn read_input(&self) -> Result<(), String> {
        fn text<E: std::fmt::Display>(r: Result<impl Sized, E>) -> Result<(), String> {
            r.map(drop).map_err(|e| e.to_string())
        }
        let input = &self.input;
        match self.reader {
            Reader::Ply | Reader::Obj => text(geometry::io::load_mesh(input)),
            Reader::SceneToml | Reader::SceneJson | Reader::SceneXml => {
                text(scene::SceneDesc::load(input))
            }
            Reader::Dataset => text(scene::Dataset::load(&self.dir)),
            Reader::Reference => text(scene::Dataset::load_reference(&self.dir)),
            Reader::Exr => text(scene::Image::read_exr(input)),
            Reader::Model => text(bssrdf::model::load(input)),
            Reader::OptimizeCheckpoint => text(Checkpoint::read(input)),
            Reader::TrainCheckpoint => {
                let (train, val) = self.train.clone().expect("set up with the target");
                let mut trainer =
                    Trainer::resume(input, None, train, val).map_err(|e| e.to_string())?;
                // What the reader accepted must be usable: one step, as `run` would take it,
                // when it is cheap (its error, e.g. a diverged loss, is the run's business,
                // not the reader's).
                let c = trainer.config();
                let draws = match c.objective {
                    learn::train::Objective::EnergyScore { draws, .. } => draws,
                    learn::train::Objective::Cvae => 1,
                };
                if trainer.step() < c.steps && c.batch_size <= 64 && draws <= 16 {
                    let _ = trainer.train_step();
                }
                Ok(())
            }
            Reader::Samples => text(learn::samplefile::read_samples(input)),
            Reader::Tables => {
                // The reader takes text; bytes that are not UTF-8 reach it as replacement
                // characters.
                let bytes =
                    std::fs::read(input).map_err(|e| format!("{}: {e}", input.display()))?;
                let text_in = String::from_utf8_lossy(&bytes);
                let name = input.display().to_string();
                match table_kind(&text_in) {
                    "incidence" => text(IncidenceTable::from_json(&text_in, &name)),
                    "curvature" => text(CurvatureTable::from_json(&text_in, &name)),
                    _ => text(ExitTable::from_json(&text_in, &name)),
                }
            }
            Reader::Son24Bin => text(bssrdf::son24::read_bin(input)),
            Reader::ColmapCamerasTxt
            | Reader::ColmapImagesTxt
            | Reader::ColmapCamerasBin
            | Reader::ColmapImagesBin => {
                let model =
                    scene::colmap::ColmapModel::read(&self.dir).map_err(|e| e.to_string())?;
                for im in &model.images {
                    model.camera(im).map_err(|e| e.to_string())?;
                }
                Ok(())
            }
            Reader::NerfTransforms => {
                let t = scene::nerf::NerfTransforms::read(input).map_err(|e| e.to_string())?;
                text(t.views(|_| Ok((64, 48))))?;
                text(t.lights())
            }
            Reader::Photo => {
                let settings = scene::image::PhotoSettings::default();
                text(scene::image::Photo::read(input, &settings))?;
                text(scene::image::PixelMask::read(input))
            }
        }
    }

    /// Whether an error message names the input: its file name, or (for readers of a folder)
    /// the folder.
    pub fn names_input(&self, message: &str) -> bool {
        message.contains(self.reader.input_name())
            || (matches!(
                self.reader,
                Reader::Dataset
                    | Reader::Reference
                    | Reader::ColmapCamerasTxt
                    | Reader::ColmapImagesTxt
                    | Reader::ColmapCamerasBin
                    | Reader::ColmapImagesBin
            ) && message.contains(&self.dir.display().to_string()))
    }
}
