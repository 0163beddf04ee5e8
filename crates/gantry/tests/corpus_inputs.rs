//! Every command that takes `--corpus` reads the same inputs through one loader: here a Zarr
//! corpus store of four analytic materials (packed from `.binary` files, so that their names
//! are plain names the server lists), given to `model build`, `fit`, `sample model`,
//! `wavelet basis` and `serve`, each of which must see the store's four materials.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Command, Output, Stdio};

fn gantry(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(args)
        .output()
        .expect("gantry runs");
    assert!(
        out.status.success(),
        "gantry {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

const SPECS: [&str; 4] = [
    "ggx:alpha=0.2",
    "ggx:alpha=0.5,kd=0.3",
    "lambert:kd=0.1",
    "ggx:alpha=0.1,kd=0.05",
];

const NAMES: [&str; 4] = ["glossy", "rough", "matte", "sharp"];

fn store(dir: &std::path::Path) -> String {
    let store = dir.join("corpus.zarr").display().to_string();
    let files: Vec<String> = NAMES
        .iter()
        .map(|n| dir.join(format!("{n}.binary")).display().to_string())
        .collect();
    for (spec, file) in SPECS.iter().zip(&files) {
        gantry(&["convert", spec, "--out", file]);
    }
    let mut args = vec!["corpus", "pack"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--out", &store, "--dtype", "f32"]);
    gantry(&args);
    store
}

#[test]
fn a_corpus_store_is_a_corpus_for_every_command() {
    let tmp = tempfile::tempdir().unwrap();
    let store = store(tmp.path());
    let p = |f: &str| tmp.path().join(f).display().to_string();

    // model build: the same eigenvalues from the store as from the specs.
    gantry(&[
        "model",
        "build",
        "--corpus",
        &store,
        "--components",
        "2",
        "--chart-dim",
        "0",
        "--out",
        &p("store.bin"),
    ]);
    let mut args = vec!["model", "build", "--corpus"];
    args.extend(SPECS);
    args.extend(["--components", "2", "--chart-dim", "0", "--out"]);
    let from_specs = p("specs.bin");
    args.push(&from_specs);
    gantry(&args);
    let a = reduce::Model::load(p("store.bin")).unwrap();
    let b = reduce::Model::load(p("specs.bin")).unwrap();
    assert_eq!(a.names, NAMES);
    for (x, y) in a.pca.eigenvalues.iter().zip(&b.pca.eigenvalues) {
        assert!((x - y).abs() <= 1e-4 * y.abs(), "{x} vs {y}");
    }

    // fit: one study row per stored material, named as in the store.
    gantry(&[
        "fit",
        "--corpus",
        &store,
        "--model",
        "lambert",
        "--bins",
        "300",
        "--starts",
        "1",
        "--out",
        &p("study.csv"),
    ]);
    let csv = std::fs::read_to_string(p("study.csv")).unwrap();
    for name in NAMES {
        assert!(csv.contains(name), "{name} missing from the study:\n{csv}");
    }

    // sample model: a training set of the four materials on a sub-grid.
    gantry(&[
        "sample",
        "model",
        "--method",
        "lincomb",
        "--corpus",
        &store,
        "--stride",
        "3",
        "3",
        "6",
        "--out",
        &p("sample.model"),
    ]);
    assert!(std::fs::metadata(p("sample.model")).unwrap().len() > 0);

    // wavelet basis: built from the store's materials.
    gantry(&[
        "wavelet",
        "basis",
        "--corpus",
        &store,
        "--target",
        "0.05",
        "--out",
        &p("b.wtree"),
    ]);
    assert!(std::fs::metadata(p("b.wtree")).unwrap().len() > 0);

    // serve: the store's materials are the library.
    let mut child = Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(["serve", "--corpus", &store, "--port", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .trim()
        .strip_prefix("gantry serve: http://")
        .and_then(|a| a.strip_suffix('/'))
        .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
        .to_string();
    let mut stream = std::net::TcpStream::connect(&addr).unwrap();
    write!(
        stream,
        "GET /api/materials HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut response = String::new();
    stream.read_to_string(&mut response).unwrap();
    child.kill().ok();
    child.wait().ok();
    assert!(response.starts_with("HTTP/1.1 200"), "{response}");
    for name in NAMES {
        assert!(
            response.contains(&format!("\"{name}\"")),
            "{name} missing from {response}"
        );
    }
}
