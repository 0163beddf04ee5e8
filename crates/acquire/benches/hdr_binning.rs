//! HDR + binning of a whole capture at full resolution, timed on the job that ships
//! ([`acquire::run`]): 330 lamp positions of 1300 × 1030 frames, the thesis's 18 exposures each,
//! on the simulated rig with its true geometry.
//!
//! `cargo bench -p acquire --bench hdr_binning [-- POSITIONS [MATERIAL [SCALE [full|adaptive]]]]`
//!
//! The fourth argument picks the exposure strategy ([`acquire::Bracketing`]); the simulated
//! capture clock and the table's error against the truth are printed for comparing them.
//!
//! Each position's log records where its wall-clock time went; the time spent waiting for the
//! devices (here: the simulator rendering the frames, which a real camera does in hardware) is
//! reported apart. The figure to compare with the goal is the processing on the capture's
//! critical path (HDR merge and consistency checks of every position; the HDR write, BRDF
//! samples and checkpoint run on the job's writer thread while the next position is captured,
//! and are printed apart) plus binning; validation and the simulated capture clock are printed
//! next to it.

use acquire::{CalibrationSource, JobSpec, Outcome, PositionLog, RunOptions, SimSetup, Station};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let n: usize = args.first().map_or(Ok(330), |s| s.parse())?;
    let material = args
        .get(1)
        .cloned()
        .unwrap_or_else(|| "merl:blue-acrylic".to_string());
    let scale: f64 = args.get(2).map_or(Ok(1.0), |s| s.parse())?;
    let mut spec = JobSpec::new(&material, n);
    if args.get(3).map(String::as_str) == Some("adaptive") {
        spec.bracketing = acquire::Bracketing::Adaptive;
    }
    let dir = tempfile::tempdir()?;
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(scale))?;
    let info = station.rig.camera.info();
    println!(
        "{material}: {n} positions of {}x{} px, {:?} bracketing, {} threads",
        info.width,
        info.height,
        spec.bracketing,
        rayon::current_num_threads()
    );
    let options = RunOptions {
        calibration: CalibrationSource::TrueGeometry,
        ..RunOptions::default()
    };
    let t0 = Instant::now();
    let Outcome::Finished(done) = acquire::run(&mut station, &spec, &options, dir.path())? else {
        return Err("the job did not finish".into());
    };
    let wall = t0.elapsed().as_secs_f64();
    let logs: Vec<PositionLog> = (0..n)
        .map(|i| {
            let path = acquire::JobDir::new(dir.path()).log(i);
            acquire::read_json(&path)
        })
        .collect::<Result<_, _>>()?;
    let t = |f: fn(&acquire::PositionTimings) -> f64| -> Vec<f64> {
        logs.iter().map(|l| f(&l.timings)).collect()
    };
    let processing: f64 = logs.iter().map(|l| l.timings.processing_s()).sum();
    let devices: f64 = logs.iter().map(|l| l.timings.devices_s).sum();
    let writing: f64 = logs
        .iter()
        .filter(|l| l.timings.background)
        .map(|l| l.timings.writing_s())
        .sum();
    let r = &done.report;
    println!(
        "per position, median ms: merge {:.1}, checks {:.1}, HDR write {:.1}, samples {:.1}, checkpoint {:.1}, processing {:.1}",
        median(t(|t| t.merge_s)) * 1e3,
        median(t(|t| t.checks_s)) * 1e3,
        median(t(|t| t.hdr_write_s)) * 1e3,
        median(t(|t| t.samples_s)) * 1e3,
        median(t(|t| t.checkpoint_s)) * 1e3,
        median(t(|t| t.processing_s())) * 1e3,
    );
    println!(
        "binning: {:.1} M samples in {:.2} s ({} passes), coverage {:.3}; validation {:.2} s",
        r.samples_total as f64 / 1e6,
        r.wall_seconds.binning,
        r.binning_passes,
        r.coverage,
        r.wall_seconds.validation
    );
    println!(
        "HDR + binning, {n} positions: {:.1} s wall (processing {:.1} s + binning {:.1} s); on the writer thread, overlapped with the next capture: {:.1} s; positions stage {:.1} s wall; devices/simulator (not counted): {:.1} s; setup {:.1} s; whole job {:.1} s; simulated capture clock {:.2} h",
        processing + r.wall_seconds.binning,
        processing,
        r.wall_seconds.binning,
        writing,
        r.wall_seconds.capture,
        devices,
        r.wall_seconds.setup,
        wall,
        r.simulated_capture_hours.unwrap_or(f64::NAN)
    );
    if let Some(e) = &r.truth_table_error {
        println!(
            "table vs truth: median |log| {:.4}, p90 {:.4}",
            e.median_abs_log, e.p90_abs_log
        );
    }
    Ok(())
}
