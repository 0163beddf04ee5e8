//! The measurement job through its library entry point, on the simulated rig at reduced size:
//! checkpoints resume to identical bytes, a resume with other parameters is refused, injected
//! faults are handled and reported as typed events, progress is reported, and the devices path
//! refuses to run without geometry or scale.

use acquire::{
    AcquireError, CalibrationSource, FaultKind, JobSpec, Outcome, Progress, RunOptions, SimSetup,
    Stage, Station,
};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// An analytic material, so that these tests need no shared data.
const MATERIAL: &str = "ggx:alpha=0.25,kd=0.3/0.2/0.1,ks=0.05";

fn spec(positions: usize) -> JobSpec {
    JobSpec::new(MATERIAL, positions)
}

fn setup() -> SimSetup {
    SimSetup::with_scale(0.12)
}

fn options() -> RunOptions {
    RunOptions {
        calibration: CalibrationSource::TrueGeometry,
        ..RunOptions::default()
    }
}

fn run(spec: &JobSpec, options: &RunOptions, dir: &Path) -> acquire::Result<Outcome> {
    run_on(spec, &setup(), options, dir)
}

fn run_on(
    spec: &JobSpec,
    setup: &SimSetup,
    options: &RunOptions,
    dir: &Path,
) -> acquire::Result<Outcome> {
    let mut station = Station::simulated(spec, setup)?;
    acquire::run(&mut station, spec, options, dir)
}

fn finished(o: Outcome) -> Box<acquire::Finished> {
    match o {
        Outcome::Finished(f) => f,
        other => panic!("job did not finish: {other:?}"),
    }
}

#[test]
fn stopped_and_resumed_job_writes_the_same_table_as_an_uninterrupted_one() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = spec(5);
    let straight = tmp.path().join("straight");
    let done = finished(run(&spec, &options(), &straight).unwrap());
    assert_eq!(done.report.positions, 5);
    let reference = std::fs::read(straight.join("brdf.binary")).unwrap();

    let stepped = tmp.path().join("stepped");
    let stop = |k| RunOptions {
        stop_after: Some(k),
        resume: true,
        ..options()
    };
    match run(&spec, &stop(2), &stepped).unwrap() {
        Outcome::Stopped { new_positions } => assert_eq!(new_positions, 2),
        other => panic!("expected a stop, got {other:?}"),
    }
    assert!(!stepped.join("brdf.binary").exists());
    match run(&spec, &stop(1), &stepped).unwrap() {
        Outcome::Stopped { new_positions } => assert_eq!(new_positions, 1),
        other => panic!("expected a stop, got {other:?}"),
    }
    finished(
        run(
            &spec,
            &RunOptions {
                resume: true,
                ..options()
            },
            &stepped,
        )
        .unwrap(),
    );
    assert_eq!(
        std::fs::read(stepped.join("brdf.binary")).unwrap(),
        reference,
        "the resumed job's table differs from the uninterrupted one"
    );
}

#[test]
fn a_second_job_in_the_same_directory_is_refused_and_resume_checks_parameters() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = spec(2);
    finished(run(&spec, &options(), tmp.path()).unwrap());
    let again = run(&spec, &options(), tmp.path()).unwrap_err();
    assert!(
        matches!(again, AcquireError::JobDirectory { .. }),
        "{again}"
    );
    let other = SimSetup { seed: 2, ..setup() };
    let resumed = RunOptions {
        resume: true,
        ..options()
    };
    let err = run_on(&spec, &other, &resumed, tmp.path()).unwrap_err();
    assert!(err.to_string().contains("different parameters"), "{err}");
}

#[test]
fn injected_faults_are_handled_and_reported_as_typed_events() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = spec(6);
    let faulty = SimSetup {
        faults: true,
        seed: 3,
        ..setup()
    };
    let clean = finished(
        run_on(
            &spec,
            &SimSetup {
                faults: false,
                ..faulty
            },
            &options(),
            &tmp.path().join("clean"),
        )
        .unwrap(),
    );
    let done = finished(run_on(&spec, &faulty, &options(), &tmp.path().join("faulty")).unwrap());
    let faults = &done.report.faults;
    assert!(faults.total > 0, "no fault was met");
    assert_eq!(faults.events.len(), faults.total);
    assert_eq!(faults.by_kind.values().sum::<usize>(), faults.total);
    for e in &faults.events {
        assert!(e.position < 6);
        assert!(faults.by_kind.get(&e.event.kind).copied().unwrap_or(0) > 0);
    }
    // Faults cost retries, not accuracy: the faulty job is as accurate as the clean one.
    let (a, b) = (
        done.report
            .truth_table_error
            .as_ref()
            .unwrap()
            .median_abs_log,
        clean
            .report
            .truth_table_error
            .as_ref()
            .unwrap()
            .median_abs_log,
    );
    assert!(a < b * 1.5 + 0.01, "faulty {a} vs clean {b}");
    // The report on disk holds the same typed events.
    let text = std::fs::read_to_string(tmp.path().join("faulty/report.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let kind = v["faults"]["events"][0]["kind"].as_str().unwrap();
    let parsed: FaultKind = serde_json::from_value(serde_json::Value::String(kind.into())).unwrap();
    assert_eq!(parsed, faults.events[0].event.kind);
}

#[test]
fn progress_reports_every_position_then_binning_and_validation() {
    let tmp = tempfile::tempdir().unwrap();
    let seen: Arc<Mutex<Vec<Progress>>> = Arc::default();
    let sink = seen.clone();
    // positions reported done whose seal was not yet on disk at the time
    let unsealed: Arc<Mutex<Vec<usize>>> = Arc::default();
    let unsealed_sink = unsealed.clone();
    let root = tmp.path().to_path_buf();
    let opts = RunOptions {
        progress: Some(Arc::new(move |p: &Progress| {
            if p.stage == Stage::Positions
                && !root
                    .join(format!("positions/{:03}.crc", p.done - 1))
                    .is_file()
            {
                unsealed_sink.lock().unwrap().push(p.done);
            }
            sink.lock().unwrap().push(*p)
        })),
        ..options()
    };
    finished(run(&spec(3), &opts, tmp.path()).unwrap());
    assert!(
        unsealed.lock().unwrap().is_empty(),
        "reported before sealed: {:?}",
        unsealed.lock().unwrap()
    );
    let seen = seen.lock().unwrap();
    let positions: Vec<usize> = seen
        .iter()
        .filter(|p| p.stage == Stage::Positions)
        .map(|p| p.done)
        .collect();
    assert_eq!(positions, vec![1, 2, 3]);
    let last = seen.last().unwrap();
    assert_eq!(
        (last.stage, last.done, last.total),
        (Stage::Validation, 3, 3)
    );
    assert!(seen
        .iter()
        .any(|p| p.stage == Stage::Binning && p.done == 1));
}

#[test]
fn rebin_from_kept_frames_reproduces_the_captured_table() {
    let tmp = tempfile::tempdir().unwrap();
    let mut spec = spec(3);
    spec.keep_frames = true;
    finished(run(&spec, &options(), tmp.path()).unwrap());
    let captured = std::fs::read(tmp.path().join("brdf.binary")).unwrap();
    // Damage the checkpoints: the re-bin re-merges them from the frames.
    std::fs::write(tmp.path().join("positions/001.samples"), b"garbage").unwrap();
    let done = acquire::rebin(tmp.path(), &RunOptions::default()).unwrap();
    assert_eq!(done.report.positions, 3);
    assert_eq!(
        std::fs::read(tmp.path().join("brdf.binary")).unwrap(),
        captured
    );
    // A corrupted frame file is refused with its path, never used.
    let frames = tmp.path().join("frames/002.frames");
    let mut bytes = std::fs::read(&frames).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&frames, bytes).unwrap();
    let err = acquire::rebin(tmp.path(), &RunOptions::default()).unwrap_err();
    assert!(err.to_string().contains("002.frames"), "{err}");
}

#[test]
fn devices_without_geometry_or_scale_are_refused_before_capturing() {
    let tmp = tempfile::tempdir().unwrap();
    let sim = hal_sim::SimRig::from_config(setup().config(MATERIAL)).unwrap();
    let mut station = Station::devices(sim.rig());
    let spec = spec(2);
    let err = acquire::run(&mut station, &spec, &RunOptions::default(), tmp.path()).unwrap_err();
    assert!(err.to_string().contains("calibration"), "{err}");
    assert!(!tmp.path().join("positions/000.samples").exists());
}

#[test]
fn logs_written_before_faults_were_typed_still_load() {
    let old = r#"{"index":4,"angle_deg":2.0,"exposures_s":[0.1],"samples":10,"valid_pixels":9,
        "series_attempts":2,"faults":["frame-dropped: attempt 1: camera dropped frame 7",
        "lamp-flicker: flicker, repeating the series"],"sim_time_s":1.0,"wall_s":0.5}"#;
    let log: acquire::PositionLog = serde_json::from_str(old).unwrap();
    assert_eq!(log.faults.len(), 2);
    assert_eq!(log.faults[0].kind, FaultKind::FrameDropped);
    assert_eq!(log.faults[1].kind, FaultKind::LampFlicker);
    assert_eq!(log.timings, acquire::PositionTimings::default());
}

#[test]
fn invalid_jobs_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    for (bad, setup) in [
        (spec(0), setup()),
        (spec(2), SimSetup::with_scale(0.0)),
        (spec(2), SimSetup::with_scale(1.5)),
    ] {
        let err = run_on(&bad, &setup, &options(), tmp.path()).unwrap_err();
        assert!(matches!(err, AcquireError::InvalidJob(_)), "{err}");
    }
    assert!(!tmp.path().join("job.json").exists());
}

#[test]
fn job_files_of_earlier_versions_still_read() {
    // job.json before the bin assignment was recorded: the reference reader's indexing.
    let old = r#"{"version":1,"backend":"sim","material":"ggx:alpha=0.25","positions":2,
        "scale":0.5,"seed":3,"faults":true,"bracketing":"full","keep_frames":false,
        "angles_deg":[0.0,90.0]}"#;
    let record: acquire::JobRecord = serde_json::from_str(old).unwrap();
    assert_eq!(format!("{:?}", record.bin_assignment), "ReferenceReader");
    assert_eq!(
        SimSetup::of_record(&record),
        Some(SimSetup {
            scale: 0.5,
            seed: 3,
            faults: true
        })
    );
    let spec = record.spec();
    assert_eq!((spec.positions, spec.angles_deg.len()), (2, 2));
    // What a job writes reads back as itself.
    let written = SimSetup::of_record(&record).unwrap().record(&spec);
    let text = serde_json::to_string(&written).unwrap();
    assert_eq!(
        serde_json::from_str::<acquire::JobRecord>(&text).unwrap(),
        record
    );
}

#[test]
fn a_finished_job_resumed_loads_its_results_and_rebin_recomputes_them() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = spec(2);
    let first = finished(run(&spec, &options(), tmp.path()).unwrap());
    let job = acquire::JobDir::new(tmp.path());
    assert!(acquire::JobStage::Binning.checkpoint(&job).exists());
    let report = std::fs::read(job.report()).unwrap();
    let resumed = RunOptions {
        resume: true,
        ..options()
    };
    let again = finished(run(&spec, &resumed, tmp.path()).unwrap());
    // Loaded, not recomputed: the report (with its wall-clock times) is the same bytes.
    assert_eq!(std::fs::read(job.report()).unwrap(), report);
    assert_eq!(again.report.coverage, first.report.coverage);
    assert_eq!(again.report.samples_total, first.report.samples_total);
    let table = std::fs::read(job.table()).unwrap();
    let rebinned = acquire::rebin(tmp.path(), &RunOptions::default()).unwrap();
    assert_eq!(rebinned.report.samples_total, first.report.samples_total);
    assert_eq!(std::fs::read(job.table()).unwrap(), table);
    assert_ne!(
        std::fs::read(job.report()).unwrap(),
        report,
        "rebin reused the report"
    );
}
