//! `matseg.Generator`: sample `i` of a 2D or 3D dataset made in memory,
//! exactly as `matseg generate` with the same seed and sources writes it.

use crate::batches::{batch_list, MixedDataset};
use crate::errors::matseg_error;
use crate::samples::sample_dict;
use matseg_data::training::GeneratorSource;
use matseg_data::{
    decode_encoded, generate_with, EncodedSample, Format, GenerateOptions, JobSlice,
};
use matseg_image::LicenceFilter;
use matseg_pipeline::files3d::recipe_3d;
use matseg_pipeline::progress::{Progress, Silent};
use matseg_pipeline::scenes::{SceneFolders, SceneRecipe, SceneSources};
use matseg_pipeline::sources::Defaults;
use matseg_scene::Recipe2d;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use std::path::PathBuf;
use std::sync::Mutex;

/// A generator of one dataset (kind, sources, recipe, seed).
#[pyclass(module = "matseg._core", name = "Generator", frozen)]
pub struct PyGenerator {
    scenes: SceneSources,
    seed: u64,
    warnings: Vec<String>,
}

/// Collects the warnings of a load (`Generator.warnings` in Python).
#[derive(Default)]
struct Warnings(Mutex<Vec<String>>);

impl Progress for Warnings {
    fn start(&self, _total: u64, _what: &str) {}
    fn advance(&self) {}
    fn finish(&self) {}
    fn warn(&self, message: &str) {
        matseg_image::sync::lock(&self.0).push(format!("skipped {message}"));
    }
}

impl PyGenerator {
    /// The encoded files of sample `index`.
    fn make(&self, py: Python<'_>, index: u64) -> PyResult<EncodedSample> {
        py.detach(|| {
            self.scenes
                .with_maker(None, |maker| maker.make(self.seed, index))
        })
        .map_err(matseg_error)
    }
}

#[pymethods]
impl PyGenerator {
    /// Loads the sources (folders; empty: the fetched corpus, else the
    /// bundled assets) and the recipe (a TOML file; none: the defaults).
    #[new]
    #[pyo3(signature = (kind, seed, photos, textures, materials, meshes, hdris, recipe, size, spp, licences, cache_mb))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments, one per setting
    fn new(
        py: Python<'_>,
        kind: &str,
        seed: u64,
        photos: Vec<PathBuf>,
        textures: Vec<PathBuf>,
        materials: Vec<PathBuf>,
        meshes: Vec<PathBuf>,
        hdris: Vec<PathBuf>,
        recipe: Option<PathBuf>,
        size: Option<u32>,
        spp: Option<u32>,
        licences: &str,
        cache_mb: usize,
    ) -> PyResult<Self> {
        let licences =
            LicenceFilter::parse(licences).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let recipe = match kind {
            "2d" => SceneRecipe::TwoD(match &recipe {
                Some(path) => Recipe2d::from_toml_file(path).map_err(matseg_error)?,
                None => Recipe2d::default(),
            }),
            "3d" => {
                SceneRecipe::ThreeD(recipe_3d(recipe.as_deref(), size, spp).map_err(matseg_error)?)
            }
            other => {
                return Err(PyValueError::new_err(format!(
                    "kind: '{other}' is not a scene kind (2d or 3d)"
                )))
            }
        };
        let folders = SceneFolders {
            photos,
            textures,
            materials,
            meshes,
            hdris,
        };
        let collected = Warnings::default();
        let scenes = py
            .detach(|| {
                SceneSources::load(
                    recipe,
                    &folders,
                    cache_mb,
                    Defaults::CorpusOrBundled,
                    &licences,
                    &collected,
                )
            })
            .map_err(matseg_error)?;
        Ok(Self {
            scenes,
            seed,
            warnings: collected.0.into_inner().unwrap_or_else(|e| e.into_inner()),
        })
    }

    /// Sample `index`, decoded (see `samples::sample_dict`).
    fn sample<'py>(&self, py: Python<'py>, index: u64) -> PyResult<Bound<'py, PyDict>> {
        let encoded = self.make(py, index)?;
        let sample = decode_encoded(&encoded).map_err(matseg_error)?;
        sample_dict(py, sample)
    }

    /// The files of sample `index` as `matseg generate` writes them into
    /// its folder (name to bytes; `Finished.txt` aside).
    fn files<'py>(&self, py: Python<'py>, index: u64) -> PyResult<Bound<'py, PyDict>> {
        let encoded = self.make(py, index)?;
        let d = PyDict::new(py);
        for (name, bytes) in matseg_data::folders::sample_files(&encoded) {
            d.set_item(name, PyBytes::new(py, bytes))?;
        }
        Ok(d)
    }

    /// Training batch `step` of online 2D scenes (with `mix`, a dataset
    /// mixed in) under `plan` (JSON), as `matseg train` draws them from
    /// this generator.
    #[pyo3(signature = (plan, seed, step, mix=None))]
    fn batch<'py>(
        &self,
        py: Python<'py>,
        plan: &str,
        seed: u64,
        step: u64,
        mix: MixedDataset<'_>,
    ) -> PyResult<Bound<'py, PyList>> {
        let SceneSources::TwoD { libraries, recipe } = &self.scenes else {
            return Err(PyValueError::new_err(
                "online training batches come from a 2d generator; write 3d scenes with matseg generate and train on the dataset",
            ));
        };
        let source = GeneratorSource {
            sources: libraries.sources(),
            recipe: recipe.clone(),
            seed: self.seed,
        };
        batch_list(py, &source, mix, plan, seed, step)
    }

    /// Writes job `shard_index` of `num_shards` of the `n`-sample dataset
    /// into `out` as `matseg generate` does (`format`: folders or wds),
    /// skipping complete samples; returns (generated, skipped, bytes).
    #[pyo3(signature = (out, n, format, shard_size, num_shards, shard_index))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments, one per setting
    fn write(
        &self,
        py: Python<'_>,
        out: PathBuf,
        n: u64,
        format: &str,
        shard_size: u64,
        num_shards: u64,
        shard_index: u64,
    ) -> PyResult<(u64, u64, u64)> {
        let format = match format {
            "folders" => Format::Folders,
            "wds" => Format::Wds,
            other => {
                return Err(PyValueError::new_err(format!(
                    "format: '{other}': expected folders or wds"
                )))
            }
        };
        let opts = GenerateOptions {
            out,
            n,
            seed: self.seed,
            format,
            shard_size,
            job: JobSlice {
                count: num_shards,
                index: shard_index,
            },
        };
        let report = py
            .detach(|| {
                self.scenes
                    .with_maker(None, |maker| generate_with(&opts, maker, &Silent))
            })
            .map_err(matseg_error)?;
        Ok((report.generated, report.skipped, report.bytes))
    }

    /// Files left out as unreadable while loading the sources.
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }
}
