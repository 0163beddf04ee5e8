//! A reduced fast capture on the simulated rig: planned positions, capture, completion from a
//! small analytic model, files and report, resume and dry run.

use acquire::{CalibrationSource, JobSpec, RunOptions, SimSetup, Station};
use brdf::analytic::Ggx;
use brdf::MerlTable;
use fast_capture::{FastDir, FastError, FastOptions, FastOutcome, PlanOptions};
use std::path::Path;

const SCALE: f64 = 0.1;
/// Not in the corpus: between its roughnesses and colours.
const MATERIAL: &str = "ggx:kd=0.25/0.2/0.1,ks=0.9,alpha=0.17,ior=1.5";

fn model() -> reduce::Model {
    model_in(reduce::Mapping::Log)
}

/// The six corpus materials' tables.
fn corpus() -> reduce::Corpus {
    let mut corpus = reduce::Corpus::new(reduce::MATERIAL_DIM);
    let materials = [
        ([0.1, 0.1, 0.1], 0.05),
        ([0.4, 0.3, 0.1], 0.1),
        ([0.2, 0.2, 0.3], 0.3),
        ([0.05, 0.1, 0.05], 0.2),
        ([0.3, 0.1, 0.1], 0.4),
        ([0.2, 0.3, 0.2], 0.15),
    ];
    for (i, (kd, alpha)) in materials.into_iter().enumerate() {
        let ggx = Ggx {
            kd,
            ks: [0.9; 3],
            alpha,
            ior: 1.5,
        };
        corpus
            .push_values(format!("m{i}"), &MerlTable::tabulate(&ggx).values())
            .unwrap();
    }
    corpus
}

/// A model of the corpus (all five components) in the space of `mapping`.
fn model_in(mapping: reduce::Mapping) -> reduce::Model {
    reduce::build_mapped_model(&corpus(), mapping, 5, None, None).unwrap()
}

fn options(stop_after: Option<usize>, resume: bool) -> FastOptions {
    FastOptions {
        plan: PlanOptions {
            max_positions: 6,
            candidates: 60,
            components: 5,
            ..PlanOptions::default()
        },
        run: RunOptions {
            calibration: CalibrationSource::TrueGeometry,
            stop_after,
            resume,
            ..RunOptions::default()
        },
        dry_run: false,
        ..FastOptions::default()
    }
}

fn run(model: &reduce::Model, options: &FastOptions, dir: &Path) -> FastOutcome {
    let spec = JobSpec::new(MATERIAL, 1);
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(SCALE)).unwrap();
    fast_capture::run(&mut station, &spec, model, options, dir).unwrap()
}

fn read_npy(path: &Path) -> Vec<f32> {
    let a = brdf::npy::read(path).unwrap();
    assert_eq!(a.shape, vec![3, brdf::BINS]);
    a.data
}

#[test]
fn a_material_of_the_span_is_completed_exactly_from_half_its_entries_in_either_mapping() {
    let corpus = corpus();
    let truth: Vec<f64> = corpus
        .row(2)
        .iter()
        .map(|&y| reduce::from_log(y).max(0.0))
        .collect();
    // Every other entry measured; the missing ones negative, as a capture writes them.
    let partial: Vec<f64> = truth
        .iter()
        .enumerate()
        .map(|(e, &v)| if e % 2 == 0 { v } else { -1.0 })
        .collect();
    let partial = MerlTable::from_values(partial).unwrap();
    for mapping in [reduce::Mapping::Log, reduce::Mapping::COSINE] {
        let model = model_in(mapping);
        let done =
            fast_capture::complete(&model, &partial, 5, fast_capture::Residual::Dropped).unwrap();
        assert_eq!(done.measured_entries, brdf::MATERIAL_DIM.div_ceil(2));
        let values = done.table.values();
        let worst = (1..brdf::MATERIAL_DIM)
            .step_by(2)
            .map(|e| (values[e] - truth[e]).abs() / (truth[e] + 1e-3))
            .fold(0.0, f64::max);
        // The material is a corpus point: the mapped table is exactly mean + U x.
        assert!(
            worst < 1e-3,
            "{}: worst relative error {worst}",
            mapping.name()
        );
    }
}

#[test]
fn a_fast_capture_completes_the_table_better_than_the_corpus_mean_and_marks_what_it_measured() {
    for mapping in [reduce::Mapping::Log, reduce::Mapping::COSINE] {
        fast_capture_beats_the_corpus_mean(&model_in(mapping));
    }
}

fn fast_capture_beats_the_corpus_mean(model: &reduce::Model) {
    let model = model.clone();
    let dir = tempfile::tempdir().unwrap();
    let FastOutcome::Finished(report) = run(&model, &options(None, false), dir.path()) else {
        panic!("no stop was asked for");
    };
    let files = FastDir::new(dir.path());

    // The plan is stored and was followed; its clock is the rig's.
    let plan: fast_capture::CapturePlan =
        serde_json::from_slice(&std::fs::read(files.plan()).unwrap()).unwrap();
    assert_eq!(plan.angles_deg, report.angles_deg);
    assert_eq!(report.positions, 6);
    let clock = report.simulated_capture_s.unwrap();
    assert!(
        (clock - plan.predicted_clock_s).abs() < 1e-6 * clock,
        "predicted {} s, rig clock {clock} s",
        plan.predicted_clock_s
    );
    assert!(clock <= plan.options.budget_s);

    // Measured entries are the capture's values, marked 1; the others are marked 0, predicted,
    // and carry an uncertainty.
    let measured = brdf::merl::read(acquire::JobDir::new(files.capture()).table()).unwrap();
    let completed = brdf::merl::read(files.table()).unwrap();
    let flags = read_npy(&files.measured());
    let sd = read_npy(&files.completion_sd());
    let (m, c) = (measured.values(), completed.values());
    let mut n_measured = 0;
    for e in 0..brdf::MATERIAL_DIM {
        if m[e] >= 0.0 {
            n_measured += 1;
            assert_eq!(flags[e], 1.0);
            assert_eq!(sd[e], 0.0);
            assert!((c[e] - m[e]).abs() <= 1e-6 * m[e].max(1e-3), "entry {e}");
        } else {
            assert_eq!(flags[e], 0.0);
            assert!(sd[e] > 0.0 && sd[e].is_finite(), "entry {e}: sd {}", sd[e]);
            assert!(c[e] >= 0.0 && c[e].is_finite());
        }
    }
    assert_eq!(n_measured, report.measured_entries);
    assert!(report.completed_entries > report.measured_entries);

    // Closer to the truth than the corpus mean, over the entries a full capture reaches.
    let truth = report.truth.expect("the simulator knows the truth");
    let mean = MerlTable::from_values(model.synthesize(&[0.0; 5]).unwrap()).unwrap();
    let truth_table = brdf::load(MATERIAL).unwrap().tabulate();
    let mean_scores = fast_capture::scores(&truth_table, &mean);
    assert!(
        truth.fast.median_abs_log < 0.5 * mean_scores.median_abs_log,
        "fast {:?}, corpus mean {mean_scores:?}",
        truth.fast
    );
    assert!(truth.fast.cosine_weighted_relative_rms < mean_scores.cosine_weighted_relative_rms);
}

#[test]
fn an_interrupted_fast_capture_resumes_its_stored_plan_and_ends_with_the_same_table() {
    let model = model();
    let whole = tempfile::tempdir().unwrap();
    let FastOutcome::Finished(_) = run(&model, &options(None, false), whole.path()) else {
        panic!("no stop was asked for");
    };
    let cut = tempfile::tempdir().unwrap();
    let FastOutcome::Stopped { new_positions } = run(&model, &options(Some(2), false), cut.path())
    else {
        panic!("the job was asked to stop");
    };
    assert_eq!(new_positions, 2);
    // A second start without resume is refused; with resume it finishes the same plan.
    let spec = JobSpec::new(MATERIAL, 1);
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(SCALE)).unwrap();
    let again = fast_capture::run(
        &mut station,
        &spec,
        &model,
        &options(None, false),
        cut.path(),
    );
    assert!(
        matches!(again, Err(FastError::InvalidOption(_))),
        "{again:?}"
    );
    let FastOutcome::Finished(_) = run(&model, &options(None, true), cut.path()) else {
        panic!("resumed to the end");
    };
    for f in [
        "brdf.binary",
        "measured.npy",
        "completion_sd.npy",
        "plan.json",
    ] {
        let same = std::fs::read(whole.path().join(f)).unwrap()
            == std::fs::read(cut.path().join(f)).unwrap();
        assert!(same, "{f} differs after a resume");
    }
    // A plan stored for another model is refused on resume.
    let mut other = model.clone();
    other.pca.coords = other.pca.coords.rows(0, 5).into_owned();
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(SCALE)).unwrap();
    let wrong = fast_capture::run(
        &mut station,
        &spec,
        &other,
        &options(None, true),
        cut.path(),
    );
    assert!(
        matches!(wrong, Err(FastError::PlanMismatch { .. })),
        "{wrong:?}"
    );
}

#[test]
fn a_dry_run_plans_within_the_budget_and_writes_nothing() {
    let model = model();
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("job");
    let mut options = options(None, false);
    options.dry_run = true;
    options.plan.budget_s = 60.0;
    options.plan.max_positions = 50;
    let FastOutcome::Planned(plan) = run(&model, &options, &target) else {
        panic!("a dry run plans");
    };
    assert!(!target.exists(), "a dry run wrote {}", target.display());
    assert!(plan.predicted_clock_s <= 60.0 && !plan.angles_deg.is_empty());
    // One more position of the candidates would not have fitted: the budget stopped it.
    assert!(plan.angles_deg.len() < 50);
    assert!(plan.angles_deg.windows(2).all(|w| w[0] < w[1]));
    assert!(plan.exposures_s.iter().all(|&t| t <= 2.0));
    // More positions never predict a larger uncertainty.
    assert!(plan
        .steps
        .windows(2)
        .all(|w| w[1].predicted_log_sd <= w[0].predicted_log_sd + 1e-12));

    // Options out of range are refused with a typed error.
    options.plan.budget_s = f64::NAN;
    let spec = JobSpec::new(MATERIAL, 1);
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(SCALE)).unwrap();
    let bad = fast_capture::run(&mut station, &spec, &model, &options, &target);
    assert!(matches!(bad, Err(FastError::InvalidOption(_))), "{bad:?}");
    options.plan.budget_s = 5.0;
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(SCALE)).unwrap();
    let none_fit = fast_capture::run(&mut station, &spec, &model, &options, &target);
    assert!(
        matches!(none_fit, Err(FastError::InvalidOption(_))),
        "{none_fit:?}"
    );
}
