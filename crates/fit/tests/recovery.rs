//! Parameter recovery: a known analytic material, tabulated on the MERL grid, is fitted by the
//! model it was made with, and the fit finds its parameters again.

use fit::{fit, FitData, FitOptions, ModelKind, Objective, Parametric, Subset};

/// Fits `kind` to the table of the material with model parameters `truth` (on a seeded subset
/// of its bins) and returns the fitted parameters.
fn recover(kind: ModelKind, truth: &[f64]) -> Vec<f64> {
    let spec = Parametric {
        kind,
        q: truth.to_vec(),
    }
    .spec();
    let table = brdf::load(&spec).unwrap().tabulate();
    let data = FitData::new(&table).unwrap();
    let options = FitOptions {
        objective: Objective::Log,
        subset: Subset::Random {
            bins: 3000,
            seed: 7,
        },
        starts: 2,
        seed: 3,
        ..FitOptions::default()
    };
    let result = fit(kind, &data, &options).unwrap();
    assert!(
        result.fit_error < 1e-3,
        "{spec}: error {}",
        result.fit_error
    );
    result.model.q
}

/// Every parameter within `tolerance` of the truth, relative (absolute below 0.05).
fn assert_close(kind: ModelKind, got: &[f64], truth: &[f64], tolerance: f64) {
    for (i, (g, t)) in got.iter().zip(truth).enumerate() {
        assert!(
            (g - t).abs() <= tolerance * t.abs().max(0.05),
            "{kind:?} parameter {i}: {g} vs {t} (all: {got:?})"
        );
    }
}

#[test]
fn ggx_parameters_are_recovered() {
    let truth = [0.2, 0.1, 0.05, 0.6, 0.5, 0.4, 0.2, 1.6];
    let got = recover(ModelKind::Ggx, &truth);
    assert_close(ModelKind::Ggx, &got, &truth, 0.02);
}

#[test]
fn ward_parameters_are_recovered() {
    let truth = [0.3, 0.2, 0.1, 0.2, 0.25, 0.3, 0.12];
    let got = recover(ModelKind::Ward, &truth);
    assert_close(ModelKind::Ward, &got, &truth, 0.02);
}
