//! End-to-end checks on a few shared measured materials (the shared data directory is
//! required: set `BRDF_DATA_DIR`, see `brdf::data_dir`): corpus loading through the NBRDF fast path, model build,
//! save/load, and the `model reconstruct` path writing a MERL `.binary` file.

use reduce::{build_model, Model};
use reduce::{to_log, Corpus};

#[test]
fn three_materials_build_save_load_and_reconstruct() {
    let dir = brdf::data_dir().join("nbrdf/merl");
    let names = brdf::nbrdf::list(&dir).unwrap_or_else(|e| {
        panic!(
            "this test needs the shared MERL materials at {} ({e}); set BRDF_DATA_DIR to the \
             shared data directory",
            dir.display()
        )
    });
    let mut corpus = Corpus::new(reduce::MATERIAL_DIM);
    for name in names.iter().take(3) {
        let net = brdf::nbrdf::Nbrdf::load(&dir, name).unwrap();
        corpus
            .push_values_f32(name.clone(), net.tabulate_f32())
            .unwrap();
    }
    let model = build_model(&corpus, 2, None, None).unwrap();
    assert_eq!(model.components(), 2);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("model.bin");
    model.save(&path).unwrap();
    let loaded = Model::load(&path).unwrap();
    assert_eq!(loaded.pca, model.pca);
    // With N − 1 = 2 components every corpus member is reproduced (up to f32 round-off) by
    // the `model reconstruct` path, which reads the material from its spec and writes a table.
    let spec = format!("nbrdf:{}/{}", dir.display(), names[1]);
    let out = tmp.path().join("rec.binary");
    let err = loaded
        .reconstruct_spec_to_file(&spec, 2, reduce::Encoder::Projection, &out)
        .unwrap();
    assert!(err.relative < 1e-3, "{err:?}");
    let rec = brdf::merl::read(&out).unwrap().values();
    let orig = corpus.row(1);
    let worst = rec
        .iter()
        .zip(orig)
        .map(|(&v, &y)| (to_log(v) - y).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-2, "worst log-space difference {worst}");
}
