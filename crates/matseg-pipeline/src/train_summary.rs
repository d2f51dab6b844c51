//! What a call of training did, as plain figures: in every build, so that
//! reports that carry it (the demo's) have the same shape with or without
//! the net.

/// What one call of `TrainingRun::train` did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrainSummary {
    /// Steps trained in this call.
    pub steps: u64,
    /// Images in those steps.
    pub images: usize,
    /// Pixels in those steps.
    pub pixels: usize,
    /// Wall seconds, checkpoints and validation included.
    pub seconds: f64,
    /// Seconds the trainer waited for batches.
    pub waited: f64,
    /// Loader threads used.
    pub loader_threads: usize,
}
