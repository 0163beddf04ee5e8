//! End-to-end tests of `gantry fit` at reduced size: parameter recovery through the command
//! line and its JSON output, and clear failures on bad input.

use std::process::{Command, Output};

fn gantry(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gantry"))
        .args(args)
        .output()
        .expect("gantry runs")
}

#[test]
fn fit_recovers_an_analytic_material_and_prints_parseable_json() {
    let truth = "ward:kd=0.3/0.2/0.1,ks=0.12/0.1/0.08,alpha=0.15";
    let out = gantry(&[
        "fit", truth, "--model", "ward", "--bins", "2000", "--starts", "2", "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(v["model"], "ward");
    assert_eq!(v["objective"], "log");
    assert_eq!(v["rows"], 2000);
    let p = &v["parameters"];
    for (k, want) in [
        ("kd.r", 0.3),
        ("kd.g", 0.2),
        ("kd.b", 0.1),
        ("ks.r", 0.12),
        ("ks.b", 0.08),
        ("alpha", 0.15),
    ] {
        let got = p[k]
            .as_f64()
            .unwrap_or_else(|| panic!("parameter {k} missing: {p}"));
        assert!((got - want).abs() <= 0.01 * want, "{k}: {got} vs {want}");
    }
    assert!(
        v["errors"]["log"].as_f64().unwrap() < 1e-3,
        "{}",
        v["errors"]
    );
    assert_eq!(v["converged"], true);
    // The printed spec is a material every command accepts, and it is the fitted model.
    let spec = v["spec"].as_str().unwrap();
    let fitted = brdf::load(spec).expect("spec loads");
    let original = brdf::load(truth).unwrap();
    let (wi, wo) = (
        brdf::Spherical::new(0.5, 0.0).to_vector(),
        brdf::Spherical::new(0.45, 3.0).to_vector(),
    );
    let (a, b) = (
        brdf::Brdf::eval(&fitted, &wi, &wo),
        brdf::Brdf::eval(&original, &wi, &wo),
    );
    for c in 0..3 {
        assert!((a[c] - b[c]).abs() <= 0.02 * b[c], "{a:?} vs {b:?}");
    }
}

#[test]
fn fit_rejects_an_unknown_model_and_a_bad_spec_with_a_clear_message() {
    let out = gantry(&["fit", "lambert:kd=0.5", "--model", "torrance-sparrow"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("torrance-sparrow"), "{err}");

    let out = gantry(&["fit", "ggx:kd=0.5,alpha=banana", "--model", "ggx"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("alpha") || err.contains("banana"), "{err}");

    let out = gantry(&["fit", "lambert:kd=0.5", "--model", "ward", "--lobes", "2"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("2 lobes"), "{err}");

    let out = gantry(&["fit", "lambert:kd=0.5", "--objective", "l1"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("l1"));
}
