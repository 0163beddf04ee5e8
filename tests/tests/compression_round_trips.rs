//! One material through every stored form of the toolkit, each written to disk and read back
//! through the material specs and corpus inputs a user gives: the MERL `.binary` table, a
//! compressed `.wtree` material on a Common Wavelet Basis, a PCA `model.bin`, and a Zarr corpus
//! store. Each comes back as the material it stored, within the error its format promises.

use brdf::metrics::log_relative_rms;
use brdf::MerlTable;

/// Materials of one family; the first is the one followed through the formats.
const SPECS: [&str; 4] = [
    "ggx:alpha=0.2,kd=0.3/0.15/0.05,ks=0.08",
    "ggx:alpha=0.35,kd=0.1/0.2/0.3,ks=0.05",
    "lambert:kd=0.4/0.4/0.35",
    "ggx:alpha=0.12,kd=0.05/0.05/0.05,ks=0.2",
];

fn tables() -> Vec<MerlTable> {
    SPECS
        .iter()
        .map(|s| brdf::load(s).unwrap().tabulate())
        .collect()
}

/// Every form of the workspace, as the CLI and the Python package install them.
fn install() {
    catalogue::Catalogue::workspace().install();
}

#[test]
fn merl_binary_round_trip_keeps_every_value() {
    let dir = tempfile::tempdir().unwrap();
    let table = &tables()[0];
    let path = dir.path().join("m.binary");
    brdf::merl::write(&path, table).unwrap();
    let back = brdf::load(path.to_str().unwrap()).unwrap().tabulate();
    let (a, b) = (table.values(), back.values());
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        // MERL files hold f64 values divided by a per-channel scale: equal up to rounding.
        assert!((x - y).abs() <= 1e-12 * x.abs().max(1e-12), "{x} vs {y}");
    }
}

#[test]
fn wavelet_material_round_trip_stays_within_the_basis_target() {
    install();
    let dir = tempfile::tempdir().unwrap();
    let corpus = tables();
    let target = 0.01;
    let basis = wavelet::build_basis(&corpus, target).unwrap();
    let basis_path = dir.path().join("basis.cwb");
    basis.write(&basis_path).unwrap();
    let basis = wavelet::CommonBasis::read(&basis_path).unwrap();
    let tree = dir.path().join("m.wtree");
    wavelet::CompressedMaterial::compress(basis, &corpus[0])
        .unwrap()
        .write(&tree)
        .unwrap();
    let back = brdf::load(&format!("wavelet:{}", tree.display()))
        .unwrap()
        .tabulate();
    let err = log_relative_rms(&corpus[0], &back).unwrap();
    // The basis keeps each corpus member's log channels within `target` (relative L2 over the
    // padded cube); over the table's valid bins the error stays of that order.
    assert!(err > 0.0 && err < 3.0 * target, "log relative RMS {err}");
}

#[test]
fn pca_model_round_trip_reconstructs_a_corpus_member() {
    let dir = tempfile::tempdir().unwrap();
    let corpus_tables = tables();
    let mut corpus = reduce::Corpus::new(brdf::MATERIAL_DIM);
    for (i, t) in corpus_tables.iter().enumerate() {
        corpus.push_values(format!("m{i}"), &t.values()).unwrap();
    }
    let k = corpus_tables.len() - 1;
    let model = reduce::build_model(&corpus, k, None, None).unwrap();
    let path = dir.path().join("model.bin");
    model.save(&path).unwrap();
    let loaded = reduce::Model::load(&path).unwrap();
    assert_eq!(loaded.components(), k);
    // All components: a member of the corpus lies in the model's span.
    let back = loaded.reconstruct(&corpus_tables[0], k).unwrap();
    let err = log_relative_rms(&corpus_tables[0], &back).unwrap();
    assert!(err < 1e-4, "full-rank reconstruction error {err}");
    // One component fewer loses something: the check above can fail.
    let truncated = loaded.reconstruct(&corpus_tables[0], 1).unwrap();
    assert!(log_relative_rms(&corpus_tables[0], &truncated).unwrap() > 10.0 * err);
}

#[test]
fn corpus_store_round_trip_returns_the_packed_tables() {
    install();
    let dir = tempfile::tempdir().unwrap();
    let corpus = tables();
    let inputs: Vec<std::path::PathBuf> = corpus
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let p = dir.path().join(format!("m{i}.binary"));
            brdf::merl::write(&p, t).unwrap();
            p
        })
        .collect();
    let store = dir.path().join("corpus.zarr");
    let job = corpus_store::PackJob {
        inputs,
        layout: corpus_store::LayoutOptions {
            out: store.clone(),
            grid: "full".parse().unwrap(),
            dtype: corpus_store::ValueType::F32,
            materials_per_chunk: 2,
            bins_per_chunk: None,
            zstd_level: 3,
        },
    };
    let report = job.run(&mut |_| {}).unwrap();
    assert_eq!(report.materials, corpus.len());
    let sources = brdf::sources(&[&store]).unwrap();
    assert_eq!(sources.len(), corpus.len());
    for (source, table) in sources.iter().zip(&corpus) {
        let back = source.table().unwrap();
        // Stored as f32 log values: relative error of f32 rounding.
        let err = log_relative_rms(table, &back).unwrap();
        assert!(err < 1e-6, "{}: {err}", source.name());
    }
}
