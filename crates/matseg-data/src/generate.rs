//! Writing a dataset: N samples, in parallel, resumable, and byte-identical
//! whatever the thread count or the split into jobs.

use crate::encode::EncodedSample;
use crate::folders;
use crate::maker::{Generator2d, SampleMaker};
use crate::wds::{shard_path, ShardWriter};
use matseg_image::outputs::{self, OutputError, SharedFolder};
use matseg_image::progress::Progress;
use matseg_scene::{Recipe2d, Sources};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// On-disk layout of a dataset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Format {
    /// One MatSeg folder per sample.
    Folders,
    /// WebDataset tar shards.
    Wds,
}

/// Which part of the work this process does: job `index` of `count` takes the
/// work units (samples for folders, shards for WebDataset) `u` with
/// `u % count == index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JobSlice {
    /// Number of jobs.
    pub count: u64,
    /// This job, `0..count`.
    pub index: u64,
}

impl JobSlice {
    /// The whole dataset in one job.
    pub const ALL: JobSlice = JobSlice { count: 1, index: 0 };

    /// The job index from `SLURM_ARRAY_TASK_ID` or `JOB_COMPLETION_INDEX`
    /// (Kubernetes indexed jobs), if either is set.
    pub fn index_from_env() -> Result<Option<u64>, JobError> {
        for var in ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"] {
            if let Ok(value) = std::env::var(var) {
                return value
                    .trim()
                    .parse()
                    .map(Some)
                    .map_err(|_| JobError::NotAnIndex { var, value });
            }
        }
        Ok(None)
    }

    /// Checks `index < count` and `count >= 1`.
    pub fn validate(&self) -> Result<(), JobError> {
        if self.count == 0 || self.index >= self.count {
            return Err(JobError::OutOfRange {
                index: self.index,
                count: self.count,
            });
        }
        Ok(())
    }
}

/// What to write.
#[derive(Clone, Debug)]
pub struct GenerateOptions {
    /// Output folder.
    pub out: PathBuf,
    /// Number of samples in the whole dataset.
    pub n: u64,
    /// Dataset seed.
    pub seed: u64,
    /// Layout.
    pub format: Format,
    /// Samples per tar shard (WebDataset only).
    pub shard_size: u64,
    /// This process's part of the work.
    pub job: JobSlice,
}

impl GenerateOptions {
    /// `n` samples of the dataset `seed` as MatSeg folders in `out`, all
    /// in this process.
    pub fn folders(out: impl Into<PathBuf>, n: u64, seed: u64) -> Self {
        Self {
            out: out.into(),
            n,
            seed,
            format: Format::Folders,
            shard_size: 1000,
            job: JobSlice { count: 1, index: 0 },
        }
    }

    /// The work unit of sample `index`: the sample itself for folders, its
    /// shard for WebDataset.
    fn unit_of(&self, index: u64) -> u64 {
        match self.format {
            Format::Folders => index,
            Format::Wds => index / self.shard_size.max(1),
        }
    }

    /// Whether this job does work unit `unit`.
    fn owns_unit(&self, unit: u64) -> bool {
        unit % self.job.count == self.job.index
    }

    /// Number of samples this job writes (or finds complete).
    pub fn samples_in_job(&self) -> u64 {
        (0..self.n)
            .filter(|&i| self.owns_unit(self.unit_of(i)))
            .count() as u64
    }
}

/// The settings a dataset was made with, stored as `dataset.json`; a resumed
/// run must match them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetManifest {
    /// Scene kind.
    pub kind: String,
    /// Layout.
    pub format: Format,
    /// Number of samples.
    pub n: u64,
    /// Seed.
    pub seed: u64,
    /// Samples per shard (WebDataset only).
    pub shard_size: Option<u64>,
    /// Fingerprint of the source files (names and sizes).
    pub sources_fingerprint: String,
    /// The recipe (2D or 3D, as its kind says).
    pub recipe: serde_json::Value,
}

/// Name of the manifest file.
pub const MANIFEST_FILE: &str = "dataset.json";

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GenerateReport {
    /// Samples generated now.
    pub generated: u64,
    /// Samples found complete and skipped.
    pub skipped: u64,
    /// Bytes of sample files written now.
    pub bytes: u64,
}

/// Failure while writing a dataset.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// A file could not be written.
    #[error("{}: {reason}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// A scene could not be generated.
    #[error("sample {index}: {error}")]
    Scene {
        /// Sample index.
        index: u64,
        /// Why.
        error: crate::maker::SampleError,
    },
    /// The output folder holds a dataset made with other settings.
    #[error("{}: holds a dataset made with other settings ({reason}); choose another --out", path.display())]
    Mismatch {
        /// The manifest.
        path: PathBuf,
        /// What differs.
        reason: String,
    },
    /// This job is not one of the jobs the work is split into.
    #[error(transparent)]
    Job(#[from] JobError),
    /// Shards of no samples.
    #[error("--shard-size must be at least 1")]
    EmptyShards,
    /// The output folder, or a name in it, is not the dataset's to write.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// A job index that does not fit the split of the work.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum JobError {
    /// A job array's variable that is not a number.
    #[error("{var}={value} is not a job index")]
    NotAnIndex {
        /// The variable (`SLURM_ARRAY_TASK_ID`, `JOB_COMPLETION_INDEX`).
        var: &'static str,
        /// Its value.
        value: String,
    },
    /// An index past the number of jobs (or no jobs at all).
    #[error("shard index {index} is not below the number of shards {count}")]
    OutOfRange {
        /// The job's index.
        index: u64,
        /// The number of jobs.
        count: u64,
    },
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> GenerateError + '_ {
    move |e| GenerateError::Io {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// An FNV-1a hash, for fingerprints of source lists (names and sizes), so
/// a resumed run notices changed sources.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fingerprint(u64);

impl Default for Fingerprint {
    fn default() -> Self {
        Fingerprint(0xcbf2_9ce4_8422_2325)
    }
}

impl Fingerprint {
    /// Hashes `bytes` in.
    pub fn add(&mut self, bytes: impl IntoIterator<Item = u8>) {
        for b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }

    /// Marks the end of one list, so moving an entry between lists counts.
    pub fn end_list(&mut self) {
        self.add([0xff]);
    }

    /// The hash as 16 hex digits.
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// The fingerprint of 2D sources: photo and texture names and sizes.
pub fn sources_fingerprint(sources: Sources<'_>) -> String {
    let mut h = Fingerprint::default();
    for lib in [sources.photos, sources.textures] {
        for e in lib.entries() {
            h.add(
                e.name
                    .bytes()
                    .chain(e.width.to_le_bytes())
                    .chain(e.height.to_le_bytes()),
            );
        }
        h.end_list();
    }
    h.hex()
}

/// True when `dir` holds anything besides the manifest (samples, shards or
/// their leftovers).
fn holds_samples(dir: &Path) -> Result<bool, GenerateError> {
    let listing = std::fs::read_dir(dir).map_err(io_err(dir))?;
    Ok(listing
        .filter_map(|e| e.ok())
        .any(|e| e.file_name() != MANIFEST_FILE))
}

/// Whether `path`, an entry of a dataset folder, is one `matseg generate`
/// writes: a sample folder holding only a sample's files, a sample's
/// staging folder, a shard or a shard being written, or the manifest.
fn is_dataset_entry(path: &Path) -> bool {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let digits = |s: &str, n: usize| s.len() == n && s.bytes().all(|b| b.is_ascii_digit());
    if name == MANIFEST_FILE {
        return path.is_file();
    }
    if digits(&name, 8) {
        return folders::holds_only_sample_files(path);
    }
    if let Some(index) = name.strip_suffix(folders::PARTIAL_SUFFIX) {
        return digits(index, 8) && outputs::is_marked(path, folders::COMMAND);
    }
    name.strip_prefix("shard-")
        .and_then(|s| s.split_once(".tar"))
        .is_some_and(|(index, rest)| {
            digits(index, 6) && (rest.is_empty() || rest.starts_with(".tmp"))
        })
}

/// Opens the dataset folder `out` (made when missing): a folder holding
/// anything but a dataset's entries and no manifest is refused.
fn open_dataset_folder(out: &Path) -> Result<SharedFolder, GenerateError> {
    let has_manifest = |dir: &Path| dir.join(MANIFEST_FILE).is_file();
    let layout = outputs::Layout {
        command: folders::COMMAND,
        sign: outputs::Sign::Own(&has_manifest),
        owns: &is_dataset_entry,
    };
    Ok(SharedFolder::open(out, &layout, &[])?)
}

/// Checks the manifest of a folder against this run's settings, or writes
/// it. A folder with a manifest but no samples (a run that failed before
/// its first sample) takes the new settings.
fn check_manifest(path: &Path, want: &DatasetManifest) -> Result<(), GenerateError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    if path.is_file() && holds_samples(dir)? {
        let text = std::fs::read_to_string(path).map_err(io_err(path))?;
        let have: DatasetManifest =
            serde_json::from_str(&text).map_err(|e| GenerateError::Mismatch {
                path: path.to_path_buf(),
                reason: format!("unreadable manifest: {e}"),
            })?;
        let differs = |what: &str| {
            Err(GenerateError::Mismatch {
                path: path.to_path_buf(),
                reason: format!("{what} differs"),
            })
        };
        if have.kind != want.kind || have.format != want.format {
            return differs("kind or format");
        }
        if have.n != want.n || have.shard_size != want.shard_size {
            return differs("sample count or shard size");
        }
        if have.seed != want.seed {
            return differs("seed");
        }
        if have.sources_fingerprint != want.sources_fingerprint {
            return differs("source files");
        }
        if have.recipe != want.recipe {
            return differs("recipe");
        }
        return Ok(());
    }
    let json = serde_json::to_vec_pretty(want).expect("manifest serialises");
    matseg_image::outputs::write_atomic(path, &json).map_err(io_err(path))
}

/// Writes the samples of `opts.job`'s slice of a 2D dataset (see
/// [`generate_with`]).
pub fn generate_dataset(
    opts: &GenerateOptions,
    recipe: &Recipe2d,
    sources: Sources<'_>,
    progress: &dyn Progress,
) -> Result<GenerateReport, GenerateError> {
    generate_with(opts, &Generator2d { recipe, sources }, progress)
}

/// Writes the samples of `opts.job`'s slice of the dataset `maker` makes,
/// skipping complete ones, on the current rayon pool. `progress` is started
/// with the job's sample count and advanced as samples are done (skipped
/// ones included).
pub fn generate_with(
    opts: &GenerateOptions,
    maker: &dyn SampleMaker,
    progress: &dyn Progress,
) -> Result<GenerateReport, GenerateError> {
    opts.job.validate()?;
    if opts.format == Format::Wds && opts.shard_size == 0 {
        return Err(GenerateError::EmptyShards);
    }
    let folder = open_dataset_folder(&opts.out)?;
    let opts = &GenerateOptions {
        out: folder.dir().to_path_buf(),
        ..opts.clone()
    };
    let manifest = DatasetManifest {
        kind: maker.kind().into(),
        format: opts.format,
        n: opts.n,
        seed: opts.seed,
        shard_size: (opts.format == Format::Wds).then_some(opts.shard_size),
        sources_fingerprint: maker.sources_fingerprint(),
        recipe: maker.recipe(),
    };
    check_manifest(&opts.out.join(MANIFEST_FILE), &manifest)?;
    let mine = |unit: u64| opts.owns_unit(unit);
    let make = |index: u64| {
        maker
            .make(opts.seed, index)
            .map_err(|error| GenerateError::Scene { index, error })
    };
    progress.start(opts.samples_in_job(), "samples");
    let report = match opts.format {
        Format::Folders => generate_folders(opts, &folder, &make, progress, &mine),
        Format::Wds => generate_shards(opts, &make, progress, &mine),
    };
    progress.finish();
    report
}

/// Makes sample `index`.
type Make<'a> = dyn Fn(u64) -> Result<EncodedSample, GenerateError> + Sync + 'a;

fn generate_folders(
    opts: &GenerateOptions,
    folder: &SharedFolder,
    make: &Make<'_>,
    progress: &dyn Progress,
    mine: &(dyn Fn(u64) -> bool + Sync),
) -> Result<GenerateReport, GenerateError> {
    let (done, pending): (Vec<u64>, Vec<u64>) = (0..opts.n)
        .filter(|&i| mine(i))
        .partition(|&i| folders::is_complete(&opts.out, i));
    // Every folder this job writes, checked before its first byte.
    let names: Vec<PathBuf> = pending
        .iter()
        .flat_map(|&i| {
            let dir = folders::sample_dir(Path::new(""), i);
            [folders::partial_dir(&dir), dir]
        })
        .collect();
    folder.claim(names.iter().map(PathBuf::as_path), &is_dataset_entry)?;
    folders::remove_stale_partials(&opts.out, mine).map_err(io_err(&opts.out))?;
    progress.advance_by(done.len() as u64);
    let bytes = pending
        .par_iter()
        .map(|&index| {
            let sample = make(index)?;
            folders::write_sample(&opts.out, &sample)
                .map_err(io_err(&folders::sample_dir(&opts.out, index)))?;
            progress.advance();
            Ok::<u64, GenerateError>(sample.bytes() as u64)
        })
        .try_reduce(|| 0, |a, b| Ok(a + b))?;
    Ok(GenerateReport {
        generated: pending.len() as u64,
        skipped: done.len() as u64,
        bytes,
    })
}

fn generate_shards(
    opts: &GenerateOptions,
    make: &Make<'_>,
    progress: &dyn Progress,
    mine: &(dyn Fn(u64) -> bool + Sync),
) -> Result<GenerateReport, GenerateError> {
    let shards = opts.n.div_ceil(opts.shard_size);
    let chunk = (rayon::current_num_threads() * 4) as u64;
    let mut report = GenerateReport::default();
    for shard in (0..shards).filter(|&s| mine(s)) {
        let start = shard * opts.shard_size;
        let end = (start + opts.shard_size).min(opts.n);
        let path = shard_path(&opts.out, shard);
        if path.is_file() {
            report.skipped += end - start;
            progress.advance_by(end - start);
            continue;
        }
        let mut writer = ShardWriter::create(path.clone()).map_err(io_err(&path))?;
        let mut first = start;
        while first < end {
            let last = (first + chunk).min(end);
            let samples: Vec<EncodedSample> = (first..last)
                .into_par_iter()
                .map(make)
                .collect::<Result<_, _>>()?;
            for sample in &samples {
                writer.append(sample).map_err(io_err(&path))?;
                report.bytes += sample.bytes() as u64;
            }
            progress.advance_by(last - first);
            first = last;
        }
        writer.finish().map_err(io_err(&path))?;
        report.generated += end - start;
    }
    Ok(report)
}
