//! Peak memory (VmHWM of `/proc/self/status`) of the two big stages of a measurement:
//!
//! ```text
//! cargo run --release -p acquire --example peak_memory -- binning 80000000 512
//! cargo run --release -p acquire --example peak_memory -- capture 3
//! ```
//!
//! `binning N MIB` writes N uniformly spread BRDF samples as position files (1 M samples each,
//! 8 bytes per sample on disk, in a temporary directory), then bins them with a memory budget
//! of MIB MiB in a fresh process and prints its peak resident memory. `capture P` measures P
//! positions of the full-resolution simulated rig (an analytic material, no shared data) with
//! the default budget and prints the peak.

use acquire::{CalibrationSource, JobSpec, RunOptions, SimSetup, Station};
use binning::{PositionSamples, Sample, SampleFiles};

const KEYS: usize = 3 * brdf::BINS;
use std::path::{Path, PathBuf};

fn vm_hwm_mib() -> f64 {
    brdf::peak_resident_bytes().map_or(f64::NAN, |b| b as f64 / 1048576.0)
}

fn write_samples(dir: &Path, total: u64) -> Vec<PathBuf> {
    let per_file = 1_000_000u64;
    let mut state = 0x5eed_u64;
    let mut paths = Vec::new();
    let mut left = total;
    let mut position = 0u32;
    while left > 0 {
        let n = left.min(per_file);
        let samples = (0..n)
            .map(|_| {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let key = ((state >> 33) % KEYS as u64) as u32;
                Sample {
                    key,
                    value: ((state >> 16) & 0xffff) as f32 / 65536.0,
                }
            })
            .collect();
        let p = dir.join(format!("{position:04}.samples"));
        PositionSamples {
            position,
            angle_deg: position as f64,
            samples,
        }
        .write(&p)
        .expect("writing sample files");
        paths.push(p);
        left -= n;
        position += 1;
    }
    paths
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("binning") => {
            let total: u64 = args.get(1).map_or(Ok(80_000_000), |s| s.parse())?;
            let budget_mib: usize = args.get(2).map_or(Ok(512), |s| s.parse())?;
            let dir = tempfile::tempdir()?;
            let paths = write_samples(dir.path(), total);
            // Bin in a fresh process so that writing the files does not count.
            let out = std::process::Command::new(std::env::current_exe()?)
                .arg("bin-files")
                .arg(budget_mib.to_string())
                .args(&paths)
                .output()?;
            print!("{}", String::from_utf8_lossy(&out.stdout));
            eprint!("{}", String::from_utf8_lossy(&out.stderr));
        }
        Some("bin-files") => {
            let budget_mib: usize = args[1].parse()?;
            let before = vm_hwm_mib();
            let files: Vec<PathBuf> = args[2..].iter().map(PathBuf::from).collect();
            let binned = binning::bin_samples(
                &SampleFiles::new(files),
                &binning::BinningOptions {
                    budget_bytes: budget_mib << 20,
                    ..Default::default()
                },
            )?;
            println!(
                "binning {} samples, budget {budget_mib} MiB: {} passes, peak RSS {:.1} MiB \
                 (at start {before:.1} MiB)",
                binned.total_samples(),
                binned.passes,
                vm_hwm_mib()
            );
        }
        Some("capture") => {
            let positions: usize = args.get(1).map_or(Ok(3), |s| s.parse())?;
            let spec = JobSpec::new("ggx:alpha=0.25,kd=0.3/0.2/0.1,ks=0.05", positions);
            let dir = tempfile::tempdir()?;
            let options = RunOptions {
                calibration: CalibrationSource::TrueGeometry,
                ..RunOptions::default()
            };
            let before = vm_hwm_mib();
            let t = std::time::Instant::now();
            let mut station = Station::simulated(&spec, &SimSetup::default())?;
            acquire::run(&mut station, &spec, &options, dir.path())?;
            println!(
                "full-resolution capture of {positions} positions ({:.0} s), budget {} MiB: \
                 peak RSS {:.1} MiB (at start {before:.1} MiB)",
                t.elapsed().as_secs_f64(),
                options.memory_mb,
                vm_hwm_mib()
            );
        }
        _ => eprintln!("usage: peak_memory binning [SAMPLES [BUDGET_MIB]] | capture [POSITIONS]"),
    }
    Ok(())
}
