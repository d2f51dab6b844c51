//! The 2D generator's throughput at the paper's scene-size distribution:
//! soft maps alone, generation in memory, encoding, and whole datasets
//! written to disk on one thread and on all of them.

use super::clock::{process_cpu_seconds, Clock};
use crate::error::PipelineError;
use crate::progress::Silent;
use crate::sources::Libraries;
use matseg_data::{encode_scene, generate_dataset, sample_rng, Format, GenerateOptions, JobSlice};
use matseg_extract::make_soft_maps;
use matseg_scene::{generate_2d, Recipe2d, Scene2d};
use std::fmt::Write as _;
use std::path::PathBuf;

/// What to measure.
#[derive(Clone, Debug)]
pub struct GeneratorBench {
    /// Scenes per row.
    pub scenes: u64,
    /// Threads of the parallel rows.
    pub threads: usize,
    /// Seed of the scenes.
    pub seed: u64,
    /// Where the end-to-end rows write (and then delete) their datasets.
    pub dir: PathBuf,
    /// Only generation in memory on one thread (a run to profile).
    pub in_memory_only: bool,
}

/// One measured row.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchRow {
    /// What was measured.
    pub name: String,
    /// Threads it ran on.
    pub threads: usize,
    /// Scenes it made.
    pub scenes: u64,
    /// Wall seconds.
    pub wall: f64,
    /// Process CPU seconds.
    pub cpu: f64,
    /// Bytes written (0: none).
    pub bytes: u64,
}

impl BenchRow {
    /// A row measured on one thread: `(wall, cpu)` seconds over `scenes`.
    fn one_thread(name: &str, scenes: u64, (wall, cpu): (f64, f64), bytes: u64) -> Self {
        Self {
            name: name.into(),
            threads: 1,
            scenes,
            wall,
            cpu,
            bytes,
        }
    }
}

/// The measured scenes' sizes and materials, to compare with the means of
/// the distribution they are drawn from.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SceneSample {
    /// Scenes counted.
    pub scenes: u64,
    /// Their pixels.
    pub pixels: u64,
    /// Their materials.
    pub materials: u64,
}

impl SceneSample {
    fn add(&mut self, scene: &Scene2d) {
        self.scenes += 1;
        self.pixels += u64::from(scene.image.width()) * u64::from(scene.image.height());
        self.materials += scene.weights.len() as u64;
    }
}

/// The rows, the scenes measured, and what they were drawn from.
#[derive(Clone, Debug)]
pub struct GeneratorReport {
    /// The measured rows, in table order.
    pub rows: Vec<BenchRow>,
    /// The scenes of one row.
    pub sample: SceneSample,
    /// Means of the recipe's distribution: megapixels and materials.
    pub distribution: (f64, f64),
    /// Photos and textures drawn from.
    pub libraries: (usize, usize),
}

/// The in-memory row's name, in the whole table and alone.
const IN_MEMORY: &str = "generate in memory (no encoding)";

impl GeneratorBench {
    /// Measures each row on scenes from `libraries`.
    pub fn run(&self, libraries: &Libraries) -> Result<GeneratorReport, PipelineError> {
        if self.scenes == 0 {
            return Err(PipelineError::setting(
                "scenes",
                None::<&str>,
                "must be at least 1",
            ));
        }
        let recipe = Recipe2d::default();
        let sources = libraries.sources();
        // Warm the photo cache so every row measures steady-state generation.
        for i in 0..8.max(libraries.photos.len() as u64 / 4) {
            generate_2d(&mut sample_rng(self.seed ^ 0xdead, i), &recipe, sources)?;
        }
        let mut rows = Vec::new();
        let mut sample = SceneSample::default();
        let report = |rows, sample| GeneratorReport {
            rows,
            sample,
            distribution: (
                recipe.scene.mean_pixels() / 1e6,
                recipe.scene.mean_materials(),
            ),
            libraries: (libraries.photos.len(), libraries.textures.len()),
        };
        if self.in_memory_only {
            let start = Clock::now();
            for i in 0..self.scenes {
                let scene = generate_2d(&mut sample_rng(self.seed, i), &recipe, sources)?;
                sample.add(&scene);
            }
            rows.push(BenchRow::one_thread(
                IN_MEMORY,
                self.scenes,
                start.elapsed(1),
                0,
            ));
            return Ok(report(rows, sample));
        }
        let start = Clock::now();
        for i in 0..self.scenes {
            let mut rng = sample_rng(self.seed, i);
            let shape = recipe.scene.draw(&mut rng);
            make_soft_maps(
                &mut rng,
                sources.photos,
                shape.width,
                shape.height,
                shape.materials,
                shape.hard,
                shape.max_occupancy,
                &recipe.maps,
            )?;
        }
        rows.push(BenchRow::one_thread(
            "soft maps only (pipeline.md §1)",
            self.scenes,
            start.elapsed(1),
            0,
        ));
        let (mut generation, mut encoding) = ((0.0, 0.0), (0.0, 0.0));
        let mut bytes = 0u64;
        let add = |total: &mut (f64, f64), (wall, cpu): (f64, f64)| {
            total.0 += wall;
            total.1 += cpu;
        };
        for i in 0..self.scenes {
            let t = Clock::now();
            let scene = generate_2d(&mut sample_rng(self.seed, i), &recipe, sources)?;
            add(&mut generation, t.elapsed(1));
            let t = Clock::now();
            let encoded = encode_scene(&scene, self.seed, i, sources);
            add(&mut encoding, t.elapsed(1));
            sample.add(&scene);
            bytes += encoded.bytes() as u64;
        }
        rows.push(BenchRow::one_thread(IN_MEMORY, self.scenes, generation, 0));
        rows.push(BenchRow::one_thread(
            "encode only (JPEG + PNG masks + JSON)",
            self.scenes,
            encoding,
            bytes,
        ));
        for (t, format) in [
            (1, Format::Folders),
            (self.threads, Format::Folders),
            (self.threads, Format::Wds),
        ] {
            let dir = self.dir.join(format!(
                "matseg-bench-{}-{t}-{format:?}",
                std::process::id()
            ));
            // A folder of this run's own, made new, so that removing it
            // after the row removes nothing of anyone else's.
            std::fs::create_dir(&dir).map_err(|e| {
                PipelineError::file(dir.display(), format!("cannot make a scratch folder: {e}"))
            })?;
            let opts = GenerateOptions {
                out: dir.clone(),
                n: self.scenes,
                seed: self.seed,
                format,
                shard_size: self.scenes,
                job: JobSlice::ALL,
            };
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .map_err(|e| PipelineError::Settings(format!("threads {t}: {e}")))?;
            let start = Clock::now();
            let written = pool.install(|| generate_dataset(&opts, &recipe, sources, &Silent));
            let (wall, cpu) = start.elapsed(t);
            let _ = std::fs::remove_dir_all(&dir);
            rows.push(BenchRow {
                name: format!(
                    "end to end, {} to disk",
                    if format == Format::Wds {
                        "wds shard"
                    } else {
                        "folders"
                    }
                ),
                threads: t,
                scenes: self.scenes,
                wall,
                cpu,
                bytes: written?.bytes,
            });
        }
        Ok(report(rows, sample))
    }
}

impl GeneratorReport {
    /// The report as text: the scenes' means beside the distribution's,
    /// then a Markdown table of the rows.
    pub fn text(&self) -> String {
        let n = self.sample.scenes.max(1) as f64;
        let mut out = format!(
            "scenes: {} per row, mean {:.3} MP and {:.2} materials (the paper's 2D distribution's means: {:.3} MP, {:.2}); {} photos, {} textures\n",
            self.sample.scenes,
            self.sample.pixels as f64 / n / 1e6,
            self.sample.materials as f64 / n,
            self.distribution.0,
            self.distribution.1,
            self.libraries.0,
            self.libraries.1,
        );
        let _ = writeln!(
            out,
            "| {:<40} | {:>7} | {:>9} | {:>13} | {:>13} | {:>8} |",
            "measure", "threads", "wall s", "CPU s / scene", "scenes/s/core", "MB/s"
        );
        let _ = writeln!(
            out,
            "|{:-<42}|{:->9}|{:->11}|{:->15}|{:->15}|{:->10}|",
            "", "", "", "", "", ""
        );
        for r in &self.rows {
            let cpu_per_scene = r.cpu / r.scenes as f64;
            let _ = writeln!(
                out,
                "| {:<40} | {:>7} | {:>9.2} | {:>13.4} | {:>13.1} | {:>8} |",
                r.name,
                r.threads,
                r.wall,
                cpu_per_scene,
                1.0 / cpu_per_scene,
                if r.bytes > 0 {
                    format!("{:.1}", r.bytes as f64 / 1e6 / r.wall)
                } else {
                    "-".into()
                }
            );
        }
        if process_cpu_seconds().is_none() {
            out.push_str(
                "(no process CPU clock here: CPU seconds are wall seconds times threads)\n",
            );
        }
        out
    }
}
