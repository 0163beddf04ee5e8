//! The per-pixel fit on synthetic series, checked against an independent least-squares solve,
//! quantisation bounds and hand-countable properties.

use gantry_hal::{BayerFrame, BayerPattern};
use hdr::{flags, merge, thesis_ladder, DefectMap, HdrError, Intercept, MergeOptions};
use proptest::prelude::*;

/// Frames of `rates.len()` pixels in one row: value = round(black + rate·t) clipped to 10 bits,
/// optionally through a response `curve` (identity for a linear sensor).
fn series(rates: &[f64], black: f64, ts: &[f64], curve: impl Fn(f64) -> f64) -> Vec<BayerFrame> {
    ts.iter()
        .enumerate()
        .map(|(k, &t)| {
            let data = rates
                .iter()
                .map(|&r| (black + curve(r * t)).round().clamp(0.0, 1023.0) as u16)
                .collect();
            BayerFrame::new(
                rates.len(),
                1,
                10,
                BayerPattern::Rggb,
                data,
                t,
                0.0,
                25.0,
                k as u64,
            )
            .unwrap()
        })
        .collect()
}

/// Weighted least squares (weights 1/t) solved from the explicit list of samples.
fn reference_fit(samples: &[(f64, f64)], black: Option<f64>) -> f64 {
    match black {
        Some(b) => {
            // minimise Σ (v − b − r t)² / t  →  r = Σ (v − b) / Σ t
            let num: f64 = samples.iter().map(|(_, v)| v - b).sum();
            let den: f64 = samples.iter().map(|(t, _)| t).sum();
            num / den
        }
        None => {
            // Normal equations of [1 t]·[a r]ᵀ with weights w = 1/t.
            let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for &(t, v) in samples {
                let w = 1.0 / t;
                a11 += w;
                a12 += w * t;
                a22 += w * t * t;
                b1 += w * v;
                b2 += w * t * v;
            }
            let det = a11 * a22 - a12 * a12;
            (a11 * b2 - a12 * b1) / det
        }
    }
}

fn in_window(frames: &[BayerFrame], i: usize, lo: f64, hi: f64) -> Vec<(f64, f64)> {
    frames
        .iter()
        .map(|f| (f.exposure_s, f.data[i] as f64))
        .filter(|(_, v)| *v >= lo && *v <= hi)
        .collect()
}

#[test]
fn slopes_match_an_independent_weighted_least_squares_solve() {
    let ts = thesis_ladder();
    // Rates from 0.5 to 5e7 DN/s, 60 per decade.
    let rates: Vec<f64> = (0..=480)
        .map(|k| 0.5 * 10f64.powf(k as f64 / 60.0))
        .collect();
    let frames = series(&rates, 4.0, &ts, |s| s);
    for intercept in [Intercept::Fitted, Intercept::BlackLevel(4.0)] {
        let opts = MergeOptions {
            intercept,
            ..Default::default()
        };
        let img = merge(&frames, None, &opts).unwrap();
        let mut compared = 0;
        for (i, &r) in rates.iter().enumerate() {
            let s = in_window(&frames, i, 10.0, 1000.0);
            assert_eq!(img.count[i] as usize, s.len(), "count of rate {r}");
            let black = match intercept {
                Intercept::BlackLevel(b) => Some(b),
                Intercept::Fitted => None,
            };
            if s.len() >= 3 {
                let want = reference_fit(&s, black);
                let got = img.radiance[i] as f64;
                assert!(
                    (got / want - 1.0).abs() < 1e-5,
                    "{intercept:?} rate {r}: {got} vs {want}"
                );
                compared += 1;
            }
            assert_eq!(img.valid[i], s.len() >= 3 && img.correlation[i] >= 0.998);
        }
        assert!(compared > 350, "{compared}");
    }
}

#[test]
fn noise_free_series_recover_the_rate_within_the_quantisation_bound() {
    let ts = thesis_ladder();
    let rates: Vec<f64> = (0..=420)
        .map(|k| 2.0 * 10f64.powf(k as f64 / 60.0))
        .collect();
    let frames = series(&rates, 4.0, &ts, |s| s);
    let img = merge(
        &frames,
        None,
        &MergeOptions {
            intercept: Intercept::BlackLevel(4.0),
            ..Default::default()
        },
    )
    .unwrap();
    for (i, &r) in rates.iter().enumerate() {
        let s = in_window(&frames, i, 10.0, 1000.0);
        if s.len() < 3 {
            continue;
        }
        // Each sample is off by at most ½ DN: |Σe| / Σt ≤ n/2 / Σt.
        let bound = 0.5 * s.len() as f64 / s.iter().map(|(t, _)| t).sum::<f64>();
        let err = (img.radiance[i] as f64 - r).abs();
        assert!(
            err <= bound * 1.0001 + 1e-6 * r,
            "rate {r}: err {err} > {bound}"
        );
        assert!(img.valid[i] && img.correlation[i] > 0.999, "rate {r}");
    }
}

#[test]
fn frame_order_does_not_matter() {
    let ts = thesis_ladder();
    let rates: Vec<f64> = (0..300).map(|k| 1.3 * 1.05f64.powi(k)).collect();
    let frames = series(&rates, 4.0, &ts, |s| s);
    let mut shuffled = frames.clone();
    shuffled.reverse();
    shuffled.swap(2, 11);
    let opts = MergeOptions::default();
    let a = merge(&frames, None, &opts).unwrap();
    let b = merge(&shuffled, None, &opts).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.exposures_s, ts);
}

#[test]
fn hot_pixels_are_masked_and_extreme_pixels_flagged() {
    let ts = thesis_ladder();
    // 0: ordinary, 1: hot, 2: too bright for 40 µs, 3: too dark for 20 s, 4: only 2 samples.
    let rates = [500.0, 500.0, 1e8, 0.1, 1000.0 / (20.0 / 2.164) * 0.6];
    let frames = series(&rates, 4.0, &ts, |s| s);
    let defects = DefectMap::from_mask(5, 1, vec![false, true, false, false, false]).unwrap();
    let img = merge(&frames, Some(&defects), &MergeOptions::default()).unwrap();
    assert!(img.valid[0] && img.flags[0] == 0);
    assert_eq!(img.flags[1] & flags::HOT, flags::HOT);
    assert!(!img.valid[1] && img.count[1] == 0);
    assert_eq!(img.flags[2], flags::SATURATED | flags::TOO_FEW);
    assert_eq!(img.count[2], 0);
    assert_eq!(img.flags[3], flags::UNDEREXPOSED | flags::TOO_FEW);
    let n4 = in_window(&frames, 4, 10.0, 1000.0).len();
    assert_eq!(img.count[4] as usize, n4);
}

#[test]
fn a_nonlinear_response_fails_the_correlation_test() {
    let ts = thesis_ladder();
    let rates: Vec<f64> = (0..100).map(|k| 5.0 * 1.1f64.powi(k)).collect();
    let linear = series(&rates, 4.0, &ts, |s| s);
    // A strongly compressive response (gamma 0.5): the fit's correlation falls below 0.998.
    let gamma = series(&rates, 4.0, &ts, |s| 31.6 * s.sqrt());
    let opts = MergeOptions::default();
    let a = merge(&linear, None, &opts).unwrap();
    let b = merge(&gamma, None, &opts).unwrap();
    let ok_a = a.valid.iter().filter(|&&v| v).count();
    let low_b = b
        .flags
        .iter()
        .filter(|&&f| f & flags::LOW_CORRELATION != 0)
        .count();
    assert!(ok_a > 90, "{ok_a}");
    assert!(low_b > 80, "{low_b}");
    // Correlations of the nonlinear series are computed, finite, and lower.
    for i in 0..rates.len() {
        if a.count[i] >= 3 && b.count[i] >= 3 {
            assert!(b.correlation[i] < a.correlation[i]);
        }
    }
}

#[test]
fn bad_input_is_a_typed_error() {
    let ts = [0.01, 0.02, 0.04];
    let frames = series(&[10.0, 20.0], 4.0, &ts, |s| s);
    let opts = MergeOptions::default();
    let empty: Vec<BayerFrame> = vec![];
    assert!(matches!(
        merge(&empty, None, &opts),
        Err(HdrError::NoFrames)
    ));
    let mut f = frames.clone();
    f[1].exposure_s = f64::NAN;
    assert!(matches!(
        merge(&f, None, &opts),
        Err(HdrError::InvalidExposure { index: 1, .. })
    ));
    let mut f = frames.clone();
    f[2].data.push(0);
    assert!(matches!(
        merge(&f, None, &opts),
        Err(HdrError::MalformedFrame { index: 2, .. })
    ));
    let mut f = frames.clone();
    f[0].width = 1;
    f[0].height = 2;
    assert!(matches!(
        merge(&f, None, &opts),
        Err(HdrError::Dimensions(_))
    ));
    let d = DefectMap::empty(3, 1);
    assert!(matches!(
        merge(&frames, Some(&d), &opts),
        Err(HdrError::Dimensions(_))
    ));
    let same = series(&[10.0], 4.0, &[0.5, 0.5, 0.5], |s| s);
    assert!(matches!(
        merge(&same, None, &opts),
        Err(HdrError::DegenerateSeries(_))
    ));
    let known = MergeOptions {
        intercept: Intercept::BlackLevel(4.0),
        min_valid: 1,
        ..Default::default()
    };
    assert!(merge(&same, None, &known).is_ok());
    for bad in [
        MergeOptions {
            low_dn: 1000.0,
            high_dn: 10.0,
            ..Default::default()
        },
        MergeOptions {
            min_correlation: f64::NAN,
            ..Default::default()
        },
        MergeOptions {
            min_valid: 1,
            ..Default::default()
        },
        MergeOptions {
            intercept: Intercept::BlackLevel(f64::INFINITY),
            ..Default::default()
        },
    ] {
        assert!(matches!(
            merge(&frames, None, &bad),
            Err(HdrError::InvalidOption(_))
        ));
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
        ..ProptestConfig::with_cases(64)
    })]
    /// Adding a whole number of DN to every sample moves the line up without changing its
    /// slope: with a fitted intercept the estimate is unchanged whenever the same exposures
    /// stay inside the window.
    #[test]
    fn fitted_slope_is_invariant_to_a_constant_offset(
        log_rate in 0.0f64..7.0,
        black in 0u16..9,
    ) {
        let rate = 10f64.powf(log_rate);
        let ts = thesis_ladder();
        let fa = series(&[rate], 0.0, &ts, |s| s);
        let fb = series(&[rate], black as f64, &ts, |s| s);
        let sa: Vec<f64> = in_window(&fa, 0, 10.0, 1000.0).iter().map(|p| p.0).collect();
        let sb: Vec<f64> = in_window(&fb, 0, 10.0, 1000.0).iter().map(|p| p.0).collect();
        prop_assume!(sa == sb && sa.len() >= 2);
        let a = merge(&fa, None, &MergeOptions::default()).unwrap();
        let b = merge(&fb, None, &MergeOptions::default()).unwrap();
        let rel = (a.radiance[0] as f64 / b.radiance[0] as f64 - 1.0).abs();
        prop_assert!(rel < 1e-6, "rel {}", rel);
        prop_assert_eq!(a.count[0], b.count[0]);
    }
}
