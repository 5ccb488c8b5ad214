//! Process CPU time, for benchmarks whose wall times carry the machine's load.

/// Process CPU time (user + system, all threads) in seconds from `/proc/self/stat`
/// (Linux; clock ticks assumed 100 per second, the Linux USER_HZ). `None` elsewhere.
pub fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ut: f64 = f.get(11)?.parse().ok()?;
    let st: f64 = f.get(12)?.parse().ok()?;
    Some((ut + st) / 100.0)
}
