//! Corpus stores (Zarr v3) with a mutated array metadata file (`values/zarr.json`) and a
//! mutated first chunk: opening, verifying every chunk and reading a material must give a
//! typed error or values, never a panic or an allocation the files cannot back. The input is
//! the metadata, a NUL byte, then the chunk's bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

const ROOT: &str = r#"{"zarr_format":3,"node_type":"group","attributes":{"format":"reflectance-corpus","format_version":2}}"#;

fuzz_target!(|data: &[u8]| {
    let (meta, chunk) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], Some(&data[i + 1..])),
        None => (data, None),
    };
    let shm = std::path::Path::new("/dev/shm");
    let base = if shm.is_dir() {
        shm.to_path_buf()
    } else {
        std::env::temp_dir()
    };
    let dir = base.join(format!("gantry-fuzz-store-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("values/c/0")).expect("scratch store");
    std::fs::write(dir.join("zarr.json"), ROOT).expect("scratch store");
    std::fs::write(dir.join("values/zarr.json"), meta).expect("scratch store");
    if let Some(c) = chunk {
        std::fs::write(dir.join("values/c/0/0"), c).expect("scratch store");
    }
    let Ok(store) = corpus_store::CorpusStore::open(&dir) else {
        return;
    };
    // (a store of millions of tiny chunks is valid, but checking each is slow, not wrong)
    let (a, b) = store.info().chunk_grid();
    if a * b <= 4096 {
        let _ = store.verify(&|_| {});
    }
    if !store.is_empty() {
        let _ = store.read_rows(0..1);
    }
});
