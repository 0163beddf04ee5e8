//! The trait study of docs/traits.md on the 96 shared MERL materials: leave-one-out Spearman ρ
//! of rated traits against the human ratings, leave-one-out sign accuracy of the three binary
//! methods on the thesis's 16 traits, angles between their directions, the non-negativity of
//! the corpus reconstructions and the time of one edit.
//!
//! `cargo run --release -p traits --example trait_study -- MODEL.bin [OUT_DIR]`
//! (`MODEL.bin` from `gantry model build --corpus $BRDF_DATA_DIR/nbrdf/merl --out MODEL.bin`;
//! writes `OUT_DIR/spearman.csv`, `OUT_DIR/binary.csv`; default `target/traits-study`).
//! `--ratings-only` stops after the ratings; `--binary-only` runs only the 16 thesis traits.

use std::fmt::Write as _;
use std::time::Instant;

use nalgebra::DMatrix;
use traits::AlbedoQuadrature;
use traits::{
    angles, loo_kernel_ridge_predictions, loo_ridge_predictions, loo_ridge_scores, rated_rows,
    spearman, KernelRidgeGrid, SetFit,
};
use traits::{reconstruct_log, Embedding, Navigator, NavigatorOptions, Space};
use traits::{serrano_ratings_path, thesis_labels, RatingSet};
use traits::{FitOptions, Method};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let model_path = args.first().ok_or("usage: study MODEL.bin [OUT_DIR]")?;
    let out = std::path::PathBuf::from(args.get(1).map_or("target/traits-study", |s| s));
    std::fs::create_dir_all(&out)?;
    let t0 = Instant::now();
    let model = reduce::Model::load(model_path)?;
    eprintln!("model loaded in {:.1} s", t0.elapsed().as_secs_f64());
    let ratings = RatingSet::load(serrano_ratings_path())?;
    let labels = thesis_labels();
    let ratings_only = args.iter().any(|a| a == "--ratings-only");
    if args.iter().any(|a| a == "--binary-only") {
        return binary_study(&model, &labels, &out);
    }

    // Feature spaces for the ratings.
    let mut spaces: Vec<(String, DMatrix<f64>)> = Vec::new();
    for k in [5, 10, 20, 45] {
        let e = Embedding::new(&model, Space::Linear, k)?;
        spaces.push((format!("linear-{k}"), e.corpus()?));
    }
    // Each PCA coordinate scaled to unit variance (the rating depends on the broad shape
    // more than on the variance of the log values).
    for k in [10, 20] {
        let c = Embedding::new(&model, Space::Linear, k)?.corpus()?;
        let sd: Vec<f64> = (0..k)
            .map(|j| model.pca.eigenvalues[j].sqrt() / (96f64).sqrt())
            .collect();
        spaces.push((
            format!("whitened-{k}"),
            DMatrix::from_fn(c.nrows(), k, |i, j| c[(i, j)] / sd[j]),
        ));
    }
    let chart = Embedding::new(&model, Space::Chart, 45)?.corpus()?;
    spaces.push(("chart-15".into(), chart.clone()));
    // Chart and the first 10 PCA coordinates side by side, each block scaled to unit RMS.
    let lin10 = spaces[1].1.clone();
    let rms = |m: &DMatrix<f64>| {
        let mean = m.row_mean();
        ((0..m.nrows())
            .map(|i| (m.row(i) - &mean).norm_squared())
            .sum::<f64>()
            / m.nrows() as f64)
            .sqrt()
    };
    let (rc, rl) = (rms(&chart), rms(&lin10));
    spaces.push((
        "chart-15+linear-10".into(),
        DMatrix::from_fn(chart.nrows(), 25, |i, j| {
            if j < 15 {
                chart[(i, j)] / rc
            } else {
                lin10[(i, j - 15)] / rl
            }
        }),
    ));

    let mut csv = String::from("space,attribute,spearman\n");
    let mut summary = Vec::new();
    // The 16 thesis-trait scores (SVM in the chart, fitted on our binary labels, which do not
    // use the ratings) as features.
    let chart_traits = SetFit {
        coords: &chart,
        names: &model.names,
        space: Space::Chart,
        options: FitOptions::default(),
        cross_validate: false,
    }
    .binary(&labels, Method::Svm)?;
    let trait_scores = DMatrix::from_fn(chart.nrows(), chart_traits.traits.len(), |i, j| {
        let x: Vec<f64> = chart.row(i).iter().copied().collect();
        chart_traits.traits[j].direction.score(&x)
    });
    spaces.push(("thesis-trait-scores-16".into(), trait_scores.clone()));
    let (rt, rc2) = (rms(&trait_scores), rms(&chart));
    spaces.push((
        "trait-scores+chart".into(),
        DMatrix::from_fn(chart.nrows(), 31, |i, j| {
            if j < 16 {
                trait_scores[(i, j)] / rt
            } else {
                chart[(i, j - 16)] / rc2
            }
        }),
    ));
    let lambdas: Vec<(String, FitOptions)> =
        std::iter::once(("loo".to_string(), FitOptions::default()))
            .chain([0.01, 0.1, 1.0].iter().map(|&l| {
                (
                    format!("{l}n"),
                    FitOptions {
                        ridge_lambda: Some(l * 64.0),
                        ..Default::default()
                    },
                )
            }))
            .collect();
    // Summary features: directional albedo curve, colour and specular lobe of each material
    // (from the full model, at the few bins they read), standardised over the corpus.
    let summary_x = summary_features(&model)?;
    let (ra, rs) = (rms(&spaces[spaces.len() - 3].1), rms(&summary_x));
    let cl = spaces[spaces.len() - 3].1.clone();
    spaces.push(("summary-25".into(), summary_x.clone()));
    spaces.push((
        "chart-15+linear-10+summary-25".into(),
        DMatrix::from_fn(cl.nrows(), cl.ncols() + summary_x.ncols(), |i, j| {
            if j < cl.ncols() {
                cl[(i, j)] / ra
            } else {
                summary_x[(i, j - cl.ncols())] / rs
            }
        }),
    ));
    let l10 = spaces[1].1.clone();
    let rl10 = rms(&l10);
    spaces.push((
        "linear-10+summary-25".into(),
        DMatrix::from_fn(l10.nrows(), 10 + summary_x.ncols(), |i, j| {
            if j < 10 {
                l10[(i, j)] / rl10
            } else {
                summary_x[(i, j - 10)] / rs
            }
        }),
    ));
    // Kernel ridge (RBF), width and λ chosen by nested leave-one-out (squared error or rank
    // agreement of the inner predictions); raw and logit targets. `--spaces a,b` restricts.
    let only: Option<Vec<String>> = args
        .iter()
        .position(|a| a == "--spaces")
        .and_then(|i| args.get(i + 1))
        .map(|v| v.split(',').map(String::from).collect());
    for ((name, x), (logit, by_rank)) in spaces
        .iter()
        .filter(|(n, _)| only.as_ref().is_none_or(|o| o.contains(n)))
        .flat_map(|s| {
            [(false, false), (true, false), (false, true)]
                .into_iter()
                .map(move |v| (s, v))
        })
    {
        let grid = KernelRidgeGrid {
            select_by_rank: by_rank,
            ..Default::default()
        };
        {
            let tname = format!(
                "{name}/kernel-rbf{}{}",
                if logit { "/logit" } else { "" },
                if by_rank { "/select-rho" } else { "" }
            );
            let (mut rhos, mut score_rhos) = (Vec::new(), Vec::new());
            for t in 0..ratings.traits.len() {
                let (xr, r) = rated_rows(x, &model.names, &ratings, t)?;
                let rt: Vec<f64> = if logit {
                    r.iter().map(|v| ((v + 0.02) / (1.02 - v)).ln()).collect()
                } else {
                    r.clone()
                };
                let pred = loo_kernel_ridge_predictions(&xr, &rt, &grid)?;
                // The same fold models without their training mean (the kernel part alone;
                // see `loo_kernel_ridge_scores`).
                let (total, n) = (rt.iter().sum::<f64>(), rt.len() as f64);
                let score: Vec<f64> = pred
                    .iter()
                    .zip(&rt)
                    .map(|(p, v)| p - (total - v) / (n - 1.0))
                    .collect();
                let (rho, srho) = (spearman(&pred, &r), spearman(&score, &r));
                writeln!(csv, "{tname},{},{rho:.4}", ratings.traits[t])?;
                writeln!(csv, "{tname}/score,{},{srho:.4}", ratings.traits[t])?;
                rhos.push(rho);
                score_rhos.push(srho);
            }
            report("", &tname, rhos, score_rhos, &mut summary);
        }
    }
    let skip_ridge = args.iter().any(|a| a == "--kernel-only");
    for (name, x) in spaces.iter().filter(|_| !skip_ridge) {
        for (lname, lopts) in &lambdas {
            let name = format!("{name}/λ={lname}");
            let (mut rhos, mut score_rhos) = (Vec::new(), Vec::new());
            for t in 0..ratings.traits.len() {
                let (xr, r) = rated_rows(x, &model.names, &ratings, t)?;
                let pred = loo_ridge_predictions(&xr, &r, lopts)?;
                let score = loo_ridge_scores(&xr, &r, lopts)?;
                let (rho, srho) = (spearman(&pred, &r), spearman(&score, &r));
                writeln!(csv, "{name},{},{rho:.4}", ratings.traits[t])?;
                writeln!(csv, "{name}/score,{},{srho:.4}", ratings.traits[t])?;
                rhos.push(rho);
                score_rhos.push(srho);
            }
            report("ridge ", &name, rhos, score_rhos, &mut summary);
        }
    }
    brdf::write_atomic(&out.join("spearman.csv"), csv.as_bytes())?;
    summary.sort_by(|a, b| b.1.total_cmp(&a.1));
    println!("best: {:?}", &summary[..3]);
    if ratings_only {
        return Ok(());
    }

    binary_study(&model, &labels, &out)?;

    // Non-negativity of the corpus reconstructions at 45 components.
    let mut worst = Vec::new();
    for i in 0..model.names.len() {
        let c: Vec<f64> = model.pca.coords.row(i).iter().take(45).copied().collect();
        let y = reconstruct_log(&model, &c)?;
        let m = y.iter().fold(f32::INFINITY, |a, &b| a.min(b));
        worst.push((reduce::from_log(m), model.names[i].clone()));
    }
    worst.sort_by(|a, b| a.0.total_cmp(&b.0));
    println!(
        "most negative reconstructed values (1/sr) at K = 45: {:?}",
        &worst[..5]
    );
    println!(
        "materials below -1e-3: {}",
        worst.iter().filter(|w| w.0 < -1e-3).count()
    );

    // Timing of edits in both spaces.
    let fit = SetFit {
        coords: &spaces[3].1,
        names: &model.names,
        space: Space::Linear,
        options: FitOptions::default(),
        cross_validate: false,
    };
    let lin = fit.binary(&labels, Method::Svm)?;
    let fitc = SetFit {
        coords: &chart,
        names: &model.names,
        space: Space::Chart,
        options: FitOptions::default(),
        cross_validate: false,
    };
    let cha = fitc.binary(&labels, Method::Svm)?;
    for (space, set) in [(Space::Linear, &lin), (Space::Chart, &cha)] {
        let nav = Navigator::new(&model, space, NavigatorOptions::default())?;
        for (mat, tr, a) in [
            ("blue-acrylic", "metallic-like", 0.5),
            ("yellow-paint", "glossiness", 1.0),
            ("gold-metallic-paint", "redness", 2.0),
        ] {
            let x = nav.embedding.of_name(mat)?;
            let t = Instant::now();
            let s = nav.state(&x)?;
            let t_state = t.elapsed().as_secs_f64();
            let fails = nav.failures(&s)?;
            if !fails.is_empty() {
                println!("{space:?} {mat}: start fails {fails:?}");
                continue;
            }
            let t = Instant::now();
            let o = nav.edit(&x, set.get(tr)?, a)?;
            println!("{space:?} {mat} +{a} {tr}: applied {:.3}, stopped {:?}, max albedo {:.3}; back-projection {:.0} ms, edit {:.0} ms",
                o.applied, o.stopped_by, o.report.max_albedo.0, 1e3 * t_state, 1e3 * t.elapsed().as_secs_f64());
        }
    }
    // An editor session in the linear space: slider moves of ±0.1 glossiness.
    let nav = Navigator::new(&model, Space::Linear, NavigatorOptions::default())?;
    let x = nav.embedding.of_name("yellow-paint")?;
    let mut session = traits::Session::new(&nav, &x)?;
    let g = lin.get("glossiness")?;
    let _ = session.nudge(g, 0.1)?; // first use: back-projects the trait direction
    let t = Instant::now();
    let moves = 10;
    for i in 0..moves {
        let (applied, why) = session.nudge(g, if i % 2 == 0 { 0.1 } else { -0.05 })?;
        if why.is_some() {
            println!("slider move {i}: applied {applied:.3}, stopped by {why:?}");
        }
    }
    println!(
        "editor slider move (linear, 45-D, full-table non-negativity + albedo): {:.1} ms per move",
        1e3 * t.elapsed().as_secs_f64() / moves as f64
    );
    Ok(())
}

/// Leave-one-out sign accuracy of the mean, Fisher and SVM directions of the thesis's 16
/// traits in both spaces, and the angles between them (`OUT/binary.csv`).
fn binary_study(
    model: &reduce::Model,
    labels: &traits::LabelSet,
    out: &std::path::Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut bcsv = String::from("space,trait,mean_acc,fisher_acc,svm_acc,angle_mean_fisher,angle_mean_svm,angle_fisher_svm\n");
    for (space, x) in [
        (
            Space::Linear,
            Embedding::new(model, Space::Linear, 45)?.corpus()?,
        ),
        (
            Space::Chart,
            Embedding::new(model, Space::Chart, 45)?.corpus()?,
        ),
    ] {
        let fit = SetFit {
            coords: &x,
            names: &model.names,
            space,
            options: FitOptions::default(),
            cross_validate: true,
        };
        let sets: Vec<_> = [Method::Mean, Method::Fisher, Method::Svm]
            .iter()
            .map(|&m| fit.binary(labels, m))
            .collect::<Result<_, _>>()?;
        let a01 = angles(&sets[0], &sets[1]);
        let a02 = angles(&sets[0], &sets[2]);
        let a12 = angles(&sets[1], &sets[2]);
        let mut means = [0.0; 3];
        for (i, t) in sets[0].traits.iter().enumerate() {
            let acc: Vec<f64> = sets
                .iter()
                .map(|s| s.traits[i].cross_validated.unwrap_or(f64::NAN))
                .collect();
            for k in 0..3 {
                means[k] += acc[k] / sets[0].traits.len() as f64;
            }
            writeln!(
                bcsv,
                "{space:?},{},{:.3},{:.3},{:.3},{:.1},{:.1},{:.1}",
                t.name, acc[0], acc[1], acc[2], a01[i].1, a02[i].1, a12[i].1
            )?;
        }
        println!(
            "{space:?}: mean LOO sign accuracy mean {:.3} fisher {:.3} svm {:.3}",
            means[0], means[1], means[2]
        );
    }
    brdf::write_atomic(&out.join("binary.csv"), bcsv.as_bytes())?;
    print!("{bcsv}");
    Ok(())
}

/// Per-material summary features from the full model, at the bins they read: log directional
/// albedo (channel mean) at 7 incidence angles, the log colour of the albedo at normal
/// incidence, the log specular lobe (channel mean) at 12 half-angles for θd ≈ 10°, φd = 90°,
/// and its colour at the peak. Each column is standardised over the corpus.
fn summary_features(model: &reduce::Model) -> Result<DMatrix<f64>, Box<dyn std::error::Error>> {
    use brdf::{bin_index, BINS};
    let angles = [0.0, 15.0, 30.0, 45.0, 60.0, 70.0, 80.0];
    let q = AlbedoQuadrature::new(&angles, 32, 32)?;
    let lobe: Vec<usize> = [0, 1, 2, 3, 5, 8, 12, 18, 27, 40, 60, 89]
        .iter()
        .map(|&th| bin_index(th, 10, 90))
        .collect();
    let p = &model.pca;
    let kk = p.components;
    let n = model.names.len();
    let value = |i: usize, c: usize, bin: usize| -> f64 {
        let d = c * BINS + bin;
        let y = p.mean[d] as f64
            + (0..kk)
                .map(|k| p.basis[d * kk + k] as f64 * p.coords[(i, k)])
                .sum::<f64>();
        reduce::from_log(y as f32).max(0.0)
    };
    let mut rows = Vec::new();
    for i in 0..n {
        let a = q.albedo_by(|c, b| value(i, c, b));
        let mut f = Vec::new();
        for v in &a {
            f.push(((v[0] + v[1] + v[2]) / 3.0 + 1e-4).ln());
        }
        let la: Vec<f64> = a[0].iter().map(|v| (v + 1e-4).ln()).collect();
        let m = la.iter().sum::<f64>() / 3.0;
        f.extend(la.iter().map(|v| v - m));
        for &b in &lobe {
            let v = (value(i, 0, b) + value(i, 1, b) + value(i, 2, b)) / 3.0;
            f.push((v + 1e-3).ln());
        }
        let lp: Vec<f64> = (0..3).map(|c| (value(i, c, lobe[0]) + 1e-3).ln()).collect();
        let m = lp.iter().sum::<f64>() / 3.0;
        f.extend(lp.iter().map(|v| v - m));
        rows.push(f);
    }
    let d = rows[0].len();
    let mut x = DMatrix::from_fn(n, d, |i, j| rows[i][j]);
    for j in 0..d {
        let c = x.column(j);
        let mean = c.mean();
        let sd = c.variance().sqrt().max(1e-12);
        for i in 0..n {
            x[(i, j)] = (x[(i, j)] - mean) / sd;
        }
    }
    Ok(x)
}

/// Prints the mean and per-attribute ρ of a method's predictions and of its scores (label
/// `NAME/score`), and adds both means to the summary.
fn report(
    prefix: &str,
    name: &str,
    rhos: Vec<f64>,
    score_rhos: Vec<f64>,
    summary: &mut Vec<(String, f64)>,
) {
    for (label, rhos) in [
        (name.to_string(), rhos),
        (format!("{name}/score"), score_rhos),
    ] {
        let mean = rhos.iter().sum::<f64>() / rhos.len() as f64;
        let per: Vec<String> = rhos.iter().map(|r| format!("{r:.2}")).collect();
        println!(
            "{prefix}{label:40} mean LOO Spearman {mean:.3}  [{}]",
            per.join(" ")
        );
        summary.push((label, mean));
    }
}
