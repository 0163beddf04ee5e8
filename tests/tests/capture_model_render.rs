//! A material measured on the simulated rig, completed by a PCA model of a corpus it is not part
//! of, and rendered: the completed table renders like the true material, and the model's
//! completion explains the material better than the corpus mean does.

use acquire::{CalibrationSource, JobSpec, Outcome, RunOptions, SimSetup, Station};
use brdf::{Brdf, MerlTable};
use std::sync::Arc;

/// The measured material (analytic, so no shared data is needed).
const MATERIAL: &str = "ggx:alpha=0.22,kd=0.28/0.14/0.06,ks=0.05";

/// A corpus of the same family around it, without the material itself.
fn corpus() -> reduce::Corpus {
    let mut c = reduce::Corpus::new(3 * brdf::BINS);
    for (i, (alpha, kd, ks)) in [
        (0.1, [0.3, 0.2, 0.1], 0.04),
        (0.3, [0.2, 0.1, 0.05], 0.06),
        (0.2, [0.1, 0.1, 0.1], 0.03),
        (0.4, [0.35, 0.15, 0.05], 0.05),
        (0.15, [0.25, 0.12, 0.02], 0.08),
        (0.25, [0.05, 0.05, 0.2], 0.04),
        (0.35, [0.3, 0.3, 0.3], 0.02),
    ]
    .into_iter()
    .enumerate()
    {
        let spec = format!("ggx:alpha={alpha},kd={}/{}/{},ks={ks}", kd[0], kd[1], kd[2]);
        let t = brdf::load(&spec).unwrap().tabulate();
        c.push_values(format!("m{i}"), &t.values()).unwrap();
    }
    c
}

fn mean_luminance(img: &render::Image) -> f64 {
    let p = img.pixels();
    p.iter()
        .map(|c| (0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]) as f64)
        .sum::<f64>()
        / p.len() as f64
}

fn render_sphere(table: MerlTable) -> render::Image {
    let material = render::SurfaceMaterial::Single(render::Material::new(Arc::new(table)));
    let scene = render::sphere_scene(material, 48, 48).unwrap();
    let options = render::RenderOptions {
        spp: 4,
        integrator: render::Integrator::Direct,
        ..render::RenderOptions::default()
    };
    render::render_scene(&scene, &options).unwrap()
}

#[test]
fn captured_material_completed_by_the_model_renders_like_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let spec = JobSpec::new(MATERIAL, 16);
    let mut station = Station::simulated(&spec, &SimSetup::with_scale(0.12)).unwrap();
    let options = RunOptions {
        calibration: CalibrationSource::TrueGeometry,
        ..RunOptions::default()
    };
    let Outcome::Finished(_) = acquire::run(&mut station, &spec, &options, dir.path()).unwrap()
    else {
        panic!("the capture did not finish");
    };
    // The measured table, as every other tool reads it.
    let measured = brdf::merl::read(dir.path().join("brdf.binary")).unwrap();
    let coverage = 1.0 - measured.missing_fraction();
    assert!(coverage > 0.0 && coverage < 0.5, "coverage {coverage}");

    let corpus = corpus();
    let model = reduce::build_model(&corpus, corpus.len(), None, None).unwrap();
    let completed = model.complete(&measured, 4, 1e-3).unwrap();
    let truth = brdf::load(MATERIAL).unwrap().tabulate();
    assert!(completed.raw().iter().all(|v| *v >= 0.0), "negative values");

    // The completion explains the material better than the corpus mean.
    let mean = MerlTable::from_values(model.synthesize(&[]).unwrap()).unwrap();
    let e_completed = acquire::table_error(&completed, &truth).median_abs_log;
    let e_mean = acquire::table_error(&mean, &truth).median_abs_log;
    assert!(
        e_completed < 0.7 * e_mean,
        "completed {e_completed} vs corpus mean {e_mean}"
    );

    // And it renders like the true material.
    let (a, b) = (render_sphere(completed), render_sphere(truth));
    let (la, lb) = (mean_luminance(&a), mean_luminance(&b));
    assert!(lb > 0.0);
    assert!(
        (la / lb - 1.0).abs() < 0.15,
        "mean luminance {la} (completed) vs {lb} (truth)"
    );
    let name = Brdf::name(&measured);
    assert!(!name.is_empty());
}
