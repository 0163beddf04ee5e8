//! The fuzz targets' bodies: one function per target, taking the fuzzer's bytes. Each libFuzzer
//! binary in `fuzz_targets/` calls its function; the end-to-end test `fuzz_replay` (main
//! workspace, stable toolchain) includes this file and replays the committed seeds and corpora
//! (`fuzz/seeds/TARGET`, `fuzz/corpus/TARGET`) through the same functions, so every input the
//! campaigns found is checked by CI without the nightly sanitizer build.
//!
//! A function returns normally for any input: a parser's typed error is a pass, a panic (an
//! assertion of the target included) is a failure.
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// A target: its name (the binary's and the seed folder's) and its body.
pub type Target = (&'static str, fn(&[u8]));

/// Every target.
pub const TARGETS: &[Target] = &[
    ("angles_csv", angles_csv),
    ("calibration_json", calibration_json),
    ("exr", exr),
    ("frames", frames),
    ("frames_structured", frames_structured),
    ("grbl_response", grbl_response),
    ("material_spec", material_spec),
    ("merl_binary", merl_binary),
    ("merl_binary_structured", merl_binary_structured),
    ("npy", npy),
    ("obj", obj),
    ("opencv_yaml", opencv_yaml),
    ("plan_csv", plan_csv),
    ("radiance_hdr", radiance_hdr),
    ("recovery_scene_toml", recovery_scene_toml),
    ("reduce_model", reduce_model),
    ("rgl_bsdf", rgl_bsdf),
    ("rig_toml", rig_toml),
    ("samples_checkpoint", samples_checkpoint),
    (
        "samples_checkpoint_structured",
        samples_checkpoint_structured,
    ),
    ("sampling_model", sampling_model),
    ("scene_toml", scene_toml),
    ("upload", upload),
    ("upload_http", upload_http),
    ("values_csv", values_csv),
    ("wavelet_basis", wavelet_basis),
    ("wavelet_tree", wavelet_tree),
    ("zarr_store", zarr_store),
];

/// A scratch directory of this process (`/dev/shm` when it exists), for readers that take a path.
fn scratch_dir() -> PathBuf {
    let shm = Path::new("/dev/shm");
    if shm.is_dir() {
        shm.to_path_buf()
    } else {
        std::env::temp_dir()
    }
}

/// A scratch file of this process holding `data`.
fn scratch(ext: &str, data: &[u8]) -> PathBuf {
    let p = scratch_dir().join(format!("gantry-fuzz-{}.{ext}", std::process::id()));
    std::fs::write(&p, data).expect("scratch file");
    p
}

/// Text inputs: the parser sees only valid UTF-8.
fn text(data: &[u8], parse: impl FnOnce(&str)) {
    if let Ok(t) = std::str::from_utf8(data) {
        parse(t);
    }
}

/// Half/difference angle lists (CSV).
pub fn angles_csv(data: &[u8]) {
    text(data, |t| {
        let _ = brdf::parse_csv(t, "fuzz.csv");
    });
}

/// Calibration JSON files.
pub fn calibration_json(data: &[u8]) {
    text(data, |t| {
        let _ = calib::Calibration::from_json(t);
    });
}

/// OpenEXR input (HDR images of the job directory, read through `hdr::read_exr`).
pub fn exr(data: &[u8]) {
    let _ = hdr::read_exr(&scratch("exr", data));
}

/// Raw frame files (`frames/NNN.frames`, GBFRAME2 with CRC, and the older GBFRAME1).
pub fn frames(data: &[u8]) {
    let _ = gantry_hal::decode_frames(data);
}

/// Frame files with the GBFRAME2 magic and a correct CRC-32 around a mutated body, so that the
/// fuzzer reaches the frame decoder behind the checksum.
pub fn frames_structured(data: &[u8]) {
    let mut out = b"GBFRAME2".to_vec();
    out.extend_from_slice(data);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    let _ = gantry_hal::decode_frames(&out);
}

/// GRBL response lines: the line classifier (ok, error:N, ALARM:N, status reports, messages)
/// and the status report parser.
pub fn grbl_response(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    for line in text.split('\n') {
        let _ = gantry_hal::grbl::Response::classify(line);
        let _ = gantry_hal::grbl::parse_status(line);
    }
}

/// Material spec strings (`merl:NAME`, `ggx:alpha=…`, …).
pub fn material_spec(data: &[u8]) {
    text(data, |t| {
        let _ = brdf::parse(t);
    });
}

/// MERL `.binary` tables: three dimensions then doubles.
pub fn merl_binary(data: &[u8]) {
    let _ = brdf::merl::parse(data, Path::new("fuzz.binary"));
}

const MERL_VALUES: usize = 3 * 90 * 90 * 180;

/// A whole MERL file of one constant value.
fn merl_base() -> &'static [u8] {
    static BASE: OnceLock<Vec<u8>> = OnceLock::new();
    BASE.get_or_init(|| {
        let mut b = Vec::with_capacity(12 + 8 * MERL_VALUES);
        for d in [90i32, 90, 180] {
            b.extend_from_slice(&d.to_le_bytes());
        }
        for _ in 0..MERL_VALUES {
            b.extend_from_slice(&0.25f64.to_le_bytes());
        }
        b
    })
}

/// MERL `.binary` tables with a valid header and full length around a mutated body, so that
/// the fuzzer reaches what comes after the size check: the value checks, the table's lookups
/// (with missing bins, negative values and huge ones) and the albedo quadrature. The input is a
/// list of patches (a bin index and a value each) over a constant table; the first byte picks
/// the interpolation.
pub fn merl_binary_structured(data: &[u8]) {
    let Some((&mode, patches)) = data.split_first() else {
        return;
    };
    let mut bytes = merl_base().to_vec();
    for p in patches.chunks_exact(12) {
        let i = u32::from_le_bytes([p[0], p[1], p[2], p[3]]) as usize % MERL_VALUES;
        bytes[12 + 8 * i..20 + 8 * i].copy_from_slice(&p[4..12]);
    }
    let Ok(mut table) = brdf::merl::parse(&bytes, Path::new("fuzz.binary")) else {
        return;
    };
    if mode & 1 == 1 {
        table = table.with_interpolation(brdf::Interpolation::Trilinear);
    }
    // lookups in directions spread over the hemisphere
    use brdf::Brdf;
    for k in 0..64u32 {
        let t = k as f64 / 64.0;
        let wi = brdf::Vec3::new((6.0 * t).sin() * 0.8, (6.0 * t).cos() * 0.3, 0.52);
        let wo = brdf::Vec3::new(-0.4 * t, 0.7 - t, 0.6);
        let _ = table.eval(&wi.normalize(), &wo.normalize());
    }
    let _ = brdf::directional_albedo(&table, 0.3, 4, 4);
}

/// NumPy `.npy` arrays (the neural-BRDF weights).
pub fn npy(data: &[u8]) {
    let _ = brdf::npy::parse(data, Path::new("fuzz.npy"));
}

/// Wavefront OBJ meshes.
pub fn obj(data: &[u8]) {
    text(data, |t| {
        let _ = render::parse_obj(t, Path::new("fuzz.obj"));
    });
}

/// OpenCV camera calibration YAML.
pub fn opencv_yaml(data: &[u8]) {
    text(data, |t| {
        let _ = calib::OpenCvCamera::from_yaml(t, Path::new("fuzz.yml"));
    });
}

/// Sampling plan CSV.
pub fn plan_csv(data: &[u8]) {
    let _ = sampling::Plan::read_csv(scratch("plan.csv", data));
}

/// Radiance `.hdr` (RGBE) input: light probes and photographs, read through
/// `render::Image::decode_hdr` (flat and run-length encoded scanlines, with a pixel limit).
pub fn radiance_hdr(data: &[u8]) {
    if let Ok(img) = render::Image::decode_hdr(data, Path::new("fuzz.hdr")) {
        assert!(img.width() * img.height() <= render::MAX_HDR_PIXELS);
        assert!(img
            .pixels()
            .iter()
            .flatten()
            .all(|v| v.is_finite() && *v >= 0.0));
    }
}

/// Recovery scene TOML (photos, lights, geometry of an inverse-rendering problem).
pub fn recovery_scene_toml(data: &[u8]) {
    text(data, |t| {
        let _ = recover::RecoveryScene::parse(t, Path::new("/nonexistent-fuzz-dir"));
    });
}

/// `model.bin` of the reduction (PCA basis, charts).
pub fn reduce_model(data: &[u8]) {
    let _ = reduce::Model::load(scratch("model.bin", data));
}

/// Rig configuration TOML.
pub fn rig_toml(data: &[u8]) {
    text(data, |t| {
        let _ = gantry_hal::RigConfig::from_toml_str(t);
    });
}

/// Position checkpoints (`positions/NNN.samples`), raw bytes.
pub fn samples_checkpoint(data: &[u8]) {
    let _ = binning::PositionSamples::parse(data, Path::new("fuzz.samples"));
}

fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Position checkpoints with a valid header and checksum around a mutated body, so that the
/// fuzzer reaches the record decoder behind the checksum.
pub fn samples_checkpoint_structured(data: &[u8]) {
    if data.len() < 13 {
        return;
    }
    let (head, body) = data.split_at(13);
    let mut out = b"GBSAMPL1".to_vec();
    out.extend_from_slice(&head[..4]);
    out.extend_from_slice(&head[4..12]);
    // The count: mostly the true one, sometimes a lie (chosen by the fuzzer).
    let count = if head[12] & 1 == 0 {
        (body.len() / 8) as u64
    } else {
        u64::from(head[12]) << (head[12] % 48)
    };
    out.extend_from_slice(&count.to_le_bytes());
    out.extend_from_slice(body);
    out.extend_from_slice(&fnv1a(body).to_le_bytes());
    let _ = binning::PositionSamples::parse(&out, Path::new("fuzz.samples"));
}

/// The sampling crate's model file (basis for reconstruction from few samples).
pub fn sampling_model(data: &[u8]) {
    let _ = sampling::from_bytes(data);
}

/// A scene's material resolver that gives analytic specs only.
struct AnalyticOnly;

impl render::MaterialResolver for AnalyticOnly {
    fn spec(&self, spec: &str) -> render::Result<Arc<dyn brdf::Brdf>> {
        match brdf::parse(spec) {
            Ok(brdf::MaterialSpec::Analytic { .. }) => render::SpecResolver.spec(spec),
            _ => Err(render::RenderError::Scene(format!(
                "{spec}: only analytic specs in this target"
            ))),
        }
    }
}

/// Render scene TOML. The parser, not the data loader, is under test: the resolver gives
/// analytic material specs only (a `merl:` or `nbrdf:` material would decode a 1.5 M-bin table,
/// seconds of legitimate work that the 1 s limit would call a hang), and mesh paths point
/// nowhere.
pub fn scene_toml(data: &[u8]) {
    text(data, |t| {
        let _ = render::parse_scene(t, Path::new("/nonexistent-fuzz-dir"), &AnalyticOnly);
    });
}

/// The file name and the body of an upload input: the bytes up to the first zero, the rest.
fn upload_parts(data: &[u8]) -> (&[u8], &[u8]) {
    let split = data.iter().position(|&b| b == 0).unwrap_or(data.len());
    (&data[..split], data.get(split + 1..).unwrap_or(&[]))
}

/// The editor's upload endpoint without its HTTP layer: what `POST /api/uploads?name=…` does
/// with a request, called in-process on one library (no runtime, no router, no thread hop), so
/// it runs at the parser's speed. The bytes up to the first zero are the file name, the rest is
/// the body. Every upload must be accepted under a name `upload-N[-stem]` whose stem is made of
/// letters, digits, `-` and `_`, or refused with an error the server answers with a client
/// status (4xx), never a server error or a panic; a refused upload leaves the library as it was.
pub fn upload(data: &[u8]) {
    static LIBRARY: OnceLock<serve::Library> = OnceLock::new();
    let lib = LIBRARY.get_or_init(|| serve::Library::open(None).expect("empty library"));
    let (name, body) = upload_parts(data);
    let file = String::from_utf8_lossy(name);
    let before = lib.upload_names();
    match lib.add_upload(&file, body) {
        Ok(added) => {
            let rest = added.strip_prefix("upload-").expect("an upload's name");
            assert!(rest
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'));
            assert!(lib.upload_table(&added).is_some());
        }
        Err(e) => {
            assert!(
                e.status().is_client_error(),
                "upload refused with {}: {e}",
                e.status()
            );
            assert_eq!(
                lib.upload_names(),
                before,
                "a refused upload changed the library"
            );
        }
    }
}

/// The server of `upload_http`: no corpus, no model, a 1 MiB upload limit.
pub struct UploadServer {
    runtime: tokio::runtime::Runtime,
    router: axum::Router,
}

/// The server of `upload_http`, built on first use (the libFuzzer binary builds it before the
/// first input: opening it takes over a second under the sanitizer).
pub fn upload_server() -> &'static UploadServer {
    static S: OnceLock<UploadServer> = OnceLock::new();
    S.get_or_init(|| {
        let app = serve::App::new(serve::Config {
            environment: None,
            upload_limit: 1 << 20,
            ..serve::Config::default()
        })
        .expect("server");
        UploadServer {
            runtime: tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("runtime"),
            router: serve::router(Arc::new(app)),
        }
    })
}

/// The editor's upload endpoint, `POST /api/uploads?name=…`, through the server's HTTP router
/// (no socket): the bytes up to the first zero are the file name (percent-encoded into the
/// query), the rest is the body. Every answer must be `201 Created` or a client error (4xx),
/// never a server error, a panic or a hang; the name an upload gets is always made of letters,
/// digits, `-` and `_`.
pub fn upload_http(data: &[u8]) {
    use std::fmt::Write;
    use tower::ServiceExt;
    let (name, body) = upload_parts(data);
    let stem = serve::upload_stem(&String::from_utf8_lossy(name));
    assert!(stem.len() <= 48);
    assert!(stem
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'));
    let mut query = String::new();
    for b in name {
        let _ = write!(query, "%{b:02X}");
    }
    let request = axum::http::Request::builder()
        .method("POST")
        .uri(format!("/api/uploads?name={query}"))
        .header("content-type", "application/octet-stream")
        .body(axum::body::Body::from(body.to_vec()))
        .expect("request");
    let s = upload_server();
    let response = s
        .runtime
        .block_on(s.router.clone().oneshot(request))
        .expect("infallible router");
    let status = response.status();
    assert!(
        status == axum::http::StatusCode::CREATED || status.is_client_error(),
        "upload answered {status}"
    );
}

/// Measured values CSV.
pub fn values_csv(data: &[u8]) {
    let _ = sampling::Measurements::read_csv(scratch("values.csv", data));
}

/// RGL tensor `.bsdf` files: the container, the material's layout checks, and evaluation at a
/// few direction pairs (which must be finite or zero, never a panic).
pub fn rgl_bsdf(data: &[u8]) {
    let Ok(file) = rgl_bsdf::TensorFile::parse(data) else {
        return;
    };
    let Ok(material) = rgl_bsdf::RglBsdf::from_tensor(&file) else {
        return;
    };
    use brdf::Brdf;
    for (ti, to, phi) in [(0.0, 0.3, 1.0), (0.7, 0.7, 3.1), (1.4, 0.2, -2.0)] {
        let wi = brdf::Vec3::new(f64::sin(ti), 0.0, f64::cos(ti));
        let wo = brdf::Vec3::new(
            f64::sin(to) * f64::cos(phi),
            f64::sin(to) * f64::sin(phi),
            f64::cos(to),
        );
        let _ = material.eval(&wi, &wo);
        let _ = material.eval_cos(&wi, &wo);
    }
}

/// Common wavelet basis files.
pub fn wavelet_basis(data: &[u8]) {
    let _ = wavelet::CommonBasis::from_bytes(data);
}

/// Compressed wavelet material (`.wtree`) files, and the coefficient tree built from them.
pub fn wavelet_tree(data: &[u8]) {
    if let Ok(m) = wavelet::CompressedMaterial::from_bytes(data) {
        let _ = wavelet::WaveletBrdf::new(&m, "fuzz");
    }
}

const STORE_ROOT: &str = r#"{"zarr_format":3,"node_type":"group","attributes":{"format":"reflectance-corpus","format_version":2}}"#;

/// Corpus stores (Zarr v3) with a mutated array metadata file (`values/zarr.json`) and a
/// mutated first chunk: opening, verifying every chunk and reading a material must give a
/// typed error or values, never a panic or an allocation the files cannot back. The input is
/// the metadata, a NUL byte, then the chunk's bytes.
pub fn zarr_store(data: &[u8]) {
    let (meta, chunk) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], Some(&data[i + 1..])),
        None => (data, None),
    };
    let dir = scratch_dir().join(format!("gantry-fuzz-store-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("values/c/0")).expect("scratch store");
    std::fs::write(dir.join("zarr.json"), STORE_ROOT).expect("scratch store");
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
}
