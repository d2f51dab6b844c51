//! Allocator tuning for the generator's allocation pattern.
//!
//! A scene allocates about a hundred planes of 0.2-4 MB and frees them when
//! it is done. glibc serves blocks above its mmap threshold (128 KiB at
//! first) with fresh `mmap`s and unmaps them on free, so every plane paid for
//! page faults and kernel zeroing again (about a tenth of the run time).
//! Raising the threshold keeps freed blocks in the heap for the next scene;
//! peak memory is unchanged.

/// Keeps blocks up to 256 MiB on the heap after they are freed (glibc only;
/// elsewhere the system allocator is left as it is).
pub fn keep_freed_blocks() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator parameters; it is called before
    // any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 256 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 512 << 20);
    }
}
