//! Recognition: which known material explains the photographs best.
//!
//! Every candidate is pushed through the same precomputed functionals (cheap: one sparse
//! matrix–vector product per image) and scored by the RMS log residual against the photos.

use brdf::MerlTable;
use rayon::prelude::*;
use serde::Serialize;

use crate::fit::{LocalModel, Problem};

/// One ranked candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ranked {
    /// Candidate name.
    pub name: String,
    /// RMS log residual over all usable pixel channels of all images.
    pub error: f64,
}

fn sort(mut v: Vec<Ranked>) -> Vec<Ranked> {
    v.sort_by(|a, b| a.error.total_cmp(&b.error));
    v
}

fn overall(problem: &Problem, pred: &[Vec<[f64; 3]>]) -> f64 {
    let per = problem.rms_of(pred);
    (per.iter().map(|v| v * v).sum::<f64>() / per.len().max(1) as f64).sqrt()
}

/// Ranks tables (e.g. the corpus itself) by how well each explains the observations.
pub fn rank_tables(problem: &Problem, candidates: &[(String, &MerlTable)]) -> Vec<Ranked> {
    sort(
        candidates
            .par_iter()
            .map(|(name, t)| {
                let pred: Vec<Vec<[f64; 3]>> = problem
                    .observations()
                    .iter()
                    .map(|o| o.functionals.apply_table(t))
                    .collect();
                Ranked {
                    name: name.clone(),
                    error: overall(problem, &pred),
                }
            })
            .collect(),
    )
}

/// Ranks the model's corpus materials, each represented by its first `k` PCA coordinates
/// (what the model file stores), by how well each explains the observations.
pub fn rank_model_corpus(
    problem: &Problem,
    model: &reduce::model::Model,
    local: &LocalModel,
) -> Vec<Ranked> {
    let k = local.k;
    sort(
        (0..model.names.len())
            .map(|i| {
                let x: Vec<f64> = (0..k).map(|j| model.pca.coords[(i, j)]).collect();
                let pred = problem.predict(&x);
                Ranked {
                    name: model.names[i].clone(),
                    error: overall(problem, &pred),
                }
            })
            .collect(),
    )
}

/// MERL materials that are metals by name but whose name does not say so.
pub const METALS: [&str; 10] = [
    "aluminium",
    "brass",
    "chrome",
    "chrome-steel",
    "nickel",
    "ss440",
    "steel",
    "tungsten-carbide",
    "two-layer-gold",
    "two-layer-silver",
];

/// Class of a material name, derived from the MERL naming scheme:
///
/// * a name with a numeric word (the wood stains `cherry-235`, `natural-209`, ...) is `wood`;
/// * the metals of [`METALS`] and names ending in `steel` are `metal`;
/// * otherwise the last `-`-separated word, trailing digits removed
///   (`blue-metallic-paint2` → `paint`, `red-fabric2` → `fabric`, `pink-felt` → `felt`).
///
/// A leading `merl:` or directory is ignored.
pub fn class_of(name: &str) -> &str {
    let base = name.rsplit(['/', ':']).next().unwrap_or(name);
    if base
        .split('-')
        .any(|w| !w.is_empty() && w.chars().all(|c| c.is_ascii_digit()))
    {
        return "wood";
    }
    if METALS.contains(&base) || base.ends_with("steel") {
        return "metal";
    }
    let word = base.rsplit('-').find(|w| !w.is_empty()).unwrap_or(base);
    word.trim_end_matches(|c: char| c.is_ascii_digit())
}
