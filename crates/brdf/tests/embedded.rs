//! The embedded sample materials are the shared corpus's materials, bit for bit.

use brdf::nbrdf::{Nbrdf, EMBEDDED_MERL};

#[test]
fn embedded_materials_equal_the_shared_corpus_files() {
    let dir = brdf::data_dir().join("nbrdf").join("merl");
    assert!(
        dir.is_dir(),
        "shared data not found at {} (set {})",
        dir.display(),
        brdf::DATA_DIR_ENV
    );
    for name in EMBEDDED_MERL {
        let embedded = Nbrdf::embedded(name).expect("listed").expect("decodes");
        let shared = Nbrdf::load(&dir, name).unwrap();
        for (th, td, pd) in [(0.0, 0.1, 0.5), (0.3, 0.7, 1.5), (1.2, 1.0, 2.9)] {
            assert_eq!(
                embedded.eval_angles(th, td, pd),
                shared.eval_angles(th, td, pd),
                "{name}"
            );
        }
        for suffix in brdf::nbrdf::FILE_SUFFIXES {
            let file = format!("{name}_{suffix}.npy");
            let ours = std::fs::read(
                std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("data/merl")
                    .join(&file),
            )
            .unwrap();
            assert_eq!(ours, std::fs::read(dir.join(&file)).unwrap(), "{file}");
        }
    }
    assert!(Nbrdf::embedded("not-a-material").is_none());
}
