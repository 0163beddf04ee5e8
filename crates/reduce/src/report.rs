//! `model report`: CSV tables and PNG plots of a model.

use std::path::{Path, PathBuf};

#[cfg(feature = "plot")]
use crate::plot::{line_plot_png, Series};
#[cfg(feature = "plot")]
use plotters::style::RGBColor;

use crate::charting::Charts;
use crate::error::{ReduceError, Result};
use crate::model::{chart_errors, ChartErrors, Model};
use crate::pca::residual_curve;

/// Highest embedding dimension of the charting error curve.
pub const MAX_CHART_DIM: usize = 20;

/// Files written by [`write_report`].
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Paths written.
    pub files: Vec<PathBuf>,
    /// Charting error for `d = 1..`, adopted definition ([`ChartErrors::unexplained_total`]:
    /// unexplained fraction of the centred log corpus's variance); empty without a chart in the
    /// model, `NaN` where the connection failed.
    pub chart_errors: Vec<f64>,
}

fn write_atomic(path: &Path, text: &str) -> Result<()> {
    Ok(brdf::write_atomic(path, text.as_bytes())?)
}

/// Charting errors (all candidate definitions, [`ChartErrors`]) for embedding dimensions
/// `1..=max_d`, with the model chart's settings (σ, floors) in its PCA coordinates; `None`
/// where the connection failed.
pub fn chart_error_table(model: &Model, max_d: usize) -> Result<Vec<Option<ChartErrors>>> {
    let Some(chart) = &model.chart else {
        return Ok(Vec::new());
    };
    let charts = Charts::fit(&chart.charts.centres, chart.charts.config)?;
    Ok((1..=max_d
        .min(charts.ambient_dim())
        .min(charts.len().saturating_sub(2)))
        .map(|d| {
            charts
                .connect(d)
                .and_then(|c| chart_errors(&model.pca, &c))
                .ok()
        })
        .collect())
}

/// Writes into `dir` (created if needed): `eigenvalues.csv` (k, eigenvalue, relative residual
/// after k components), `eigenvalues.png` (log scale), `reconstruction_error.png`,
/// `coordinates.csv` (PCA coordinates of the corpus) and, when the model has a chart,
/// `chart_embedding.csv`, `charting_error.csv` (every [`ChartErrors`] definition and the PCA
/// counterpart, d = 1..20) and `charting_error.png` (chart in red, PCA with k = d in blue).
/// The PNG files are written with feature `plot` only.
pub fn write_report(model: &Model, dir: impl AsRef<Path>) -> Result<Report> {
    let dir = dir.as_ref();
    std::fs::create_dir_all(dir).map_err(|e| ReduceError::io(dir, e))?;
    let mut rep = Report::default();
    let ev = &model.pca.eigenvalues;
    let curve = residual_curve(ev);
    let mut csv = String::from("k,eigenvalue,relative_residual_after_k\n");
    for (k, l) in ev.iter().enumerate() {
        csv += &format!("{},{:e},{:e}\n", k + 1, l, curve[k + 1]);
    }
    let p = dir.join("eigenvalues.csv");
    write_atomic(&p, &csv)?;
    rep.files.push(p);
    #[cfg(feature = "plot")]
    write_pca_plots(model, &curve, dir, &mut rep)?;
    let k = model.components();
    let mut csv = String::from("material");
    for c in 0..k {
        csv += &format!(",x{}", c + 1);
    }
    csv.push('\n');
    for (i, name) in model.names.iter().enumerate() {
        csv += &csv_field(name);
        for c in 0..k {
            csv += &format!(",{:e}", model.pca.coords[(i, c)]);
        }
        csv.push('\n');
    }
    let p = dir.join("coordinates.csv");
    write_atomic(&p, &csv)?;
    rep.files.push(p);
    if let Some(chart) = &model.chart {
        let e = chart.embedding()?;
        let mut csv = String::from("material");
        for c in 0..chart.dim {
            csv += &format!(",e{}", c + 1);
        }
        csv.push('\n');
        for (i, name) in model.names.iter().enumerate() {
            csv += &csv_field(name);
            for c in 0..chart.dim {
                csv += &format!(",{:e}", e[(i, c)]);
            }
            csv.push('\n');
        }
        let p = dir.join("chart_embedding.csv");
        write_atomic(&p, &csv)?;
        rep.files.push(p);
        let table = chart_error_table(model, MAX_CHART_DIM)?;
        rep.chart_errors = table
            .iter()
            .map(|e| e.map_or(f64::NAN, |e| e.unexplained_total))
            .collect();
        let total: f64 = model.pca.eigenvalues.iter().sum();
        let pca_unexplained = |k: usize| model.pca.eigenvalues.iter().skip(k).sum::<f64>() / total;
        let mut csv = String::from(
            "d,unexplained_total,relative_total,relative_in_coords,unexplained_in_coords,relative_uncentred,pca_unexplained_at_k_eq_d\n",
        );
        for (i, e) in table.iter().enumerate() {
            let d = i + 1;
            match e {
                Some(e) => {
                    csv += &format!(
                        "{d},{:e},{:e},{:e},{:e},{:e},{:e}\n",
                        e.unexplained_total,
                        e.relative_total,
                        e.relative_in_coords,
                        e.unexplained_in_coords,
                        e.relative_uncentred,
                        pca_unexplained(d)
                    )
                }
                None => csv += &format!("{d},NaN,NaN,NaN,NaN,NaN,{:e}\n", pca_unexplained(d)),
            }
        }
        let p = dir.join("charting_error.csv");
        write_atomic(&p, &csv)?;
        rep.files.push(p);
        #[cfg(feature = "plot")]
        write_chart_plot(&rep.chart_errors, &pca_unexplained, dir, &mut rep.files)?;
    }
    Ok(rep)
}

#[cfg(feature = "plot")]
fn write_pca_plots(model: &Model, curve: &[f64], dir: &Path, rep: &mut Report) -> Result<()> {
    let ev = &model.pca.eigenvalues;
    let blue = RGBColor(30, 80, 200);
    // Numerically zero eigenvalues (the centred corpus has rank N − 1) are left out of the plot.
    let tol = crate::pca::RELATIVE_EIGEN_TOLERANCE * ev.first().copied().unwrap_or(0.0);
    let positive: Vec<(f64, f64)> = ev
        .iter()
        .enumerate()
        .filter(|(_, &l)| l > tol)
        .map(|(k, &l)| ((k + 1) as f64, l))
        .collect();
    let p = dir.join("eigenvalues.png");
    line_plot_png(
        &p,
        &[Series {
            points: positive,
            color: blue,
        }],
        true,
        (800, 600),
    )?;
    rep.files.push(p);
    let p = dir.join("reconstruction_error.png");
    let pts: Vec<(f64, f64)> = curve
        .iter()
        .enumerate()
        .take(ev.len())
        .map(|(k, &e)| (k as f64, e))
        .collect();
    line_plot_png(
        &p,
        &[Series {
            points: pts,
            color: blue,
        }],
        false,
        (800, 600),
    )?;
    rep.files.push(p);
    Ok(())
}

#[cfg(feature = "plot")]
fn write_chart_plot(
    chart_errors: &[f64],
    pca_unexplained: &dyn Fn(usize) -> f64,
    dir: &Path,
    files: &mut Vec<PathBuf>,
) -> Result<()> {
    let pts: Vec<(f64, f64)> = chart_errors
        .iter()
        .enumerate()
        .filter(|(_, e)| e.is_finite())
        .map(|(d, &e)| ((d + 1) as f64, e))
        .collect();
    let pca_pts: Vec<(f64, f64)> = (1..=chart_errors.len())
        .map(|d| (d as f64, pca_unexplained(d)))
        .filter(|(_, e)| *e > 0.0)
        .collect();
    let p = dir.join("charting_error.png");
    line_plot_png(
        &p,
        &[
            Series {
                points: pts,
                color: RGBColor(200, 40, 40),
            },
            Series {
                points: pca_pts,
                color: RGBColor(40, 80, 200),
            },
        ],
        true,
        (800, 600),
    )?;
    files.push(p);
    Ok(())
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::corpus::Corpus;
    use crate::model::build_model;
    use rand::{Rng, SeedableRng};

    #[test]
    fn report_tables_match_the_model() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut c = Corpus::new(300);
        for i in 0..10 {
            let v: Vec<f64> = (0..300).map(|_| rng.gen_range(0.01..5.0)).collect();
            c.push_values(format!("m,{i}"), &v).unwrap();
        }
        let m = build_model(&c, 5, Some(2), None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let rep = write_report(&m, dir.path()).unwrap();
        assert_eq!(rep.files.len(), if cfg!(feature = "plot") { 7 } else { 4 });
        assert!(rep.files.iter().all(|f| f.is_file()));
        let csv = std::fs::read_to_string(dir.path().join("eigenvalues.csv")).unwrap();
        let rows: Vec<Vec<f64>> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 10);
        for (r, l) in rows.iter().zip(&m.pca.eigenvalues) {
            assert!((r[1] - l).abs() <= 1e-12 * l.abs().max(1.0));
        }
        // The residual after all components is zero, after none it is one.
        assert!(
            rows[9][2] < 1e-6
                && (rows[0][2]
                    - (1.0 - m.pca.eigenvalues[0] / m.pca.eigenvalues.iter().sum::<f64>()).sqrt())
                .abs()
                    < 1e-9
        );
        let coords = std::fs::read_to_string(dir.path().join("coordinates.csv")).unwrap();
        assert!(coords.lines().nth(1).unwrap().starts_with("\"m,0\","));
        // d runs up to the chart's ambient dimension (5 PCA coordinates).
        assert_eq!(rep.chart_errors.len(), 5);
    }
}
