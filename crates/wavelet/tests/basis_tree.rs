//! Thresholding, the Common Wavelet Basis and the Common Wavelet Coefficient Tree.

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use wavelet::{
    forward_full, inverse_full, CoefficientTree, CommonBasis, Cube, Layout, Wavelet, WaveletError,
};
use wavelet::{keep_for_relative_error, keep_largest, relative_l2_error, zero_all_but};

/// A small MERL-like layout: a 12 × 12 × 24 table in a 32³ cube.
const SMALL: Layout = Layout {
    side: 32,
    extent: [12, 12, 24],
    wavelet: Wavelet::Haar,
};

/// A synthetic BRDF-like channel on the small grid: diffuse term plus a specular lobe in θh
/// whose width and height vary with `p`, plus a Fresnel-like rise in θd.
fn lobe(p: f64, q: f64) -> Vec<f32> {
    let [ex, ey, ez] = SMALL.extent;
    let mut v = Vec::with_capacity(ex * ey * ez);
    for i in 0..ex {
        let th = (i as f64 / ex as f64).powi(2) * std::f64::consts::FRAC_PI_2;
        for j in 0..ey {
            let td = j as f64 / ey as f64 * std::f64::consts::FRAC_PI_2;
            for k in 0..ez {
                let pd = k as f64 / ez as f64 * std::f64::consts::PI;
                let spec = (-(th / (0.05 + 0.2 * p)).powi(2)).exp() * (1.0 + 5.0 * p);
                let fres = q * (1.0 - td.cos()).powi(5);
                let aniso = 0.02 * (2.0 * pd).cos() * q;
                v.push((0.1 + 0.3 * q + spec + fres + aniso) as f32);
            }
        }
    }
    v
}

fn corpus() -> Vec<Vec<f32>> {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    (0..8)
        .map(|_| lobe(rng.gen_range(0.0..1.0), rng.gen_range(0.0..1.0)))
        .collect()
}

fn reconstruct_with(layout: Layout, values: &[f32], keep: &[u32]) -> Vec<f32> {
    let mut c = layout.analyse(values).unwrap();
    zero_all_but(c.data_mut(), keep);
    layout.synthesise(c).unwrap()
}

#[test]
fn thresholding_meets_the_target_with_the_fewest_coefficients() {
    let f = lobe(0.3, 0.6);
    let coeffs = SMALL.analyse(&f).unwrap();
    for target in [0.1, 0.03, 0.01] {
        let t = keep_for_relative_error(coeffs.data(), target).unwrap();
        assert!(t.relative_error <= target);
        // Independent check by inverse transform over the whole cube: the reconstruction error
        // equals the prediction (Parseval) and meets the target.
        let mut c = coeffs.clone();
        zero_all_but(c.data_mut(), &t.indices);
        inverse_full(&mut c, Wavelet::Haar).unwrap();
        let full = Cube::embed(&f, SMALL.extent, SMALL.side).unwrap();
        let err = relative_l2_error(full.data(), c.data());
        assert!(err <= target + 1e-5, "target {target}: {err}");
        assert!((err - t.relative_error).abs() < 1e-4);
        // Minimality: one coefficient fewer (the largest-count rule) misses the target.
        let fewer = keep_largest(coeffs.data(), t.indices.len() - 1);
        let mut c = coeffs.clone();
        zero_all_but(c.data_mut(), &fewer);
        inverse_full(&mut c, Wavelet::Haar).unwrap();
        assert!(relative_l2_error(full.data(), c.data()) > target - 1e-6);
    }
    // Tighter targets keep more.
    let a = keep_for_relative_error(coeffs.data(), 0.1).unwrap();
    let b = keep_for_relative_error(coeffs.data(), 0.01).unwrap();
    assert!(a.indices.len() < b.indices.len());
    assert_eq!(
        keep_for_relative_error(coeffs.data(), 0.0)
            .unwrap()
            .indices
            .len(),
        b.nonzero
    );
}

#[test]
fn keep_largest_keeps_the_largest() {
    let c = [0.0f32, -5.0, 1.0, 3.0, -0.5, 2.0];
    assert_eq!(keep_largest(&c, 3), vec![1, 3, 5]);
    assert_eq!(keep_largest(&c, 10), vec![1, 2, 3, 4, 5]);
    let mut d = c;
    zero_all_but(&mut d, &[2, 5]);
    assert_eq!(d, [0.0, 0.0, 1.0, 0.0, 0.0, 2.0]);
}

#[test]
fn common_basis_is_the_union_and_represents_every_component() {
    let corpus = corpus();
    let refs: Vec<&[f32]> = corpus.iter().map(|v| v.as_slice()).collect();
    let (cwb, stats) = CommonBasis::build(SMALL, &refs, 0.03).unwrap();
    assert_eq!(stats.len(), corpus.len());
    let max_kept = stats.iter().map(|s| s.kept).max().unwrap();
    let sum_kept: usize = stats.iter().map(|s| s.kept).sum();
    assert!(cwb.len() >= max_kept && cwb.len() <= sum_kept);
    // Coherence: the union is much smaller than the sum.
    assert!(cwb.len() < sum_kept, "{} vs {}", cwb.len(), sum_kept);
    for (f, s) in corpus.iter().zip(&stats) {
        let own = SMALL.analyse(f).unwrap();
        let own = keep_for_relative_error(own.data(), 0.03).unwrap();
        assert_eq!(own.indices.len(), s.kept);
        // Every kept coefficient of this component is in the basis.
        for i in &own.indices {
            assert!(cwb.indices().binary_search(i).is_ok());
        }
        // So its projection on the basis is at least as accurate (checked over the table).
        let p = cwb.project(f).unwrap();
        let err = relative_l2_error(f, &p);
        let own_err = relative_l2_error(f, &reconstruct_with(SMALL, f, &own.indices));
        assert!(err <= own_err + 1e-6, "{err} > {own_err}");
        assert!(err <= 0.03 + 1e-5);
    }
    let hist = cwb.level_histogram();
    assert_eq!(hist.iter().sum::<usize>(), cwb.len());
    assert!((cwb.fraction_of_table() - cwb.len() as f64 / 3456.0).abs() < 1e-12);
}

#[test]
fn tree_evaluation_equals_inverse_transform_everywhere() {
    let corpus = corpus();
    let refs: Vec<&[f32]> = corpus.iter().map(|v| v.as_slice()).collect();
    let (cwb, _) = CommonBasis::build(SMALL, &refs, 0.03).unwrap();
    let tree = CoefficientTree::from_functions(&cwb, &refs).unwrap();
    assert_eq!(tree.functions(), corpus.len());
    let recon: Vec<Vec<f32>> = corpus.iter().map(|f| cwb.project(f).unwrap()).collect();
    let [ex, ey, ez] = SMALL.extent;
    let mut out = vec![0.0f32; corpus.len()];
    let mut max_visited = 0;
    for i in 0..ex {
        for j in 0..ey {
            for k in 0..ez {
                let visited = tree.eval_bin(i, j, k, &mut out).unwrap();
                max_visited = max_visited.max(visited);
                let b = (i * ey + j) * ez + k;
                for (f, r) in recon.iter().enumerate() {
                    assert!(
                        (out[f] - r[b]).abs() < 1e-5 * (1.0 + r[b].abs()),
                        "cell {i} {j} {k} function {f}: {} vs {}",
                        out[f],
                        r[b]
                    );
                }
            }
        }
    }
    // One node per level at most: log2(32) = 5.
    assert!((1..=5).contains(&max_visited));
    // Batch evaluation agrees with single evaluation.
    let cells = [[0, 0, 0], [3, 7, 20], [11, 11, 23]];
    let batch = tree.eval_cells(&cells).unwrap();
    for (c, chunk) in cells.iter().zip(batch.chunks(corpus.len())) {
        tree.eval_cell(*c, &mut out).unwrap();
        assert_eq!(chunk, out.as_slice());
    }
    let st = tree.storage();
    assert_eq!(st.rows, cwb.len());
    assert_eq!(st.coefficient_bytes, cwb.len() * corpus.len() * 4);
    assert_eq!(st.nodes, tree.node_count());
}

#[test]
fn tree_and_basis_reject_bad_input() {
    let corpus = corpus();
    let refs: Vec<&[f32]> = corpus.iter().map(|v| v.as_slice()).collect();
    let (cwb, _) = CommonBasis::build(SMALL, &refs[..2], 0.05).unwrap();
    assert_eq!(
        CoefficientTree::new(&cwb, &[]).unwrap_err(),
        WaveletError::NoFunctions
    );
    assert!(matches!(
        CoefficientTree::new(&cwb, &[vec![0.0; cwb.len() + 1]]),
        Err(WaveletError::Length { .. })
    ));
    let tree = CoefficientTree::from_functions(&cwb, &refs[..2]).unwrap();
    let mut out = vec![0.0; 2];
    assert!(matches!(
        tree.eval_cell([32, 0, 0], &mut out),
        Err(WaveletError::IndexOutOfRange { .. })
    ));
    assert!(matches!(
        tree.eval_cell([0, 0, 0], &mut [0.0; 3]),
        Err(WaveletError::Length { .. })
    ));
    let smooth = Layout {
        wavelet: Wavelet::Cdf53,
        ..SMALL
    };
    let b = CommonBasis::from_indices(smooth, vec![0, 5]).unwrap();
    assert!(matches!(
        CoefficientTree::new(&b, &[vec![1.0, 2.0]]),
        Err(WaveletError::UnsupportedWavelet(_))
    ));
    assert!(matches!(
        CommonBasis::from_indices(SMALL, vec![32 * 32 * 32]),
        Err(WaveletError::IndexOutOfRange { .. })
    ));
    assert!(matches!(
        CommonBasis::build(SMALL, &refs[..1], 1.5),
        Err(WaveletError::BadErrorTarget(_))
    ));
    assert!(matches!(
        CommonBasis::build(SMALL, &[&[0.0; 7][..]], 0.03),
        Err(WaveletError::Length { .. })
    ));
    let mut bad = corpus[0].clone();
    bad[3] = f32::INFINITY;
    assert!(matches!(
        cwb.coefficients(&bad),
        Err(WaveletError::NonFinite { index: 3 })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
        ..ProptestConfig::with_cases(24)
    })]
    /// For arbitrary sparse coefficient sets on an 8³ cube, the tree evaluates exactly the
    /// inverse Haar transform of the coefficients.
    #[test]
    fn tree_matches_inverse_for_random_sparse_sets(
        picks in proptest::collection::vec((0usize..512, -2.0f32..2.0, -2.0f32..2.0), 1..40)
    ) {
        let layout = Layout { side: 8, extent: [8, 8, 8], wavelet: Wavelet::Haar };
        let idx: Vec<u32> = picks.iter().map(|p| p.0 as u32).collect();
        let basis = CommonBasis::from_indices(layout, idx).unwrap();
        // Two functions with coefficients from the picks (last pick wins on duplicates).
        let mut dense = [vec![0.0f32; 512], vec![0.0f32; 512]];
        for p in &picks {
            dense[0][p.0] = p.1;
            dense[1][p.0] = p.2;
        }
        let coefs: Vec<Vec<f32>> = dense
            .iter()
            .map(|d| basis.indices().iter().map(|&i| d[i as usize]).collect())
            .collect();
        let tree = CoefficientTree::new(&basis, &coefs).unwrap();
        let mut out = [0.0f32; 2];
        for (f, d) in dense.iter().enumerate() {
            let mut c = Cube::from_vec(8, d.clone()).unwrap();
            inverse_full(&mut c, Wavelet::Haar).unwrap();
            for cell in 0..512 {
                let xyz = c.coords(cell);
                tree.eval_cell(xyz, &mut out).unwrap();
                prop_assert!((out[f] - c.data()[cell]).abs() < 1e-5);
            }
        }
        // Round trip through the forward transform as well.
        let mut c = Cube::from_vec(8, dense[0].clone()).unwrap();
        inverse_full(&mut c, Wavelet::Haar).unwrap();
        forward_full(&mut c, Wavelet::Haar).unwrap();
        for (a, b) in c.data().iter().zip(&dense[0]) {
            prop_assert!((a - b).abs() < 1e-5);
        }
    }
}

#[test]
fn smooth_wavelets_beat_haar_on_smooth_functions_at_equal_count() {
    use wavelet::error_at_equal_counts;
    // A smooth function filling the whole 32³ cube, periodic along every axis so that neither
    // the symmetric (CDF 5/3) nor the periodic (Daubechies-4) boundary rule creates an edge.
    let layout = Layout {
        side: 32,
        extent: [32, 32, 32],
        wavelet: Wavelet::Haar,
    };
    let tau = std::f64::consts::TAU / 32.0;
    let mut f = Vec::with_capacity(32 * 32 * 32);
    for x in 0..32 {
        for y in 0..32 {
            for z in 0..32 {
                let (x, y, z) = (x as f64 * tau, y as f64 * tau, z as f64 * tau);
                f.push((2.0 + x.cos() * (2.0 * y).sin() + 0.5 * (x + z).cos()) as f32);
            }
        }
    }
    // Approximation order shows once the coarse levels are spent (at a few dozen
    // coefficients Haar can still win on this function).
    let counts = [100, 200, 400, 1000];
    let r = error_at_equal_counts(layout, &f, &Wavelet::ALL, &counts).unwrap();
    for (i, &n) in counts.iter().enumerate() {
        let haar = r[i].relative_error;
        let cdf = r[counts.len() + i].relative_error;
        let d4 = r[2 * counts.len() + i].relative_error;
        assert_eq!(r[i].count, n);
        assert!(
            cdf < haar && d4 < haar,
            "count {n}: haar {haar} cdf {cdf} d4 {d4}"
        );
    }
    // More coefficients, less error.
    assert!(r[0].relative_error > r[3].relative_error);
    // All coefficients: exact.
    let all = error_at_equal_counts(layout, &f, &[Wavelet::Cdf53], &[32 * 32 * 32]).unwrap();
    assert!(all[0].relative_error < 1e-5);
}

#[test]
fn basis_file_round_trip_and_malformed_files() {
    let corpus = corpus();
    let refs: Vec<&[f32]> = corpus.iter().map(|v| v.as_slice()).collect();
    let (cwb, _) = CommonBasis::build(SMALL, &refs[..3], 0.03).unwrap();
    let dir = std::env::temp_dir().join(format!("wavelet-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("basis.cwb");
    cwb.write(&path).unwrap();
    assert_eq!(CommonBasis::read(&path).unwrap(), cwb);
    let bytes = cwb.to_bytes();
    assert!(matches!(
        CommonBasis::from_bytes(&bytes[..bytes.len() - 1]),
        Err(WaveletError::Format(_))
    ));
    assert!(matches!(
        CommonBasis::from_bytes(b"garbage"),
        Err(WaveletError::Format(_))
    ));
    let mut wrong = bytes.clone();
    wrong[24] = 9;
    assert!(matches!(
        CommonBasis::from_bytes(&wrong),
        Err(WaveletError::Format(_))
    ));
    assert!(matches!(
        CommonBasis::read(dir.join("missing.cwb")),
        Err(WaveletError::Io(_))
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn basis_at_cell_is_the_row_of_h() {
    use wavelet::haar_basis_value;
    let layout = Layout {
        side: 16,
        extent: [16, 16, 16],
        wavelet: Wavelet::Haar,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let idx: Vec<u32> = (0..300).map(|_| rng.gen_range(0..4096)).collect();
    let basis = CommonBasis::from_indices(layout, idx).unwrap();
    let tree = CoefficientTree::structure(&basis).unwrap();
    assert_eq!(tree.functions(), 0);
    let mut row = Vec::new();
    for cell in 0..4096usize {
        let xyz = [cell / 256, (cell / 16) % 16, cell % 16];
        tree.basis_at_cell(xyz, &mut row).unwrap();
        let mut dense = vec![0.0f64; basis.len()];
        for &(b, v) in &row {
            dense[b as usize] = v as f64;
        }
        for (b, &i) in basis.indices().iter().enumerate() {
            let expect = haar_basis_value(16, i as usize, xyz);
            assert!((dense[b] - expect).abs() < 1e-7, "cell {xyz:?} basis {i}");
        }
        // Haar: one node per level, at most 8 types each.
        assert!(row.len() <= 8 * 4);
    }
}

#[test]
fn coarse_grid_of_block_means_gives_the_low_levels() {
    use wavelet::coarse_to_fine_scale;
    // A function constant on 4³ blocks of a 32³ cube, and the 8³ grid of its block values.
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let coarse_vals: Vec<f32> = (0..512).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut fine = Cube::zeros(32).unwrap();
    for x in 0..32 {
        for y in 0..32 {
            for z in 0..32 {
                let i = fine.index(x, y, z);
                fine.data_mut()[i] = coarse_vals[((x / 4) * 8 + y / 4) * 8 + z / 4];
            }
        }
    }
    let mut coarse = Cube::from_vec(8, coarse_vals).unwrap();
    forward_full(&mut fine, Wavelet::Haar).unwrap();
    forward_full(&mut coarse, Wavelet::Haar).unwrap();
    let s = coarse_to_fine_scale(32, 8) as f32;
    for x in 0..8 {
        for y in 0..8 {
            for z in 0..8 {
                let a = coarse.data()[coarse.index(x, y, z)] * s;
                let b = fine.data()[fine.index(x, y, z)];
                assert!((a - b).abs() < 1e-4, "{x} {y} {z}: {a} vs {b}");
            }
        }
    }
    // Finer levels of a block-constant function vanish.
    let max_fine = (0..32 * 32 * 32)
        .filter(|&i| fine.coords(i).iter().any(|&c| c >= 8))
        .map(|i| fine.data()[i].abs())
        .fold(0.0f32, f32::max);
    assert!(max_fine < 1e-4);
}

#[test]
fn dimension_major_matrices_split_into_functions() {
    use wavelet::functions_from_dimension_major;
    // Two vectors of length 6 (two functions of 3 values each), stored dimension-major.
    let v = [
        [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0],
        [7.0, 8.0, 9.0, 10.0, 11.0, 12.0],
    ];
    let m: Vec<f32> = (0..6).flat_map(|d| [v[0][d], v[1][d]]).collect();
    let f = functions_from_dimension_major(&m, 2, 3).unwrap();
    assert_eq!(
        f,
        vec![
            vec![1.0, 2.0, 3.0],
            vec![4.0, 5.0, 6.0],
            vec![7.0, 8.0, 9.0],
            vec![10.0, 11.0, 12.0]
        ]
    );
    assert!(functions_from_dimension_major(&m, 2, 4).is_err());
    assert!(functions_from_dimension_major(&m, 0, 3).is_err());
}
