//! Trains on the 96 shared MERL materials, tests on the 8 Nielsen materials, and prints both
//! error metrics per method and material (the table of docs/sampling.md).
//!
//! `cargo run --release -p sampling --example acquisition_table -- [--step H,D,P] [--k K]
//!  [--noise S] [--proposals P] [--sphere N] [--cwb-target T] [--out-dir DIR]
//!  [--wavelet-model FILE]`
//!
//! The default grid is the full 90 × 90 × 180 MERL grid (`--step 1,1,1`); `--step 3,3,6` gives
//! the 30³ sub-grid of earlier runs. With `--out-dir`, the per-material results
//! (`results.csv`), the linear-combination sweep (`lincomb_sweep.csv`, `lincomb_sweep.png`)
//! and the PCA sweep (`pca_sweep.csv`) are written there. `--wavelet-model FILE` caches the
//! Common Wavelet Basis model (built and saved if FILE is missing, loaded otherwise).
//! Every random choice is seeded. `--plot-only DIR` only redraws the PNG from DIR's CSV files.

use std::path::{Path, PathBuf};
use std::time::Instant;

use image::ImageEncoder;
use plotters::prelude::*;
use sampling::metrics::{image_rms_relative, log_rms_relative};
use sampling::write_atomic;
use sampling::LogPcaModel;
use sampling::{from_log_clamped, tabulate_nbrdf_f32, to_log};
use sampling::{measure_plan, GridTable, Measurements, Plan, SampleGrid};
use sampling::{
    plan, plan_from_rows, reconstruct, uniform_plan, Method, Model, PlanOptions,
    WAVELET_CGLS_ITERATIONS, WAVELET_DAMPING,
};
use sampling::{CoarseGrid, WaveletPatternModel};
use sampling::{SearchBasis, SwapSearch};

mod common;

use common::{arg, grid_arg, load_benchmark, Error};

/// One line of the results table.
struct Row {
    method: String,
    n: usize,
    material: String,
    log_rms: f64,
    sphere_rms: f64,
    plan_seconds: f64,
}

/// Collects and prints results; means per (method, n).
struct Report {
    names: Vec<String>,
    refs: Vec<GridTable>,
    sphere: usize,
    rows: Vec<Row>,
}

impl Report {
    /// Scores `recon(i)` against every test material; returns the means (log, sphere).
    fn run(
        &mut self,
        method: &str,
        n: usize,
        plan_seconds: f64,
        recon: &dyn Fn(usize) -> GridTable,
    ) -> (f64, f64) {
        let t = Instant::now();
        let mut sums = (0.0, 0.0);
        for i in 0..self.refs.len() {
            let est = recon(i);
            let e_log = log_rms_relative(&self.refs[i], &est).unwrap_or(f64::NAN);
            let e_img = image_rms_relative(&self.refs[i], &est, self.sphere).unwrap_or(f64::NAN);
            sums.0 += e_log;
            sums.1 += e_img;
            println!(
                "{method},{n},{},{e_log:.4},{e_img:.4},{plan_seconds:.2}",
                self.names[i]
            );
            self.rows.push(Row {
                method: method.into(),
                n,
                material: self.names[i].clone(),
                log_rms: e_log,
                sphere_rms: e_img,
                plan_seconds,
            });
        }
        let c = self.refs.len() as f64;
        let mean = (sums.0 / c, sums.1 / c);
        println!(
            "{method},{n},MEAN,{:.4},{:.4},{plan_seconds:.2}   # {:.1} s",
            mean.0,
            mean.1,
            t.elapsed().as_secs_f64()
        );
        mean
    }

    fn csv(&self) -> String {
        let mut s = String::from("method,n,material,log_rms_rel,sphere_rms_rel,plan_seconds\n");
        for r in &self.rows {
            s += &format!(
                "{},{},{},{:.6},{:.6},{:.3}\n",
                r.method, r.n, r.material, r.log_rms, r.sphere_rms, r.plan_seconds
            );
        }
        s
    }
}

/// Log-x line plot of the sweep (no text: the numbers are in the CSV next to it).
/// Red = log-RMS, blue = sphere RMS (both in %); dashed = the PCA reference at 40 samples.
fn sweep_png(path: &Path, sweep: &[(usize, f64, f64)], pca40: (f64, f64)) -> Result<(), Error> {
    let (w, h) = (800u32, 500u32);
    let mut rgb = vec![0u8; 3 * (w * h) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let x0 = (sweep.first().map_or(10, |s| s.0) as f64).log10();
        let x1 = (sweep.last().map_or(2000, |s| s.0) as f64).log10();
        let ymax = sweep
            .iter()
            .flat_map(|s| [s.1, s.2])
            .chain([pca40.0, pca40.1])
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max)
            * 100.0
            * 1.05;
        let mut chart = ChartBuilder::on(&root)
            .margin(20)
            .build_cartesian_2d(x0..x1, 0.0..ymax.max(1.0))?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .y_labels(0)
            .draw()?;
        for dec in [1.0f64, 2.0, 3.0] {
            if dec >= x0 && dec <= x1 {
                chart.draw_series(LineSeries::new([(dec, 0.0), (dec, ymax)], BLACK.mix(0.3)))?;
            }
        }
        let pts = |f: fn(&(usize, f64, f64)) -> f64| -> Vec<(f64, f64)> {
            sweep
                .iter()
                .map(|s| ((s.0 as f64).log10(), 100.0 * f(s)))
                .collect()
        };
        chart.draw_series(LineSeries::new(pts(|s| s.1), RED.stroke_width(2)))?;
        chart.draw_series(LineSeries::new(pts(|s| s.2), BLUE.stroke_width(2)))?;
        for (v, c) in [(pca40.0, RED), (pca40.1, BLUE)] {
            let y = 100.0 * v;
            let segs: Vec<f64> = (0..40).map(|i| x0 + (x1 - x0) * i as f64 / 40.0).collect();
            for pair in segs.chunks(2) {
                if let [a, b] = *pair {
                    chart.draw_series(LineSeries::new(vec![(a, y), (b, y)], c.mix(0.6)))?;
                }
            }
        }
        root.present()?;
    }
    brdf::write_atomic_with(path, |out| {
        image::codecs::png::PngEncoder::new(out)
            .write_image(&rgb, w, h, image::ExtendedColorType::Rgb8)
            .map_err(std::io::Error::other)
    })?;
    Ok(())
}

/// Redraws `lincomb_sweep.png` from the CSV files of an earlier run in `dir`.
fn plot_only(dir: &Path) -> Result<(), Error> {
    let read = |name: &str| -> Result<Vec<Vec<f64>>, Error> {
        let text = std::fs::read_to_string(dir.join(name))?;
        text.lines()
            .skip(1)
            .map(|l| {
                l.split(',')
                    .map(|v| v.parse::<f64>().map_err(Error::from))
                    .collect()
            })
            .collect()
    };
    let sweep: Vec<(usize, f64, f64)> = read("lincomb_sweep.csv")?
        .iter()
        .map(|r| (r[0] as usize, r[1], r[2]))
        .collect();
    let pca40 = read("pca_sweep.csv")?
        .iter()
        .find(|r| r[0] == 40.0)
        .map_or((f64::NAN, f64::NAN), |r| (r[1], r[2]));
    sweep_png(&dir.join("lincomb_sweep.png"), &sweep, pca40)
}

fn main() -> Result<(), Error> {
    let args: Vec<String> = std::env::args().collect();
    if let Some(d) = args
        .iter()
        .position(|a| a == "--plot-only")
        .and_then(|i| args.get(i + 1))
    {
        return plot_only(Path::new(d));
    }
    let grid = grid_arg(&args)?;
    let k: usize = arg(&args, "--k", 40);
    let noise: f64 = arg(&args, "--noise", 0.0);
    let proposals: usize = arg(&args, "--proposals", 2000);
    let sphere: usize = arg(&args, "--sphere", 64);
    let cwb_target: f64 = arg(&args, "--cwb-target", 0.03);
    let out_dir: Option<PathBuf> = args
        .iter()
        .position(|a| a == "--out-dir")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from);
    let wavelet_cache: Option<PathBuf> = args
        .iter()
        .position(|a| a == "--wavelet-model")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from);
    if let Some(d) = &out_dir {
        std::fs::create_dir_all(d)?;
    }

    let common::Benchmark {
        training,
        test,
        refs,
        decode_seconds,
    } = load_benchmark(grid)?;
    println!(
        "# grid {:?} = {} points x 3 channels; {} training, {} test materials; decode {:.1} s",
        grid.shape(),
        grid.len(),
        training.len(),
        test.len(),
        decode_seconds
    );
    let mut report = Report {
        names: test.iter().map(|m| m.material_name().to_string()).collect(),
        refs,
        sphere,
        rows: Vec::new(),
    };
    let measure = |p: &Plan, i: usize| -> Measurements {
        measure_plan(p, &test[i], noise, 1000 + i as u64).expect("valid plan")
    };
    let opts = PlanOptions {
        seed: 7,
        swap_proposals: proposals,
    };
    println!("method,n,material,log_rms_rel,sphere_rms_rel,plan_seconds");

    // Beyond the thesis: log-space PCA with A-optimal rows. Greedy selection is nested, so the
    // plans for every n are prefixes of the largest one.
    let pca_ns = [10usize, 20, 30, 40, 80];
    let mut pca_sweep = Vec::new();
    {
        let t = Instant::now();
        let pca = LogPcaModel::fit(&training, k, noise.max(0.0))?;
        println!("# log PCA k = {k} fit {:.1} s", t.elapsed().as_secs_f64());
        report.run("pca-projection", 0, 0.0, &|i| {
            let a = pca.project(&report_ref(&test, grid, i)).expect("same grid");
            pca.reconstruct(&a).expect("component count")
        });
        let t = Instant::now();
        let (all_rows, _) = pca.select_rows(*pca_ns.last().expect("non-empty"))?;
        let secs = t.elapsed().as_secs_f64();
        println!("# pca row selection (n = {}) {secs:.1} s", all_rows.len());
        let model = Model::LogPca(pca);
        for &n in &pca_ns {
            let p = plan_from_rows(&grid, &all_rows[..n]);
            let mean = report.run("pca", n, secs, &|i| {
                reconstruct(Method::Pca, &measure(&p, i), &model).expect("pca")
            });
            pca_sweep.push((n, mean.0, mean.1));
        }
    }

    // Linear combination (§6.5): greedy swap search over all measurable rows.
    let lincomb_ns = [10usize, 20, 40, 100, 200, 400, 800, 1000, 1500, 2000];
    let mut sweep = Vec::new();
    let mut sweep_csv = String::from(
        "n,log_rms_rel_mean,sphere_rms_rel_mean,initial_ratio,final_ratio,accepted,plan_seconds\n",
    );
    let lin_model = Model::LinComb(training);
    let training_ref = lin_model.lincomb_training().expect("built above");
    for &n in &lincomb_ns {
        let t = Instant::now();
        let sel = sampling::select_rows(
            training_ref,
            n,
            SwapSearch {
                proposals: opts.swap_proposals,
                basis: SearchBasis::Materials,
                seed: opts.seed,
            },
        )?;
        let secs = t.elapsed().as_secs_f64();
        println!(
            "# lincomb n={n}: eigenvalue ratio {:.3e} -> {:.3e} ({} swaps accepted)",
            sel.initial_ratio, sel.final_ratio, sel.accepted
        );
        let p = plan_from_rows(&grid, &sel.rows);
        let mean = report.run("lincomb", n, secs, &|i| {
            reconstruct(
                Method::LinComb(Default::default()),
                &measure(&p, i),
                &lin_model,
            )
            .expect("lincomb")
        });
        sweep.push((n, mean.0, mean.1));
        sweep_csv += &format!(
            "{n},{:.6},{:.6},{:.6e},{:.6e},{},{secs:.3}\n",
            mean.0, mean.1, sel.initial_ratio, sel.final_ratio, sel.accepted
        );
    }
    let Model::LinComb(training) = lin_model else {
        unreachable!("built above")
    };

    // Wavelet pattern (§6.3) and pull-push from the same points (§6.4).
    let t = Instant::now();
    let wmodel = match &wavelet_cache {
        Some(path) if path.exists() => match sampling::load(path)? {
            Model::Wavelet(w) if w.grid == grid => w,
            _ => {
                return Err(
                    format!("{} is not a wavelet model on this grid", path.display()).into(),
                )
            }
        },
        _ => {
            let w = WaveletPatternModel::build(&training, cwb_target)?;
            if let Some(path) = &wavelet_cache {
                sampling::save(&Model::Wavelet(w.clone()), path)?;
            }
            w
        }
    };
    drop(training);
    let cwb_secs = t.elapsed().as_secs_f64();
    println!(
        "# CWB (log space, target {cwb_target}): {} functions = {:.2}% of {} grid values; {cwb_secs:.1} s; levels {:?}",
        wmodel.len(),
        100.0 * wmodel.basis.fraction_of_table(),
        grid.len(),
        wmodel.basis.level_histogram()
    );
    let g = grid.len();
    report.run("cwb-alone", wmodel.len(), 0.0, &|i| {
        let r = report_ref(&test, grid, i);
        let mut v = vec![0.0; 3 * g];
        for ch in 0..3 {
            let logs: Vec<f32> = r.values[ch * g..(ch + 1) * g]
                .iter()
                .map(|&x| to_log(x) as f32)
                .collect();
            let proj = wmodel.basis.project(&logs).expect("layout");
            for (o, y) in v[ch * g..(ch + 1) * g].iter_mut().zip(proj) {
                *o = from_log_clamped(y as f64);
            }
        }
        GridTable::new(grid, v).expect("size")
    });
    let side = wmodel.basis.layout().side;
    let wm = Model::Wavelet(wmodel);
    let Model::Wavelet(wref) = &wm else {
        unreachable!("built above")
    };
    let samples_of = |p: &Plan, m: &Measurements| -> Vec<(usize, usize, f64)> {
        p.rows(&grid)
            .iter()
            .zip(&m.values)
            .map(|(&(q, c), &v)| (q, c, v))
            .collect()
    };
    // One point per CWB function, and the thesis's 69,000 points scaled to this grid.
    let seed_points = (g as f64 * 69_000.0 / 1_458_000.0).round() as usize;
    for n_values in [0usize, 3 * seed_points] {
        let t = Instant::now();
        let wp = plan(Method::Wavelet, n_values, &wm, opts)?;
        let secs = t.elapsed().as_secs_f64();
        let n = wp.len();
        println!(
            "# wavelet pattern: {} points, planned in {secs:.1} s",
            n / 3
        );
        report.run("wavelet-pattern-coarse16", n, secs, &|i| {
            reconstruct(Method::Wavelet, &measure(&wp, i), &wm).expect("wavelet")
        });
        report.run("wavelet-pattern-solve-only", n, secs, &|i| {
            let m = measure(&wp, i);
            wref.reconstruct(
                &samples_of(&wp, &m),
                WAVELET_CGLS_ITERATIONS,
                WAVELET_DAMPING,
                None,
            )
            .expect("wavelet")
        });
        report.run("pullpush-wavelet-points", n, secs, &|i| {
            reconstruct(Method::PullPush, &measure(&wp, i), &wm).expect("pullpush")
        });
    }
    println!(
        "# coarse grid for the lowest levels: {:?}",
        CoarseGrid::for_cube(side)
    );

    // Pull-push from uniform random plans: the thesis's sampling fraction (69,000 points x 3
    // channels of 1,458,000 x 3) and 4x that.
    let grid_model = Model::Grid(grid);
    for n in [3 * seed_points, 12 * seed_points] {
        let p = uniform_plan(&grid, n, 7)?;
        report.run("pullpush-uniform", n, 0.0, &|i| {
            reconstruct(Method::PullPush, &measure(&p, i), &grid_model).expect("pullpush")
        });
    }

    if let Some(d) = &out_dir {
        write_atomic(&d.join("results.csv"), report.csv().as_bytes())?;
        write_atomic(&d.join("lincomb_sweep.csv"), sweep_csv.as_bytes())?;
        let mut pca_csv = String::from("n,log_rms_rel_mean,sphere_rms_rel_mean\n");
        for (n, a, b) in &pca_sweep {
            pca_csv += &format!("{n},{a:.6},{b:.6}\n");
        }
        write_atomic(&d.join("pca_sweep.csv"), pca_csv.as_bytes())?;
        let pca40 = pca_sweep
            .iter()
            .find(|s| s.0 == 40)
            .map_or((f64::NAN, f64::NAN), |s| (s.1, s.2));
        sweep_png(&d.join("lincomb_sweep.png"), &sweep, pca40)?;
        println!("# wrote {}", d.display());
    }
    println!("# total {:.1} s", decode_seconds);
    Ok(())
}

/// The reference table of test material `i` (re-tabulated, so that closures do not borrow the
/// report mutably while it records).
fn report_ref(test: &[brdf::nbrdf::Nbrdf], grid: SampleGrid, i: usize) -> GridTable {
    let v = tabulate_nbrdf_f32(&test[i], grid);
    GridTable::new(grid, v.iter().map(|&x| f64::from(x)).collect()).expect("size")
}
