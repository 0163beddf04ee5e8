//! This process's memory and CPU time, where the system reports them (Linux `/proc`): the
//! memory budgets of the capture job and of out-of-core PCA, and the reports that state them.
//!
//! ```
//! if cfg!(target_os = "linux") {
//!     let now = brdf::process::resident_bytes().unwrap();
//!     assert!(brdf::process::peak_resident_bytes().unwrap() >= now);
//! }
//! ```

/// A `kB` field of `/proc/self/status` (`VmRSS`, `VmHWM`, ...), in bytes.
fn status_bytes(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let value = status
        .lines()
        .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))?;
    let kb: u64 = value.trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kb * 1024)
}

/// Resident memory now (`VmRSS`), in bytes; `None` where the system does not report it.
pub fn resident_bytes() -> Option<u64> {
    status_bytes("VmRSS")
}

/// Peak resident memory so far (`VmHWM`), in bytes; `None` where the system does not report
/// it.
pub fn peak_resident_bytes() -> Option<u64> {
    status_bytes("VmHWM")
}

/// User plus system CPU time so far, in seconds (at the usual 100 clock ticks per second);
/// `None` where the system does not report it.
pub fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}
