//! Minimal PNG line plots with plotters' bitmap backend.

use std::path::Path;

use image::ImageEncoder;
use plotters::prelude::*;

use crate::error::{ReduceError, Result};

/// One curve of a PNG line plot (plotters' bitmap backend): points and colour.
///
/// The plots draw no text (axes, grid and curves only), so no font library is needed at build or
/// run time; the numbers behind every plot are written next to it as CSV (see [`crate::Report`]).
#[derive(Debug, Clone)]
pub struct Series {
    /// `(x, y)` points, drawn in order.
    pub points: Vec<(f64, f64)>,
    /// Curve colour.
    pub color: RGBColor,
}

/// Draws curves into a `width × height` PNG at `path` (written atomically). With `log_y`, the
/// y axis is log₁₀ (non-positive values are dropped) and grid lines mark the decades; otherwise
/// grid lines are at tenths of the y range.
pub fn line_plot_png(path: &Path, series: &[Series], log_y: bool, size: (u32, u32)) -> Result<()> {
    let tx = |y: f64| if log_y { y.log10() } else { y };
    let pts: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter(|p| p.0.is_finite() && p.1.is_finite() && (!log_y || p.1 > 0.0))
                .map(|&(x, y)| (x, tx(y)))
                .collect()
        })
        .collect();
    let all: Vec<&(f64, f64)> = pts.iter().flatten().collect();
    if all.is_empty() {
        return Err(ReduceError::Plot("nothing to plot".into()));
    }
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &&(x, y) in &all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if log_y {
        y0 = y0.floor();
        y1 = y1.ceil();
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if y1 <= y0 {
        y1 = y0 + 1.0;
    }
    let ypad = if log_y { 0.0 } else { 0.05 * (y1 - y0) };
    let (w, h) = size;
    let mut rgb = vec![0u8; 3 * w as usize * h as usize];
    let mut draw = || -> std::result::Result<(), Box<dyn std::error::Error>> {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(24)
            .build_cartesian_2d(x0..x1, (y0 - ypad)..(y1 + ypad))?;
        let grid = RGBColor(220, 220, 220);
        let lines: Vec<f64> = if log_y {
            (y0 as i64..=y1 as i64).map(|v| v as f64).collect()
        } else {
            (0..=10).map(|i| y0 + (y1 - y0) * i as f64 / 10.0).collect()
        };
        for g in lines {
            chart.draw_series(LineSeries::new([(x0, g), (x1, g)], &grid))?;
        }
        let frame = [
            (x0, y0 - ypad),
            (x1, y0 - ypad),
            (x1, y1 + ypad),
            (x0, y1 + ypad),
            (x0, y0 - ypad),
        ];
        chart.draw_series(LineSeries::new(frame, &BLACK))?;
        for (s, p) in series.iter().zip(&pts) {
            chart.draw_series(LineSeries::new(p.iter().copied(), s.color.stroke_width(2)))?;
            chart.draw_series(p.iter().map(|&q| Circle::new(q, 3, s.color.filled())))?;
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| ReduceError::Plot(e.to_string()))?;
    brdf::write_atomic_with(path, |out| {
        image::codecs::png::PngEncoder::new(out)
            .write_image(&rgb, w, h, image::ExtendedColorType::Rgb8)
            .map_err(std::io::Error::other)
    })
    .map_err(|e| ReduceError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_with_the_curve_pixels() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("curve.png");
        let s = Series {
            points: (1..=20)
                .map(|k| (k as f64, 10f64.powf(-(k as f64) / 5.0)))
                .collect(),
            color: RGBColor(200, 0, 0),
        };
        line_plot_png(&p, &[s], true, (320, 240)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        // The decoded image has the requested size and holds pixels of the curve's colour.
        let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .unwrap()
            .to_rgb8();
        assert_eq!(img.dimensions(), (320, 240));
        let curve = img.pixels().filter(|px| px.0 == [200, 0, 0]).count();
        assert!(curve > 100, "{curve} curve pixels");
        // Only the PNG remains in the directory (temporary file renamed).
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        assert!(line_plot_png(&p, &[], false, (10, 10)).is_err());
    }
}
