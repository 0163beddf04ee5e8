//! How well a model describes materials it was not built from: leave-one-out over a corpus
//! and scores on a separate set, with the errors a user of the table sees.
//!
//! Each held-out material is projected on the PCA of the others (in the space of a
//! [`Mapping`]) with `k` components, decoded to BRDF values and compared with its own table:
//!
//! * `relative`: `‖y − ŷ‖ / ‖y − ȳ‖` in the thesis's log space (`y = ln(f + ε)`, ȳ the mean of
//!   the training materials), the fraction of its deviation from the mean left unexplained;
//! * `rms_log`: `‖y − ŷ‖ / √D`;
//! * `cosine_rms`: [`brdf::metrics::cosine_weighted_relative_rms`];
//! * `median_abs_log`: [`brdf::metrics::table_error`]'s median |ln(f̂ / f)|.
//!
//! The leave-one-out PCA never forms the `N` models: all of them follow from one Gram matrix of
//! the corpus (the training mean, centred Gram matrix and the held-out material's products
//! with the training materials are sums of its entries), and each reconstruction is one
//! weighted sum of corpus rows.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::corpus::Corpus;
use crate::encode::{least_absolute, robust_sample, Encoder};
use crate::error::{ReduceError, Result};
use crate::gram::{column_means, cross_gram_matrix, gram_matrix};
use crate::mapping::Mapping;
use crate::pca::{sorted_symmetric_eigen, RELATIVE_EIGEN_TOLERANCE};

/// Errors of one material reconstructed by a model built without it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct UnseenError {
    /// The material.
    pub name: String,
    /// Components used (fewer than asked when the training set has lower rank).
    pub k: usize,
    /// `‖y − ŷ‖ / ‖y − ȳ‖` in log space.
    pub relative: f64,
    /// `‖y − ŷ‖ / √D` in log space.
    pub rms_log: f64,
    /// Cosine-weighted relative RMS of the BRDF values (NaN off the full MERL grid).
    pub cosine_rms: f64,
    /// Median |ln(f̂ / f)| over the entries where both are positive (NaN off the full MERL
    /// grid).
    pub median_abs_log: f64,
}

/// Mapped corpus rows and their Gram matrix about the corpus mean.
struct Mapped {
    n: usize,
    dim: usize,
    rows: Vec<f32>,
    centre: Vec<f32>,
    gram: DMatrix<f64>,
    /// Entries the robust encoder fits ([`robust_sample`]; empty for projections).
    sample: Vec<usize>,
    /// The rows at `sample`, `n × |sample|`.
    sample_rows: DMatrix<f64>,
}

/// The PCA of one training set, in terms of its Gram matrix.
struct Fold {
    train: Vec<usize>,
    vecs: DMatrix<f64>,
    vals: Vec<f64>,
    rank: usize,
    p: DVector<f64>,
}

impl Mapped {
    fn new(corpus: &Corpus, mapping: &Mapping, encoder: Encoder) -> Result<Mapped> {
        let (n, dim) = (corpus.len(), corpus.dim());
        let mut rows = corpus.data().to_vec();
        for r in rows.chunks_mut(dim) {
            mapping.from_log_in_place(r)?;
        }
        let centre = column_means(&rows, n, dim)?;
        let gram = gram_matrix(&rows, n, dim, Some(&centre))?;
        let sample = match encoder {
            Encoder::Projection => Vec::new(),
            Encoder::Robust => robust_sample(dim),
        };
        let sample_rows =
            DMatrix::from_fn(n, sample.len(), |j, s| rows[j * dim + sample[s]] as f64);
        Ok(Mapped {
            n,
            dim,
            rows,
            centre,
            gram,
            sample,
            sample_rows,
        })
    }

    /// The PCA of the rows `train` and the products `p` of the vector to encode with its
    /// principal directions (unnormalised); `h[j] = (z_j − c)·(t − c)` with `c` the centre.
    fn fold(&self, train: &[usize], h: &[f64]) -> Result<Fold> {
        let nt = train.len();
        if nt < 2 {
            return Err(ReduceError::NotEnoughData(format!(
                "a model needs at least 2 training materials, got {nt}"
            )));
        }
        let g = |a: usize, b: usize| self.gram[(train[a], train[b])];
        let r: Vec<f64> = (0..nt)
            .map(|a| (0..nt).map(|b| g(a, b)).sum::<f64>() / nt as f64)
            .collect();
        let mm = r.iter().sum::<f64>() / nt as f64;
        let ht: Vec<f64> = train.iter().map(|&j| h[j]).collect();
        let mt = ht.iter().sum::<f64>() / nt as f64;
        let c = DMatrix::from_fn(nt, nt, |a, b| g(a, b) - r[a] - r[b] + mm);
        let p = DVector::from_fn(nt, |a, _| ht[a] - r[a] - mt + mm);
        let (vals, vecs) = sorted_symmetric_eigen(c);
        let tol = vals[0].max(0.0) * RELATIVE_EIGEN_TOLERANCE;
        let rank = vals.iter().take_while(|&&v| v > tol).count();
        Ok(Fold {
            train: train.to_vec(),
            vecs,
            vals,
            rank,
            p,
        })
    }

    /// Coefficients on the first `k` orthonormal directions of `fold` of the vector whose
    /// sampled entries are `t_sample` (used by the robust encoder only).
    fn coefficients(&self, fold: &Fold, k: usize, encoder: Encoder, t_sample: &[f64]) -> Vec<f64> {
        let a0 = DVector::from_fn(k, |c, _| {
            fold.vecs.column(c).dot(&fold.p) / fold.vals[c].sqrt()
        });
        match encoder {
            Encoder::Projection => a0.iter().copied().collect(),
            Encoder::Robust => {
                let rows = &self.sample_rows;
                let ns = self.sample.len();
                let nt = fold.train.len();
                let zbar: Vec<f64> = (0..ns)
                    .map(|s| fold.train.iter().map(|&j| rows[(j, s)]).sum::<f64>() / nt as f64)
                    .collect();
                let x = DMatrix::from_fn(ns, nt, |s, a| rows[(fold.train[a], s)] - zbar[s]);
                let v = DMatrix::from_fn(nt, k, |a, c| fold.vecs[(a, c)] / fold.vals[c].sqrt());
                let u = x * v;
                let t = DVector::from_fn(ns, |s, _| t_sample[s] - zbar[s]);
                least_absolute(&u, &t, a0).iter().copied().collect()
            }
        }
    }

    /// Weights `β` (one per corpus row, 0 outside the fold's training rows) of the
    /// reconstruction `ẑ = Σ_j β_j z_j` with coefficients `a` on the first `a.len()`
    /// orthonormal directions of `fold`.
    fn beta(&self, fold: &Fold, a: &[f64]) -> Vec<f64> {
        let nt = fold.train.len();
        let mut w = vec![0.0; nt];
        for (c, ac) in a.iter().enumerate() {
            let s = ac / fold.vals[c].sqrt();
            for (i, wi) in w.iter_mut().enumerate() {
                *wi += fold.vecs[(i, c)] * s;
            }
        }
        let shift = (1.0 - w.iter().sum::<f64>()) / nt as f64;
        let mut beta = vec![0.0; self.n];
        for (i, &j) in fold.train.iter().enumerate() {
            beta[j] = w[i] + shift;
        }
        beta
    }

    /// `(k used, β)` for each `k` of `ks` (capped at the fold's rank).
    fn weights(
        &self,
        fold: &Fold,
        ks: &[usize],
        encoder: Encoder,
        t_sample: &[f64],
    ) -> Vec<(usize, Vec<f64>)> {
        ks.iter()
            .map(|&k| {
                let k = k.min(fold.rank);
                let a = self.coefficients(fold, k, encoder, t_sample);
                (k, self.beta(fold, &a))
            })
            .collect()
    }

    /// `Σ_j β_j z_j` for several weight vectors at once (one pass over the rows).
    fn combine(&self, betas: &[&[f64]]) -> Vec<Vec<f32>> {
        const CHUNK: usize = 8192;
        let mut out: Vec<Vec<f32>> = vec![vec![0.0; self.dim]; betas.len()];
        let mut slices: Vec<_> = out.iter_mut().map(|o| o.chunks_mut(CHUNK)).collect();
        let chunks: Vec<Vec<&mut [f32]>> = (0..self.dim.div_ceil(CHUNK))
            .map(|_| slices.iter_mut().map(|s| s.next().unwrap()).collect())
            .collect();
        chunks
            .into_par_iter()
            .enumerate()
            .for_each(|(ci, mut outs)| {
                let start = ci * CHUNK;
                let len = outs[0].len();
                let mut acc = vec![0.0f64; len];
                for (o, beta) in outs.iter_mut().zip(betas) {
                    acc.iter_mut().for_each(|a| *a = 0.0);
                    for (j, &b) in beta.iter().enumerate() {
                        if b == 0.0 {
                            continue;
                        }
                        let row = &self.rows[j * self.dim + start..j * self.dim + start + len];
                        for (a, &z) in acc.iter_mut().zip(row) {
                            *a += b * z as f64;
                        }
                    }
                    for (d, a) in o.iter_mut().zip(&acc) {
                        *d = *a as f32;
                    }
                }
            });
        out
    }
}

/// The material being scored: its name, its log vector `y`, the training mean `ybar` (log
/// space) and the mapping its reconstructions are in.
struct ScoreInput<'a> {
    name: &'a str,
    mapping: &'a Mapping,
    y: &'a [f32],
    ybar: &'a [f64],
}

impl Mapped {
    /// Encodes the material on each `k` of `ks` of `fold`, decodes it in one pass over the
    /// rows and scores every reconstruction.
    fn encode_and_score(
        &self,
        fold: &Fold,
        ks: &[usize],
        encoder: Encoder,
        t_sample: &[f64],
        input: &ScoreInput,
    ) -> Result<Vec<UnseenError>> {
        let betas = self.weights(fold, ks, encoder, t_sample);
        let refs: Vec<&[f64]> = betas.iter().map(|(_, b)| b.as_slice()).collect();
        let recs = self.combine(&refs);
        betas
            .iter()
            .zip(&recs)
            .map(|((k, _), zhat)| score(input, *k, zhat))
            .collect()
    }
}

/// Scores one reconstruction (mapped vector `zhat`, `k` components) of `input`.
fn score(input: &ScoreInput, k: usize, zhat: &[f32]) -> Result<UnseenError> {
    let ScoreInput {
        name,
        mapping,
        y,
        ybar,
    } = *input;
    let est = mapping.to_values(zhat)?;
    let (num, den) = y
        .par_iter()
        .zip(&est)
        .zip(ybar)
        .map(|((&y, &f), &m)| {
            let yh = brdf::to_log(f);
            ((yh - y as f64).powi(2), (y as f64 - m).powi(2))
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    let sqrt_d = (y.len() as f64).sqrt();
    let (relative, rms_log) = (num.sqrt() / den.sqrt().max(1e-300), num.sqrt() / sqrt_d);
    let (cosine_rms, median_abs_log) = if y.len() == brdf::MATERIAL_DIM {
        let truth = brdf::MerlTable::from_values(brdf::values_from_log(y))?;
        let est = brdf::MerlTable::from_values(est)?;
        (
            brdf::metrics::cosine_weighted_relative_rms(&truth, &est),
            brdf::metrics::table_error(&est, &truth).median_abs_log,
        )
    } else {
        (f64::NAN, f64::NAN)
    };
    Ok(UnseenError {
        name: name.to_string(),
        k,
        relative,
        rms_log,
        cosine_rms,
        median_abs_log,
    })
}

/// Leave-one-out over a corpus: each material encoded by `encoder` on `k` components (each
/// of `ks`) of the PCA of the other materials in the space of `mapping`, and decoded. Returns, per material in
/// corpus order, one [`UnseenError`] per `k`.
///
/// ```
/// use reduce::{leave_one_out, Corpus, Encoder, Mapping};
///
/// // five materials of 30 values on a plane through the origin: four span it, so each is
/// // rebuilt exactly from the PCA of the others with 2 components
/// let mut corpus = Corpus::new(30);
/// for i in 0..5 {
///     let (a, b) = (1.0 + i as f64, (i * i % 7) as f64);
///     let v: Vec<f64> = (0..30).map(|d| (a * d as f64 + b * (30 - d) as f64) * 1e-3).collect();
///     let y: Vec<f32> = v.iter().map(|&v| v as f32).collect();
///     corpus.push_log(format!("m{i}"), &y).unwrap();
/// }
/// let scores = leave_one_out(&corpus, &Mapping::Log, Encoder::Projection, &[1, 2]).unwrap();
/// assert_eq!(scores.len(), 5);
/// for s in &scores {
///     assert!(s[1].rms_log < 1e-5, "{:?}", s[1]);
///     assert!(s[0].rms_log >= s[1].rms_log);
/// }
/// ```
pub fn leave_one_out(
    corpus: &Corpus,
    mapping: &Mapping,
    encoder: Encoder,
    ks: &[usize],
) -> Result<Vec<Vec<UnseenError>>> {
    leave_one_out_sized(corpus, mapping, encoder, ks, None)
}

/// Seed of the training subsets of [`leave_one_out_sized`] (mixed with the held-out index).
pub const TRAINING_SUBSET_SEED: u64 = 0x7a11_5eed;

/// [`leave_one_out`] with models built from `train_size` of the other materials (a seeded
/// random subset per held-out material; all of them when `None` or not smaller): how the
/// error falls as the corpus grows.
pub fn leave_one_out_sized(
    corpus: &Corpus,
    mapping: &Mapping,
    encoder: Encoder,
    ks: &[usize],
    train_size: Option<usize>,
) -> Result<Vec<Vec<UnseenError>>> {
    use rand::SeedableRng;
    let mapped = Mapped::new(corpus, mapping, encoder)?;
    let (n, dim) = (mapped.n, mapped.dim);
    let sums = column_sums(corpus.data(), n, dim);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut train: Vec<usize> = (0..n).filter(|&j| j != i).collect();
        let subset = train_size.filter(|&m| m < train.len());
        if let Some(m) = subset {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(TRAINING_SUBSET_SEED ^ i as u64);
            let picked = rand::seq::index::sample(&mut rng, train.len(), m);
            let mut sub: Vec<usize> = picked.iter().map(|a| train[a]).collect();
            sub.sort_unstable();
            train = sub;
        }
        let h: Vec<f64> = (0..n).map(|j| mapped.gram[(j, i)]).collect();
        let fold = mapped.fold(&train, &h)?;
        let t_sample: Vec<f64> = mapped.sample_rows.row(i).iter().copied().collect();
        let y = corpus.row(i);
        let ybar: Vec<f64> = if subset.is_some() {
            let mut m = vec![0.0f64; dim];
            for &j in &train {
                m.iter_mut()
                    .zip(corpus.row(j))
                    .for_each(|(a, &v)| *a += v as f64);
            }
            m.iter().map(|v| v / train.len() as f64).collect()
        } else {
            sums.iter()
                .zip(y)
                .map(|(&s, &v)| (s - v as f64) / (n - 1) as f64)
                .collect()
        };
        let scores = ScoreInput {
            name: &corpus.names()[i],
            mapping,
            y,
            ybar: &ybar,
        };
        out.push(mapped.encode_and_score(&fold, ks, encoder, &t_sample, &scores)?);
        tracing::info!(material = %corpus.names()[i], "held out");
    }
    Ok(out)
}

/// Scores materials outside a corpus (`tests`) on the PCA of the whole corpus (`training`)
/// in the space of `mapping`, encoded by `encoder` on `k` components for each of `ks`.
pub fn score_unseen(
    training: &Corpus,
    tests: &Corpus,
    mapping: &Mapping,
    encoder: Encoder,
    ks: &[usize],
) -> Result<Vec<Vec<UnseenError>>> {
    if tests.dim() != training.dim() {
        return Err(ReduceError::Dimension {
            what: "vector length of the materials scored",
            expected: training.dim(),
            got: tests.dim(),
        });
    }
    let mapped = Mapped::new(training, mapping, encoder)?;
    let (n, dim) = (mapped.n, mapped.dim);
    let sums = column_sums(training.data(), n, dim);
    let ybar: Vec<f64> = sums.iter().map(|s| s / n as f64).collect();
    let train: Vec<usize> = (0..n).collect();
    let mut centred = mapped.rows.clone();
    for r in centred.chunks_mut(dim) {
        r.iter_mut().zip(&mapped.centre).for_each(|(v, c)| *v -= c);
    }
    let mut out = Vec::with_capacity(tests.len());
    for (t, name) in tests.names().iter().enumerate() {
        let y = tests.row(t);
        let mut z = y.to_vec();
        mapping.from_log_in_place(&mut z)?;
        let t_sample: Vec<f64> = mapped.sample.iter().map(|&s| z[s] as f64).collect();
        z.iter_mut().zip(&mapped.centre).for_each(|(v, c)| *v -= c);
        let h = cross_gram_matrix(&centred, n, &z, 1, dim)?;
        let h: Vec<f64> = h.column(0).iter().copied().collect();
        let fold = mapped.fold(&train, &h)?;
        let scores = ScoreInput {
            name,
            mapping,
            y,
            ybar: &ybar,
        };
        out.push(mapped.encode_and_score(&fold, ks, encoder, &t_sample, &scores)?);
    }
    Ok(out)
}

fn column_sums(data: &[f32], n: usize, dim: usize) -> Vec<f64> {
    let mut s = vec![0.0f64; dim];
    s.par_chunks_mut(8192).enumerate().for_each(|(c, part)| {
        let start = c * 8192;
        for i in 0..n {
            let row = &data[i * dim + start..i * dim + start + part.len()];
            part.iter_mut().zip(row).for_each(|(a, &v)| *a += v as f64);
        }
    });
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build_model;

    fn corpus(n: usize, dim: usize, seed: u64) -> Corpus {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut c = Corpus::new(dim);
        for i in 0..n {
            let y: Vec<f32> = (0..dim).map(|_| rng.gen_range(-6.0..2.0f32)).collect();
            c.push_log(format!("m{i}"), &y).unwrap();
        }
        c
    }

    /// The Gram-matrix shortcut against models built without each material.
    #[test]
    fn leave_one_out_agrees_with_models_built_without_each_material() {
        let c = corpus(9, 200, 7);
        let ks = [1, 3, 7, 20];
        let loo = leave_one_out(&c, &Mapping::Log, Encoder::Projection, &ks).unwrap();
        for (i, scores) in loo.iter().enumerate() {
            let mut rest = Corpus::new(c.dim());
            for j in (0..c.len()).filter(|&j| j != i) {
                rest.push_log(c.names()[j].clone(), c.row(j)).unwrap();
            }
            let model = build_model(&rest, 20, None, None).unwrap();
            let y = c.row(i);
            for (s, &k) in scores.iter().zip(&ks) {
                assert_eq!(s.k, k.min(7), "rank of 8 centred materials is 7");
                let x = model.pca.project(y, k.min(model.components())).unwrap();
                let rec = model.pca.reconstruct(&x).unwrap();
                let est: Vec<f64> = rec.iter().map(|&v| crate::from_log(v).max(0.0)).collect();
                let num: f64 = est
                    .iter()
                    .zip(y)
                    .map(|(&f, &y)| (brdf::to_log(f) - y as f64).powi(2))
                    .sum();
                let want = (num / y.len() as f64).sqrt();
                assert!(
                    (s.rms_log - want).abs() <= 1e-4 * want.max(1e-3),
                    "material {i}, k {k}: {} vs {want}",
                    s.rms_log
                );
                assert!(s.relative > 0.0 && s.relative <= 1.0 + 1e-6, "{s:?}");
            }
        }
    }

    /// The robust encoder's fit is at least as close in L1 as the projection, over its
    /// sample (here every entry), for a material with a few gross outliers.
    #[test]
    fn robust_coefficients_have_the_smaller_absolute_residual() {
        let mut c = corpus(8, 300, 5);
        let mut y = c.row(3).to_vec();
        for d in [5, 70, 71, 200] {
            y[d] += 8.0;
        }
        c.push_log("outliers", &y).unwrap();
        let m = Mapped::new(&c, &Mapping::Log, Encoder::Robust).unwrap();
        assert_eq!(m.sample.len(), 300);
        let i = 8;
        let train: Vec<usize> = (0..8).collect();
        let h: Vec<f64> = (0..9).map(|j| m.gram[(j, i)]).collect();
        let fold = m.fold(&train, &h).unwrap();
        let t: Vec<f64> = m.sample_rows.row(i).iter().copied().collect();
        let l1 = |enc: Encoder| {
            // all 7 directions: the material is a training one (row 3) plus the outliers
            let a = m.coefficients(&fold, 7, enc, &t);
            let rec = &m.combine(&[&m.beta(&fold, &a)])[0];
            rec.iter()
                .zip(&y)
                .map(|(r, y)| (r - y).abs() as f64)
                .sum::<f64>()
        };
        let (proj, robust) = (l1(Encoder::Projection), l1(Encoder::Robust));
        assert!(robust < 0.8 * proj, "{robust} vs {proj}");
        // what is left is the outliers themselves
        assert!((robust - 32.0).abs() < 0.5, "{robust}");
    }

    /// With a training subset, each held-out material scores as it does on a model built from
    /// the subset alone (here: its score against the subset as an unseen set).
    #[test]
    fn training_subsets_score_as_models_of_the_subset() {
        use rand::SeedableRng;
        let c = corpus(10, 120, 3);
        let ks = [2, 5];
        let loo =
            leave_one_out_sized(&c, &Mapping::Log, Encoder::Projection, &ks, Some(6)).unwrap();
        for (i, scores) in loo.iter().enumerate() {
            let others: Vec<usize> = (0..10).filter(|&j| j != i).collect();
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(TRAINING_SUBSET_SEED ^ i as u64);
            let mut sub: Vec<usize> = rand::seq::index::sample(&mut rng, 9, 6)
                .iter()
                .map(|a| others[a])
                .collect();
            sub.sort_unstable();
            let (mut train, mut test) = (Corpus::new(120), Corpus::new(120));
            for &j in &sub {
                train.push_log(c.names()[j].clone(), c.row(j)).unwrap();
            }
            test.push_log(c.names()[i].clone(), c.row(i)).unwrap();
            let want =
                score_unseen(&train, &test, &Mapping::Log, Encoder::Projection, &ks).unwrap();
            for (a, b) in scores.iter().zip(&want[0]) {
                assert_eq!(a.k, b.k);
                assert!((a.rms_log - b.rms_log).abs() < 1e-5, "{a:?} vs {b:?}");
                assert!((a.relative - b.relative).abs() < 1e-5, "{a:?} vs {b:?}");
            }
        }
        // the subset differs from all the others: the errors grow
        let all = leave_one_out(&c, &Mapping::Log, Encoder::Projection, &ks).unwrap();
        let mean = |r: &[Vec<UnseenError>]| r.iter().map(|s| s[1].rms_log).sum::<f64>();
        assert!(mean(&loo) > mean(&all));
    }

    /// A material outside the corpus scores as the last corpus member does when held out.
    #[test]
    fn unseen_scores_agree_with_leave_one_out() {
        let c = corpus(7, 150, 11);
        let ks = [2, 6];
        let loo = leave_one_out(&c, &Mapping::Log, Encoder::Projection, &ks).unwrap();
        let (mut train, mut test) = (Corpus::new(150), Corpus::new(150));
        for j in 0..6 {
            train.push_log(c.names()[j].clone(), c.row(j)).unwrap();
        }
        test.push_log("m6", c.row(6)).unwrap();
        let unseen = score_unseen(&train, &test, &Mapping::Log, Encoder::Projection, &ks).unwrap();
        for (a, b) in unseen[0].iter().zip(&loo[6]) {
            assert_eq!(a.k, b.k);
            assert!((a.rms_log - b.rms_log).abs() < 1e-5, "{a:?} vs {b:?}");
            assert!((a.relative - b.relative).abs() < 1e-5, "{a:?} vs {b:?}");
        }
        assert!(score_unseen(
            &train,
            &corpus(1, 10, 1),
            &Mapping::Log,
            Encoder::Projection,
            &ks
        )
        .is_err());
        let mut two = Corpus::new(150);
        two.push_log("a", c.row(0)).unwrap();
        assert!(leave_one_out(&two, &Mapping::Log, Encoder::Projection, &ks).is_err());
    }
}
