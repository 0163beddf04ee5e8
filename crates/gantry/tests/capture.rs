//! End-to-end tests of `gantry capture` on the simulated rig at reduced resolution:
//! interrupted jobs resume to the same bytes, injected faults are survived and reported.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const SCALE: &str = "0.15";
const POSITIONS: &str = "8";
const GEOMETRY: &str = "--true-geometry";

fn capture(out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args([
            "capture",
            "--sim",
            "--material",
            "merl:pink-felt",
            "--positions",
            POSITIONS,
        ])
        .args(["--scale", SCALE, GEOMETRY, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("gantry runs")
}

fn ok(o: &std::process::Output) {
    assert!(
        o.status.success(),
        "gantry failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

fn table(dir: &Path) -> Vec<u8> {
    std::fs::read(dir.join("brdf.binary")).expect("brdf.binary written")
}

#[test]
fn interrupted_and_resumed_jobs_give_identical_tables() {
    let tmp = tempfile::tempdir().unwrap();
    let straight = tmp.path().join("straight");
    ok(&capture(&straight, &[]));
    let reference = table(&straight);

    // Stopped cleanly after 1, then 3 more positions, then finished.
    let stepped = tmp.path().join("stepped");
    ok(&capture(&stepped, &["--stop-after", "1"]));
    assert!(!stepped.join("brdf.binary").exists());
    ok(&capture(&stepped, &["--resume", "--stop-after", "3"]));
    ok(&capture(&stepped, &["--resume"]));
    assert_eq!(table(&stepped), reference, "stepped run differs");

    // Killed (SIGKILL) at several moments, then resumed.
    for (k, delay_ms) in [150u64, 500, 900].into_iter().enumerate() {
        let dir = tmp.path().join(format!("killed{k}"));
        let mut child = Command::new(env!("CARGO_BIN_EXE_gantry"))
            .args([
                "capture",
                "--sim",
                "--material",
                "merl:pink-felt",
                "--positions",
                POSITIONS,
            ])
            .args(["--scale", SCALE, GEOMETRY, "--out"])
            .arg(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(delay_ms));
        let _ = child.kill();
        let _ = child.wait();
        // No temporary files may be mistaken for results; resuming completes the job.
        let resume = if dir.join("job.json").exists() {
            capture(&dir, &["--resume"])
        } else {
            capture(&dir, &[])
        };
        ok(&resume);
        assert_eq!(
            table(&dir),
            reference,
            "run killed after {delay_ms} ms differs"
        );
    }

    // A resume with other parameters is refused, and so is a second run into the same directory.
    let o = capture(&straight, &["--resume", "--seed", "2"]);
    assert!(!o.status.success());
    let o = capture(&straight, &[]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--resume"));
}

#[test]
fn faults_are_survived_reported_and_resumable() {
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("faulty");
    // Seed 3 injects at least one fault of each kind over this short run.
    let args = ["--faults", "--seed", "3"];
    ok(&capture(&a, &args));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("report.json")).unwrap()).unwrap();
    let total = report["faults"]["total"].as_u64().unwrap();
    assert!(total > 0, "no fault was met: {}", report["faults"]);
    // Every position was completed.
    for i in 0..8 {
        assert!(a.join(format!("positions/{i:03}.samples")).exists());
        assert!(a.join(format!("hdr/{i:03}.exr")).exists());
    }
    // The faulty job is as accurate as a clean one (faults only cost retries).
    let err = report["truth_table_error"]["median_abs_log"]
        .as_f64()
        .unwrap();
    assert!(err < 0.05, "median |log| error {err}");
    // Interrupted and resumed with the same faults, it ends with the same bytes.
    let b = tmp.path().join("faulty-resumed");
    let mut stop = args.to_vec();
    stop.extend(["--stop-after", "3"]);
    ok(&capture(&b, &stop));
    let mut resume = args.to_vec();
    resume.push("--resume");
    ok(&capture(&b, &resume));
    assert_eq!(table(&a), table(&b));
}

#[test]
fn report_and_validation_outputs_exist() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("job");
    ok(&capture(&dir, &["--save-truth", "--keep-frames"]));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["validation"].as_array().unwrap().len(), 8);
    assert!(report["coverage"].as_f64().unwrap() > 0.0);
    assert!(report["simulated_capture_s"].as_f64().unwrap() > 8.0 * 30.0);
    assert!(dir.join("previews/contact_sheet.png").exists());
    assert!(dir.join("truth/000.exr").exists());
    let measured = brdf::merl::read(dir.join("brdf.binary")).unwrap();
    // Rebinning from the stored frames reproduces the table exactly.
    let o = Command::new(env!("CARGO_BIN_EXE_gantry"))
        .arg("rebin")
        .arg(&dir)
        .output()
        .unwrap();
    ok(&o);
    let again = brdf::merl::read(dir.join("brdf.binary")).unwrap();
    assert_eq!(measured.raw(), again.raw());
}
