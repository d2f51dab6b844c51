//! Training batches prepared ahead in background threads. Batch `s`
//! depends only on (seed, s) ([`crate::data::batch_samples`], [`crate::train::TrainingData`]),
//! so the threads take turns (worker `k` prepares batches `first + k`,
//! `first + k + workers`, ...) and the trainer reads them back in step order:
//! the batches are the same whatever the number of threads.

use crate::data::DataError;
use crate::NetError;
use std::sync::mpsc::{sync_channel, Receiver};
use std::thread::Scope;

/// Batches each worker may hold ready beyond the one it is preparing.
const READY_PER_WORKER: usize = 1;

/// The receiving end of the workers [`BatchLoader::spawn`] started.
pub struct BatchLoader<B> {
    first: u64,
    workers: Vec<Receiver<Result<B, NetError>>>,
}

impl<B: Send> BatchLoader<B> {
    /// Starts `workers` threads (at least one) in `scope` preparing batches
    /// `first..end` with `make`. A worker stops after a failed batch, and
    /// when the loader is dropped.
    pub fn spawn<'scope, F>(
        scope: &'scope Scope<'scope, '_>,
        make: &'scope F,
        (first, end): (u64, u64),
        workers: usize,
    ) -> Self
    where
        F: Fn(u64) -> Result<B, NetError> + Sync,
        B: 'scope,
    {
        let count = workers.max(1);
        let receivers = (0..count as u64)
            .map(|k| {
                let (tx, rx) = sync_channel(READY_PER_WORKER);
                scope.spawn(move || {
                    for step in (first + k..end).step_by(count) {
                        let batch = make(step);
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
    pub fn batch(&self, step: u64) -> Result<B, NetError> {
        let worker = ((step - self.first) % self.workers.len() as u64) as usize;
        self.workers[worker]
            .recv()
            .unwrap_or(Err(NetError::Data(DataError::WorkerStopped(step))))
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
    use crate::batch::TrainingSample;
    use crate::data::{batch_samples, BatchPlan, SampleSource};

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
            let make = |s| Ok(batch_samples(&source, &PLAN, 5, s)?);
            let loaded: Vec<_> = std::thread::scope(|scope| {
                let loader = BatchLoader::spawn(scope, &make, (3, 12), workers);
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
        let make = |s| Ok(batch_samples(&source, &PLAN, 5, s)?);
        let first = std::thread::scope(|scope| {
            let loader = BatchLoader::spawn(scope, &make, (0, 50), 3);
            loader.batch(0)
        });
        assert_eq!(
            first.expect_err("a failed batch").to_string(),
            "training data: sample 0: broken"
        );
    }
}
