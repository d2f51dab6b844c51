//! Training batches prepared ahead in background threads. Batch `s` depends
//! only on (seed, s) ([`batch_samples`]), so the threads take turns (worker
//! `k` prepares batches `first + k`, `first + k + workers`, ...) and the
//! trainer reads them back in step order: the batches are the same whatever
//! the number of threads.

use crate::batch::TrainingSample;
use crate::data::{batch_samples, BatchPlan, DataError, SampleSource};
use std::sync::mpsc::{sync_channel, Receiver};
use std::thread::Scope;

/// Batches each worker may hold ready beyond the one it is preparing.
const READY_PER_WORKER: usize = 1;

/// One prepared batch, or why it could not be prepared.
pub type PreparedBatch = Result<Vec<TrainingSample>, DataError>;

/// The receiving end of the workers [`BatchLoader::spawn`] started.
pub struct BatchLoader {
    first: u64,
    workers: Vec<Receiver<PreparedBatch>>,
}

impl BatchLoader {
    /// Starts `workers` threads (at least one) in `scope` preparing batches
    /// `first..end` of `source` under `plan` and `seed`. A worker stops
    /// after a failed batch, and when the loader is dropped.
    pub fn spawn<'scope>(
        scope: &'scope Scope<'scope, '_>,
        source: &'scope dyn SampleSource,
        plan: BatchPlan,
        seed: u64,
        (first, end): (u64, u64),
        workers: usize,
    ) -> Self {
        let count = workers.max(1);
        let receivers = (0..count as u64)
            .map(|k| {
                let (tx, rx) = sync_channel(READY_PER_WORKER);
                scope.spawn(move || {
                    for step in (first + k..end).step_by(count) {
                        let batch = batch_samples(source, &plan, seed, step);
                        let failed = batch.is_err();
                        if tx.send(batch).is_err() || failed {
                            return;
                        }
                    }
                });
                rx
            })
            .collect();
        Self {
            first,
            workers: receivers,
        }
    }

    /// Batch `step`, waiting for it. Steps must be asked for in order, from
    /// the first, and only below the end given to [`BatchLoader::spawn`].
    pub fn batch(&self, step: u64) -> PreparedBatch {
        let worker = ((step - self.first) % self.workers.len() as u64) as usize;
        self.workers[worker]
            .recv()
            .unwrap_or(Err(DataError::WorkerStopped(step)))
    }
}

/// Loader threads to use by default on a device: on the CPU one (the net's
/// own threads use the cores), on a GPU all cores but two (one for the
/// trainer's thread, one for the CUDA driver's).
pub fn default_workers(on_gpu: bool) -> usize {
    if on_gpu {
        std::thread::available_parallelism()
            .map_or(1, |n| n.get().saturating_sub(2))
            .max(1)
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tiny constant samples; index `fail_at` cannot be made.
    struct Counting {
        fail_at: Option<u64>,
    }

    impl SampleSource for Counting {
        fn sample(&self, index: u64) -> Result<TrainingSample, DataError> {
            if Some(index) == self.fail_at {
                return Err(DataError::Read(matseg_data::ReadError::Io {
                    path: format!("sample {index}").into(),
                    reason: "broken".into(),
                }));
            }
            let (w, h) = (8, 6);
            Ok(TrainingSample {
                rgb: (0..w * h * 3).map(|i| (i as u64 + index) as u8).collect(),
                width: w,
                height: h,
                weights: vec![vec![index as f32; w * h], vec![1.0; w * h]],
                roi: vec![1.0; w * h],
            })
        }

        fn count(&self) -> Option<u64> {
            None
        }
    }

    const PLAN: BatchPlan = BatchPlan {
        min_side: 32,
        max_side: 64,
        pixels: 4096,
        ..BatchPlan::SPEC
    };

    /// What identifies a sample: its size, pixels and weights, in bytes.
    fn key(batch: &[TrainingSample]) -> Vec<Vec<u8>> {
        batch
            .iter()
            .map(|s| {
                let mut bytes = format!("{}x{}", s.width, s.height).into_bytes();
                bytes.extend(&s.rgb);
                bytes.extend(s.weights.iter().flatten().flat_map(|v| v.to_le_bytes()));
                bytes
            })
            .collect()
    }

    #[test]
    fn batches_are_the_same_whatever_the_worker_count() {
        let source = Counting { fail_at: None };
        let direct: Vec<_> = (3..12)
            .map(|s| key(&batch_samples(&source, &PLAN, 5, s).unwrap()))
            .collect();
        for workers in [1, 2, 4] {
            let loaded: Vec<_> = std::thread::scope(|scope| {
                let loader = BatchLoader::spawn(scope, &source, PLAN, 5, (3, 12), workers);
                (3..12).map(|s| key(&loader.batch(s).unwrap())).collect()
            });
            assert_eq!(loaded, direct, "{workers} workers");
        }
    }

    #[test]
    fn a_failed_batch_is_reported_at_its_step_and_the_workers_end() {
        // Online indices: batch s holds samples s * max_images + j, so
        // sample 0 is in batch 0. The scope ends only if the other
        // workers, blocked on full channels, stop when the loader drops.
        let source = Counting { fail_at: Some(0) };
        let first = std::thread::scope(|scope| {
            let loader = BatchLoader::spawn(scope, &source, PLAN, 5, (0, 50), 3);
            loader.batch(0)
        });
        assert_eq!(first.unwrap_err().to_string(), "sample 0: broken");
    }
}
