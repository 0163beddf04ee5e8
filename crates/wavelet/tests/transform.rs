//! Forward/inverse transforms: perfect reconstruction, orthonormality, agreement with
//! PyWavelets and with direct filter convolutions, vanishing moments, basis functions.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use wavelet::{forward, forward_full, inverse, inverse_full, Cube, Wavelet, WaveletError};
use wavelet::{forward_rows, inverse_rows};
use wavelet::{haar_basis_value, CoefficientAddress};

fn random_cube(side: usize, seed: u64) -> Cube {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let data = (0..side * side * side)
        .map(|_| rng.gen_range(-1.0f32..1.0))
        .collect();
    Cube::from_vec(side, data).unwrap()
}

fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn perfect_reconstruction_all_filters_all_levels() {
    for w in Wavelet::ALL {
        for levels in [1, 3, 5] {
            let orig = random_cube(32, 11);
            let mut c = orig.clone();
            forward(&mut c, w, levels).unwrap();
            assert!(
                max_abs_diff(c.data(), orig.data()) > 0.1,
                "{w:?} did nothing"
            );
            inverse(&mut c, w, levels).unwrap();
            let err = max_abs_diff(c.data(), orig.data());
            assert!(err < 2e-5, "{w:?} levels {levels}: max error {err}");
        }
    }
}

#[test]
fn orthonormal_filters_preserve_energy() {
    let orig = random_cube(32, 5);
    for w in [Wavelet::Haar, Wavelet::Daub4] {
        assert!(w.is_orthonormal());
        let mut c = orig.clone();
        forward_full(&mut c, w).unwrap();
        let (e0, e1) = (orig.energy(), c.energy());
        assert!((e0 - e1).abs() < 1e-5 * e0, "{w:?}: {e0} vs {e1}");
    }
    // CDF 5/3 is biorthogonal: energy is not preserved exactly (the flag says so).
    assert!(!Wavelet::Cdf53.is_orthonormal());
}

/// The fixture cube of tools/wavelet/make_fixtures.py.
fn fixture_input() -> Cube {
    let n = 16usize;
    let mut data = Vec::with_capacity(n * n * n);
    for x in 0..n {
        for y in 0..n {
            for z in 0..n {
                let v = (37 * x + 11 * y + 5 * z + x * y * z) % 17;
                data.push((v as f64 / 17.0 - 0.5) as f32);
            }
        }
    }
    Cube::from_vec(n, data).unwrap()
}

fn read_fixture(name: &str) -> Vec<f32> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name);
    let bytes = std::fs::read(&path).unwrap();
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

#[test]
fn haar_matches_pywavelets_wavedecn() {
    for (levels, name) in [(4, "haar16_full.f32"), (2, "haar16_l2.f32")] {
        let mut c = fixture_input();
        forward(&mut c, Wavelet::Haar, levels).unwrap();
        let expect = read_fixture(name);
        assert_eq!(expect.len(), c.data().len());
        let err = max_abs_diff(c.data(), &expect);
        assert!(err < 1e-5, "{name}: max difference {err}");
    }
}

/// 1D one-level transform by direct periodic convolution with the Daubechies-4 filters.
fn d4_direct(x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let r3 = 3f64.sqrt();
    let d = 4.0 * 2f64.sqrt();
    let h = [
        (1.0 + r3) / d,
        (3.0 + r3) / d,
        (3.0 - r3) / d,
        (1.0 - r3) / d,
    ];
    // High-pass taps, aligned one sample pair earlier than the low-pass (lifting alignment).
    let g = [-h[3], h[2], -h[1], h[0]];
    let n = x.len();
    let lo = (0..n / 2)
        .map(|i| (0..4).map(|k| h[k] * x[(2 * i + k) % n]).sum())
        .collect();
    let hi = (0..n / 2)
        .map(|i| (0..4).map(|k| g[k] * x[(2 * i + n - 2 + k) % n]).sum())
        .collect();
    (lo, hi)
}

#[test]
fn daub4_lifting_equals_direct_convolution() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for n in [4usize, 8, 64] {
        let x: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let mut out = vec![0.0f32; n];
        forward_rows(Wavelet::Daub4, &xf, &mut out, n, 1);
        let (lo, hi) = d4_direct(&x);
        for i in 0..n / 2 {
            assert!((out[i] as f64 - lo[i]).abs() < 1e-5, "lo {i} n {n}");
            assert!((out[n / 2 + i] as f64 - hi[i]).abs() < 1e-5, "hi {i} n {n}");
        }
    }
}

#[test]
fn cdf53_matches_filter_definition_in_the_interior() {
    // Analysis filters of CDF 5/3 (scaled as in the crate): low-pass √2·(−1, 2, 6, 2, −1)/8,
    // high-pass (−1, 2, −1)/(2√2) centred on odd samples.
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let n = 32;
    let x: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    let mut out = vec![0.0f32; n];
    forward_rows(Wavelet::Cdf53, &xf, &mut out, n, 1);
    let s2 = 2f64.sqrt();
    for i in 1..n / 2 - 1 {
        let lo = s2
            * (-x[2 * i - 2] + 2.0 * x[2 * i - 1] + 6.0 * x[2 * i] + 2.0 * x[2 * i + 1]
                - x[2 * i + 2])
            / 8.0;
        let hi = (-x[2 * i] + 2.0 * x[2 * i + 1] - x[2 * i + 2]) / (2.0 * s2);
        assert!((out[i] as f64 - lo).abs() < 1e-5, "lo {i}");
        assert!((out[n / 2 + i] as f64 - hi).abs() < 1e-5, "hi {i}");
    }
}

#[test]
fn vanishing_moments() {
    let n = 64;
    let constant = vec![3.0f32; n];
    let ramp: Vec<f32> = (0..n).map(|i| 0.25 * i as f32 - 2.0).collect();
    for w in Wavelet::ALL {
        let mut out = vec![0.0f32; n];
        forward_rows(w, &constant, &mut out, n, 1);
        for (i, d) in out[n / 2..].iter().enumerate() {
            assert!(d.abs() < 1e-5, "{w:?}: constant gives detail {d} at {i}");
        }
    }
    // Two vanishing moments: linear signals give zero details away from the boundary
    // (CDF 5/3 symmetric extension bends the ramp at the right end; Daubechies-4 wraps).
    for w in [Wavelet::Cdf53, Wavelet::Daub4] {
        let mut out = vec![0.0f32; n];
        forward_rows(w, &ramp, &mut out, n, 1);
        for i in 1..n / 2 - 1 {
            let d = out[n / 2 + i];
            assert!(d.abs() < 1e-4, "{w:?}: ramp gives detail {d} at {i}");
        }
    }
    // Haar has only one: the ramp leaves non-zero details.
    let mut out = vec![0.0f32; n];
    forward_rows(Wavelet::Haar, &ramp, &mut out, n, 1);
    assert!(out[n / 2..].iter().all(|d| d.abs() > 0.1));
}

#[test]
fn row_transform_inverts_for_vector_samples() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (s, len) = (16, 5);
    let x: Vec<f32> = (0..s * len).map(|_| rng.gen_range(-1.0..1.0)).collect();
    for w in Wavelet::ALL {
        let mut c = vec![0.0; s * len];
        forward_rows(w, &x, &mut c, s, len);
        // Each column must equal the scalar transform of that column.
        for k in 0..len {
            let col: Vec<f32> = (0..s).map(|r| x[r * len + k]).collect();
            let mut cc = vec![0.0; s];
            forward_rows(w, &col, &mut cc, s, 1);
            for r in 0..s {
                assert!((cc[r] - c[r * len + k]).abs() < 1e-6);
            }
        }
        let mut back = vec![0.0; s * len];
        inverse_rows(w, &mut c, &mut back, s, len);
        assert!(max_abs_diff(&back, &x) < 1e-5, "{w:?}");
    }
}

#[test]
fn haar_basis_functions_are_the_inverse_transform_of_unit_coefficients() {
    let n = 8;
    for index in 0..n * n * n {
        let mut c = Cube::zeros(n).unwrap();
        c.data_mut()[index] = 1.0;
        inverse_full(&mut c, Wavelet::Haar).unwrap();
        for cell in 0..n * n * n {
            let xyz = c.coords(cell);
            let v = haar_basis_value(n, index, xyz);
            assert!(
                (v as f32 - c.data()[cell]).abs() < 1e-6,
                "index {index} cell {xyz:?}"
            );
        }
        let a = CoefficientAddress::from_coords(c.coords(index));
        assert_eq!(a.to_coords(), c.coords(index));
    }
}

#[test]
fn coefficient_addresses_count_like_the_seed() {
    // 8 coefficients at level 0 (scaling + 7 wavelets), then 7·8^l per level.
    let n = 256;
    let mut per_level = [0usize; 8];
    for x in 0..n {
        for y in 0..n {
            // Counting all z for every (x, y) is 16 M addresses; sample the z axis analytically.
            for z in [0usize, 1, 2, 3, 5, 9, 17, 33, 65, 129, 255] {
                let a = CoefficientAddress::from_coords([x, y, z]);
                assert!(a.level < 8);
                assert_eq!(a.to_coords(), [x, y, z]);
                if z == 0 {
                    per_level[a.level as usize] += 1;
                }
            }
        }
    }
    // Coefficients with z = 0 at level l: (2^{l+1})² − (2^l)² plus the level-0 scaling term.
    assert_eq!(per_level[0], 4);
    for (l, &count) in per_level.iter().enumerate().skip(1) {
        let s = 1usize << (l + 1);
        assert_eq!(count, s * s - s * s / 4, "level {l}");
    }
}

#[test]
fn full_merl_cube_reconstructs_perfectly() {
    // One 256³ round trip with a MERL-sized table (the thesis's configuration).
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let table: Vec<f32> = (0..90 * 90 * 180)
        .map(|_| rng.gen_range(0.0f32..2.0))
        .collect();
    let mut c = Cube::embed_merl(&table).unwrap();
    forward_full(&mut c, Wavelet::Haar).unwrap();
    inverse_full(&mut c, Wavelet::Haar).unwrap();
    let back = c.extract_merl().unwrap();
    assert!(max_abs_diff(&back, &table) < 1e-4);
    // The padding stays zero.
    assert!(c.data()[c.index(200, 3, 3)].abs() < 1e-5);
}

#[test]
fn bad_inputs_are_typed_errors() {
    assert_eq!(Cube::zeros(12), Err(WaveletError::NotPowerOfTwo(12)));
    assert_eq!(Cube::zeros(1), Err(WaveletError::NotPowerOfTwo(1)));
    assert!(matches!(
        Cube::from_vec(4, vec![0.0; 10]),
        Err(WaveletError::Length {
            expected: 64,
            found: 10
        })
    ));
    let mut v = vec![0.0f32; 90 * 90 * 180];
    v[123] = f32::NAN;
    assert_eq!(
        Cube::embed_merl(&v),
        Err(WaveletError::NonFinite { index: 123 })
    );
    assert!(matches!(
        Cube::embed(&[0.0; 8], [2, 2, 2], 1),
        Err(WaveletError::NotPowerOfTwo(1))
    ));
    assert!(matches!(
        Cube::embed(&vec![0.0; 9 * 4 * 4], [9, 4, 4], 8),
        Err(WaveletError::ExtentTooLarge { .. })
    ));
    let mut c = Cube::zeros(8).unwrap();
    assert!(matches!(
        forward(&mut c, Wavelet::Haar, 4),
        Err(WaveletError::TooManyLevels { max: 3, .. })
    ));
    assert!(matches!(
        inverse(&mut c, Wavelet::Cdf53, 9),
        Err(WaveletError::TooManyLevels { .. })
    ));
    assert_eq!("db4".parse::<Wavelet>(), Ok(Wavelet::Daub4));
    assert!("sym8".parse::<Wavelet>().is_err());
}

/// Naive nonstandard decomposition: every level, every line along every axis, one scalar 1D
/// step at a time.
fn naive_forward(cube: &Cube, w: Wavelet, levels: u32) -> Vec<f32> {
    let n = cube.side();
    let mut d = cube.data().to_vec();
    let idx = |x: usize, y: usize, z: usize| (x * n + y) * n + z;
    for l in 0..levels {
        let s = n >> l;
        for axis in 0..3 {
            for u in 0..s {
                for v in 0..s {
                    let at = |t: usize| match axis {
                        0 => idx(t, u, v),
                        1 => idx(u, t, v),
                        _ => idx(u, v, t),
                    };
                    let line: Vec<f32> = (0..s).map(|t| d[at(t)]).collect();
                    let mut out = vec![0.0f32; s];
                    forward_rows(w, &line, &mut out, s, 1);
                    for (t, &o) in out.iter().enumerate() {
                        d[at(t)] = o;
                    }
                }
            }
        }
    }
    d
}

#[test]
fn blocked_3d_transform_equals_naive_line_by_line_transform() {
    for w in Wavelet::ALL {
        for levels in [1, 2, 5] {
            let orig = random_cube(32, 21);
            let mut c = orig.clone();
            forward(&mut c, w, levels).unwrap();
            let naive = naive_forward(&orig, w, levels);
            let err = max_abs_diff(c.data(), &naive);
            assert!(err < 1e-5, "{w:?} levels {levels}: {err}");
        }
    }
}
