//! The job directory: where each file of a measurement lives.

use crate::error::{io, AcquireError, Result};
use hdr::DefectMap;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The files of one job directory.
///
/// The job directory: where each file of a measurement lives, and how it is read and written
/// (every write is atomic: a temporary file renamed over the target).
///
/// ```text
/// DIR/job.json               parameters of the job (checked on resume)
/// DIR/calibration.json       geometry used for binning
/// DIR/lamp_constant.json     absolute scale (white reference)
/// DIR/defects.json           hot photosites from the 60 s dark frame
/// DIR/ambient.json           ambient signal rate with the lamp off, DN/s per channel
/// DIR/positions/NNN.samples  BRDF samples of position NNN (checkpoint)
/// DIR/positions/NNN.json     log of position NNN: angle, exposures, faults, timings
/// DIR/positions/NNN.crc      checksums of position NNN's files, written last (its seal)
/// DIR/frames/NNN.frames      raw frames of position NNN (when kept)
/// DIR/hdr/NNN.exr            HDR radiance (DN/s) of position NNN
/// DIR/truth/NNN.exr          noise-free signal rate (simulator only, when asked for)
/// DIR/brdf.binary            the measured table (MERL format)
/// DIR/counts.bin             samples per bin and channel (u32, MERL order)
/// DIR/report.json            timings, sample counts, coverage, validation, faults
/// DIR/previews/contact_sheet.png   measured vs re-rendered (log scale)
/// DIR/job.lock               pid of the process running the job (while it runs)
/// ```
///
/// A position counts as done only when its seal verifies: every file it lists has the length
/// and CRC-32 recorded there. A position killed half-way (no seal yet), or whose files were
/// truncated or damaged later, is captured again on resume; a damaged file is never used.
/// Position directories written before seals existed are captured again too.
///
/// # Examples
///
/// ```
/// use acquire::JobDir;
/// use std::path::Path;
///
/// let dir = JobDir::new("capture");
/// assert_eq!(dir.job(), Path::new("capture/job.json"));
/// assert_eq!(dir.samples(7), Path::new("capture/positions/007.samples"));
/// assert_eq!(dir.calibration(), Path::new("capture/calibration.json"));
/// ```
#[derive(Debug, Clone)]
pub struct JobDir {
    root: PathBuf,
}

impl JobDir {
    /// The job directory at `root` (nothing is created).
    pub fn new(root: impl Into<PathBuf>) -> Self {
        Self { root: root.into() }
    }
    /// The directory itself.
    pub fn root(&self) -> &Path {
        &self.root
    }
    /// `job.json`.
    pub fn job(&self) -> PathBuf {
        self.root.join("job.json")
    }
    /// `calibration.json`.
    pub fn calibration(&self) -> PathBuf {
        self.root.join("calibration.json")
    }
    /// `ambient.json`.
    pub fn ambient(&self) -> PathBuf {
        self.root.join("ambient.json")
    }
    /// `lamp_constant.json`.
    pub fn lamp_constant(&self) -> PathBuf {
        self.root.join("lamp_constant.json")
    }
    /// `defects.json`.
    pub fn defects(&self) -> PathBuf {
        self.root.join("defects.json")
    }
    /// `positions/NNN.samples`, the checkpoint of position `i`.
    pub fn samples(&self, i: usize) -> PathBuf {
        self.root.join("positions").join(format!("{i:03}.samples"))
    }
    /// `positions/NNN.json`, the log of position `i`.
    pub fn log(&self, i: usize) -> PathBuf {
        self.root.join("positions").join(format!("{i:03}.json"))
    }
    /// `frames/NNN.frames`, the raw frames of position `i`.
    pub fn frames(&self, i: usize) -> PathBuf {
        self.root.join("frames").join(format!("{i:03}.frames"))
    }
    /// `hdr/NNN.exr`, the HDR image of position `i`.
    pub fn hdr(&self, i: usize) -> PathBuf {
        hdr::hdr_path(&self.root, i)
    }
    /// `brdf.binary`, the measured table.
    pub fn table(&self) -> PathBuf {
        self.root.join("brdf.binary")
    }
    /// `counts.bin`.
    pub fn counts(&self) -> PathBuf {
        self.root.join("counts.bin")
    }
    /// `binning.json`, the binning's checkpoint (written after `brdf.binary` and `counts.bin`).
    pub fn binning(&self) -> PathBuf {
        self.root.join("binning.json")
    }
    /// `inverse_report.json`, the inverse mapping's report.
    pub fn inverse_report(&self) -> PathBuf {
        self.root.join("inverse_report.json")
    }
    /// `report.json`.
    pub fn report(&self) -> PathBuf {
        self.root.join("report.json")
    }
    /// `previews/contact_sheet.png`.
    pub fn contact_sheet(&self) -> PathBuf {
        self.root.join("previews").join("contact_sheet.png")
    }
    /// `positions/NNN.crc`, the seal of position `i` (checksums of its files).
    pub fn seal(&self, i: usize) -> PathBuf {
        self.root.join("positions").join(format!("{i:03}.crc"))
    }
    /// `job.lock`.
    pub fn lock(&self) -> PathBuf {
        self.root.join("job.lock")
    }
    /// The files a finished position `i` consists of (the frames when kept).
    fn position_files(&self, i: usize) -> Vec<PathBuf> {
        let mut files = vec![self.samples(i), self.hdr(i), self.log(i)];
        if self.frames(i).exists() {
            files.push(self.frames(i));
        }
        files
    }
    /// Seals position `i`: writes `positions/NNN.crc` with the length and CRC-32 of each of
    /// its files. Called after every file of the position is on disk; from then on the
    /// position is done.
    pub fn seal_position(&self, i: usize) -> Result<()> {
        let mut text = String::new();
        for f in self.position_files(i) {
            let bytes = std::fs::read(&f).map_err(io(&f))?;
            let rel = f.strip_prefix(&self.root).unwrap_or(&f);
            text.push_str(&format!(
                "{:08x} {} {}\n",
                crc32fast::hash(&bytes),
                bytes.len(),
                rel.display()
            ));
        }
        write_atomic(&self.seal(i), text.as_bytes())
    }
    /// Checks position `i` against its seal.
    pub fn check_position(&self, i: usize) -> PositionCheck {
        let seal = self.seal(i);
        let Ok(text) = std::fs::read_to_string(&seal) else {
            return if self.samples(i).exists() || self.log(i).exists() {
                PositionCheck::Damaged(format!("{} is missing or unreadable", seal.display()))
            } else {
                PositionCheck::Missing
            };
        };
        let mut listed = 0;
        for line in text.lines() {
            let mut parts = line.splitn(3, ' ');
            let (Some(crc), Some(len), Some(rel)) = (parts.next(), parts.next(), parts.next())
            else {
                return PositionCheck::Damaged(format!("{}: malformed line", seal.display()));
            };
            let (Ok(crc), Ok(len)) = (u32::from_str_radix(crc, 16), len.parse::<usize>()) else {
                return PositionCheck::Damaged(format!("{}: malformed line", seal.display()));
            };
            let path = self.root.join(rel);
            // Only the position's own files may be listed (a damaged seal must not point
            // elsewhere).
            if !self.position_files(i).contains(&path) && path != self.frames(i) {
                return PositionCheck::Damaged(format!("{}: lists {rel}", seal.display()));
            }
            match std::fs::read(&path) {
                Ok(bytes) if bytes.len() != len => {
                    return PositionCheck::Damaged(format!(
                        "{}: {} bytes, sealed with {len}",
                        path.display(),
                        bytes.len()
                    ))
                }
                Ok(bytes) if crc32fast::hash(&bytes) != crc => {
                    return PositionCheck::Damaged(format!("{}: checksum mismatch", path.display()))
                }
                Ok(_) => listed += 1,
                Err(e) => return PositionCheck::Damaged(format!("{}: {e}", path.display())),
            }
        }
        // The samples, HDR image and log must all be sealed.
        if listed < 3 {
            return PositionCheck::Damaged(format!("{}: incomplete", seal.display()));
        }
        PositionCheck::Done
    }
    /// Removes the temporary files an atomic write of a killed job left behind
    /// (`.NAME.tmpPID`); call it only while holding the job's lock. Returns how many were
    /// removed.
    pub fn remove_temporaries(&self) -> usize {
        fn walk(dir: &Path, removed: &mut usize) {
            let Ok(entries) = std::fs::read_dir(dir) else {
                return;
            };
            for e in entries.flatten() {
                let p = e.path();
                let name = e.file_name();
                let name = name.to_string_lossy();
                if e.file_type().is_ok_and(|t| t.is_dir()) {
                    walk(&p, removed);
                } else if name.starts_with('.')
                    && name.contains(".tmp")
                    && std::fs::remove_file(&p).is_ok()
                {
                    *removed += 1;
                }
            }
        }
        let mut removed = 0;
        walk(&self.root, &mut removed);
        if removed > 0 {
            tracing::info!(removed, "removed temporaries of an interrupted job");
        }
        removed
    }
    /// Whether position `i` has finished: its seal verifies ([`JobDir::check_position`]).
    pub fn position_done(&self, i: usize) -> bool {
        self.check_position(i) == PositionCheck::Done
    }
    /// Creates the sub-directories a capture writes into.
    pub fn create(&self) -> Result<()> {
        for sub in ["positions", "hdr", "previews"] {
            let d = self.root.join(sub);
            std::fs::create_dir_all(&d).map_err(io(&d))?;
        }
        Ok(())
    }
}

/// What [`JobDir::check_position`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PositionCheck {
    /// Every file of the position matches its seal.
    Done,
    /// The position was never started (no files).
    Missing,
    /// The position is unfinished or damaged (the reason names the file); capture it again.
    Damaged(String),
}

/// The lock of a job directory: `DIR/job.lock` holds the pid (and, on Linux, the start time) of
/// the process running the job. Released (removed) when dropped. A lock whose process is gone
/// (a killed job) is stale and taken over.
#[derive(Debug)]
pub struct JobLock {
    path: PathBuf,
}

/// Identity of a process: pid and, where `/proc` exists, its start time in clock ticks (so a
/// recycled pid is not mistaken for the owner).
fn process_identity(pid: u32) -> Option<String> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Field 22 (starttime) counted after the command name, which is in parentheses.
    let rest = &stat[stat.rfind(')')? + 1..];
    rest.split_whitespace().nth(19).map(|s| s.to_string())
}

/// Whether the process that wrote lock text `text` still runs.
fn lock_owner_alive(text: &str) -> Option<u32> {
    let mut parts = text.split_whitespace();
    let pid: u32 = parts.next()?.parse().ok()?;
    if !Path::new("/proc/self").exists() {
        // No way to tell: assume the owner runs (the operator removes a stale lock).
        return Some(pid);
    }
    let now = process_identity(pid)?;
    match parts.next() {
        Some(start) if start != now => None,
        _ => Some(pid),
    }
}

impl JobLock {
    /// Locks `dir` (created if needed) for this process; refused with
    /// [`AcquireError::Locked`] while another live process holds it.
    pub fn acquire(dir: &JobDir) -> Result<JobLock> {
        std::fs::create_dir_all(dir.root()).map_err(io(dir.root()))?;
        let path = dir.lock();
        let me = std::process::id();
        let text = format!(
            "{me} {}\n",
            process_identity(me).unwrap_or_else(|| "-".into())
        );
        for _ in 0..3 {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    use std::io::Write;
                    f.write_all(text.as_bytes())
                        .and_then(|_| f.sync_all())
                        .map_err(io(&path))?;
                    return Ok(JobLock { path });
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let old = std::fs::read_to_string(&path).unwrap_or_default();
                    match lock_owner_alive(&old) {
                        Some(pid) => {
                            return Err(AcquireError::Locked {
                                path: path.clone(),
                                pid,
                            })
                        }
                        None => {
                            tracing::warn!(
                                lock = %path.display(),
                                owner = old.trim(),
                                "stale lock of a job that is no longer running, taking it over"
                            );
                            let _ = std::fs::remove_file(&path);
                        }
                    }
                }
                Err(e) => return Err(io(&path)(e)),
            }
        }
        Err(AcquireError::JobDirectory {
            path,
            reason: "could not take the job lock".into(),
        })
    }
    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for JobLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Writes `bytes` to `path` atomically, creating its parent directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(io(parent))?;
    }
    brdf::write_atomic(path, bytes)?;
    Ok(())
}

/// Writes `value` as pretty JSON to `path`, atomically.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let mut text = serde_json::to_vec_pretty(value).map_err(|e| AcquireError::Malformed {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    text.push(b'\n');
    write_atomic(path, &text)
}

/// Reads JSON from `path`.
pub fn read_json<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<T> {
    let text = std::fs::read(path).map_err(io(path))?;
    serde_json::from_slice(&text).map_err(|e| AcquireError::Malformed {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// A lamp constant file: three finite, positive numbers (JSON array).
pub fn read_lamp_constant(path: &Path) -> Result<[f64; 3]> {
    let k: [f64; 3] = read_json(path)?;
    if !k.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Err(AcquireError::Malformed {
            path: path.to_path_buf(),
            reason: format!("lamp constant {k:?} must be three finite positive numbers"),
        });
    }
    Ok(k)
}

/// Hot-pixel list as stored in `DIR/defects.json`.
#[derive(Debug, Serialize, Deserialize)]
pub struct HotPixels {
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Hot photosites, `(x, y)`.
    pub hot: Vec<(usize, usize)>,
}

impl HotPixels {
    /// The hot photosites of `map`.
    pub fn of(map: &DefectMap) -> Self {
        Self {
            width: map.width(),
            height: map.height(),
            hot: map.hot_pixels(),
        }
    }

    /// The defect map of this list; `path` names the file in errors.
    pub fn to_map(&self, path: &Path) -> Result<DefectMap> {
        let n = self.width.saturating_mul(self.height);
        if n == 0 || n > (1 << 28) {
            return Err(AcquireError::Malformed {
                path: path.to_path_buf(),
                reason: format!("sensor size {}x{}", self.width, self.height),
            });
        }
        let mut mask = vec![false; n];
        for &(x, y) in &self.hot {
            if x >= self.width || y >= self.height {
                return Err(AcquireError::Malformed {
                    path: path.to_path_buf(),
                    reason: format!("hot pixel ({x}, {y}) outside the sensor"),
                });
            }
            mask[y * self.width + x] = true;
        }
        Ok(DefectMap::from_mask(self.width, self.height, mask)?)
    }

    /// Reads `DIR/defects.json` as a defect map.
    pub fn read_map(path: &Path) -> Result<DefectMap> {
        read_json::<HotPixels>(path)?.to_map(path)
    }
}
