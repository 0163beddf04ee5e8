//! The model comparison across a corpus.

use crate::data::{FitData, Rows, Subset};
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

/// One material made ready for its fits: the valid bins, the evaluation rows and the fit rows of
/// every objective.
struct Prepared {
    name: String,
    data: FitData,
    eval: EvalRows,
    fit_rows: BTreeMap<Objective, Rows>,
}

impl Prepared {
    fn new(name: &str, table: &MerlTable, options: &StudyOptions) -> Result<Self> {
        let data = FitData::new(table)?;
        let eval = EvalRows::with_subset(&data, options.evaluation)?;
        let mut fit_rows = BTreeMap::new();
        for &o in &options.objectives {
            fit_rows.insert(o, o.rows(&data, options.fit.subset)?);
        }
        Ok(Prepared {
            name: name.to_string(),
            data,
            eval,
            fit_rows,
        })
    }

    fn fit(&self, model: ModelKind, objective: Objective, options: &StudyOptions) -> StudyRow {
        let t = Instant::now();
        let opts = FitOptions {
            objective,
            ..options.fit
        };
        let r = fit_rows(model, &self.data, &self.fit_rows[&objective], &opts);
        let errors = self.eval.errors(&r.model);
        StudyRow {
            material: self.name.clone(),
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
    }
}

/// Every (model, objective) pair of the options, in order.
fn jobs(options: &StudyOptions) -> Vec<(ModelKind, Objective)> {
    options
        .models
        .iter()
        .flat_map(|m| options.objectives.iter().map(move |o| (*m, *o)))
        .collect()
}

/// A rough relative cost of one fit, only to start the longest fits first (measured over the
/// study: HTSG's series and the sphere objective's pixels dominate).
fn expected_cost(model: ModelKind, objective: Objective) -> f64 {
    let per_row = match model {
        ModelKind::Htsg => 12.0,
        _ => 1.0 + model.dimension() as f64 / 6.0,
    };
    let rows = match objective {
        Objective::Sphere => 3.0,
        _ => 1.0,
    };
    per_row * rows
}

/// Fits every model with every objective to one table.
///
/// With [`study_corpus`] this is the model comparison across a corpus: every material × model ×
/// objective, a CSV ([`write_csv`]) and the summary statistics of the docs table (ranking, wins,
/// multi-start effect; [`markdown_summary`]).
pub fn study_material(
    name: &str,
    table: &MerlTable,
    options: &StudyOptions,
) -> Result<Vec<StudyRow>> {
    let prepared = Prepared::new(name, table, options)?;
    Ok(jobs(options)
        .par_iter()
        .map(|&(model, objective)| prepared.fit(model, objective, options))
        .collect())
}

/// Runs [`study_material`] over a corpus: `load(i)` gives the table of material `i` (labelled
/// `labels[i]`). Materials are worked on in groups of twice as many as rayon has threads: a
/// group's tables are decoded in parallel, then all its fits go to the threads longest first
/// (greedy scheduling), so no thread waits on another's last long fit while work remains.
/// The rows come out in corpus, model and objective order, and are the same whatever the
/// thread count (every fit is seeded and independent). `done(k, rows)` is called in corpus
/// order after each material with the number of materials finished and every row so far (for
/// progress and incremental CSV writes); its error, like a load or fit error, stops the study.
///
/// ```no_run
/// use fit::{study_corpus, StudyOptions};
/// let dir = brdf::data_dir().join("nbrdf/merl");
/// let names = brdf::nbrdf::list(&dir)?;
/// let rows = study_corpus(
///     &names,
///     |i| -> Result<_, Box<dyn std::error::Error + Send + Sync>> {
///         Ok(brdf::nbrdf::Nbrdf::load(&dir, &names[i])?.tabulate())
///     },
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
    let group = 2 * rayon::current_num_threads().max(1);
    let pairs = jobs(options);
    let mut rows = Vec::new();
    let mut finished = 0;
    let indices: Vec<usize> = (0..labels.len()).collect();
    for chunk in indices.chunks(group) {
        let prepared = chunk
            .par_iter()
            .map(|&i| {
                let table = load(i)?;
                Ok(Prepared::new(&labels[i], &table, options)?)
            })
            .collect::<std::result::Result<Vec<Prepared>, E>>()?;
        // (material in the group, job index), longest expected fit first.
        let mut order: Vec<(usize, usize)> = (0..prepared.len())
            .flat_map(|m| (0..pairs.len()).map(move |j| (m, j)))
            .collect();
        order.sort_by(|a, b| {
            let (ca, cb) = (
                expected_cost(pairs[a.1].0, pairs[a.1].1),
                expected_cost(pairs[b.1].0, pairs[b.1].1),
            );
            cb.total_cmp(&ca).then(a.cmp(b))
        });
        // par_bridge hands the next job to whichever thread is free: greedy scheduling.
        let mut fitted: Vec<((usize, usize), StudyRow)> = order
            .into_iter()
            .par_bridge()
            .map(|(m, j)| ((m, j), prepared[m].fit(pairs[j].0, pairs[j].1, options)))
            .collect();
        fitted.sort_by_key(|(key, _)| *key);
        let mut fitted = fitted.into_iter().peekable();
        for m in 0..prepared.len() {
            while let Some((_, row)) = fitted.next_if(|((mm, _), _)| *mm == m) {
                rows.push(row);
            }
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
