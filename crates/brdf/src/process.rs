//! This process's memory and CPU time, read from Linux `/proc`.

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
///
/// This and [`peak_resident_bytes`] and [`cpu_seconds`] read Linux `/proc`; they hold the
/// capture job and out-of-core PCA to their memory budgets and feed the reports that state them.
///
/// # Examples
///
/// ```
/// if cfg!(target_os = "linux") {
///     let now = brdf::resident_bytes().unwrap();
///     assert!(brdf::peak_resident_bytes().unwrap() >= now);
/// }
/// ```
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
