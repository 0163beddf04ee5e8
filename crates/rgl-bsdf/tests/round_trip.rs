//! Materials written as `.bsdf` and read back: exact where the format can be exact (a
//! Lambertian surface), close on a glossy microfacet material, and every malformed layout a
//! typed error.

use brdf::{Brdf, Spherical, Vec3};
use rand::{Rng, SeedableRng};
use rgl_bsdf::{Field, RglBsdf, RglError, TensorFile, WriteOptions};

fn pairs(n: usize, max_theta: f64, seed: u64) -> Vec<(Vec3, Vec3)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let wi = Spherical::new(
                rng.gen::<f64>() * max_theta,
                rng.gen::<f64>() * std::f64::consts::TAU,
            )
            .to_vector();
            let wo = Spherical::new(
                rng.gen::<f64>() * max_theta,
                rng.gen::<f64>() * std::f64::consts::TAU,
            )
            .to_vector();
            (wi, wo)
        })
        .collect()
}

fn round_trip(spec: &str, options: &WriteOptions) -> (brdf::Material, RglBsdf) {
    let m = brdf::load(spec).unwrap();
    let bytes = rgl_bsdf::write(m.as_brdf(), options).unwrap().to_bytes();
    let back = RglBsdf::from_tensor(&TensorFile::parse(&bytes).unwrap()).unwrap();
    (m, back)
}

#[test]
fn a_lambertian_surface_comes_back_exactly() {
    let (_, back) = round_trip("lambert:kd=0.6", &WriteOptions::default());
    let kd = 0.6 / std::f64::consts::PI;
    let mut errors = Vec::new();
    for (wi, wo) in pairs(2000, 1.5, 1) {
        let f = back.eval(&wi, &wo);
        assert!((f[0] - kd).abs() < 1e-4, "{f:?} at {wi:?} {wo:?}");
        // the renderers' value, f cos θo, blends the grid's nodes
        let c = back.eval_cos(&wi, &wo);
        errors.push((c[2] / (kd * wo.z) - 1.0).abs());
    }
    errors.sort_by(f64::total_cmp);
    let (median, p95) = (errors[errors.len() / 2], errors[errors.len() * 95 / 100]);
    eprintln!("f cos θo relative error: median {median:.4}, 95th percentile {p95:.4}");
    assert!(
        median < 0.01 && p95 < 0.05,
        "median {median}, 95th percentile {p95}"
    );
}

#[test]
fn a_glossy_material_comes_back_within_a_few_percent() {
    let (m, back) = round_trip("ggx:alpha=0.3,kd=0.2", &WriteOptions::default());
    let mut rel: Vec<f64> = pairs(2000, 1.2, 2)
        .iter()
        .map(|(wi, wo)| {
            let (f, g) = (m.as_brdf().eval(wi, wo)[1], back.eval(wi, wo)[1]);
            (g - f).abs() / f
        })
        .collect();
    rel.sort_by(f64::total_cmp);
    let (median, p90) = (rel[rel.len() / 2], rel[rel.len() * 9 / 10]);
    assert!(
        median < 0.02 && p90 < 0.08,
        "median {median}, 90th percentile {p90}"
    );
}

#[test]
fn reflectance_is_non_negative_and_albedo_stays_below_one() {
    let (_, back) = round_trip("ggx:alpha=0.1,kd=0.5", &WriteOptions::small());
    let n = 64;
    for theta_i in [0.0, 0.5, 1.0, 1.3] {
        let wi = Spherical::new(theta_i, 0.3).to_vector();
        let mut albedo = 0.0;
        for a in 0..n {
            for b in 0..n {
                let (u, v) = ((a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64);
                // cosine-weighted hemisphere: albedo = mean of f π
                let (r, phi) = (u.sqrt(), std::f64::consts::TAU * v);
                let wo = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).sqrt());
                let f = back.eval(&wi, &wo);
                assert!(f.iter().all(|&x| x >= 0.0 && x.is_finite()));
                albedo += f[1] * std::f64::consts::PI;
            }
        }
        albedo /= (n * n) as f64;
        assert!(
            albedo > 0.3 && albedo < 1.0,
            "θi {theta_i}: albedo {albedo}"
        );
    }
}

#[test]
fn inconsistent_layouts_are_typed_errors() {
    let m = brdf::load("lambert:kd=0.5").unwrap();
    let good = rgl_bsdf::write(m.as_brdf(), &WriteOptions::small()).unwrap();
    assert!(RglBsdf::from_tensor(&good).is_ok());
    let with = |f: Field| {
        let mut t = good.clone();
        t.push(f);
        RglBsdf::from_tensor(&t)
    };
    // a theta_i of the wrong length for the tables
    assert!(matches!(
        with(Field::f32("theta_i", &[2], &[0.0, 0.5])),
        Err(RglError::Layout(_))
    ));
    // decreasing elevations
    assert!(matches!(
        with(Field::f32("theta_i", &[5], &[0.0, 0.5, 0.4, 0.9, 1.2])),
        Err(RglError::Layout(_))
    ));
    // a NaN in a table
    let mut vndf = good.field("vndf").unwrap().clone();
    vndf.data[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(matches!(with(vndf), Err(RglError::Field { .. })));
    // the wrong element type
    let jac = Field {
        dtype: rgl_bsdf::Dtype::I8,
        ..good.field("jacobian").unwrap().clone()
    };
    assert!(with(jac).is_err());
    // a missing field
    let mut t = TensorFile::default();
    for f in good.fields().iter().filter(|f| f.name != "sigma") {
        t.push(f.clone());
    }
    assert!(matches!(RglBsdf::from_tensor(&t), Err(RglError::MissingField(n)) if n == "sigma"));
    // options out of range are refused before any work
    let bad = WriteOptions {
        resolution: 1,
        ..WriteOptions::small()
    };
    assert!(matches!(
        rgl_bsdf::write(m.as_brdf(), &bad),
        Err(RglError::Options(_))
    ));
}

#[test]
fn spectral_tables_are_read_through_the_cie_observer() {
    // a flat spectrum of 0.5 / π on 16 wavelengths reads as grey 0.5 / π
    let m = brdf::load("lambert:kd=0.5").unwrap();
    let rgb = rgl_bsdf::write(m.as_brdf(), &WriteOptions::small()).unwrap();
    let f = rgb.field("rgb").unwrap();
    let [np, nt, _, h, w] = [f.shape[0], f.shape[1], f.shape[2], f.shape[3], f.shape[4]];
    let values = f.to_f32().unwrap();
    let n = 16;
    let mut spectra = Vec::with_capacity(np * nt * n * h * w);
    for s in 0..np * nt {
        for _ in 0..n {
            spectra.extend_from_slice(&values[(s * 3 + 1) * h * w..(s * 3 + 2) * h * w]);
        }
    }
    let mut t = TensorFile::default();
    for f in rgb.fields().iter().filter(|f| f.name != "rgb") {
        t.push(f.clone());
    }
    let wavelengths: Vec<f32> = (0..n).map(|k| 380.0 + 25.0 * k as f32).collect();
    t.push(Field::f32("wavelengths", &[n], &wavelengths));
    t.push(Field::f32("spectra", &[np, nt, n, h, w], &spectra));
    let back = RglBsdf::from_tensor(&t).unwrap();
    assert_eq!(back.channels(), &rgl_bsdf::Channels::Spectral(wavelengths));
    for (wi, wo) in pairs(100, 1.4, 3) {
        let f = back.eval(&wi, &wo);
        for c in f {
            assert!((c - 0.5 / std::f64::consts::PI).abs() < 1e-4, "{f:?}");
        }
    }
}

#[test]
fn a_spectral_file_reads_back_as_its_rgb_twin() {
    let m = brdf::load("ggx:alpha=0.3,kd=0.4/0.2/0.1").unwrap();
    let rgb = RglBsdf::from_tensor(&rgl_bsdf::write(m.as_brdf(), &WriteOptions::small()).unwrap())
        .unwrap();
    let options = WriteOptions {
        spectral: true,
        ..WriteOptions::small()
    };
    let file = rgl_bsdf::write(m.as_brdf(), &options).unwrap();
    assert!(file.field("rgb").is_none() && file.field("spectra").is_some());
    let spectral = RglBsdf::from_tensor(&file).unwrap();
    assert!(matches!(spectral.channels(), rgl_bsdf::Channels::Spectral(w) if w.len() == 48));
    for (wi, wo) in pairs(300, 1.3, 4) {
        let (a, b) = (rgb.eval(&wi, &wo), spectral.eval(&wi, &wo));
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() < 1e-4 * a[c].abs().max(1e-3),
                "{a:?} {b:?}"
            );
        }
    }
}
