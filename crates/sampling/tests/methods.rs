mod common;

use sampling::metrics::log_rms_relative;
use sampling::LogPcaModel;
use sampling::{eigenvalue_ratio, row_matrix, RowWeights, SearchBasis, SwapSearch};
use sampling::{measurable, row_of, to_log};
use sampling::{measure_plan, GridTable, Measurements, SamplePoint};
use sampling::{plan, reconstruct, uniform_plan, Method, Model, PlanOptions};
use sampling::{pull_push, pull_push_channel, Domain};

#[test]
fn swap_search_lowers_the_eigenvalue_ratio_it_reports() {
    let (training, _) = common::corpus(common::small_grid());
    for basis in [SearchBasis::Materials, SearchBasis::Whitened] {
        for n in [6, 40] {
            let sel = sampling::select_rows(
                &training,
                n,
                SwapSearch {
                    proposals: 300,
                    seed: 5,
                    basis,
                },
            )
            .unwrap();
            assert_eq!(sel.rows.len(), n);
            let mut uniq = sel.rows.clone();
            uniq.sort_unstable();
            uniq.dedup();
            assert_eq!(uniq.len(), n, "rows are distinct ({basis:?})");
            assert!(sel.final_ratio <= sel.initial_ratio);
            assert!(sel.accepted > 0, "{basis:?} n = {n}");
            let g = training.grid;
            assert!(sel.rows.iter().all(|&r| measurable(&g, r % g.len())));
            if basis == SearchBasis::Materials {
                // The incrementally updated ratio equals one computed from scratch.
                let fresh = eigenvalue_ratio(&row_matrix(&training, &sel.rows));
                assert!(
                    (fresh / sel.final_ratio - 1.0).abs() < 1e-6,
                    "{fresh} vs {}",
                    sel.final_ratio
                );
            }
        }
    }
}

#[test]
fn whitened_search_conditions_the_fit_better_than_the_material_basis() {
    // The ratio in whitened coordinates measures how far the subset's Gram matrix is from the
    // corpus's own; a subset with a small whitened ratio keeps every direction of the corpus
    // well determined. Compare both selections by that common yardstick: the whitened ratio
    // computed here independently, from the corpus Gram matrix over all measurable rows.
    let (training, _) = common::corpus(common::small_grid());
    let g = training.grid;
    let all: Vec<usize> = (0..training.dim())
        .filter(|&r| measurable(&g, r % g.len()))
        .collect();
    let y = row_matrix(&training, &all);
    let e = (y.transpose() * &y).symmetric_eigen();
    let w =
        &e.eigenvectors * nalgebra::DMatrix::from_diagonal(&e.eigenvalues.map(|l| 1.0 / l.sqrt()));
    let whitened_ratio = |rows: &[usize]| eigenvalue_ratio(&(row_matrix(&training, rows) * &w));
    let pick = |basis| {
        sampling::select_rows(
            &training,
            48,
            SwapSearch {
                proposals: 600,
                seed: 3,
                basis,
            },
        )
        .unwrap()
    };
    let whitened = pick(SearchBasis::Whitened);
    let seed = pick(SearchBasis::Materials);
    let (rw, rs) = (whitened_ratio(&whitened.rows), whitened_ratio(&seed.rows));
    assert!(
        (rw / whitened.final_ratio - 1.0).abs() < 1e-6,
        "reported {} vs independent {rw}",
        whitened.final_ratio
    );
    assert!(
        rw < rs,
        "whitened search {rw} vs material-basis search {rs}"
    );
}

#[test]
fn relative_equations_weigh_each_row_by_its_corpus_mean() {
    let (training, _) = common::corpus(common::small_grid());
    let RowWeights::PerRow(w) = RowWeights::relative(&training) else {
        panic!("relative weights are per row")
    };
    assert_eq!(w.len(), training.dim());
    for r in [0, 17, training.dim() / 2, training.dim() - 1] {
        let mean = (0..training.len())
            .map(|m| f64::from(training.material(m)[r]).max(0.0))
            .sum::<f64>()
            / training.len() as f64;
        assert!((w[r] * (mean + 1e-3) - 1.0).abs() < 1e-9, "row {r}");
    }
    // Bad weights are refused by both the search and the fit.
    let search = SwapSearch::default();
    let short = RowWeights::PerRow(vec![1.0; 5]);
    assert!(sampling::select_rows_weighted(&training, 10, search, &short).is_err());
    let mut nan = w.clone();
    nan[3] = f64::NAN;
    let nan = RowWeights::PerRow(nan);
    assert!(sampling::select_rows_weighted(&training, 10, search, &nan).is_err());
    assert!(sampling::fit_coefficients_weighted(&training, &[0, 1], &[0.1, 0.2], &nan).is_err());
}

#[test]
fn lincomb_recovers_an_exact_linear_combination() {
    let grid = common::small_grid();
    let (training, tables) = common::corpus(grid);
    let weights = [0.3, 0.0, 0.5, 0.0, 0.0, 0.2, 0.0, 0.0, 0.0, 0.0, 0.4, 0.0];
    let mut truth = vec![0.0; training.dim()];
    for (w, t) in weights.iter().zip(&tables) {
        for (o, v) in truth.iter_mut().zip(&t.values) {
            *o += w * v;
        }
    }
    let truth = GridTable::new(grid, truth).unwrap();
    let model = Model::LinComb(training.clone());
    for name in ["lincomb", "lincomb-whitened", "lincomb-relative"] {
        let method: Method = name.parse().unwrap();
        let Method::LinComb(options) = method else {
            panic!("{name} is a linear combination")
        };
        let p = plan(method, 60, &model, PlanOptions::default()).unwrap();
        let rows: Vec<usize> = p
            .rows(&grid)
            .iter()
            .map(|&(q, c)| row_of(&grid, q, c))
            .collect();
        let b: Vec<f64> = rows.iter().map(|&r| truth.values[r]).collect();
        let c =
            sampling::fit_coefficients_weighted(&training, &rows, &b, &options.weights(&training))
                .unwrap();
        // The training set holds f32 values (relative rounding 6·10⁻⁸), which the conditioning
        // of the 60 rows amplifies.
        for (got, want) in c.iter().zip(weights) {
            assert!((got - want).abs() < 1e-5, "{name}: {got} vs {want}");
        }
        // Through the public plan → measure → reconstruct path with a noiseless measurement
        // of a BRDF that is itself a table.
        let m = Measurements::new(p.points.clone(), b).unwrap();
        let rec = reconstruct(method, &m, &model).unwrap();
        assert!(log_rms_relative(&truth, &rec).unwrap() < 1e-6, "{name}");
    }
}

#[test]
fn log_pca_reconstructs_a_material_in_its_span() {
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    let model = LogPcaModel::fit(&training, 6, 0.0).unwrap();
    // A material exactly in the model: mean + U a for a plausible a.
    let a: Vec<f64> = model
        .prior_variance
        .iter()
        .enumerate()
        .map(|(j, v)| v.sqrt() * if j % 2 == 0 { 0.7 } else { -0.4 })
        .collect();
    let truth = model.reconstruct(&a).unwrap();
    let (rows, traces) = model.select_rows(24).unwrap();
    assert!(
        traces.windows(2).all(|w| w[1] <= w[0] + 1e-15),
        "posterior trace decreases"
    );
    let b: Vec<f64> = rows.iter().map(|&r| truth.values[r]).collect();
    let est = model.fit_coefficients(&rows, &b).unwrap();
    for (e, t) in est.iter().zip(&a) {
        assert!(
            (e - t).abs() < 0.02 * model.prior_variance[0].sqrt(),
            "{e} vs {t}"
        );
    }
    let rec = model.reconstruct(&est).unwrap();
    assert!(log_rms_relative(&truth, &rec).unwrap() < 0.01);
}

#[test]
fn optimised_rows_beat_random_rows_on_materials_drawn_from_the_model() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    let pca = LogPcaModel::fit(&training, 6, 0.0).unwrap();
    let model = Model::LogPca(pca.clone());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let n = 8;
    let p_opt = plan(Method::Pca, n, &model, PlanOptions::default()).unwrap();
    let randoms: Vec<_> = (0..6).map(|s| uniform_plan(&grid, n, s).unwrap()).collect();
    let (mut e_opt, mut e_rand) = (0.0, 0.0);
    for _ in 0..10 {
        let a: Vec<f64> = pca
            .prior_variance
            .iter()
            .map(|v| {
                let z: f64 = StandardNormal.sample(&mut rng);
                v.sqrt() * z
            })
            .collect();
        let truth = pca.reconstruct(&a).unwrap();
        let measure = |p: &sampling::Plan| measure_plan(p, &truth, 0.0, 0).unwrap();
        let err = |p: &sampling::Plan| {
            log_rms_relative(
                &truth,
                &reconstruct(Method::Pca, &measure(p), &model).unwrap(),
            )
            .unwrap()
        };
        e_opt += err(&p_opt);
        e_rand += randoms.iter().map(err).sum::<f64>() / randoms.len() as f64;
    }
    assert!(e_opt < 0.8 * e_rand, "optimised {e_opt} vs random {e_rand}");
}

#[test]
fn pull_push_keeps_samples_and_fills_constants() {
    let grid = common::small_grid();
    let n = grid.len();
    // Every point sampled: output = input.
    let full: Vec<(usize, f64)> = (0..n).map(|p| (p, (p as f64 * 0.37).sin())).collect();
    let out = pull_push_channel(&grid, &full).unwrap();
    for (o, (_, v)) in out.iter().zip(&full) {
        assert!((o - v).abs() < 1e-12);
    }
    // Sparse samples of a constant: constant everywhere.
    let sparse: Vec<(usize, f64)> = (0..n).step_by(37).map(|p| (p, 2.5)).collect();
    let out = pull_push_channel(&grid, &sparse).unwrap();
    assert!(out.iter().all(|v| (v - 2.5).abs() < 1e-12));
    // Measured samples stay where they are.
    let mixed: Vec<(usize, f64)> = (0..n).step_by(11).map(|p| (p, p as f64)).collect();
    let out = pull_push_channel(&grid, &mixed).unwrap();
    for (p, v) in &mixed {
        assert!((out[*p] - v).abs() < 1e-9);
    }
    assert!(pull_push_channel(&grid, &[]).is_err());
    assert!(pull_push_channel(&grid, &[(n, 1.0)]).is_err());
}

#[test]
fn pull_push_error_falls_with_sample_density() {
    let grid = common::small_grid();
    let (_, tables) = common::corpus(grid);
    let truth = &tables[1]; // Blinn-Phong, smooth lobe
    let mut last = f64::INFINITY;
    for n in [300, 1500, 6000] {
        let p = uniform_plan(&grid, n, 2).unwrap();
        let m = measure_plan(&p, truth, 0.0, 0).unwrap();
        let samples = m.grid_samples(&grid);
        let rec = pull_push(&grid, &samples, Domain::Log).unwrap();
        let e = log_rms_relative(truth, &rec).unwrap();
        assert!(e < last, "n = {n}: {e} ≥ {last}");
        last = e;
    }
    assert!(last < 0.05, "{last}");
}

#[test]
fn methods_reject_mismatched_models_and_bad_input() {
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    let model = Model::LinComb(training);
    assert!(plan(Method::Pca, 5, &model, PlanOptions::default()).is_err());
    assert!(plan(
        Method::LinComb(Default::default()),
        0,
        &model,
        PlanOptions::default()
    )
    .is_err());
    assert!("wavelets".parse::<Method>().is_err());
    assert_eq!("pca".parse::<Method>().unwrap(), Method::Pca);
    let m = Measurements::new(
        vec![SamplePoint {
            theta_h: 0.1,
            theta_d: 0.1,
            phi_d: 0.1,
            channel: 0,
        }],
        vec![1.0],
    )
    .unwrap();
    assert!(reconstruct(Method::Pca, &m, &model).is_err());
    assert!(Measurements::new(m.points.clone(), vec![f64::NAN]).is_err());
    assert!(Measurements::new(m.points.clone(), vec![]).is_err());
    assert!(to_log(-1.0).is_finite());
}

#[test]
fn model_files_round_trip_and_reject_corruption() {
    use sampling::{from_bytes, load, save, to_bytes};
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    let pca = LogPcaModel::fit(&training, 4, 0.02).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for model in [
        Model::LinComb(training.clone()),
        Model::LogPca(pca),
        Model::Grid(grid),
    ] {
        let p = dir.path().join("m.bin");
        save(&model, &p).unwrap();
        let back = load(&p).unwrap();
        assert_eq!(to_bytes(&back), to_bytes(&model));
        let bytes = to_bytes(&model);
        assert!(from_bytes(&bytes[..bytes.len() - 3]).is_err(), "truncated");
        let mut extra = bytes.clone();
        extra.push(0);
        assert!(from_bytes(&extra).is_err(), "trailing");
        let mut bad = bytes.clone();
        bad[0] = b'X';
        assert!(from_bytes(&bad).is_err(), "magic");
    }
    // A NaN inside a model is refused.
    let mut bytes = to_bytes(&Model::LinComb(training));
    let at = bytes.len() - 7 - 8;
    bytes[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    assert!(from_bytes(&bytes).is_err());
}

#[test]
fn build_model_gives_each_method_its_model() {
    use sampling::build_model;
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    for (method, kind) in [
        (Method::LinComb(Default::default()), 0),
        (Method::Pca, 1),
        (Method::PullPush, 2),
        (Method::Wavelet, 3),
    ] {
        let model = build_model(method, training.clone(), 0.0).unwrap();
        let got = match model {
            Model::LinComb(_) => 0,
            Model::LogPca(_) => 1,
            Model::Grid(_) => 2,
            Model::Wavelet(_) => 3,
        };
        assert_eq!(got, kind);
        assert_eq!(model.grid(), grid);
        // Plan → measure (a training material) → reconstruct runs end to end.
        let n = if method == Method::Wavelet { 0 } else { 30 };
        let p = plan(method, n, &model, PlanOptions::default()).unwrap();
        let m = measure_plan(&p, &common::materials()[2], 0.0, 0).unwrap();
        let rec = reconstruct(method, &m, &model).unwrap();
        assert_eq!(rec.grid, grid);
    }
}

#[test]
fn pull_push_interpolates_a_smooth_field_between_sparse_samples() {
    use rand::{Rng, SeedableRng};
    use sampling::pull_push_channel_with_gain;
    let grid = common::small_grid();
    let (na, nb, nc) = grid.shape();
    let field = |p: usize| {
        let (a, b, c) = grid.coords(p);
        1.0 + a as f64 / na as f64 + 0.5 * b as f64 / nb as f64 + 0.25 * c as f64 / nc as f64
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let samples: Vec<(usize, f64)> = (0..grid.len())
        .filter(|_| rng.gen_bool(0.3))
        .map(|p| (p, field(p)))
        .collect();
    let rms = |gain: f64| {
        let out = pull_push_channel_with_gain(&grid, &samples, gain).unwrap();
        let s: f64 = (0..grid.len()).map(|p| (out[p] - field(p)).powi(2)).sum();
        (s / grid.len() as f64).sqrt()
    };
    let (default, literal) = (rms(8.0), rms(1.0));
    // The field spans 1.75 in value; filled points must stay close to it.
    assert!(default < 0.03, "rms {default}");
    assert!(
        literal > 2.0 * default,
        "literal {literal} vs default {default}"
    );
    assert!(pull_push_channel_with_gain(&grid, &samples, 0.0).is_err());
}

/// Brute-force greedy A-optimal selection: recomputes `P u` for every row at every step.
fn brute_force_rows(model: &LogPcaModel, n: usize) -> Vec<usize> {
    use nalgebra::{DMatrix, DVector};
    let k = model.components;
    let mut p = DMatrix::from_diagonal(&DVector::from_column_slice(&model.prior_variance));
    let measurable = sampling::measurable_rows(&model.grid);
    let mut chosen = vec![false; model.dim()];
    let mut rows = Vec::new();
    for _ in 0..n {
        let mut best = (f64::NEG_INFINITY, usize::MAX);
        for r in 0..model.dim() {
            if chosen[r] || !measurable[r] {
                continue;
            }
            let u = DVector::from_column_slice(&model.basis[r * k..(r + 1) * k]);
            let pu = &p * &u;
            let var = model.residual_variance[r] + model.noise_variance + 1e-12;
            let gain = pu.norm_squared() / (var + u.dot(&pu));
            if gain > best.0 {
                best = (gain, r);
            }
        }
        let r = best.1;
        let u = DVector::from_column_slice(&model.basis[r * k..(r + 1) * k]);
        let pu = &p * &u;
        let var = model.residual_variance[r] + model.noise_variance + 1e-12;
        p -= &pu * pu.transpose() / (var + u.dot(&pu));
        chosen[r] = true;
        rows.push(r);
    }
    rows
}

#[test]
fn incremental_row_selection_matches_brute_force_and_is_nested() {
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    let model = LogPcaModel::fit(&training, 6, 0.01).unwrap();
    let (rows, _) = model.select_rows(15).unwrap();
    assert_eq!(rows, brute_force_rows(&model, 15));
    let (short, _) = model.select_rows(5).unwrap();
    assert_eq!(short[..], rows[..5]);
}

#[test]
fn blocked_pca_fit_agrees_with_a_dense_computation() {
    use nalgebra::DMatrix;
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    let k = 5;
    let model = LogPcaModel::fit(&training, k, 0.0).unwrap();
    let (n, d) = (training.len(), training.dim());
    // Dense: centred log matrix, its SVD, the top-k right singular vectors.
    let logs = DMatrix::from_fn(n, d, |m, r| {
        sampling::to_log(f64::from(training.values[m * d + r]))
    });
    let mean: Vec<f64> = (0..d).map(|r| logs.column(r).mean()).collect();
    let c = DMatrix::from_fn(n, d, |m, r| logs[(m, r)] - mean[r]);
    for (a, b) in model.mean.iter().zip(&mean) {
        assert!((a - b).abs() < 1e-9);
    }
    let svd = c.clone().svd(false, true);
    let vt = svd.v_t.unwrap();
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
    for j in 0..k {
        let s = svd.singular_values[order[j]];
        assert!((model.prior_variance[j] - s * s / n as f64).abs() < 1e-9 * s * s);
        // Same direction up to sign.
        let dot: f64 = (0..d)
            .map(|r| model.basis[r * k + j] * vt[(order[j], r)])
            .sum();
        assert!((dot.abs() - 1.0).abs() < 1e-8, "component {j}: {dot}");
    }
    // Residual variance per row after projecting on the k components.
    let u = DMatrix::from_fn(d, k, |r, j| model.basis[r * k + j]);
    let resid = &c - &c * &u * u.transpose();
    for r in (0..d).step_by(97) {
        let v = resid.column(r).norm_squared() / n as f64;
        assert!(
            (model.residual_variance[r] - v).abs() < 1e-9 * (1.0 + v),
            "row {r}"
        );
    }
}

/// `‖est − ref‖ / ‖ref‖` over the measurable rows.
fn linear_error(reference: &GridTable, estimate: &GridTable) -> f64 {
    let g = reference.grid;
    let (mut num, mut den) = (0.0, 0.0);
    for r in 0..3 * g.len() {
        if measurable(&g, r % g.len()) {
            let (y, e) = (reference.values[r], estimate.values[r]);
            num += (e - y) * (e - y);
            den += y * y;
        }
    }
    (num / den).sqrt()
}

#[test]
fn whitened_rows_fit_a_new_material_nearly_as_well_as_every_row() {
    // Materials outside the corpus's families: the fit on every measurable row sets the floor
    // of any selection; the whitened search's few rows come close to it (§6.5: "adding more
    // constraints does not improve the solution").
    use brdf::analytic::{Ggx, Ward};
    let grid = common::small_grid();
    let (training, _) = common::corpus(grid);
    let model = Model::LinComb(training.clone());
    let all: Vec<usize> = (0..training.dim())
        .filter(|&r| measurable(&grid, r % grid.len()))
        .collect();
    let news: Vec<Box<dyn brdf::Brdf>> = vec![
        Box::new(Ggx {
            kd: [0.2, 0.1, 0.05],
            ks: [0.6, 0.5, 0.4],
            alpha: 0.25,
            ior: 1.6,
        }),
        Box::new(Ward {
            kd: [0.1, 0.3, 0.2],
            ks: [0.2, 0.2, 0.2],
            alpha_x: 0.2,
            alpha_y: 0.2,
        }),
    ];
    for (i, m) in news.iter().enumerate() {
        let truth = GridTable::tabulate(m.as_ref(), grid);
        let b: Vec<f64> = all.iter().map(|&r| truth.values[r]).collect();
        let c = sampling::fit_coefficients(&training, &all, &b).unwrap();
        let floor = linear_error(&truth, &sampling::combine(&training, &c).unwrap());
        let error_of = |name: &str| {
            let method: Method = name.parse().unwrap();
            let p = plan(method, 60, &model, PlanOptions::default()).unwrap();
            let v: Vec<f64> = p
                .rows(&grid)
                .iter()
                .map(|&(q, ch)| truth.values[row_of(&grid, q, ch)])
                .collect();
            let m = Measurements::new(p.points, v).unwrap();
            linear_error(&truth, &reconstruct(method, &m, &model).unwrap())
        };
        let (seed, whitened) = (error_of("lincomb"), error_of("lincomb-whitened"));
        // Measured: floors 0.134 and 0.380; whitened 0.174 and 0.416; the thesis's search 1.70
        // and 11.9, since its criterion keeps the highlight rows out.
        assert!(
            whitened < 1.5 * floor,
            "material {i}: {whitened} vs floor {floor}"
        );
        assert!(whitened < seed, "material {i}: {whitened} vs {seed}");
    }
}
