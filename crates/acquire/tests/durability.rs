//! Durability of a capture at reduced size: SIGKILL at seeded random moments with a resume after
//! each ends with the same `brdf.binary` as an uninterrupted run; damaged checkpoints are
//! detected and captured again; a second job on a directory is refused and a killed job's lock
//! is recognised as stale; a full disk (a small tmpfs) stops the job with an error naming the
//! file, leaves nothing half-written, and the job resumes once space is freed.
//!
//! The killed jobs run in child processes: this test binary re-runs itself with the ignored
//! test `child_job` and the job directory in `ACQUIRE_CHILD_DIR`.

use acquire::{
    AcquireError, CalibrationSource, FaultKind, JobDir, JobLock, JobSpec, Outcome, PositionCheck,
    RunOptions, SimSetup, Station,
};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const MATERIAL: &str = "ggx:alpha=0.25,kd=0.3/0.2/0.1,ks=0.05";
const CHILD_DIR: &str = "ACQUIRE_CHILD_DIR";
/// Positions of the killed job.
const CHILD_POSITIONS: usize = 10;

fn spec(positions: usize) -> JobSpec {
    JobSpec::new(MATERIAL, positions)
}

fn options(resume: bool) -> RunOptions {
    RunOptions {
        calibration: CalibrationSource::TrueGeometry,
        resume,
        ..RunOptions::default()
    }
}

fn run(spec: &JobSpec, resume: bool, dir: &Path) -> acquire::Result<Outcome> {
    let mut station = Station::simulated(spec, &SimSetup::with_scale(0.12))?;
    acquire::run(&mut station, spec, &options(resume), dir)
}

fn finish(spec: &JobSpec, dir: &Path) -> Box<acquire::Finished> {
    match run(spec, true, dir).unwrap() {
        Outcome::Finished(f) => f,
        other => panic!("job did not finish: {other:?}"),
    }
}

/// The job the kill test runs in child processes; run directly, it measures a
/// temporary directory.
#[test]
#[ignore = "the child process of the kill test (runs a whole job)"]
fn child_job() {
    let dir = match std::env::var_os(CHILD_DIR) {
        Some(d) => PathBuf::from(d),
        None => std::env::temp_dir().join(format!("acquire-child-{}", std::process::id())),
    };
    finish(&spec(CHILD_POSITIONS), &dir);
}

fn spawn_child(dir: &Path) -> Child {
    Command::new(std::env::current_exe().unwrap())
        .args([
            "child_job",
            "--exact",
            "--ignored",
            "--test-threads=1",
            "--quiet",
        ])
        .env(CHILD_DIR, dir)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("re-running the test binary as a child job")
}

/// A small seeded generator (splitmix64) for the kill moments.
struct Moments(u64);
impl Moments {
    fn next_unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Every position is either sealed and intact, or not counted as done; no temporary file of
/// the atomic writer is left next to a result.
fn assert_nothing_half_written(dir: &Path, positions: usize) -> usize {
    let job = JobDir::new(dir);
    let mut done = 0;
    for i in 0..positions {
        match job.check_position(i) {
            PositionCheck::Done => done += 1,
            PositionCheck::Missing | PositionCheck::Damaged(_) => {}
        }
    }
    if let Ok(bytes) = std::fs::read(job.table()) {
        // A table on disk is whole: the MERL header and 3 channels of doubles.
        brdf::merl::parse(&bytes, &job.table()).expect("brdf.binary on disk is a whole table");
    }
    done
}

#[test]
fn sigkill_at_twenty_seeded_moments_then_resume_gives_the_uninterrupted_table() {
    let tmp = tempfile::tempdir().unwrap();
    let positions = CHILD_POSITIONS;
    // Uninterrupted reference, in a child too (so its wall time is that of a child run).
    let straight = tmp.path().join("straight");
    let t0 = Instant::now();
    let status = spawn_child(&straight).wait().unwrap();
    let full = t0.elapsed();
    assert!(status.success(), "the uninterrupted child job failed");
    let reference = std::fs::read(straight.join("brdf.binary")).unwrap();

    let killed = tmp.path().join("killed");
    let mut moments = Moments(0x6b69_6c6c);
    let mut finished_before_kill = 0;
    let mut stale_locks = 0;
    let mut done_at_kill = Vec::new();
    for _ in 0..20 {
        // A moment within the first tenth of a whole job's time: the kills fall into set-up,
        // the positions and (once the capture is complete) binning and the result writes.
        let delay = full.mul_f64(0.1 * moments.next_unit());
        let mut child = spawn_child(&killed);
        let start = Instant::now();
        let mut exited = None;
        while start.elapsed() < delay {
            if let Some(s) = child.try_wait().unwrap() {
                exited = Some(s);
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        match exited {
            Some(s) => {
                assert!(s.success(), "a resumed child job failed");
                finished_before_kill += 1;
            }
            None => {
                child.kill().unwrap(); // SIGKILL
                child.wait().unwrap();
                if killed.join("job.lock").exists() {
                    stale_locks += 1;
                }
            }
        }
        done_at_kill.push(assert_nothing_half_written(&killed, positions));
    }
    eprintln!(
        "kill test: whole job {:.2} s; sealed positions at each kill {done_at_kill:?}; \
         {finished_before_kill} runs ended before their kill; {stale_locks} stale locks left",
        full.as_secs_f64()
    );
    assert!(
        stale_locks > 0,
        "no kill left a lock behind: the stale-lock path was not exercised"
    );
    // The last resume completes (in this process: the children's stale lock is taken over).
    finish(&spec(positions), &killed);
    assert!(
        !killed.join("job.lock").exists(),
        "the lock outlived the job"
    );
    assert_eq!(
        temporaries(&killed),
        Vec::<PathBuf>::new(),
        "temporaries of killed runs remain"
    );
    assert_eq!(
        std::fs::read(killed.join("brdf.binary")).unwrap(),
        reference,
        "the table after 20 kills and resumes differs from the uninterrupted one"
    );
}

#[test]
fn damaged_checkpoints_are_detected_on_resume_and_captured_again() {
    let tmp = tempfile::tempdir().unwrap();
    let mut spec = spec(4);
    spec.keep_frames = true;
    finish(&spec, tmp.path());
    let reference = std::fs::read(tmp.path().join("brdf.binary")).unwrap();
    let job = JobDir::new(tmp.path());
    // 0: samples truncated; 1: one bit of the HDR image flipped; 2: one bit of the kept frames
    // flipped; 3: the seal itself damaged.
    let truncate = |p: PathBuf| {
        let b = std::fs::read(&p).unwrap();
        std::fs::write(&p, &b[..b.len() / 2]).unwrap();
    };
    let flip = |p: PathBuf| {
        let mut b = std::fs::read(&p).unwrap();
        let k = b.len() / 3;
        b[k] ^= 0x10;
        std::fs::write(&p, b).unwrap();
    };
    truncate(job.samples(0));
    flip(job.hdr(1));
    flip(job.frames(2));
    flip(job.seal(3));
    for i in 0..4 {
        assert!(
            matches!(job.check_position(i), PositionCheck::Damaged(_)),
            "damage of position {i} not detected"
        );
    }
    let done = finish(&spec, tmp.path());
    let damaged: Vec<usize> = done
        .report
        .faults
        .events
        .iter()
        .filter(|e| e.event.kind == FaultKind::CheckpointDamaged)
        .map(|e| e.position)
        .collect();
    assert_eq!(
        damaged,
        vec![0, 1, 2, 3],
        "every damaged position is reported"
    );
    for i in 0..4 {
        assert_eq!(job.check_position(i), PositionCheck::Done);
    }
    assert_eq!(
        std::fs::read(tmp.path().join("brdf.binary")).unwrap(),
        reference,
        "re-captured positions changed the table"
    );
}

#[test]
fn a_second_job_is_refused_while_the_lock_is_held_and_a_dead_owners_lock_is_stale() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = spec(2);
    let job = JobDir::new(tmp.path());
    {
        let _held = JobLock::acquire(&job).unwrap();
        let err = run(&spec, false, tmp.path()).unwrap_err();
        match &err {
            AcquireError::Locked { path, pid } => {
                assert_eq!(*pid, std::process::id());
                assert!(path.ends_with("job.lock"));
            }
            other => panic!("expected a lock refusal, got {other}"),
        }
        assert!(err.to_string().contains("in use"), "{err}");
        assert!(
            !tmp.path().join("job.json").exists(),
            "the refused job wrote"
        );
    }
    // A process that has ended: its lock is stale and taken over.
    let mut dead = Command::new("true").spawn().unwrap();
    let dead_pid = dead.id();
    dead.wait().unwrap();
    std::fs::write(job.lock(), format!("{dead_pid} 12345\n")).unwrap();
    // A lock naming this pid with another start time (a recycled pid) is stale too.
    finish(&spec, tmp.path());
    assert!(!job.lock().exists());
    std::fs::write(job.lock(), format!("{} 1\n", std::process::id())).unwrap();
    finish(&spec, tmp.path());
    assert!(!job.lock().exists());
}

/// A tmpfs mounted for the life of the value.
struct Tmpfs {
    dir: PathBuf,
}

impl Tmpfs {
    fn mount(dir: &Path, bytes: u64) -> Tmpfs {
        std::fs::create_dir_all(dir).unwrap();
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={bytes}"), "tmpfs"])
            .arg(dir)
            .output()
            .expect("running mount");
        assert!(
            out.status.success(),
            "the disk-full test needs to mount a small tmpfs (run as root, or in a container \
             with CAP_SYS_ADMIN): mount said: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Tmpfs {
            dir: dir.to_path_buf(),
        }
    }
    fn resize(&self, bytes: u64) {
        let out = Command::new("mount")
            .args(["-o", &format!("remount,size={bytes}")])
            .arg(&self.dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.dir).status();
    }
}

fn tree_bytes(dir: &Path) -> u64 {
    let mut total = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let m = e.metadata().unwrap();
        total += if m.is_dir() {
            tree_bytes(&e.path())
        } else {
            // Rounded up to 4 KiB pages, as tmpfs counts them.
            m.len().div_ceil(4096) * 4096
        };
    }
    total
}

fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            found.extend(temporaries(&p));
        } else if p
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.contains(".tmp"))
        {
            found.push(p);
        }
    }
    found
}

#[test]
fn disk_full_during_checkpoints_or_results_is_a_clear_error_and_resume_completes() {
    let tmp = tempfile::tempdir().unwrap();
    let positions = 4;
    let spec = spec(positions);
    // Sizes of a whole job and of its capture alone (before binning writes the results).
    let reference_dir = tmp.path().join("reference");
    finish(&spec, &reference_dir);
    let reference = std::fs::read(reference_dir.join("brdf.binary")).unwrap();
    let total = tree_bytes(&reference_dir);
    // The results: what binning, validation and the report write after the capture.
    let page = |p: PathBuf| std::fs::metadata(p).map_or(0, |m| m.len().div_ceil(4096) * 4096);
    let results = page(reference_dir.join("brdf.binary"))
        + page(reference_dir.join("counts.bin"))
        + page(reference_dir.join("report.json"))
        + tree_bytes(&reference_dir.join("previews"));
    let capture = total - results;
    eprintln!("disk full test: whole job {total} bytes, capture {capture} bytes");
    assert!(total > capture + reference.len() as u64);

    // The disk fills during the capture (half of it fits), then during the result writes
    // (the capture fits, the table does not).
    for (name, size, during) in [
        ("checkpoints", capture / 2, "capture"),
        ("results", capture + 256 * 1024, "results"),
    ] {
        let mnt = tmp.path().join(format!("full-{name}"));
        let fs = Tmpfs::mount(&mnt, size);
        let dir = mnt.join("job");
        let err = run(&spec, false, &dir).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains(dir.to_str().unwrap()),
            "disk full during the {during}: the error does not name the file: {text}"
        );
        assert!(
            text.contains("No space left") || text.contains("space"),
            "disk full during the {during}: the error does not say why: {text}"
        );
        assert_eq!(
            temporaries(&dir),
            Vec::<PathBuf>::new(),
            "temporaries left behind"
        );
        let done = assert_nothing_half_written(&dir, positions);
        if during == "results" {
            assert_eq!(done, positions, "the capture itself fitted");
        } else {
            assert!(done < positions);
        }
        eprintln!("disk full during the {during} ({size} bytes): {text}; {done} positions sealed");
        fs.resize(total * 2);
        finish(&spec, &dir);
        assert_eq!(
            std::fs::read(dir.join("brdf.binary")).unwrap(),
            reference,
            "the table resumed after a full disk ({during}) differs"
        );
    }
}
