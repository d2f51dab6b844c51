//! The names of a resume checkpoint's tensors (`checkpoint.safetensors`),
//! the one source both trainers read: `matseg train` here and
//! `python -m matseg.train` (through `matseg._core.net_constants()`), so
//! that each resumes the other's runs.

/// Prefix of each net variable (`model.NAME`).
pub const MODEL: &str = "model.";
/// Prefix of the optimizer's state (`optim.m.NAME`, `optim.steps`...).
pub const OPTIMIZER: &str = "optim.";
/// Prefix, within the optimizer's state, of AdamW's first moment of a
/// parameter (`m.NAME`).
pub const FIRST_MOMENT: &str = "m.";
/// Prefix, within the optimizer's state, of AdamW's second moment of a
/// parameter (`v.NAME`).
pub const SECOND_MOMENT: &str = "v.";
/// The optimizer's updates taken (an int64 scalar, within its state).
pub const OPTIMIZER_STEPS: &str = "steps";
/// The next step to train (an int64 scalar).
pub const NEXT_STEP: &str = "next_step";
/// The next batch of the stream (an int64 scalar): the next step times the
/// processes that trained; absent where one process trained.
pub const NEXT_BATCH: &str = "next_batch";
