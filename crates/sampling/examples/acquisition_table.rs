//! Trains on the 96 shared MERL materials, tests on the 8 Nielsen materials, and prints both
//! error metrics per method and material.
//!
//! `cargo run --release -p sampling --example acquisition_table -- [--step H,D,P] [--k K]
//!  [--noise S] [--proposals P] [--sphere N]`
//!
//! Models are trained on a sub-grid of the MERL grid (default every 3rd θh, 3rd θd and 6th φd
//! index: 30 × 30 × 30 points); errors are measured on that sub-grid.

use std::time::Instant;

use brdf::nbrdf::{load_dir, Nbrdf};
use sampling::lincomb;
use sampling::logpca::LogPcaModel;
use sampling::methods::{plan, reconstruct, uniform_plan, Method, Model, PlanOptions};
use sampling::metrics::{image_rms_relative, log_rms_relative};
use sampling::training::TrainingSet;
use sampling::wavelet_pattern::WaveletPatternModel;
use sampling::{measure_plan, GridTable, SampleGrid};

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let step: String = arg(&args, "--step", "3,3,6".to_string());
    let s: Vec<usize> = step
        .split(',')
        .map(|v| v.parse())
        .collect::<Result<_, _>>()?;
    let grid = SampleGrid::new(s[0], s[1], s[2])?;
    let k: usize = arg(&args, "--k", 40);
    let noise: f64 = arg(&args, "--noise", 0.0);
    let proposals: usize = arg(&args, "--proposals", 2000);
    let sphere: usize = arg(&args, "--sphere", 64);
    let cwb_target: f64 = arg(&args, "--cwb-target", 0.03);
    let data = brdf::data_dir().join("nbrdf");

    let t0 = Instant::now();
    let train: Vec<Nbrdf> = load_dir(data.join("merl"))?;
    let test: Vec<Nbrdf> = load_dir(data.join("nielsen"))?;
    let tables: Vec<GridTable> = train
        .iter()
        .map(|m| GridTable::from_nbrdf(m, grid))
        .collect();
    let names = train
        .iter()
        .map(|m| m.material_name().to_string())
        .collect();
    let training = TrainingSet::from_tables(names, &tables)?;
    let refs: Vec<GridTable> = test
        .iter()
        .map(|m| GridTable::from_nbrdf(m, grid))
        .collect();
    println!(
        "# grid {:?} = {} points x 3 channels; {} training, {} test materials; decode {:.1} s",
        grid.shape(),
        grid.len(),
        training.len(),
        test.len(),
        t0.elapsed().as_secs_f64()
    );
    let t1 = Instant::now();
    let pca = LogPcaModel::fit(&training, k, noise.max(0.0))?;
    println!("# log PCA k = {k} fit {:.1} s", t1.elapsed().as_secs_f64());

    let lin_model = Model::LinComb(training.clone());
    let pca_model = Model::LogPca(pca.clone());
    let grid_model = Model::Grid(grid);
    let opts = PlanOptions {
        seed: 7,
        swap_proposals: proposals,
    };

    println!("method,n,material,log_rms_rel,sphere_rms_rel,plan_seconds");
    let report = |label: &str, n: usize, plan_secs: f64, recon: &dyn Fn(usize) -> GridTable| {
        let mut sums = (0.0, 0.0);
        for (i, m) in test.iter().enumerate() {
            let est = recon(i);
            let e_log = log_rms_relative(&refs[i], &est).unwrap_or(f64::NAN);
            let e_img = image_rms_relative(&refs[i], &est, sphere).unwrap_or(f64::NAN);
            sums.0 += e_log;
            sums.1 += e_img;
            println!(
                "{label},{n},{},{e_log:.4},{e_img:.4},{plan_secs:.2}",
                m.material_name()
            );
        }
        let c = test.len() as f64;
        println!(
            "{label},{n},MEAN,{:.4},{:.4},{plan_secs:.2}",
            sums.0 / c,
            sums.1 / c
        );
    };

    // Best the PCA basis can do: projection of the full reference.
    report("pca-projection", 0, 0.0, &|i| {
        let a = pca.project(&refs[i]).expect("same grid");
        pca.reconstruct(&a).expect("component count")
    });

    let measure = |p: &sampling::Plan, i: usize| {
        measure_plan(p, &test[i], noise, 1000 + i as u64).expect("valid plan")
    };

    for &n in &[10usize, 20, 40, 100, 200, 400, 800, 2000] {
        let t = Instant::now();
        let p = plan(Method::LinComb, n, &lin_model, opts)?;
        let secs = t.elapsed().as_secs_f64();
        let sel_ratio = lincomb::eigenvalue_ratio(&lincomb::row_matrix(
            &training,
            &p.rows(&grid)
                .iter()
                .map(|&(pt, c)| sampling::training::row_of(&grid, pt, c))
                .collect::<Vec<_>>(),
        ));
        println!("# lincomb n={n}: eigenvalue ratio after search {sel_ratio:.3e}");
        report("lincomb", n, secs, &|i| {
            reconstruct(Method::LinComb, &measure(&p, i), &lin_model).expect("lincomb")
        });
    }

    for &n in &[10usize, 20, 30, 40, 80] {
        let t = Instant::now();
        let p = plan(Method::Pca, n, &pca_model, opts)?;
        let secs = t.elapsed().as_secs_f64();
        report("pca", n, secs, &|i| {
            reconstruct(Method::Pca, &measure(&p, i), &pca_model).expect("pca")
        });
    }

    // Wavelet pattern (§6.3) and pull-push from the same points (§6.4).
    let t = Instant::now();
    let wmodel = WaveletPatternModel::build(&training, cwb_target)?;
    let cwb_secs = t.elapsed().as_secs_f64();
    println!(
        "# CWB (log space, target {cwb_target}): {} functions = {:.2}% of {} grid values; built in {cwb_secs:.1} s; levels {:?}",
        wmodel.len(),
        100.0 * wmodel.basis.fraction_of_table(),
        grid.len(),
        wmodel.basis.level_histogram()
    );
    report("cwb-alone", wmodel.len(), 0.0, &|i| {
        let g = grid.len();
        let mut v = vec![0.0; 3 * g];
        for ch in 0..3 {
            let logs: Vec<f32> = refs[i].values[ch * g..(ch + 1) * g]
                .iter()
                .map(|&x| sampling::training::to_log(x) as f32)
                .collect();
            let proj = wmodel.basis.project(&logs).expect("layout");
            for (o, y) in v[ch * g..(ch + 1) * g].iter_mut().zip(proj) {
                *o = sampling::training::from_log(y as f64);
            }
        }
        GridTable::new(grid, v).expect("size")
    });
    let wm = Model::Wavelet(wmodel);
    let t = Instant::now();
    let wp = plan(Method::Wavelet, 0, &wm, opts)?;
    let secs = t.elapsed().as_secs_f64();
    report("wavelet-pattern", wp.len(), secs, &|i| {
        reconstruct(Method::Wavelet, &measure(&wp, i), &wm).expect("wavelet")
    });
    report("pullpush-wavelet-points", wp.len(), secs, &|i| {
        reconstruct(Method::PullPush, &measure(&wp, i), &wm).expect("pullpush")
    });

    // Pull-push from a uniform plan with the seed's sampling fraction (69,000 / 1,458,000).
    let n_pp = (3.0 * grid.len() as f64 * 69_000.0 / 1_458_000.0).round() as usize;
    for &n in &[n_pp, 4 * n_pp] {
        let p = uniform_plan(&grid, n, 7)?;
        report("pullpush-uniform", n, 0.0, &|i| {
            reconstruct(Method::PullPush, &measure(&p, i), &grid_model).expect("pullpush")
        });
    }
    println!("# total {:.1} s", t0.elapsed().as_secs_f64());
    Ok(())
}
