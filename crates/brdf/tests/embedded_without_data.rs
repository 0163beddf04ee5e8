//! `merl:` specs of the embedded materials load on a machine without the shared data (this
//! test binary points the data directory at an empty folder, so only the embedded copies can
//! answer).

#[test]
fn merl_specs_of_embedded_materials_load_without_the_shared_data() {
    let empty = tempfile::tempdir().unwrap();
    std::env::set_var(brdf::DATA_DIR_ENV, empty.path());
    let m = brdf::load("merl:blue-acrylic").expect("embedded material");
    let v = m.as_brdf().eval_half_diff(&brdf::HalfDiff {
        theta_h: 0.0,
        phi_h: 0.0,
        theta_d: 0.2,
        phi_d: 0.0,
    });
    assert!(v.iter().all(|x| x.is_finite() && *x > 0.0), "{v:?}");
    // Materials that are not embedded still need the data.
    assert!(brdf::load("merl:gold-metallic-paint").is_err());
}
