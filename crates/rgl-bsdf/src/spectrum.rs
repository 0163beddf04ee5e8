//! Spectra and linear sRGB: the CIE 1931 2° colour matching functions (the multi-lobe
//! Gaussian fit of Wyman, Sloan & Shirley 2013, within a few percent of the tabulated
//! functions), the CIE standard illuminant D65 (the white that renderers light an RGB scene
//! with in their spectral modes) and the XYZ → linear sRGB matrix.

/// Relative spectral power of CIE standard illuminant D65 from 360 to 830 nm in 10 nm steps
/// (CIE 15, normalised to 100 at 560 nm).
const D65: [f64; 48] = [
    46.6383, 52.0891, 49.9755, 54.6482, 82.7549, 91.486, 93.4318, 86.6823, 104.865, 117.008,
    117.812, 114.861, 115.923, 108.811, 109.354, 107.802, 104.79, 107.689, 104.405, 104.046, 100.0,
    96.3342, 95.788, 88.6856, 90.0062, 89.5991, 87.6987, 83.2886, 83.6992, 80.0268, 80.2146,
    82.2778, 78.2842, 69.7213, 71.6091, 74.349, 61.604, 69.8856, 75.087, 63.5927, 46.4182, 66.8054,
    63.3828, 64.304, 59.4519, 51.959, 57.4406, 60.3125,
];

/// D65 at wavelength `l` (nm), interpolated linearly, the end values outside 360–830 nm.
pub fn d65(l: f64) -> f64 {
    let x = ((l - 360.0) / 10.0).clamp(0.0, 47.0);
    let i = (x as usize).min(46);
    let t = x - i as f64;
    D65[i] * (1.0 - t) + D65[i + 1] * t
}

/// A piecewise Gaussian lobe: width `s1` below the mean, `s2` above.
fn lobe(l: f64, mean: f64, s1: f64, s2: f64) -> f64 {
    let t = (l - mean) / if l < mean { s1 } else { s2 };
    (-0.5 * t * t).exp()
}

/// CIE 1931 x̄, ȳ, z̄ at wavelength `l` (nm).
pub fn cie_xyz(l: f64) -> [f64; 3] {
    [
        1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7)
            - 0.065 * lobe(l, 501.1, 20.4, 26.2),
        0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1),
        1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8),
    ]
}

/// XYZ → linear sRGB (D65 white).
pub fn xyz_to_srgb(xyz: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = xyz;
    [
        3.2406 * x - 1.5372 * y - 0.4986 * z,
        -0.9689 * x + 1.8758 * y + 0.0415 * z,
        0.0557 * x - 0.2040 * y + 1.0570 * z,
    ]
}

/// Weights that turn reflectance values sampled at `wavelengths` (nm, increasing) into linear
/// sRGB as seen under D65 light: trapezoidal integration against the colour matching functions
/// times D65, balanced so that a constant spectrum of 1 gives RGB (1, 1, 1).
pub fn rgb_weights(wavelengths: &[f32]) -> Vec<[f64; 3]> {
    let n = wavelengths.len();
    let width = |k: usize| -> f64 {
        if n == 1 {
            return 1.0;
        }
        let lo = if k == 0 {
            wavelengths[0]
        } else {
            wavelengths[k - 1]
        } as f64;
        let hi = if k + 1 == n {
            wavelengths[n - 1]
        } else {
            wavelengths[k + 1]
        } as f64;
        0.5 * (hi - lo)
    };
    let mut weights: Vec<[f64; 3]> = (0..n)
        .map(|k| {
            let l = wavelengths[k] as f64;
            let xyz = cie_xyz(l).map(|c| c * d65(l) * width(k));
            xyz_to_srgb(xyz)
        })
        .collect();
    let mut white = [0.0; 3];
    for w in &weights {
        for c in 0..3 {
            white[c] += w[c];
        }
    }
    for w in &mut weights {
        for c in 0..3 {
            if white[c].abs() > 1e-12 {
                w[c] /= white[c];
            }
        }
    }
    weights
}

/// The wavelengths of the spectral files the writer makes: 360 to 830 nm in 10 nm steps.
pub fn spectral_wavelengths() -> Vec<f32> {
    (0..48).map(|k| 360.0 + 10.0 * k as f32).collect()
}

/// Three smooth spectra, one per linear sRGB channel, that sum to 1 at every wavelength and
/// whose colours under [`rgb_weights`] are exactly red, green and blue: `r S_r + g S_g + b S_b`
/// is then a smooth spectrum of colour `(r, g, b)`, grey spectra stay flat, and the upsampling
/// is linear (it commutes with the renderers' interpolation). The colours are those under D65
/// light ([`rgb_weights`]), the white of renderers' spectral modes. Built from Gaussian bumps at 610,
/// 545 and 455 nm normalised to a partition of unity, then mixed by the inverse of their 3 × 3
/// colour matrix (which keeps the partition). A saturated colour may dip below zero at the
/// ends of the range.
pub fn rgb_basis(wavelengths: &[f32]) -> [Vec<f64>; 3] {
    let bump = |l: f64, mean: f64, width: f64| (-0.5 * ((l - mean) / width).powi(2)).exp();
    let raw: Vec<[f64; 3]> = wavelengths
        .iter()
        .map(|&l| {
            let l = l as f64;
            let w = [
                bump(l, 610.0, 45.0),
                bump(l, 545.0, 35.0),
                bump(l, 455.0, 35.0),
            ];
            let s = w[0] + w[1] + w[2];
            if s > 0.0 {
                w.map(|v| v / s)
            } else {
                [1.0 / 3.0; 3]
            }
        })
        .collect();
    let weights = rgb_weights(wavelengths);
    // p[i][j]: channel i of basis spectrum j
    let mut p = [[0.0f64; 3]; 3];
    for (k, w) in weights.iter().enumerate() {
        for i in 0..3 {
            for j in 0..3 {
                p[i][j] += w[i] * raw[k][j];
            }
        }
    }
    let inv = invert3(&p);
    let mut basis = [
        vec![0.0; wavelengths.len()],
        vec![0.0; wavelengths.len()],
        vec![0.0; wavelengths.len()],
    ];
    for (k, r) in raw.iter().enumerate() {
        for j in 0..3 {
            basis[j][k] = (0..3).map(|c| r[c] * inv[c][j]).sum();
        }
    }
    basis
}

fn invert3(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    let c = |a: usize, b: usize, d: usize, e: usize| m[a][b] * m[d][e] - m[a][e] * m[d][b];
    [
        [
            c(1, 1, 2, 2) / det,
            -c(0, 1, 2, 2) / det,
            c(0, 1, 1, 2) / det,
        ],
        [
            -c(1, 0, 2, 2) / det,
            c(0, 0, 2, 2) / det,
            -c(0, 0, 1, 2) / det,
        ],
        [
            c(1, 0, 2, 1) / det,
            -c(0, 0, 2, 1) / det,
            c(0, 0, 1, 1) / det,
        ],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_colour_matching_functions_peak_where_the_cie_tables_do() {
        let argmax = |c: usize, lo: usize, hi: usize| {
            (lo..hi)
                .max_by(|&a, &b| cie_xyz(a as f64)[c].total_cmp(&cie_xyz(b as f64)[c]))
                .unwrap()
        };
        assert!((argmax(1, 380, 780) as i32 - 555).abs() <= 6);
        assert!((argmax(0, 500, 780) as i32 - 599).abs() <= 6);
        assert!((argmax(2, 380, 780) as i32 - 446).abs() <= 8);
    }

    #[test]
    fn the_upsampling_reproduces_every_colour_and_keeps_grey_flat() {
        let l = spectral_wavelengths();
        let basis = rgb_basis(&l);
        let w = rgb_weights(&l);
        for rgb in [
            [0.2, 0.5, 0.9],
            [1.0, 0.0, 0.0],
            [0.3, 0.3, 0.3],
            [4.0, 2.0, 0.5],
        ] {
            let s: Vec<f64> = (0..l.len())
                .map(|k| (0..3).map(|c| rgb[c] * basis[c][k]).sum())
                .collect();
            let mut back = [0.0; 3];
            for (k, v) in s.iter().enumerate() {
                for c in 0..3 {
                    back[c] += v * w[k][c];
                }
            }
            for c in 0..3 {
                assert!((back[c] - rgb[c]).abs() < 1e-9, "{rgb:?} → {back:?}");
            }
            if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
                assert!(s.iter().all(|v| (v - rgb[0]).abs() < 1e-9));
            }
        }
    }

    #[test]
    fn a_flat_spectrum_is_white_and_a_red_one_is_red() {
        let l: Vec<f32> = (0..41).map(|k| 380.0 + 10.0 * k as f32).collect();
        let w = rgb_weights(&l);
        let project = |s: &dyn Fn(f32) -> f64| {
            let mut rgb = [0.0; 3];
            for (k, &lk) in l.iter().enumerate() {
                for c in 0..3 {
                    rgb[c] += s(lk) * w[k][c];
                }
            }
            rgb
        };
        let white = project(&|_| 0.5);
        assert!(white.iter().all(|v| (v - 0.5).abs() < 1e-9));
        let red = project(&|l| if l > 600.0 { 1.0 } else { 0.0 });
        assert!(
            red[0] > 3.0 * red[1].max(0.0) && red[0] > 3.0 * red[2].max(0.0),
            "{red:?}"
        );
    }
}
