//! How a long job tells its front end how far it is: a progress bar in the
//! CLI, a message stream in the web app, a callback in Python.

/// Receives a job's progress. Methods may be called from worker threads.
pub trait Progress: Sync {
    /// The job has `total` steps of `what` (e.g. "materials") to do.
    fn start(&self, total: u64, what: &str);
    /// One more step is done.
    fn advance(&self);
    /// The job is over.
    fn finish(&self);
    /// Something was skipped; the job goes on. `message` names the file
    /// and the problem.
    fn warn(&self, message: &str);
}
