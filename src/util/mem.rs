//! Process memory, for reports and benchmarks, and a cache hint for memory-bound passes.

/// The process's peak resident set size in bytes (Linux `VmHWM`), or None where it is unknown.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Peak RSS in MiB (0 where unknown), rounded.
pub fn peak_rss_mib() -> u64 {
    peak_rss_bytes().map(|b| (b + (1 << 19)) >> 20).unwrap_or(0)
}

/// Reset the peak RSS to the current RSS (Linux: "5" into /proc/self/clear_refs), so the next
/// [`peak_rss_bytes`] is the peak of what follows. False where that is not possible.
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// Ask for the cache line holding `buf[i]` (a hint: no effect on results; nothing off x86-64).
#[inline(always)]
pub fn prefetch<T>(buf: &[T], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(x) = buf.get(i) {
        // SAFETY: a prefetch hint reads nothing and cannot fault; the pointer is in bounds.
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                (x as *const T).cast(),
            )
        };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (buf, i);
}
