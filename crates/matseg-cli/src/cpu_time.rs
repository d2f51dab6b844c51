//! Process CPU time, for benchmarks that report CPU seconds rather than
//! wall-clock seconds (on a shared or virtual machine the two differ).

/// CPU seconds (user and system, all threads) this process has used so far,
/// where the platform tells (Linux with glibc); `None` elsewhere.
pub fn process_cpu_seconds() -> Option<f64> {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes one timespec into `t`.
        let ok = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) } == 0;
        if ok {
            return Some(t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9);
        }
    }
    None
}
