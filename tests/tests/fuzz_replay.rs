//! Every committed fuzz input, replayed on the stable toolchain: the seeds (`fuzz/seeds/TARGET`)
//! and the corpora the campaigns kept (`fuzz/corpus/TARGET`, minimized), through the very
//! functions the libFuzzer binaries call (`fuzz/src/lib.rs`, included here). An input that
//! makes a target panic, an assertion of the target included, fails the test with its path.
//! The nightly sanitizer build stays for the long runs (`fuzz/campaign.py`, `fuzz/run.sh`).

#[allow(dead_code)]
#[path = "../../fuzz/src/lib.rs"]
mod fuzz_targets;

use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
}

/// The repository's own files that seed `target` (`fuzz/repo-seeds.txt`).
fn repo_seeds(target: &str) -> Vec<PathBuf> {
    let list = std::fs::read_to_string(fuzz_dir().join("repo-seeds.txt")).expect("repo-seeds.txt");
    list.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .filter_map(|l| l.split_once(' '))
        .filter(|(t, _)| *t == target)
        .map(|(_, p)| fuzz_dir().join("..").join(p.trim()))
        .collect()
}

/// The files of `fuzz/KIND/TARGET` (`repo` for the repository's own seeds), sorted; none when
/// the folder does not exist.
fn inputs(kind: &str, target: &str) -> Vec<PathBuf> {
    if kind == "repo" {
        return repo_seeds(target);
    }
    let dir = fuzz_dir().join(kind).join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

#[test]
fn every_target_has_seeds_and_every_seed_folder_a_target() {
    let names: Vec<&str> = fuzz_targets::TARGETS.iter().map(|(n, _)| *n).collect();
    for name in &names {
        assert!(
            !inputs("seeds", name).is_empty() || !inputs("repo", name).is_empty(),
            "fuzz target {name} has no seeds in fuzz/seeds/{name} nor fuzz/repo-seeds.txt"
        );
        for p in inputs("repo", name) {
            assert!(
                p.is_file(),
                "{}: a seed of {name} that does not exist",
                p.display()
            );
        }
    }
    for kind in ["seeds", "corpus"] {
        let Ok(rd) = std::fs::read_dir(fuzz_dir().join(kind)) else {
            continue;
        };
        for e in rd.flatten() {
            let folder = e.file_name().to_string_lossy().into_owned();
            if e.path().is_dir() && folder != "logs" {
                assert!(
                    names.contains(&folder.as_str()),
                    "fuzz/{kind}/{folder} belongs to no target of fuzz/src/lib.rs"
                );
            }
        }
    }
    // The libFuzzer binaries and the table agree.
    let bins: Vec<String> = std::fs::read_dir(fuzz_dir().join("fuzz_targets"))
        .expect("fuzz/fuzz_targets")
        .flatten()
        .filter_map(|e| {
            e.file_name()
                .to_string_lossy()
                .strip_suffix(".rs")
                .map(str::to_owned)
        })
        .collect();
    assert_eq!(
        bins.len(),
        names.len(),
        "binaries {bins:?} vs targets {names:?}"
    );
    for b in &bins {
        assert!(names.contains(&b.as_str()), "binary {b} is not in TARGETS");
    }
}

#[test]
fn every_committed_fuzz_input_replays_without_a_panic() {
    let mut failures = Vec::new();
    let mut total = 0;
    for (name, body) in fuzz_targets::TARGETS {
        let files: Vec<PathBuf> = ["seeds", "repo", "corpus"]
            .iter()
            .flat_map(|kind| inputs(kind, name))
            .collect();
        for path in &files {
            let bytes = std::fs::read(path).expect("a fuzz input");
            if std::panic::catch_unwind(|| body(&bytes)).is_err() {
                failures.push(path.display().to_string());
            }
        }
        eprintln!("{name}: {} inputs", files.len());
        total += files.len();
    }
    eprintln!("{total} inputs replayed");
    assert!(failures.is_empty(), "fuzz inputs that panic: {failures:#?}");
}
