//! End-to-end tests of `gantry capture` on the simulated rig at reduced resolution:
//! interrupted jobs resume to the same bytes, injected faults are survived and reported.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const SCALE: &str = "0.15";
const POSITIONS: &str = "8";
const GEOMETRY: &str = "--true-geometry";

/// The reduced capture job of these tests, writing to `out`.
fn capture_command(out: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_gantry"));
    c.args([
        "capture",
        "--sim",
        "--material",
        "merl:pink-felt",
        "--positions",
        POSITIONS,
    ])
    .args(["--scale", SCALE, GEOMETRY, "--out"])
    .arg(out);
    c
}

fn capture(out: &Path, extra: &[&str]) -> std::process::Output {
    capture_command(out)
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
        let mut child = capture_command(&dir)
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

fn gantry(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(args)
        .output()
        .expect("gantry runs")
}

fn rig_toml(path: &Path, material: &str) {
    std::fs::write(
        path,
        format!("backend = \"sim\"\n[sim]\nseed = 1\nscale = {SCALE}\nmaterial = \"{material}\"\n"),
    )
    .unwrap();
}

/// The operator's path on devices (`--rig`, here a rig file whose backend is the simulator, so the
/// job sees only device traits and no ground truth): a white-standard run gives the lamp constant,
/// then the sample is captured with a calibration file. It must produce exactly the table of the
/// simulator shortcut (`--sim`), which calibrates and measures the white standard by itself.
#[test]
fn device_path_with_white_standard_matches_the_simulator_shortcut() {
    let tmp = tempfile::tempdir().unwrap();
    let p = |s: &str| tmp.path().join(s).to_str().unwrap().to_string();
    let shortcut = tmp.path().join("shortcut");
    ok(&capture(&shortcut, &[]));

    // The geometry the shortcut used, as the operator's calibration file.
    let calibration = p("shortcut/calibration.json");
    rig_toml(&tmp.path().join("white.toml"), "lambert:kd=0.99");
    let white = gantry(&[
        "capture",
        "--rig",
        &p("white.toml"),
        "--calibration",
        &calibration,
        "--white-reference",
        "0.99",
        "--out",
        &p("white"),
    ]);
    ok(&white);
    let k = p("white/lamp_constant.json");
    assert!(Path::new(&k).exists());

    rig_toml(&tmp.path().join("sample.toml"), "merl:pink-felt");
    // Without a lamp constant the device path refuses, saying what is missing.
    let missing = gantry(&[
        "capture",
        "--rig",
        &p("sample.toml"),
        "--calibration",
        &calibration,
        "--positions",
        POSITIONS,
        "--out",
        &p("nok"),
    ]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("--lamp-constant"));

    // The sample on the devices, with the calibration file and the lamp constant.
    let on_devices = |extra: &[&str]| {
        let sample = p("sample.toml");
        let mut args = vec![
            "capture",
            "--rig",
            &sample,
            "--calibration",
            &calibration,
            "--lamp-constant",
            &k,
        ];
        args.extend_from_slice(extra);
        gantry(&args)
    };
    let device = on_devices(&[
        "--positions",
        POSITIONS,
        "--scale",
        SCALE,
        "--out",
        &p("device"),
    ]);
    ok(&device);
    // The same physics through the device traits: the white standards agree to their noise, and
    // so do the tables (the two runs see different noise, so the bytes differ).
    let read_k = |path: &Path| -> Vec<f64> {
        serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
    };
    let (kd, ks) = (
        read_k(Path::new(&k)),
        read_k(&shortcut.join("lamp_constant.json")),
    );
    for c in 0..3 {
        assert!(
            (kd[c] / ks[c] - 1.0).abs() < 0.005,
            "lamp constants differ: {kd:?} vs {ks:?}"
        );
    }
    let td = brdf::merl::read(tmp.path().join("device/brdf.binary")).unwrap();
    let ts = brdf::merl::read(shortcut.join("brdf.binary")).unwrap();
    let (mut both, mut only_one) = (Vec::new(), 0usize);
    for c in 0..3 {
        for b in 0..brdf::BINS {
            match (td.is_valid(c, b), ts.is_valid(c, b)) {
                (true, true) => both.push((td.get(c, b) / ts.get(c, b)).ln().abs()),
                (false, false) => {}
                _ => only_one += 1,
            }
        }
    }
    both.sort_by(f64::total_cmp);
    let median = both[both.len() / 2];
    assert!(
        median < 0.02,
        "device and shortcut tables differ by a median {median}"
    );
    assert!(
        (only_one as f64) < 0.02 * both.len() as f64,
        "{only_one} bins covered by one run only, {} by both",
        both.len()
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("device/report.json")).unwrap())
            .unwrap();
    assert!(report.get("truth_table_error").is_none_or(|v| v.is_null()));

    // The fast capture on the device path: planned for the calibration file's geometry,
    // captured through the device traits, completed; no truth to compare with.
    ok(&gantry(&[
        "model",
        "build",
        "--corpus",
        "lambert:kd=0.5/0.4/0.3",
        "ggx:alpha=0.2,kd=0.3",
        "ggx:alpha=0.4,kd=0.1/0.2/0.3",
        "lambert:kd=0.2",
        "--components",
        "3",
        "--chart-dim",
        "0",
        "--out",
        &p("model.bin"),
    ]));
    let fast = on_devices(&[
        "--fast",
        "--model",
        &p("model.bin"),
        "--fast-positions",
        "3",
        "--components",
        "3",
        "--out",
        &p("fast-device"),
    ]);
    ok(&fast);
    let report: serde_json::Value = serde_json::from_slice(
        &std::fs::read(tmp.path().join("fast-device/fast_report.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(report["positions"], 3);
    assert!(report["truth"].is_null() && report["simulated_capture_s"].is_null());
    let table = brdf::merl::read(tmp.path().join("fast-device/brdf.binary")).unwrap();
    assert!(table.values().iter().all(|v| v.is_finite() && *v >= 0.0));
}

/// `rebin --inverse` fills the grid from the stored HDR images by the thesis's inverse mapping; where
/// both methods have a value they agree, and interpolating between lamp positions reaches more bins
/// than forward binning (kept apart in brdf_inverse_all.binary).
#[test]
fn inverse_mapping_agrees_with_forward_binning() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("inv");
    ok(&capture(&dir, &[]));
    let o = gantry(&["rebin", dir.to_str().unwrap(), "--inverse"]);
    ok(&o);
    let read = |name: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(dir.join(name)).unwrap()).unwrap()
    };
    let inv = read("inverse_report.json");
    let fwd = read("report.json");
    let vs_forward = inv["versus_forward"]["median_abs_log"].as_f64().unwrap();
    assert!(vs_forward < 0.05, "inverse vs forward median {vs_forward}");
    let (ci, ca, cf) = (
        inv["coverage"].as_f64().unwrap(),
        inv["coverage_all"].as_f64().unwrap(),
        fwd["coverage"].as_f64().unwrap(),
    );
    assert!(ca > cf, "inverse coverage {ca} not above forward {cf}");
    // The guarded table keeps only bins forward binning reached, nearly all of them.
    assert!(
        ci <= cf && ci > 0.9 * cf,
        "guarded coverage {ci}, forward {cf}"
    );
    let t = brdf::merl::read(dir.join("brdf_inverse.binary")).unwrap();
    assert!(t.values().iter().all(|v| v.is_finite()));
}

/// On real devices that are absent the job fails at once, naming the device, and leaves no job
/// directory behind (so a later run needs no `--resume`).
#[test]
fn absent_devices_fail_fast_and_leave_nothing_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let rig = tmp.path().join("real.toml");
    // The documented example configuration, switched to real devices on a port that does not exist.
    let example = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/rig.example.toml"),
    )
    .unwrap()
    .replace("backend = \"sim\"", "backend = \"real\"")
    .replace("/dev/ttyUSB0", "/dev/gantry-test-no-such-port");
    // Without the USB presence list, which (feature `usb`) would fail first, naming the USB device.
    let example: String = example
        .lines()
        .scan(false, |in_usb, line| {
            if line.starts_with("[[usb]]") {
                *in_usb = true;
            } else if line.starts_with('[') || line.starts_with('#') {
                *in_usb = false;
            }
            Some(if *in_usb {
                String::new()
            } else {
                format!("{line}\n")
            })
        })
        .collect();
    std::fs::write(&rig, example).unwrap();
    let k = tmp.path().join("k.json");
    std::fs::write(&k, "[1.0, 1.0, 1.0]").unwrap();
    let out = tmp.path().join("job");
    let started = std::time::Instant::now();
    let o = gantry(&[
        "capture",
        "--rig",
        rig.to_str().unwrap(),
        "--calibration",
        "/nonexistent/calibration.json",
        "--lamp-constant",
        k.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("/dev/gantry-test-no-such-port"),
        "error does not name the device: {err}"
    );
    assert!(started.elapsed() < Duration::from_secs(30));
    assert!(
        !out.exists(),
        "a failed start left {} behind",
        out.display()
    );
}

#[test]
fn a_quick_tenth_scale_trial_calibrates_without_the_partial_boards_and_completes() {
    // The quick trial a new user runs: calibration included, at a tenth of the sensor, where
    // some target images lose border corners. They are dropped and reported, not fatal.
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("trial");
    let o = gantry(&[
        "capture",
        "--sim",
        "--positions",
        "12",
        "--scale",
        "0.1",
        "--out",
        dir.to_str().unwrap(),
    ]);
    ok(&o);
    let cal: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("calibration.json")).unwrap()).unwrap();
    let used = cal["fit"]["target_images"].as_u64().unwrap();
    let dropped = cal["fit"]["dropped_target_images"].as_u64().unwrap_or(0);
    assert_eq!(used + dropped, 30, "{cal}");
    assert!(dropped > 0 && used >= 10, "{cal}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let geometry = report["geometry"].as_str().unwrap();
    assert!(
        geometry.contains(&format!("{dropped} dropped")),
        "{geometry}"
    );
    assert!(brdf::merl::read(dir.join("brdf.binary")).is_ok());
}

/// `capture --fast`: a dry run prints the plan and writes nothing; the run writes the completed
/// table, the measured-entry flags and the plan; `--fast` without `--model` is refused.
#[test]
fn fast_capture_plans_captures_and_completes_from_a_model() {
    let tmp = tempfile::tempdir().unwrap();
    let p = |s: &str| tmp.path().join(s).to_str().unwrap().to_string();
    ok(&gantry(&[
        "model",
        "build",
        "--corpus",
        "ggx:alpha=0.05,kd=0.1",
        "ggx:alpha=0.2,kd=0.3/0.2/0.1",
        "ggx:alpha=0.4,kd=0.2",
        "lambert:kd=0.5/0.4/0.3",
        "ggx:alpha=0.1,kd=0.05/0.1/0.2",
        "--components",
        "4",
        "--chart-dim",
        "0",
        "--out",
        &p("model.bin"),
    ]));
    let fast = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "capture",
            "--sim",
            "--fast",
            "--material",
            "ggx:alpha=0.15,kd=0.2/0.15/0.1",
            "--scale",
            "0.1",
            GEOMETRY,
            "--fast-positions",
            "4",
            "--components",
            "4",
            "--out",
        ];
        args.push(out);
        args.extend_from_slice(extra);
        gantry(&args)
    };
    let dry = fast(&p("dry"), &["--model", &p("model.bin"), "--dry-run"]);
    ok(&dry);
    let text = String::from_utf8_lossy(&dry.stdout);
    assert!(
        text.starts_with("4 positions, predicted capture clock"),
        "{text}"
    );
    assert!(!tmp.path().join("dry").exists());

    let run = fast(&p("fast"), &["--model", &p("model.bin")]);
    ok(&run);
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(text.contains("vs truth over the"), "{text}");
    for f in [
        "plan.json",
        "brdf.binary",
        "measured.npy",
        "completion_sd.npy",
        "fast_report.json",
    ] {
        assert!(tmp.path().join("fast").join(f).exists(), "{f} missing");
    }
    let table = brdf::merl::read(tmp.path().join("fast/brdf.binary")).unwrap();
    assert!(table.values().iter().all(|v| v.is_finite() && *v >= 0.0));
    // The same directory again without --resume is refused, nothing is overwritten.
    let again = fast(&p("fast"), &["--model", &p("model.bin")]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--resume"));

    let missing = fast(&p("none"), &[]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("--model"));
}
