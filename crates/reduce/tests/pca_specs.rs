//! `pca:` material specs against the model they name: a corpus material on all components is
//! the material itself, and the four forms agree with each other and with `Model`.

use brdf::Brdf;
use reduce::build_model;
use reduce::Corpus;

#[test]
fn pca_specs_name_points_of_the_model_space() {
    reduce::register_spec_resolver();
    let specs = [
        "lambert:kd=0.3/0.2/0.1",
        "ggx:alpha=0.25,kd=0.1,ks=0.5",
        "phong:kd=0.2,ks=0.3,n=40",
    ];
    let corpus = Corpus::load(&specs).unwrap();
    // three materials span a two-dimensional centred space: two components reconstruct them
    let model = build_model(&corpus, 2, None, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.bin");
    model.save(&path).unwrap();
    let p = path.display();

    let original = brdf::load(specs[1]).unwrap().tabulate();
    let by_name = brdf::load(&format!("pca:{p}?material={}", specs[1]))
        .unwrap()
        .tabulate();
    let projected = brdf::load(&format!("pca:{p}?of={}", specs[1]))
        .unwrap()
        .tabulate();
    let (a, b, c) = (original.values(), by_name.values(), projected.values());
    let mut worst: f64 = 0.0;
    for i in 0..a.len() {
        let rel = (b[i] - a[i]).abs() / (a[i] + 1e-3);
        worst = worst.max(rel).max((c[i] - b[i]).abs() / (b[i] + 1e-3));
    }
    assert!(worst < 1e-3, "relative error {worst}");

    // explicit coordinates: those the model stores for the material
    let x: Vec<String> = (0..2)
        .map(|j| format!("{}", model.pca.coords[(1, j)]))
        .collect();
    let by_coords = brdf::load(&format!("pca:{p}?c={}", x.join("/")))
        .unwrap()
        .tabulate();
    let bc = by_coords.values();
    assert!(max_rel(&bc, &b) < 1e-9, "{}", max_rel(&bc, &b));

    // the mean, and the truncation to one component, are what Model computes
    let mean = brdf::load(&format!("pca:{p}")).unwrap().tabulate();
    assert!(max_rel(&mean.values(), &model.synthesize(&[]).unwrap()) < 1e-9);
    let k1 = brdf::load(&format!("pca:{p}?of={}&k=1", specs[0]))
        .unwrap()
        .tabulate();
    let expected = model
        .reconstruct_values(&brdf::load(specs[0]).unwrap().tabulate().values(), 1)
        .unwrap();
    assert!(max_rel(&k1.values(), &expected) < 1e-9);
    assert!(k1.name().contains("PCA 1"), "{}", k1.name());

    // errors: too many components, unknown material, missing file
    for bad in [
        format!("pca:{p}?of={}&k=3", specs[0]),
        format!("pca:{p}?material=chrome"),
        format!("pca:{p}?c=1/2/3"),
        "pca:/nonexistent/model.bin".to_string(),
    ] {
        assert!(brdf::load(&bad).is_err(), "{bad}");
    }
}

fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / (y.abs() + 1e-3))
        .fold(0.0, f64::max)
}
