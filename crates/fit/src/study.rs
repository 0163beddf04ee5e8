//! The model comparison across a corpus: every material × model × objective, a CSV, and the
//! summary statistics of the docs table (ranking, wins, multi-start effect).

use crate::data::{FitData, Subset};
use crate::error::{FitError, Result};
use crate::model::ModelKind;
use crate::objective::{Errors, EvalRows, Objective};
use crate::solve::{fit_rows, FitOptions};
use brdf::MerlTable;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// What the study fits.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyOptions {
    /// Models to fit.
    pub models: Vec<ModelKind>,
    /// Objectives to minimise.
    pub objectives: Vec<Objective>,
    /// Fit options (the objective field is overridden per fit).
    pub fit: FitOptions,
    /// Bins the reported log and Ngan errors are computed on.
    pub evaluation: Subset,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            models: ModelKind::ALL.to_vec(),
            objectives: Objective::ALL.to_vec(),
            fit: FitOptions {
                subset: Subset::Random {
                    bins: 2000,
                    seed: 7,
                },
                starts: 3,
                patience: 25,
                ..FitOptions::default()
            },
            evaluation: Subset::Random {
                bins: 100_000,
                seed: 11,
            },
        }
    }
}

/// One fit of the study.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StudyRow {
    /// Material name.
    pub material: String,
    /// Model fitted.
    pub model: ModelKind,
    /// Objective minimised.
    pub objective: Objective,
    /// Solver variables.
    pub dim: usize,
    /// Rows fitted.
    pub rows: usize,
    /// Error on the fit rows, in the objective's metric.
    pub fit_error: f64,
    /// Errors on the evaluation bins / every lit pixel in the three metrics.
    pub errors: Errors,
    /// Whether the best start converged.
    pub converged: bool,
    /// Index of the best start.
    pub best_start: usize,
    /// Solver evaluations over all starts.
    pub evaluations: usize,
    /// Wall time of the fit, seconds.
    pub seconds: f64,
    /// Material spec of the fitted model.
    pub spec: String,
}

/// Fits every model with every objective to one table.
pub fn study_material(
    name: &str,
    table: &MerlTable,
    options: &StudyOptions,
) -> Result<Vec<StudyRow>> {
    let data = FitData::new(table)?;
    let eval = EvalRows::with_subset(&data, options.evaluation)?;
    let mut fit_rows_by_objective = BTreeMap::new();
    for &o in &options.objectives {
        fit_rows_by_objective.insert(o, o.rows(&data, options.fit.subset)?);
    }
    let jobs: Vec<(ModelKind, Objective)> = options
        .models
        .iter()
        .flat_map(|m| options.objectives.iter().map(move |o| (*m, *o)))
        .collect();
    let out = jobs
        .par_iter()
        .map(|&(model, objective)| {
            let t = Instant::now();
            let opts = FitOptions {
                objective,
                ..options.fit
            };
            let r = fit_rows(model, &data, &fit_rows_by_objective[&objective], &opts);
            let errors = eval.errors(&r.model);
            StudyRow {
                material: name.to_string(),
                model,
                objective,
                dim: model.dimension(),
                rows: r.rows,
                fit_error: r.fit_error,
                errors,
                converged: r.converged,
                best_start: r.best_start,
                evaluations: r.starts.iter().map(|s| s.evaluations).sum(),
                seconds: t.elapsed().as_secs_f64(),
                spec: r.spec(),
            }
        })
        .collect();
    Ok(out)
}

/// Runs [`study_material`] over a corpus: `load(i)` gives the table of material `i` (labelled
/// `labels[i]`), and the materials are worked on as many at a time as rayon has threads, so that
/// decoding one table and the longest fits of one material overlap with the fits of another.
/// `done(k, rows)` is called in corpus order after each material with the number of materials
/// finished and every row so far (for progress and incremental CSV writes); its error, like a
/// load or fit error, stops the study.
///
/// ```no_run
/// use fit::study::{study_corpus, StudyOptions};
/// let dir = brdf::data_dir().join("nbrdf/merl");
/// let names = brdf::nbrdf::list(&dir)?;
/// let rows = study_corpus(
///     &names,
///     |i| Ok::<_, Box<dyn std::error::Error + Send + Sync>>(brdf::nbrdf::Nbrdf::load(&dir, &names[i])?.tabulate()),
///     &StudyOptions::default(),
///     |k, _| {
///         eprintln!("{k}/{} materials", names.len());
///         Ok(())
///     },
/// )?;
/// # Ok::<(), Box<dyn std::error::Error + Send + Sync>>(())
/// ```
pub fn study_corpus<E, L, D>(
    labels: &[String],
    load: L,
    options: &StudyOptions,
    mut done: D,
) -> std::result::Result<Vec<StudyRow>, E>
where
    E: From<FitError> + Send,
    L: Fn(usize) -> std::result::Result<MerlTable, E> + Sync,
    D: FnMut(usize, &[StudyRow]) -> std::result::Result<(), E>,
{
    let width = rayon::current_num_threads().max(1);
    let mut rows = Vec::new();
    let mut finished = 0;
    let indices: Vec<usize> = (0..labels.len()).collect();
    for chunk in indices.chunks(width) {
        let results: Vec<std::result::Result<Vec<StudyRow>, E>> = chunk
            .par_iter()
            .map(|&i| {
                let table = load(i)?;
                Ok(study_material(&labels[i], &table, options)?)
            })
            .collect();
        for r in results {
            rows.extend(r?);
            finished += 1;
            done(finished, &rows)?;
        }
    }
    Ok(rows)
}

/// The CSV header of [`write_csv`].
pub const CSV_HEADER: &str = "material,model,objective,dim,rows,fit_error,log_error,ngan_error,sphere_error,converged,best_start,evaluations,seconds,spec";

/// Writes the study rows as CSV (atomically).
pub fn write_csv(rows: &[StudyRow], path: &Path) -> Result<()> {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{:.6},{:.6},{:.6},{:.6},{},{},{},{:.3},\"{}\"",
            r.material,
            r.model.name(),
            r.objective.name(),
            r.dim,
            r.rows,
            r.fit_error,
            r.errors.log,
            r.errors.ngan,
            r.errors.sphere,
            r.converged,
            r.best_start,
            r.evaluations,
            r.seconds,
            r.spec
        );
    }
    brdf::write_atomic(path, s.as_bytes()).map_err(|e| FitError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    })
}

fn metric(e: &Errors, o: Objective) -> f64 {
    match o {
        Objective::Log => e.log,
        Objective::Ngan => e.ngan,
        Objective::Sphere => e.sphere,
    }
}

/// Ranking of the models for one objective, each judged in that objective's own metric on
/// every valid bin.
#[derive(Debug, Clone, PartialEq)]
pub struct Ranking {
    /// The objective.
    pub objective: Objective,
    /// (model, mean error, median error, wins) sorted by mean error.
    pub models: Vec<(ModelKind, f64, f64, usize)>,
}

/// Rankings per objective.
pub fn rankings(rows: &[StudyRow]) -> Vec<Ranking> {
    let mut out = Vec::new();
    for o in Objective::ALL {
        let mut by_model: BTreeMap<ModelKind, Vec<f64>> = BTreeMap::new();
        let mut by_material: BTreeMap<&str, (ModelKind, f64)> = BTreeMap::new();
        for r in rows.iter().filter(|r| r.objective == o) {
            let e = metric(&r.errors, o);
            by_model.entry(r.model).or_default().push(e);
            let best = by_material
                .entry(&r.material)
                .or_insert((r.model, f64::INFINITY));
            if e < best.1 {
                *best = (r.model, e);
            }
        }
        if by_model.is_empty() {
            continue;
        }
        let mut models: Vec<(ModelKind, f64, f64, usize)> = by_model
            .into_iter()
            .map(|(m, mut v)| {
                v.sort_by(f64::total_cmp);
                let mean = v.iter().sum::<f64>() / v.len() as f64;
                let median = if v.len() % 2 == 1 {
                    v[v.len() / 2]
                } else {
                    0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2])
                };
                let wins = by_material.values().filter(|(w, _)| *w == m).count();
                (m, mean, median, wins)
            })
            .collect();
        models.sort_by(|a, b| a.1.total_cmp(&b.1));
        out.push(Ranking {
            objective: o,
            models,
        });
    }
    out
}

/// Share of materials on which the best model (for `objective`, judged in its own metric) has
/// a strictly lower error than the one-lobe Lafortune model.
pub fn share_best_beats_lafortune(rows: &[StudyRow], objective: Objective) -> (usize, usize) {
    let mut per: BTreeMap<&str, (f64, f64)> = BTreeMap::new();
    for r in rows.iter().filter(|r| r.objective == objective) {
        let e = metric(&r.errors, objective);
        let x = per
            .entry(&r.material)
            .or_insert((f64::INFINITY, f64::INFINITY));
        if r.model == ModelKind::Lafortune1 {
            x.1 = e;
        } else {
            x.0 = x.0.min(e);
        }
    }
    let valid: Vec<_> = per.values().filter(|(_, l)| l.is_finite()).collect();
    (valid.iter().filter(|(b, l)| b < l).count(), valid.len())
}

/// A markdown summary of the study: rankings per objective, the share of materials where the
/// best model beats Lafortune, how often the best start is not the default one, and convergence.
pub fn markdown_summary(rows: &[StudyRow]) -> String {
    let mut s = String::new();
    for rk in rankings(rows) {
        let _ = writeln!(
            s,
            "\n**Objective `{}`** (error in its own metric)\n\n| model | mean | median | wins |\n|---|---|---|---|",
            rk.objective.name()
        );
        for (m, mean, median, wins) in &rk.models {
            let _ = writeln!(
                s,
                "| {} | {:.2} % | {:.2} % | {} |",
                m.name(),
                100.0 * mean,
                100.0 * median,
                wins
            );
        }
        let (b, n) = share_best_beats_lafortune(rows, rk.objective);
        let _ = writeln!(
            s,
            "\nBest model beats one-lobe Lafortune on {b} of {n} materials."
        );
    }
    let n = rows.len();
    let moved = rows.iter().filter(|r| r.best_start != 0).count();
    let unconv = rows.iter().filter(|r| !r.converged).count();
    let _ = writeln!(
        s,
        "\nBest start differs from the default start in {moved} of {n} fits ({:.1} %); {unconv} fits stopped without convergence (best point kept).",
        100.0 * moved as f64 / n.max(1) as f64
    );
    s
}
