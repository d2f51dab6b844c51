//! How a long job tells its front end how far it is: a progress bar in the
//! CLI, a job state in the web app, a callback in Python. Every library
//! job that reports progress takes a `&dyn Progress`.

/// Receives a job's progress. Methods may be called from worker threads.
pub trait Progress: Sync {
    /// The job has `total` steps of `what` (e.g. "materials") to do.
    fn start(&self, total: u64, what: &str);
    /// One more step is done.
    fn advance(&self);
    /// `steps` more steps are done (e.g. samples found complete from an
    /// earlier run).
    fn advance_by(&self, steps: u64) {
        for _ in 0..steps {
            self.advance();
        }
    }
    /// What the job is doing now (e.g. the package being unpacked), for
    /// displays that show a message beside the count; ignored by default.
    fn status(&self, _message: &str) {}
    /// The job is over.
    fn finish(&self);
    /// Something was skipped; the job goes on. `message` names the file
    /// and the problem.
    fn warn(&self, message: &str);
    /// Whether the front end wants the job stopped (the web app's Cancel,
    /// or the server shutting down). Jobs that can stop early ask between
    /// steps and end with an error that says they were cancelled; never,
    /// by default.
    fn cancelled(&self) -> bool {
        false
    }
}

/// Progress nobody watches: every report is dropped, warnings included.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {
    fn start(&self, _total: u64, _what: &str) {}
    fn advance(&self) {}
    fn finish(&self) {}
    fn warn(&self, _message: &str) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicU64, Ordering};

    #[derive(Default)]
    struct Count(AtomicU64);

    impl Progress for Count {
        fn start(&self, _total: u64, _what: &str) {}
        fn advance(&self) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn finish(&self) {}
        fn warn(&self, _message: &str) {}
    }

    #[test]
    fn advance_by_counts_each_step_once() {
        let count = Count::default();
        count.advance_by(5);
        count.advance();
        count.advance_by(0);
        assert_eq!(count.0.load(Ordering::Relaxed), 6);
    }
}
