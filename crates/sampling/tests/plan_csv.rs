mod common;

use brdf::analytic::Lambert;
use brdf::{Brdf, HalfDiff};
use sampling::uniform_plan;
use sampling::{measure_plan, Measurements, Plan, SamplePoint, SamplingError};

fn example_plan() -> Plan {
    uniform_plan(&common::small_grid(), 50, 3).unwrap()
}

#[test]
fn plan_and_values_round_trip_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let plan = example_plan();
    let p = dir.path().join("plan.csv");
    plan.write_csv(&p).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.starts_with("theta_h,theta_d,phi_d,channel\n"));
    assert_eq!(Plan::read_csv(&p).unwrap(), plan);

    let values: Vec<f64> = (0..plan.len()).map(|i| 0.1 * i as f64 + 1e-7).collect();
    let m = Measurements::new(plan.points.clone(), values).unwrap();
    let v = dir.path().join("values.csv");
    m.write_csv(&v).unwrap();
    assert!(std::fs::read_to_string(&v)
        .unwrap()
        .starts_with("theta_h,theta_d,phi_d,channel,value\n"));
    assert_eq!(Measurements::read_csv(&v).unwrap(), m);
    // No temporary files left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn malformed_csv_is_a_typed_error() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("bad_header.csv", "a,b,c,d\n0,0,0,0\n", false),
        (
            "fields.csv",
            "theta_h,theta_d,phi_d,channel\n0.1,0.2,0.3\n",
            false,
        ),
        (
            "number.csv",
            "theta_h,theta_d,phi_d,channel\n0.1,x,0.3,1\n",
            false,
        ),
        (
            "channel.csv",
            "theta_h,theta_d,phi_d,channel\n0.1,0.2,0.3,3\n",
            false,
        ),
        (
            "nan.csv",
            "theta_h,theta_d,phi_d,channel\nNaN,0.2,0.3,0\n",
            false,
        ),
        ("empty.csv", "", false),
        (
            "value_nan.csv",
            "theta_h,theta_d,phi_d,channel,value\n0.1,0.2,0.3,0,inf\n",
            true,
        ),
    ];
    for (name, text, values) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let err = if values {
            Measurements::read_csv(&p).unwrap_err()
        } else {
            Plan::read_csv(&p).unwrap_err()
        };
        assert!(
            matches!(err, SamplingError::MalformedCsv { .. }),
            "{name}: {err}"
        );
    }
    let missing = Plan::read_csv(dir.path().join("nope.csv")).unwrap_err();
    assert!(matches!(missing, SamplingError::Io { .. }));
}

#[test]
fn noiseless_measurement_equals_the_brdf() {
    let mat = Lambert {
        kd: [0.2, 0.4, 0.6],
    };
    let plan = example_plan();
    let m = measure_plan(&plan, &mat, 0.0, 9).unwrap();
    for (p, v) in m.points.iter().zip(&m.values) {
        let hd = HalfDiff::isotropic(p.theta_h, p.theta_d, p.phi_d);
        let expect = mat.eval_half_diff(&hd)[p.channel];
        assert_eq!(*v, expect);
    }
}

#[test]
fn measurement_noise_is_seeded_and_has_the_requested_spread() {
    let mat = Lambert {
        kd: [0.5, 0.5, 0.5],
    };
    let point = SamplePoint {
        theta_h: 0.2,
        theta_d: 0.3,
        phi_d: 1.0,
        channel: 1,
    };
    let plan = Plan {
        points: vec![point; 4000],
    };
    let a = measure_plan(&plan, &mat, 0.05, 11).unwrap();
    let b = measure_plan(&plan, &mat, 0.05, 11).unwrap();
    let c = measure_plan(&plan, &mat, 0.05, 12).unwrap();
    assert_eq!(a, b);
    assert_ne!(a, c);
    let truth = 0.5 / std::f64::consts::PI;
    let logs: Vec<f64> = a.values.iter().map(|v| (v / truth).ln()).collect();
    let mean = logs.iter().sum::<f64>() / logs.len() as f64;
    let sd = (logs.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / logs.len() as f64).sqrt();
    assert!(mean.abs() < 0.005, "mean log ratio {mean}");
    assert!((sd - 0.05).abs() < 0.005, "sd {sd}");
    assert!(measure_plan(&plan, &mat, f64::NAN, 1).is_err());
}
