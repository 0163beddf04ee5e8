//! The fast capture against the full one and the model's floor, on the simulated rig.
//!
//! ```text
//! cargo run --release -p fast-capture --example study -- MODEL MATERIAL OUT [SCALE] [COUNTS] [CAPS]
//! ```
//!
//! For MATERIAL (a spec; the model should not contain it) it runs, under OUT: a full capture of
//! 330 positions (`full/`, reused when finished), and for each longest exposure of CAPS (seconds,
//! default 2) and each position count of COUNTS (default `5,10,20,40`; fewer when the 600 s
//! budget allows fewer) a capture of the planned positions (`planned-N/`) and, unless
//! `STUDY_NO_EVEN` is set, one of as many evenly spaced positions (`even-N/`); directories of
//! other caps than 2 s end in `-capC`. Each is completed from the model's first 45 components
//! keeping the measured entries, with the misfit dropped ("kept") and spread by pull-push
//! ("pullpush"). Errors against the true table are taken over the entries the full capture
//! measured: median |log| and the cosine-weighted relative RMS, with their ratios to the floor
//! (the true table projected on the same components). One CSV line per table goes to stdout.
//! With `STUDY_WEIGHTING=cosine` the plan weighs entries by their share of the cosine-weighted
//! error (`Weighting::Cosine`; directories `planned-N-capC-cos/`).
//! With `STUDY_HYBRID=S,L` it also merges S planned positions to 2 s with L planned positions to
//! 20 s (two jobs) and completes the merged table ("hybrid-pullpush").

use acquire::{CalibrationSource, JobSpec, Outcome, RunOptions, SimSetup, Station};
use brdf::MerlTable;
use fast_capture::{
    complete, plan_capture, scores, FastOptions, PlanOptions, Residual, Scores, Weighting,
};
use std::path::Path;

type Error = Box<dyn std::error::Error>;

fn capture(
    material: &str,
    angles: &[f64],
    cap: Option<f64>,
    scale: f64,
    dir: &Path,
) -> Result<(MerlTable, f64), Error> {
    let spec = JobSpec {
        positions: angles.len(),
        angles_deg: angles.to_vec(),
        max_exposure_s: cap,
        ..JobSpec::new(material, angles.len())
    };
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(scale))?;
    let options = RunOptions {
        calibration: CalibrationSource::TrueGeometry,
        resume: dir.join("job.json").exists(),
        ..RunOptions::default()
    };
    let Outcome::Finished(done) = acquire::run(&mut station, &spec, &options, dir)? else {
        return Err("the capture did not finish".into());
    };
    let table = brdf::merl::read(acquire::JobDir::new(dir).table())?;
    Ok((table, done.report.simulated_capture_s.unwrap_or(f64::NAN)))
}

fn masked(truth: &MerlTable, reference: &MerlTable) -> Result<MerlTable, Error> {
    let v: Vec<f64> = truth
        .values()
        .iter()
        .zip(reference.values())
        .map(|(&t, r)| if r >= 0.0 { t } else { -1.0 })
        .collect();
    Ok(MerlTable::from_values(v)?)
}

#[allow(clippy::too_many_arguments)]
fn line(
    material: &str,
    kind: &str,
    cap: f64,
    n: usize,
    clock: f64,
    measured: usize,
    s: &Scores,
    ratio: (f64, f64),
) {
    println!(
        "{material},{kind},{cap},{n},{clock:.1},{measured},{:.5},{:.4},{:.3},{:.3}",
        s.median_abs_log, s.cosine_weighted_relative_rms, ratio.0, ratio.1
    );
}

/// The plan of at most `n` positions with exposures to `cap` seconds within `budget` seconds,
/// for the model's first 45 components (or all it has), on the simulated rig at `scale`.
fn plan_of(
    model: &reduce::Model,
    material: &str,
    scale: f64,
    (n, cap, budget): (usize, f64, f64),
    weighting: Weighting,
) -> Result<fast_capture::CapturePlan, Error> {
    let options = FastOptions {
        plan: PlanOptions {
            max_positions: n,
            max_exposure_s: Some(cap),
            components: 45.min(model.pca.components),
            budget_s: budget,
            weighting,
            ..PlanOptions::default()
        },
        run: RunOptions {
            calibration: CalibrationSource::TrueGeometry,
            ..RunOptions::default()
        },
        dry_run: true,
        ..FastOptions::default()
    };
    let spec = JobSpec::new(material, 1);
    let station = Station::simulated(&spec, &SimSetup::with_scale(scale))?;
    Ok(plan_capture(&station, &spec, model, &options)?)
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: study MODEL MATERIAL OUT [SCALE] [COUNTS]".into());
    }
    let model = reduce::Model::load(&args[0])?;
    let material = args[1].as_str();
    let out = Path::new(&args[2]);
    let scale: f64 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(0.5);
    let counts: Vec<usize> = args
        .get(4)
        .map(|s| s.split(',').map(|c| c.parse()).collect::<Result<_, _>>())
        .transpose()?
        .unwrap_or_else(|| vec![5, 10, 20, 40]);
    let k = 45.min(model.pca.components);
    let truth = brdf::load(material)?.tabulate();
    let (full, full_clock) = capture(
        material,
        &gantry_hal::position_angles(330),
        None,
        scale,
        &out.join("full"),
    )?;
    let compared = masked(&truth, &full)?;
    let floor = scores(&compared, &model.reconstruct(&truth, k)?);
    let ratio = |s: &Scores| {
        (
            s.median_abs_log / floor.median_abs_log,
            s.cosine_weighted_relative_rms / floor.cosine_weighted_relative_rms,
        )
    };
    let caps: Vec<f64> = args
        .get(5)
        .map(|s| s.split(',').map(|c| c.parse()).collect::<Result<_, _>>())
        .transpose()?
        .unwrap_or_else(|| vec![fast_capture::DEFAULT_MAX_EXPOSURE_S]);
    let even = std::env::var_os("STUDY_NO_EVEN").is_none();
    let weighting = match std::env::var("STUDY_WEIGHTING").as_deref() {
        Ok("cosine") => Weighting::Cosine,
        _ => Weighting::Uniform,
    };
    // (the study's runs name the weighting explicitly: uniform unless asked)
    println!("material,kind,max_exposure_s,positions,clock_s,measured_entries,median_abs_log,cosine_weighted_relative_rms,median_vs_floor,cosine_vs_floor");
    let measured_full = full.values().iter().filter(|v| **v >= 0.0).count();
    let s = scores(&compared, &full);
    line(
        material,
        "full",
        20.0,
        330,
        full_clock,
        measured_full,
        &s,
        ratio(&s),
    );
    line(material, "floor", 0.0, 0, 0.0, 0, &floor, (1.0, 1.0));
    for &cap in &caps {
        for &n in &counts {
            let plan = plan_of(&model, material, scale, (n, cap, 600.0), weighting)?;
            let n = plan.angles_deg.len();
            eprintln!("{material} cap {cap} planned {n}: {:?}", plan.angles_deg);
            let mut kinds = vec![("planned", plan.angles_deg.clone())];
            if even {
                kinds.push(("even", fast_capture::even_angles(n)));
            }
            for (kind, angles) in kinds {
                let name = if weighting == Weighting::Cosine && kind == "planned" {
                    format!("{kind}-{n}-cap{cap}-cos")
                } else if cap == fast_capture::DEFAULT_MAX_EXPOSURE_S {
                    format!("{kind}-{n}")
                } else {
                    format!("{kind}-{n}-cap{cap}")
                };
                let (measured, clock) =
                    capture(material, &angles, Some(cap), scale, &out.join(name))?;
                for (variant, residual) in [
                    ("kept", Residual::Dropped),
                    ("pullpush", Residual::PullPush),
                ] {
                    let c = complete(&model, &measured, k, residual)?;
                    let sc = scores(&compared, &c.table);
                    line(
                        material,
                        &format!("{kind}-{variant}"),
                        cap,
                        n,
                        clock,
                        c.measured_entries,
                        &sc,
                        ratio(&sc),
                    );
                }
            }
        }
    }
    if let Some(spec) = std::env::var_os("STUDY_HYBRID") {
        // "SHORT,LONG": SHORT planned positions to 2 s and LONG planned positions to 20 s, merged.
        let spec = spec.to_string_lossy().to_string();
        let (short_n, long_n) = spec.split_once(',').ok_or("STUDY_HYBRID=SHORT,LONG")?;
        let (short_n, long_n): (usize, usize) = (short_n.parse()?, long_n.parse()?);
        let mut tables = Vec::new();
        let mut clock = 0.0;
        for (n, cap) in [(short_n, 2.0), (long_n, 20.0)] {
            let plan = plan_of(&model, material, scale, (n, cap, 1e9), weighting)?;
            let name = if cap == 2.0 {
                format!("planned-{n}")
            } else {
                format!("planned-{n}-cap{cap}")
            };
            let (t, c) = capture(
                material,
                &plan.angles_deg,
                Some(cap),
                scale,
                &out.join(name),
            )?;
            tables.push(t);
            clock += c;
        }
        let (a, b) = (tables[0].values(), tables[1].values());
        let merged: Vec<f64> = a
            .iter()
            .zip(&b)
            .map(|(&x, &y)| match (x >= 0.0, y >= 0.0) {
                (true, true) => (x * y).sqrt(),
                (true, false) => x,
                (false, true) => y,
                (false, false) => -1.0,
            })
            .collect();
        let merged = MerlTable::from_values(merged)?;
        let c = complete(&model, &merged, k, Residual::PullPush)?;
        let sc = scores(&compared, &c.table);
        line(
            material,
            "hybrid-pullpush",
            20.0,
            short_n + long_n,
            clock,
            c.measured_entries,
            &sc,
            ratio(&sc),
        );
    }
    Ok(())
}
