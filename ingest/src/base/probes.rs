//! What the benchmarks read of a stage's own run: CPU time and peak memory.

/// CPU time of this process so far, user plus system, all threads, in seconds, from
/// /proc/self/stat (Linux only; in clock ticks of 1/100 s, USER_HZ on Linux), for
/// benchmarks: on a machine of few cores CPU time, not wall time, says what a change saved.
pub fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) in parentheses; utime and
    // stime are fields 14 and 15 of the line, the 12th and 13th after the name.
    let mut f = stat.rsplit_once(')')?.1.split_whitespace().skip(11);
    let utime: u64 = f.next()?.parse().ok()?;
    let stime: u64 = f.next()?.parse().ok()?;
    Some((utime + stime) as f64 / 100.0)
}

/// Prints `peak_rss_kb N` and `cpu_s S` to stderr, for `cargo xtask bench`.
pub fn print_usage() {
    match peak_rss_kb() {
        Some(kb) => eprintln!("peak_rss_kb {kb}"),
        None => eprintln!("peak_rss_kb unavailable"),
    }
    if let Some(s) = cpu_seconds() {
        eprintln!("cpu_s {s}");
    }
}

/// Peak resident set size of this process in kB, from /proc (Linux only), for benchmarks.
pub fn peak_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
