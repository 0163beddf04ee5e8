//! End-to-end tests of the first `gantry` commands on the shared reference data.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn gantry(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(args)
        .output()
        .expect("gantry runs")
}

fn merl_dir() -> PathBuf {
    brdf::data_dir().join("nbrdf/merl")
}

/// A straightforward decode of the neural BRDF, written separately from the library's.
fn independent_decode(dir: &Path, name: &str, th: f64, td: f64, pd: f64) -> [f64; 3] {
    let load = |k: &str| brdf::npy::read(dir.join(format!("{name}_{k}.npy"))).unwrap();
    let (fc1, b1, fc2, b2, fc3, b3) = (
        load("fc1"),
        load("b1"),
        load("fc2"),
        load("b2"),
        load("fc3"),
        load("b3"),
    );
    let dense = |x: &[f64], w: &brdf::npy::NpyArray, b: &brdf::npy::NpyArray, relu: bool| {
        let cols = w.shape[1];
        (0..cols)
            .map(|j| {
                let s = b.data[j] as f64
                    + x.iter()
                        .enumerate()
                        .map(|(i, xi)| xi * w.data[i * cols + j] as f64)
                        .sum::<f64>();
                if relu {
                    s.max(0.0)
                } else {
                    s
                }
            })
            .collect::<Vec<f64>>()
    };
    let x = [
        th.sin(),
        0.0,
        th.cos(),
        td.sin() * pd.cos(),
        td.sin() * pd.sin(),
        td.cos(),
    ];
    let a1 = dense(&x, &fc1, &b1, true);
    let a2 = dense(&a1, &fc2, &b2, true);
    let o = dense(&a2, &fc3, &b3, false);
    [0, 1, 2].map(|c| (o[c].exp() - 1.0).max(0.0))
}

#[test]
fn eval_agrees_with_an_independent_decode() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("angles.csv");
    let mut text = String::from("theta_h,theta_d,phi_d\n");
    let mut pts = Vec::new();
    for i in 0..200 {
        let f = i as f64 / 200.0;
        let p = (
            (f * 7.3).fract() * std::f64::consts::FRAC_PI_2,
            (f * 3.1 + 0.2).fract() * std::f64::consts::FRAC_PI_2,
            (f * 11.7).fract() * std::f64::consts::TAU,
        );
        text.push_str(&format!("{},{},{}\n", p.0, p.1, p.2));
        pts.push(p);
    }
    std::fs::write(&csv, text).unwrap();
    for name in ["blue-acrylic", "chrome", "pink-felt"] {
        let spec = format!("nbrdf:{}/{name}", merl_dir().display());
        let out = gantry(&["eval", &spec, "--angles", csv.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let stdout = String::from_utf8(out.stdout).unwrap();
        let mut lines = stdout.lines();
        assert_eq!(lines.next(), Some("theta_h,theta_d,phi_d,r,g,b"));
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), pts.len());
        for (row, p) in rows.iter().zip(&pts) {
            let expect = independent_decode(&merl_dir(), name, p.0, p.1, p.2);
            for c in 0..3 {
                let tol = 1e-4 * expect[c].abs().max(1e-6);
                assert!(
                    (row[3 + c] - expect[c]).abs() <= tol,
                    "{name} {p:?} ch {c}: {} vs {}",
                    row[3 + c],
                    expect[c]
                );
            }
        }
    }
}

#[test]
fn convert_refuses_an_output_format_it_does_not_write() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["x.exr", "x.bin", "x"] {
        let out_path = dir.path().join(name);
        let out = gantry(&[
            "convert",
            "lambert:kd=0.5",
            "--out",
            out_path.to_str().unwrap(),
        ]);
        assert!(!out.status.success(), "{name} was accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("unknown output format"), "{name}: {err}");
        assert!(!out_path.exists(), "{name} was written");
    }
}

#[test]
fn convert_writes_an_rgl_bsdf_file_that_loads_back_as_a_material() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("grey.bsdf");
    let path = out_path.to_str().unwrap();
    let out = gantry(&[
        "convert",
        "lambert:kd=0.5",
        "--out",
        path,
        "--resolution",
        "8",
        "--theta-i",
        "4",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("rgl-bsdf"));
    // the file is a spec of its own: a Lambertian of albedo 0.5 reads back as one
    let info = gantry(&["info", path, "--json"]);
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    let text = summary.to_string();
    assert!(text.contains("albedo"), "{text}");
    let rgl = gantry(&["info", &format!("rgl:{path}")]);
    assert!(rgl.status.success());
    // a truncated file is refused with the reader's message
    let bytes = std::fs::read(&out_path).unwrap();
    std::fs::write(&out_path, &bytes[..bytes.len() / 2]).unwrap();
    let bad = gantry(&["info", path]);
    assert!(!bad.status.success());
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("past the end"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}

#[test]
fn convert_writes_a_table_that_reads_back_identically() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("pink-felt.binary");
    let spec = format!("nbrdf:{}/pink-felt", merl_dir().display());
    let out = gantry(&["convert", &spec, "--out", out_path.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let table = brdf::merl::read(&out_path).unwrap();
    let direct = brdf::nbrdf::Nbrdf::load(merl_dir(), "pink-felt")
        .unwrap()
        .tabulate();
    assert_eq!(table.raw(), direct.raw());
    // Converting the written table again reproduces the file byte for byte.
    let again = dir.path().join("again.binary");
    let out = gantry(&[
        "convert",
        out_path.to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    assert_eq!(
        std::fs::read(&out_path).unwrap(),
        std::fs::read(&again).unwrap()
    );
    // info on the written table works and reports no missing bins.
    let out = gantry(&["info", out_path.to_str().unwrap(), "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["missing_fraction"].as_f64(), Some(0.0));
    let albedo0 = v["albedo"][0]["albedo"][0].as_f64().unwrap();
    assert!(
        albedo0 > 0.05 && albedo0 < 1.0,
        "pink felt albedo {albedo0}"
    );
}

#[test]
fn malformed_input_fails_with_one_line_and_no_panic() {
    let dir = tempfile::tempdir().unwrap();
    let trunc = dir.path().join("trunc.binary");
    std::fs::write(&trunc, [90u8, 0, 0, 0, 90, 0, 0, 0]).unwrap();
    let bad_csv = dir.path().join("bad.csv");
    std::fs::write(&bad_csv, "theta_h,theta_d,phi_d\n0.1,abc,0\n").unwrap();
    let no_header = dir.path().join("nohdr.csv");
    std::fs::write(&no_header, "a,b\n1,2\n").unwrap();
    let cases: Vec<Vec<String>> = vec![
        vec!["info".into(), trunc.display().to_string()],
        vec!["info".into(), "ggx:alpha=nan".into()],
        vec!["info".into(), "merl:no-such-material".into()],
        vec![
            "eval".into(),
            "lambert".into(),
            "--angles".into(),
            bad_csv.display().to_string(),
        ],
        vec![
            "eval".into(),
            "lambert".into(),
            "--angles".into(),
            no_header.display().to_string(),
        ],
        vec![
            "convert".into(),
            "lambert".into(),
            "--out".into(),
            "/nonexistent-dir/x.binary".into(),
        ],
    ];
    for args in cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = gantry(&a);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{a:?} should fail");
        assert!(!err.contains("panicked"), "{a:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{a:?}: {err}");
        assert!(err.starts_with("error: "), "{a:?}: {err}");
    }
}

/// The operator's path: calibrating from the files a session collected (target images, flat
/// frames and the digitizer log, here those `calibrate --sim` writes) gives the calibration of
/// the session itself.
#[test]
fn calibration_from_collected_files_matches_the_session() {
    let tmp = tempfile::tempdir().unwrap();
    let sim = tmp.path().join("sim");
    let from = tmp.path().join("from");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let o = gantry(&["calibrate", "--sim", "--scale", "0.25", "--out", &s(&sim)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = gantry(&["calibrate", "--from", &s(&sim), "--out", &s(&from)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = |d: &Path| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(d.join("calibration.json")).unwrap()).unwrap()
    };
    let (a, b) = (read(&sim), read(&from));
    for key in ["fx", "fy", "cx", "cy", "k1"] {
        let (x, y) = (
            a["camera"][key].as_f64().unwrap(),
            b["camera"][key].as_f64().unwrap(),
        );
        assert!(
            (x - y).abs() <= 1e-6 * x.abs().max(1.0),
            "camera {key}: session {x}, from files {y}"
        );
    }
    let (ra, rb) = (
        a["sphere"]["radius"].as_f64().unwrap(),
        b["sphere"]["radius"].as_f64().unwrap(),
    );
    assert!((ra - rb).abs() < 1e-9, "sphere radius {ra} vs {rb}");
    // The session's flat frames are used: without them the corners, hence the camera, move.
    assert_eq!(std::fs::read_dir(sim.join("flats")).unwrap().count(), 16);
    std::fs::remove_dir_all(sim.join("flats")).unwrap();
    let o = gantry(&["calibrate", "--from", &s(&sim), "--out", &s(&from)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let c = read(&from);
    let moved = ["fx", "cx", "cy"].iter().any(|k| {
        (a["camera"][k].as_f64().unwrap() - c["camera"][k].as_f64().unwrap()).abs() > 1e-6
    });
    assert!(
        moved,
        "calibration without flat frames equals the one with them"
    );
    // A missing digitizer log and an empty target directory are named in the error.
    std::fs::remove_file(sim.join("digitizer.csv")).unwrap();
    let o = gantry(&["calibrate", "--from", &s(&sim), "--out", &s(&from)]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("digitizer.csv"));
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(empty.join("targets")).unwrap();
    let o = gantry(&["calibrate", "--from", &s(&empty), "--out", &s(&from)]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("no target images"));
}

/// `calibrate --rig` checks what the camera delivers while the operator is still there: flat
/// frames that cannot measure the sensor stop the session at once, and a pose in which the board
/// is not found is asked for again. (The rig file's simulated camera sees the dark room and the
/// sphere, never a diffuser or a board.)
#[test]
fn calibration_on_devices_checks_flats_and_poses_as_they_are_taken() {
    use std::io::Write;
    let tmp = tempfile::tempdir().unwrap();
    let rig = tmp.path().join("rig.toml");
    std::fs::write(
        &rig,
        "backend = \"sim\"\n[sim]\nseed = 1\nscale = 0.1\nmaterial = \"lambert:kd=0.5\"\n",
    )
    .unwrap();
    let digitizer = tmp.path().join("digitizer.csv");
    let run = |extra: &[&str], enters: usize| {
        let out = tmp.path().join("cal");
        let mut args = vec![
            "calibrate",
            "--rig",
            rig.to_str().unwrap(),
            "--digitizer",
            digitizer.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--frames-per-view",
            "1",
            "--exposure-s",
            "0.01",
        ];
        args.extend_from_slice(extra);
        let mut child = Command::new(env!("CARGO_BIN_EXE_gantry"))
            .args(&args)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // The session may end before it reads its input (a broken pipe here is no failure).
        let _ = child
            .stdin
            .take()
            .unwrap()
            .write_all("\n".repeat(enters).as_bytes());
        child.wait_with_output().unwrap()
    };
    // A digitizer log that cannot be read stops the session before the camera is used.
    std::fs::write(&digitizer, "kind,index\ntip,zero\n").unwrap();
    let o = run(&["--flat-frames", "2"], 5);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("digitizer.csv") && !err.contains("flat field"),
        "{err}"
    );
    std::fs::write(
        &digitizer,
        "kind,index,angle_deg,x_m,y_m,z_m,u_px,v_px\ncaliper,0,,0.0508,,,,\n",
    )
    .unwrap();
    let o = run(&["--flat-frames", "2"], 5);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("flat frames cannot measure"), "{err}");
    assert!(!err.contains("target 1/"), "{err}");
    // Without flat frames: three tries at the first pose, each refused, then the input ends.
    let o = run(&["--flat-frames", "0"], 3);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert_eq!(err.matches("checkerboard not found").count(), 3, "{err}");
    assert!(err.contains("target 1/30 again"), "{err}");
    assert!(err.contains("standard input closed"), "{err}");
}

#[test]
fn an_error_names_each_cause_once() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.bsdf");
    let spec = format!("rgl:{}", missing.display());
    let out = gantry(&["info", &spec]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let line = err
        .lines()
        .find(|l| l.starts_with("error:"))
        .unwrap_or_else(|| panic!("{err}"));
    assert!(line.contains(&spec), "{line}");
    let cause = std::fs::File::open(&missing).unwrap_err().to_string();
    assert_eq!(line.matches(&cause).count(), 1, "{line}");
}

#[test]
fn a_render_names_its_png_or_its_exr_and_writes_both() {
    let dir = tempfile::tempdir().unwrap();
    let render = |out: &Path| {
        gantry(&[
            "render",
            "sphere",
            "lambert:kd=0.5",
            "--size",
            "16",
            "--spp",
            "2",
            "--out",
            out.to_str().unwrap(),
        ])
    };
    for name in ["a.png", "b.exr"] {
        let out = dir.path().join(name);
        let o = render(&out);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let png = std::fs::read(out.with_extension("png")).unwrap();
        let exr = std::fs::read(out.with_extension("exr")).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{name}: the PNG is a PNG");
        assert_eq!(
            &exr[..4],
            &[0x76, 0x2f, 0x31, 0x01],
            "{name}: the EXR is an OpenEXR file"
        );
    }
    let bad = dir.path().join("c.txt");
    let o = render(&bad);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains(".exr"));
    assert!(!bad.exists());
}
