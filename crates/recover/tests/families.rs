//! `gantry recover`'s job with the families of materials: the PCA coefficients, a non-negative
//! combination of corpus materials (thesis §6.5), and the choice between them by held-out
//! pixel blocks; files in, table and report out.

mod common;

use recover::{log_relative_rms, Functionals, RecoverError, RecoverJob, RecoveryScene};

const SIZE: usize = 32;

/// A scene file of a unit sphere under a point light, a photo of `truth` in it, the corpus as
/// `.binary` files and the model of the corpus, under `dir`.
fn files(dir: &std::path::Path, truth: &brdf::MerlTable) -> RecoverJob {
    let tables = common::corpus_tables();
    let corpus = dir.join("corpus");
    std::fs::create_dir(&corpus).unwrap();
    for (n, t) in &tables {
        brdf::merl::write(corpus.join(format!("{n}.binary")), t).unwrap();
    }
    let model = dir.join("model.bin");
    common::model(&tables).save(&model).unwrap();
    let lights = RecoveryScene::point_light_toml([2.0, 2.0, 4.0], 25.0);
    let text = format!(
        "[camera]\nposition = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 32.0\n\
         width = {SIZE}\nheight = {SIZE}\n\
         [[objects]]\nkind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\n\
         material = \"object\"\n{lights}\n"
    );
    let scene_path = dir.join("scene.toml");
    std::fs::write(&scene_path, &text).unwrap();
    let scene = RecoveryScene::parse(&text, dir).unwrap();
    let f = Functionals::build(&scene, &Default::default()).unwrap();
    let pixels = f.to_image(&f.apply_table(truth), None);
    let image = dir.join("photo.exr");
    render::Image::from_pixels(SIZE, SIZE, pixels)
        .unwrap()
        .write_exr(&image)
        .unwrap();
    RecoverJob {
        scene: vec![scene_path],
        image: vec![image],
        mask: Vec::new(),
        model,
        out: dir.join("out.binary"),
        report: Some(dir.join("report.json")),
        k: 5,
        env_samples: 16,
        stride: 1,
        prior: 1.0,
        saturation: None,
        family: "combination".into(),
        corpus: vec![corpus],
    }
}

/// 40 % of the second corpus material and 60 % of the fifth.
fn mixture() -> brdf::MerlTable {
    let tables = common::corpus_tables();
    let (a, b) = (tables[1].1.values(), tables[4].1.values());
    let mix = a.iter().zip(&b).map(|(x, y)| 0.4 * x + 0.6 * y).collect();
    brdf::MerlTable::from_values(mix).unwrap()
}

#[test]
fn a_mixture_of_corpus_materials_is_recovered_as_their_combination() {
    let dir = tempfile::tempdir().unwrap();
    let truth = mixture();
    let job = files(dir.path(), &truth);
    let report = job.run().unwrap();
    assert_eq!(report.family, "combination");
    let names: Vec<&str> = report
        .combination
        .iter()
        .map(|t| t.material.as_str())
        .collect();
    assert_eq!(&names[..2], ["green-ggx", "red-lambert"], "{report:?}");
    assert!(
        (report.combination[0].coefficient - 0.6).abs() < 0.01,
        "{report:?}"
    );
    assert!(
        (report.combination[1].coefficient - 0.4).abs() < 0.01,
        "{report:?}"
    );
    assert!(report.images[0].residual_rms_log < 1e-3);
    let found = brdf::merl::read(&job.out).unwrap();
    assert!(log_relative_rms(&truth, &found) < 0.01);
    assert!(found.values().iter().all(|v| *v >= 0.0));
    // The report and its side-by-side image are written.
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(job.report.as_ref().unwrap()).unwrap()).unwrap();
    assert_eq!(json["family"], "combination");
    assert!(report.images[0].comparison_png.as_ref().unwrap().exists());
}

#[test]
fn auto_compares_both_families_on_held_out_pixel_blocks() {
    let dir = tempfile::tempdir().unwrap();
    // A corpus material: both families explain it exactly, and both scores are reported.
    let truth = common::corpus_tables()[3].1.clone();
    let job = RecoverJob {
        family: "auto".into(),
        ..files(dir.path(), &truth)
    };
    let report = job.run().unwrap();
    let scores = report
        .family_scores
        .as_ref()
        .expect("auto reports both scores");
    assert!(scores.pca.is_finite() && scores.combination.is_finite());
    let expected = if scores.combination < scores.pca {
        "combination"
    } else {
        "pca"
    };
    assert_eq!(report.family, expected);
    let found = brdf::merl::read(&job.out).unwrap();
    assert!(log_relative_rms(&truth, &found) < 0.02);
}

#[test]
fn a_combination_without_a_corpus_or_an_unknown_family_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let job = files(dir.path(), &mixture());
    let no_corpus = RecoverJob {
        corpus: Vec::new(),
        ..job.clone()
    };
    let e = no_corpus.run().unwrap_err();
    assert!(matches!(e, RecoverError::InvalidParameter(_)), "{e}");
    assert!(e.to_string().contains("--corpus"), "{e}");
    let unknown = RecoverJob {
        family: "neural".into(),
        ..job.clone()
    };
    let e = unknown.run().unwrap_err();
    assert!(e.to_string().contains("unknown family"), "{e}");
    assert!(!job.out.exists(), "nothing is written on a bad request");
}
