//! Process measures for benchmarks: CPU time (benchmarks report CPU seconds
//! rather than wall-clock seconds, which a shared or virtual machine
//! inflates), peak memory, and the median of repeated timings.

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

/// This process's peak resident memory (Linux `VmHWM`), in MiB.
pub fn peak_rss_mib() -> Option<f64> {
    process_memory_mib(std::process::id()).map(|(_, peak)| peak)
}

/// Process `pid`'s resident memory now and at its peak (Linux `VmRSS` and
/// `VmHWM`), in MiB; `None` where the platform does not tell.
pub fn process_memory_mib(pid: u32) -> Option<(f64, f64)> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let field = |name: &str| -> Option<f64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib / 1024.0)
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

/// Wall-clock and process CPU time, read together.
#[derive(Clone, Copy, Debug)]
pub struct Clock {
    wall: std::time::Instant,
    cpu: Option<f64>,
}

impl Clock {
    /// The clock now.
    pub fn now() -> Self {
        Self {
            wall: std::time::Instant::now(),
            cpu: process_cpu_seconds(),
        }
    }

    /// Wall seconds and CPU seconds since `self`; CPU seconds are wall
    /// seconds times `threads` where the platform gives no CPU time.
    pub fn elapsed(self, threads: usize) -> (f64, f64) {
        let wall = self.wall.elapsed().as_secs_f64();
        let cpu = match (self.cpu, process_cpu_seconds()) {
            (Some(a), Some(b)) => b - a,
            _ => wall * threads as f64,
        };
        (wall, cpu)
    }
}

/// The median (mean of the middle two for an even count); NaN when empty.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_of_odd_and_even_counts() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(Vec::new()).is_nan());
    }

    #[test]
    fn cpu_time_counts_work_done() {
        let clock = Clock::now();
        let mut x = 0u64;
        for i in 0..5_000_000u64 {
            x = x.wrapping_mul(31).wrapping_add(i);
        }
        std::hint::black_box(x);
        let (wall, cpu) = clock.elapsed(1);
        assert!(wall > 0.0 && cpu > 0.0, "{wall} {cpu}");
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn memory_counts_an_allocation_touched() {
        let block = vec![1u8; 64 << 20];
        std::hint::black_box(&block);
        let (resident, peak) = process_memory_mib(std::process::id()).unwrap();
        assert!(resident >= 64.0 && resident <= peak, "{resident} {peak}");
        assert_eq!(peak_rss_mib().map(|p| p >= peak), Some(true));
    }
}
