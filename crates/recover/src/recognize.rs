//! Recognition: which known material explains the photographs best.

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
///
/// Every candidate is pushed through the same precomputed functionals (cheap: one sparse
/// matrix–vector product per image) and scored by the RMS log residual against the photos.
///
/// # Examples
///
/// ```
/// use recover::{rank_tables, FitOptions, LocalModel, Problem};
/// # use recover::{FunctionalOptions, Functionals, Observation, Photo, RecoveryScene};
/// // Four analytic materials on the MERL grid and the 3-component PCA model of them.
/// let specs = ["lambert:kd=0.7", "lambert:kd=0.2/0.3/0.6", "ggx:alpha=0.2,kd=0.1", "ggx:alpha=0.4,kd=0.4"];
/// let tables: Vec<brdf::MerlTable> = specs.iter().map(|s| brdf::load(s).unwrap().tabulate()).collect();
/// let mut corpus = reduce::Corpus::new(reduce::MATERIAL_DIM);
/// for (s, t) in specs.iter().zip(&tables) {
///     corpus.push_values(s.to_string(), &t.values()).unwrap();
/// }
/// let model = reduce::build_model(&corpus, 3, None, None).unwrap();
/// // A 24 × 24 view of a unit sphere under one point light, "photographed" in the third
/// // material: every pixel's radiance is its functional applied to the true table.
/// let light = RecoveryScene::point_light_toml([2.0, 2.0, 4.0], 25.0);
/// let scene = RecoveryScene::unit_sphere(24, &light).unwrap();
/// let functionals = Functionals::build(&scene, &FunctionalOptions::default()).unwrap();
/// let mut pixels = vec![[0.0f32; 3]; 24 * 24];
/// for (&p, v) in functionals.pixels.iter().zip(functionals.apply_table(&tables[2])) {
///     pixels[p as usize] = v.map(|x| x as f32);
/// }
/// let photo = Photo::new(24, 24, pixels).unwrap();
/// let observations = vec![Observation::new(functionals, &photo, None).unwrap()];
/// let local = LocalModel::new(&model, 3, &[&observations[0].functionals]).unwrap();
/// let problem = Problem::new(&local, &observations, &FitOptions::default()).unwrap();
/// let candidates: Vec<(String, &brdf::MerlTable)> =
///     specs.iter().map(|s| s.to_string()).zip(&tables).collect();
/// let ranked = rank_tables(&problem, &candidates);
/// // The material the photograph was made of comes first, with no residual.
/// assert_eq!(ranked[0].name, specs[2]);
/// assert!(ranked[0].error < 1e-6 && ranked[1].error > 0.01);
/// assert!(ranked.windows(2).all(|w| w[0].error <= w[1].error));
/// ```
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
    model: &reduce::Model,
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
