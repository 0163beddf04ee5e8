//! Validation previews (thesis §3.6): measured and re-rendered sphere images side by side.

use crate::geometry::SphereView;

/// An 8-bit RGB image, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Rgb8Image {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `3 · width · height` bytes.
    pub data: Vec<u8>,
}

/// One row of a contact sheet: a measured and a re-rendered full-sensor mosaic (NaN = no data).
#[derive(Debug, Clone)]
pub struct SheetRow {
    /// Measured signal rates, `width · height`.
    pub measured: Vec<f32>,
    /// Re-rendered signal rates, `width · height`.
    pub rendered: Vec<f32>,
}

/// Spreads values given in `view.pixels` order over a full-sensor mosaic (NaN elsewhere).
pub fn to_mosaic(view: &SphereView, values: &[f32]) -> Vec<f32> {
    let mut out = vec![f32::NAN; view.width * view.height];
    for (p, v) in view.pixels.iter().zip(values) {
        out[p.index as usize] = *v;
    }
    out
}

/// Lays out rows of (measured | re-rendered) crops of the sphere's bounding box: the validation
/// preview of thesis §3.6. `channel_at(x, y)` gives the Bayer channel of a photosite.
///
/// The images are raw Bayer mosaics of signal rates; a preview shows each 2 × 2 cell as one RGB
/// pixel (red, mean of the greens, blue) on a logarithmic scale spanning `decades` below the
/// brightest value of the sheet.
pub fn contact_sheet(
    view: &SphereView,
    rows: &[SheetRow],
    channel_at: impl Fn(usize, usize) -> usize,
    decades: f64,
) -> Rgb8Image {
    let (mut x0, mut x1, mut y0, mut y1) = (usize::MAX, 0, usize::MAX, 0);
    for p in &view.pixels {
        let (x, y) = (p.index as usize % view.width, p.index as usize / view.width);
        x0 = x0.min(x);
        x1 = x1.max(x + 1);
        y0 = y0.min(y);
        y1 = y1.max(y + 1);
    }
    if view.pixels.is_empty() || rows.is_empty() {
        return Rgb8Image {
            width: 0,
            height: 0,
            data: Vec::new(),
        };
    }
    // Whole Bayer cells only.
    x0 &= !1;
    y0 &= !1;
    let cw = (x1 - x0).div_ceil(2);
    let ch = (y1 - y0).div_ceil(2);
    let gap = 4;
    let width = 2 * cw + 3 * gap;
    let height = rows.len() * (ch + gap) + gap;
    let max = rows
        .iter()
        .flat_map(|r| r.measured.iter().chain(&r.rendered))
        .filter(|v| v.is_finite())
        .fold(0.0f32, |a, &b| a.max(b));
    let lmax = (max.max(1e-30) as f64).log10();
    let to_byte = |v: f64| -> u8 {
        if !(v.is_finite() && v > 0.0) {
            return 0;
        }
        let t = ((v.log10() - (lmax - decades)) / decades).clamp(0.0, 1.0);
        (t * 255.0).round() as u8
    };
    let mut data = vec![32u8; 3 * width * height];
    for (r, row) in rows.iter().enumerate() {
        let oy = gap + r * (ch + gap);
        for (col, img) in [&row.measured, &row.rendered].into_iter().enumerate() {
            let ox = gap + col * (cw + gap);
            for cy in 0..ch {
                for cx in 0..cw {
                    let mut sum = [0.0f64; 3];
                    let mut n = [0usize; 3];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (x, y) = (x0 + 2 * cx + dx, y0 + 2 * cy + dy);
                        if x >= view.width || y >= view.height {
                            continue;
                        }
                        let v = img[y * view.width + x];
                        if v.is_finite() {
                            let c = channel_at(x, y);
                            sum[c] += v as f64;
                            n[c] += 1;
                        }
                    }
                    let k = 3 * ((oy + cy) * width + ox + cx);
                    for c in 0..3 {
                        data[k + c] = if n[c] > 0 {
                            to_byte(sum[c] / n[c] as f64)
                        } else {
                            0
                        };
                    }
                }
            }
        }
    }
    Rgb8Image {
        width,
        height,
        data,
    }
}
