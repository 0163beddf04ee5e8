//! Smoke-level end-to-end checks of the model, sample and render commands, each asserting a
//! property of the result.

use std::process::Command;

fn gantry(args: &[&str]) -> std::process::Output {
    let o = Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(args)
        .output()
        .expect("gantry runs");
    assert!(
        o.status.success(),
        "gantry {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn nielsen() -> String {
    brdf::data_dir().join("nbrdf/nielsen").display().to_string()
}

/// `gantry sample model → plan → measure → reconstruct` of nielsen:cardboard, a member of the
/// training corpus, with `model_method` for the model and `method` for the plan and the
/// reconstruction. Returns the median |log error| of the reconstruction over the grid.
fn sparse_round_trip(model_method: &str, method: &str, n: usize) -> f64 {
    let tmp = tempfile::tempdir().unwrap();
    let p = |f: &str| tmp.path().join(f).display().to_string();
    let corpus = nielsen();
    let n = n.to_string();
    gantry(&[
        "sample",
        "model",
        "--method",
        model_method,
        "--corpus",
        &corpus,
        "--stride",
        "3",
        "3",
        "6",
        "--out",
        &p("m"),
    ]);
    gantry(&[
        "sample",
        "plan",
        "--method",
        method,
        "--n",
        &n,
        "--model",
        &p("m"),
        "--out",
        &p("plan.csv"),
    ]);
    gantry(&[
        "sample",
        "measure",
        "nielsen:cardboard",
        "--plan",
        &p("plan.csv"),
        "--out",
        &p("v.csv"),
    ]);
    gantry(&[
        "sample",
        "reconstruct",
        "--method",
        method,
        "--plan",
        &p("plan.csv"),
        "--values",
        &p("v.csv"),
        "--model",
        &p("m"),
        "--out",
        &p("x.binary"),
    ]);
    let rec = brdf::merl::read(p("x.binary")).unwrap();
    let truth = brdf::load("nielsen:cardboard").unwrap().tabulate();
    let mut errs = Vec::new();
    for c in 0..3 {
        for b in (0..brdf::BINS).step_by(97) {
            let (r, t) = (rec.get(c, b), truth.get(c, b));
            if t > 1e-3 && r > 0.0 {
                errs.push((r / t).ln().abs());
            }
        }
    }
    errs.sort_by(|a, b| a.total_cmp(b));
    errs[errs.len() / 2]
}

#[test]
fn sparse_measurement_reproduces_a_material_of_the_training_span() {
    // The reconstruction agrees with the material it measured (a member of the training set)
    // in log space over the grid.
    let median = sparse_round_trip("pca", "pca", 30);
    assert!(median < 0.1, "median |log error| {median}");
}

#[test]
fn relative_linear_combination_recovers_a_corpus_member_from_its_plan() {
    // A corpus member is an exact combination of the corpus, so the only error left is the
    // grid: the sub-grid table against the full table.
    let median = sparse_round_trip("lincomb", "lincomb-relative", 60);
    assert!(median < 0.05, "median |log error| {median}");
}

#[test]
fn model_reconstruction_with_all_components_recovers_a_corpus_member() {
    let tmp = tempfile::tempdir().unwrap();
    let p = |f: &str| tmp.path().join(f).display().to_string();
    gantry(&[
        "model",
        "build",
        "--corpus",
        &nielsen(),
        "--out",
        &p("model.bin"),
        "--components",
        "7",
    ]);
    gantry(&[
        "model",
        "reconstruct",
        "nielsen:bluebook",
        "--model",
        &p("model.bin"),
        "--k",
        "7",
        "--out",
        &p("r.binary"),
    ]);
    let rec = brdf::merl::read(p("r.binary")).unwrap();
    let truth = brdf::load("nielsen:bluebook").unwrap().tabulate();
    // With as many components as materials minus one, a member is reproduced up to float error.
    let mut worst = 0.0f64;
    for b in (0..brdf::BINS).step_by(101) {
        let (r, t) = (rec.get(1, b), truth.get(1, b));
        worst = worst.max(((r + 1e-3) / (t + 1e-3)).ln().abs());
    }
    assert!(worst < 1e-3, "worst |log error| {worst}");
    gantry(&["model", "report", &p("model.bin"), "--out", &p("report")]);
    assert!(tmp.path().join("report/eigenvalues.png").exists());
}

#[test]
fn sphere_render_writes_exr_and_png() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s.exr");
    gantry(&[
        "render",
        "sphere",
        "lambert:kd=0.8",
        "--size",
        "24",
        "--spp",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    let img = render::Image::read_exr(&out).unwrap();
    let lit = img.pixels().iter().filter(|p| p[0] > 0.0).count();
    assert!(lit > 24 * 24 / 10, "{lit} lit pixels");
    assert!(out.with_extension("png").exists());
}

#[test]
fn wavelet_compressed_material_renders_like_the_original() {
    let tmp = tempfile::tempdir().unwrap();
    let p = |f: &str| tmp.path().join(f).display().to_string();
    gantry(&[
        "wavelet",
        "basis",
        "--corpus",
        "merl:pink-felt",
        "--out",
        &p("cwb.bin"),
    ]);
    gantry(&[
        "wavelet",
        "compress",
        "merl:pink-felt",
        "--basis",
        &p("cwb.bin"),
        "--out",
        &p("pf.wtree"),
    ]);
    let spec = format!("wavelet:{}", p("pf.wtree"));
    for (s, out) in [(spec.as_str(), "w.exr"), ("merl:pink-felt", "o.exr")] {
        gantry(&[
            "render",
            "sphere",
            s,
            "--size",
            "32",
            "--spp",
            "4",
            "--out",
            &p(out),
        ]);
    }
    let w = render::Image::read_exr(tmp.path().join("w.exr").as_path()).unwrap();
    let o = render::Image::read_exr(tmp.path().join("o.exr").as_path()).unwrap();
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (a, b) in w.pixels().iter().zip(o.pixels()) {
        for c in 0..3 {
            num += (a[c] as f64 - b[c] as f64).powi(2);
            den += (b[c] as f64).powi(2);
        }
    }
    let rel = (num / den).sqrt();
    assert!(den > 0.0 && rel < 0.05, "relative image difference {rel}");
    // A corrupted file is refused.
    let mut bytes = std::fs::read(p("pf.wtree")).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 1;
    std::fs::write(p("bad.wtree"), bytes).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args([
            "render",
            "sphere",
            &format!("wavelet:{}", p("bad.wtree")),
            "--out",
            &p("b.exr"),
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
}
