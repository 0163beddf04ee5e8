//! The Common Wavelet Basis and tree on real measured materials (two shared MERL materials at
//! full 256³ resolution). Needs the shared data directory (set `BRDF_DATA_DIR`, see
//! `brdf::data_dir`): without it the test fails saying so.

use brdf::nbrdf::Nbrdf;
use brdf::BINS;
use wavelet::relative_l2_error;
use wavelet::{CoefficientTree, CommonBasis, Layout};

#[test]
fn merl_materials_are_represented_within_the_target_by_their_common_basis() {
    let dir = brdf::data_dir().join("nbrdf/merl");
    assert!(
        dir.is_dir(),
        "this test needs the shared MERL materials at {}; set BRDF_DATA_DIR to the shared data \
         directory",
        dir.display()
    );
    let tables: Vec<Vec<f32>> = ["blue-metallic-paint", "white-fabric"]
        .iter()
        .map(|n| Nbrdf::load(&dir, n).unwrap().tabulate_f32())
        .collect();
    // Green channel of each: one specular, one diffuse material.
    let comps: Vec<&[f32]> = tables.iter().map(|t| &t[BINS..2 * BINS]).collect();
    let (cwb, stats) = CommonBasis::build(Layout::MERL_HAAR, &comps, 0.03).unwrap();
    assert!(cwb.len() >= stats.iter().map(|s| s.kept).max().unwrap());
    // A measured channel is compressible: far fewer coefficients than table values.
    assert!(cwb.fraction_of_table() < 0.2, "{}", cwb.fraction_of_table());
    let tree = CoefficientTree::from_functions(&cwb, &comps).unwrap();
    for (k, c) in comps.iter().enumerate() {
        // Independent check of the target by inverse transform, over the table region.
        let p = cwb.project(c).unwrap();
        let err = relative_l2_error(c, &p);
        assert!(err <= 0.03 + 1e-4, "material {k}: {err}");
        // The tree reproduces the projection at the specular peak and elsewhere.
        let mut out = [0.0f32; 2];
        for (i, j, l) in [(0, 0, 0), (1, 45, 90), (40, 30, 17), (89, 89, 179)] {
            tree.eval_bin(i, j, l, &mut out).unwrap();
            let b = l + 180 * (j + 90 * i);
            assert!((out[k] - p[b]).abs() <= 1e-4 * (1.0 + p[b].abs()));
        }
    }
}
