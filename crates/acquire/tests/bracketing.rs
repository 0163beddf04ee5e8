//! Adaptive bracketing planned on the pixels lit at each position: the same job with the full
//! ladder and with adaptive bracketing, on the simulated rig at reduced size.

use acquire::{
    Bracketing, CalibrationSource, JobSpec, Outcome, PositionLog, RunOptions, SimSetup, Station,
};

/// An analytic material, so that the test needs no shared data.
const MATERIAL: &str = "ggx:alpha=0.25,kd=0.3/0.2/0.1,ks=0.05";

fn run(
    bracketing: Bracketing,
    dir: &std::path::Path,
) -> (Box<acquire::Finished>, Vec<PositionLog>) {
    let mut spec = JobSpec::new(MATERIAL, 24);
    spec.bracketing = bracketing;
    let options = RunOptions {
        calibration: CalibrationSource::TrueGeometry,
        ..RunOptions::default()
    };
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(0.12)).unwrap();
    let Outcome::Finished(done) = acquire::run(&mut station, &spec, &options, dir).unwrap() else {
        panic!("the job did not finish");
    };
    let logs = (0..24)
        .map(|i| acquire::read_json(&acquire::JobDir::new(dir).log(i)).unwrap())
        .collect();
    (done, logs)
}

#[test]
fn adaptive_bracketing_shortens_the_clock_and_keeps_the_table() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (full, full_logs) = run(Bracketing::Full, a.path());
    let (adaptive, adaptive_logs) = run(Bracketing::Adaptive, b.path());
    let ladder = hdr::thesis_ladder();
    // The first position has no previous image and takes the full ladder; every series is a
    // subset of the ladder.
    assert_eq!(adaptive_logs[0].exposures_s, ladder);
    for l in &adaptive_logs[1..] {
        assert!(l.exposures_s.iter().all(|t| ladder.contains(t)), "{l:?}");
    }
    let shortened = adaptive_logs
        .iter()
        .filter(|l| l.exposures_s.len() < ladder.len())
        .count();
    assert!(
        shortened > 0,
        "no adaptive series was shorter than the ladder"
    );
    assert!(full_logs.iter().all(|l| l.exposures_s == ladder));
    let hours = |d: &acquire::Finished| d.report.simulated_capture_hours.unwrap();
    assert!(
        hours(&adaptive) < 0.95 * hours(&full),
        "{} vs {} h",
        hours(&adaptive),
        hours(&full)
    );
    let err = |d: &acquire::Finished| d.report.truth_table_error.as_ref().unwrap().median_abs_log;
    assert!(
        err(&adaptive) <= err(&full) + 0.003,
        "median |log| error {} (adaptive) vs {} (full)",
        err(&adaptive),
        err(&full)
    );
}
