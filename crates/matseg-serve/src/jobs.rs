//! The server's background work (tracking a video, evaluating a
//! benchmark): each job a thread of its own with a progress the pages
//! poll and a flag that stops it between steps. When the server stops,
//! every job is told to stop and waited for.

use matseg_image::progress::Progress;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A job's progress, updated by its thread, and whether it was asked to
/// stop.
#[derive(Default)]
pub struct JobProgress {
    done: AtomicU64,
    total: AtomicU64,
    /// What the job is doing now (e.g. the model being scored).
    doing: Mutex<String>,
    cancel: AtomicBool,
}

impl JobProgress {
    /// Steps done and the total (0 until the job has counted its steps).
    pub fn counts(&self) -> (u64, u64) {
        (
            self.done.load(Ordering::Relaxed),
            self.total.load(Ordering::Relaxed),
        )
    }

    /// What the job says it is doing now (empty until it says).
    pub fn doing(&self) -> String {
        matseg_image::sync::lock(&self.doing).clone()
    }

    /// Asks the job to stop at its next step.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}

impl Progress for JobProgress {
    fn start(&self, total: u64, _what: &str) {
        self.total.store(total, Ordering::Relaxed);
    }
    fn advance(&self) {
        self.advance_by(1);
    }
    fn advance_by(&self, steps: u64) {
        self.done.fetch_add(steps, Ordering::Relaxed);
    }
    fn status(&self, message: &str) {
        *matseg_image::sync::lock(&self.doing) = message.to_string();
    }
    fn finish(&self) {}
    fn warn(&self, _message: &str) {}
    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

/// The job threads started, with their progress.
#[derive(Default)]
pub struct Workers {
    threads: Mutex<Vec<(Arc<JobProgress>, JoinHandle<()>)>>,
}

impl Workers {
    /// Runs `work` on a thread of its own named `name`; `progress` is the
    /// one it reports to, cancelled when the server stops.
    pub fn spawn(
        &self,
        name: &str,
        progress: Arc<JobProgress>,
        work: impl FnOnce() + Send + 'static,
    ) -> std::io::Result<()> {
        let handle = std::thread::Builder::new()
            .name(name.to_string())
            .spawn(work)?;
        let mut threads = matseg_image::sync::lock(&self.threads);
        threads.retain(|(_, thread)| !thread.is_finished());
        threads.push((progress, handle));
        Ok(())
    }

    /// Tells every job to stop (not waiting for them).
    pub fn cancel_all(&self) {
        for (progress, _) in matseg_image::sync::lock(&self.threads).iter() {
            progress.cancel();
        }
    }

    /// Tells every job to stop and waits up to `wait` for them to end;
    /// whether they all did.
    pub fn stop_all(&self, wait: Duration) -> bool {
        self.cancel_all();
        let threads = std::mem::take(&mut *matseg_image::sync::lock(&self.threads));
        let deadline = Instant::now() + wait;
        while threads.iter().any(|(_, t)| !t.is_finished()) {
            if Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        for (_, thread) in threads {
            let _ = thread.join();
        }
        true
    }
}

/// Runs `work` in the background share of the machine: this thread (a
/// job's own) at the lowest CPU priority, and `work`'s parallel loops in a
/// pool of one thread of its own (libtorch's threads, started from it,
/// inherit the priority). Clicks on the pages, at normal priority and in
/// the shared pool, keep their latency while it runs.
pub fn run_in_background<T: Send>(
    work: impl FnOnce() -> T + Send,
) -> Result<T, rayon::ThreadPoolBuildError> {
    lower_priority();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(|_| "matseg-background".into())
        .build()?;
    Ok(pool.install(work))
}

/// Puts the calling thread, and the threads it starts from now on, at the
/// lowest CPU priority (Linux: nice 19 for this thread; elsewhere nothing).
fn lower_priority() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: setpriority on this thread's own id changes only its niceness.
    unsafe {
        let thread = libc::gettid();
        libc::setpriority(libc::PRIO_PROCESS, thread as libc::id_t, 19);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stopping_cancels_every_job_and_waits_for_it() {
        let workers = Workers::default();
        let ended = Arc::new(AtomicU64::new(0));
        for i in 0..3 {
            let progress = Arc::new(JobProgress::default());
            let (mine, ended) = (progress.clone(), ended.clone());
            workers
                .spawn(&format!("job {i}"), progress, move || {
                    mine.start(1000, "steps");
                    while !mine.cancelled() {
                        mine.advance();
                        std::thread::sleep(Duration::from_millis(1));
                    }
                    ended.fetch_add(1, Ordering::Relaxed);
                })
                .unwrap();
        }
        assert!(workers.stop_all(Duration::from_secs(10)));
        assert_eq!(ended.load(Ordering::Relaxed), 3);
        // A job that does not look: not waited for past the bound.
        let stuck = Arc::new(JobProgress::default());
        workers
            .spawn("stuck", stuck, || {
                std::thread::sleep(Duration::from_millis(500))
            })
            .unwrap();
        assert!(!workers.stop_all(Duration::from_millis(50)));
    }

    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn background_work_runs_at_the_lowest_priority_in_one_thread() {
        let nice = || {
            let stat = std::fs::read_to_string("/proc/thread-self/stat").unwrap();
            // Field 19 is the niceness, counted after the command's ")".
            let after = &stat[stat.rfind(')').unwrap() + 2..];
            after.split(' ').nth(16).unwrap().parse::<i32>().unwrap()
        };
        let (outer, inner, threads) = std::thread::spawn(move || {
            run_in_background(|| (nice(), rayon::current_num_threads()))
                .map(|(inner, threads)| (nice(), inner, threads))
                .unwrap()
        })
        .join()
        .unwrap();
        assert_eq!((outer, inner, threads), (19, 19, 1));
        assert_eq!(nice(), 0, "the caller's own thread is left as it was");
    }

    #[test]
    fn progress_counts_steps_of_the_total() {
        let progress = JobProgress::default();
        progress.start(10, "images");
        progress.advance();
        progress.advance_by(2);
        assert_eq!(progress.counts(), (3, 10));
        progress.status("default (2 of 2)");
        assert_eq!(progress.doing(), "default (2 of 2)");
        assert!(!progress.cancelled());
        progress.cancel();
        assert!(progress.cancelled());
    }
}
