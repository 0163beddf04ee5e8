//! The API end to end through the router (no sockets), on a corpus of analytic materials
//! tabulated here and a small model and trait fitted to them; and a load test of 20
//! concurrent clients over loopback TCP.

use axum::body::Body;
use axum::http::{Request, StatusCode};
use brdf::analytic::Ggx;
use brdf::MerlTable;
use http_body_util::BodyExt;
use serve::{App, Config};
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use tower::ServiceExt;
use traits::{fit_binary, FitOptions, Method};
use traits::{Space, TraitSet, TraitVector};

/// Six GGX materials, from rough to glossy (α), and a seventh file beside the corpus that
/// must never be reachable.
struct Fixture {
    _dir: tempfile::TempDir,
    corpus: PathBuf,
    model: PathBuf,
    traits: PathBuf,
    outside: PathBuf,
}

const ALPHAS: [f64; 6] = [0.5, 0.35, 0.25, 0.15, 0.1, 0.07];

static FIXTURE: OnceLock<Fixture> = OnceLock::new();

extern "C" {
    fn atexit(callback: extern "C" fn()) -> std::os::raw::c_int;
}

/// A static is never dropped, so the fixture's folder (about 300 MB) is removed when the
/// test process exits.
extern "C" fn remove_fixture_folder() {
    if let Some(f) = FIXTURE.get() {
        let _ = std::fs::remove_dir_all(f._dir.path());
    }
}

fn fixture() -> &'static Fixture {
    FIXTURE.get_or_init(|| {
        // SAFETY: `atexit` takes a plain function pointer, called once at process exit.
        assert_eq!(unsafe { atexit(remove_fixture_folder) }, 0);
        let dir = tempfile::tempdir().unwrap();
        let corpus = dir.path().join("corpus");
        std::fs::create_dir(&corpus).unwrap();
        for (i, a) in ALPHAS.iter().enumerate() {
            let g = Ggx {
                kd: [0.25 - 0.02 * i as f64, 0.12, 0.06 + 0.02 * i as f64],
                ks: [0.15; 3],
                alpha: *a,
                ior: 1.5,
            };
            brdf::merl::write(
                corpus.join(format!("ggx-{i}.binary")),
                &MerlTable::tabulate(&g),
            )
            .unwrap();
        }
        let outside = dir.path().join("secret.binary");
        std::fs::write(&outside, b"not for clients").unwrap();
        let c = reduce::Corpus::load(&[&corpus]).unwrap();
        let k = 5;
        let model = reduce::build_model(&c, k, None, None).unwrap();
        let x = model.pca.coords.columns(0, k).into_owned();
        // Glossy: the three smallest α.
        let present: Vec<bool> = model
            .names
            .iter()
            .map(|n| n.trim_start_matches("ggx-").parse::<usize>().unwrap() >= 3)
            .collect();
        let w = fit_binary(&x, &present, Method::Svm, &FitOptions::default()).unwrap();
        let set = TraitSet {
            space: Space::Linear,
            dim: k,
            method: Method::Svm,
            traits: vec![TraitVector {
                name: "glossiness".into(),
                direction: w,
                cross_validated: None,
                variant: None,
            }],
        };
        let model_path = dir.path().join("model.bin");
        model.save(&model_path).unwrap();
        let traits = dir.path().join("traits.json");
        set.save(&traits).unwrap();
        Fixture {
            corpus,
            model: model_path,
            traits,
            outside,
            _dir: dir,
        }
    })
}

fn app(edit: bool, upload_limit: u64) -> Arc<App> {
    let f = fixture();
    Arc::new(
        App::new(Config {
            corpus: Some(f.corpus.clone()),
            model: edit.then(|| f.model.clone()),
            traits: if edit { vec![f.traits.clone()] } else { vec![] },
            upload_limit,
            ..Config::default()
        })
        .unwrap(),
    )
}

async fn call(app: &Arc<App>, method: &str, uri: &str, body: Vec<u8>) -> (StatusCode, Vec<u8>) {
    let req = Request::builder()
        .method(method)
        .uri(uri)
        .header(
            "content-type",
            if body.first() == Some(&b'{') {
                "application/json"
            } else {
                "application/octet-stream"
            },
        )
        .body(Body::from(body))
        .unwrap();
    let r = serve::router(app.clone()).oneshot(req).await.unwrap();
    let status = r.status();
    let bytes = r.into_body().collect().await.unwrap().to_bytes().to_vec();
    (status, bytes)
}

fn json(b: &[u8]) -> serde_json::Value {
    serde_json::from_slice(b).unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(b)))
}

fn decode(png: &[u8]) -> image::RgbImage {
    image::load_from_memory(png).unwrap().to_rgb8()
}

fn corpus_listing(p: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(p)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn every_route_is_in_the_openapi_file_and_nothing_else() {
    let doc: serde_json::Value = serde_json::from_str(serve::OPENAPI_JSON).unwrap();
    let paths = doc["paths"].as_object().unwrap();
    let routes = serve::routes();
    for (method, path, _) in &routes {
        assert!(
            paths.get(*path).and_then(|p| p.get(*method)).is_some(),
            "{method} {path} is not in docs/serve.openapi.json"
        );
    }
    for (path, ops) in paths {
        for method in ops.as_object().unwrap().keys() {
            assert!(
                routes.iter().any(|(m, p, _)| m == method && p == path),
                "docs/serve.openapi.json lists {method} {path}, which the router does not have"
            );
        }
    }
}

#[tokio::test]
async fn page_assets_and_unknown_routes() {
    let a = app(false, serve::DEFAULT_UPLOAD_LIMIT);
    let (s, b) = call(&a, "GET", "/", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    let html = String::from_utf8(b).unwrap();
    assert!(
        html.contains("/assets/app.js") && !html.contains("http://") && !html.contains("https://")
    );
    for asset in ["/assets/app.js", "/assets/app.css"] {
        let (s, b) = call(&a, "GET", asset, vec![]).await;
        assert_eq!(s, StatusCode::OK);
        let text = String::from_utf8(b).unwrap();
        assert!(
            !text.contains("https://") && !text.contains("http://"),
            "{asset} reaches the network"
        );
    }
    let (s, b) = call(&a, "GET", "/api/nothing", vec![]).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    assert_eq!(json(&b)["kind"], "not-found");
}

#[tokio::test]
async fn corpus_names_cannot_reach_outside_the_corpus() {
    let f = fixture();
    let a = app(false, serve::DEFAULT_UPLOAD_LIMIT);
    let before = corpus_listing(&f.corpus);
    // The file beside the corpus exists, but no name reaches it.
    assert!(f.outside.is_file());
    for name in [
        "..%2Fsecret",
        "..%2F..%2Fetc%2Fpasswd",
        "%2Fetc%2Fpasswd",
        "..",
        "ggx-0%2F..%2F..%2Fsecret",
        "..%5Csecret",
        ".%2Fggx-0",
        "ggx-0%00",
    ] {
        for view in [
            "sphere.png",
            "export.binary",
            "export.bsdf",
            "albedo",
            "thumbnail.png",
        ] {
            let (s, b) = call(&a, "GET", &format!("/api/materials/{name}/{view}"), vec![]).await;
            assert_eq!(s, StatusCode::BAD_REQUEST, "{name}/{view}");
            assert_eq!(json(&b)["kind"], "invalid-name");
        }
    }
    // A plain name that is not in the corpus (the stem of the outside file) is unknown.
    let (s, b) = call(&a, "GET", "/api/materials/secret/export.binary", vec![]).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    assert_eq!(json(&b)["kind"], "unknown-material");
    // Names in queries are checked the same way.
    let (s, _) = call(&a, "GET", "/api/compare?a=ggx-0&b=..%2Fsecret", vec![]).await;
    assert_eq!(s, StatusCode::BAD_REQUEST);
    // A real corpus material is served as an RGL .bsdf file that reads back as a material.
    let (s, b) = call(&a, "GET", "/api/materials/ggx-0/export.bsdf", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    let file = rgl_bsdf::TensorFile::parse(&b).unwrap();
    let m = rgl_bsdf::RglBsdf::from_tensor(&file).unwrap();
    assert_eq!(brdf::Brdf::name(&m), "ggx-0");
    // And as a MERL table.
    let (s, b) = call(&a, "GET", "/api/materials/ggx-0/export.binary", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    let t = brdf::merl::parse(&b, Path::new("ggx-0")).unwrap();
    assert_eq!(
        t.raw(),
        brdf::merl::read(f.corpus.join("ggx-0.binary"))
            .unwrap()
            .raw()
    );
    assert_eq!(corpus_listing(&f.corpus), before);
}

#[tokio::test]
async fn uploads_are_limited_checked_and_never_touch_the_corpus() {
    let f = fixture();
    let before = corpus_listing(&f.corpus);
    let small = app(false, 1000);
    let (s, b) = call(
        &small,
        "POST",
        "/api/uploads?name=x.binary",
        vec![0u8; 5000],
    )
    .await;
    assert_eq!(s, StatusCode::PAYLOAD_TOO_LARGE);
    assert_eq!(json(&b)["kind"], "too-large");

    let a = app(false, serve::DEFAULT_UPLOAD_LIMIT);
    let good = std::fs::read(f.corpus.join("ggx-2.binary")).unwrap();
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("short", good[..4096].to_vec(), "wrong-size"),
        ("tiny", vec![1, 2, 3], "wrong-size"),
        ("long", [good.as_slice(), &[0u8; 16]].concat(), "wrong-size"),
    ];
    let mut header = good.clone();
    header[4..8].copy_from_slice(&45i32.to_le_bytes());
    cases.push(("header", header, "bad-header"));
    let mut nan = good.clone();
    nan[12 + 8 * 1000..12 + 8 * 1001].copy_from_slice(&f64::NAN.to_le_bytes());
    cases.push(("nan", nan, "non-finite"));
    for (what, bytes, kind) in cases {
        let (s, b) = call(&a, "POST", "/api/uploads?name=bad.binary", bytes).await;
        assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{what}");
        let j = json(&b);
        assert_eq!(j["kind"], kind, "{what}: {j}");
        assert!(!j["error"].as_str().unwrap().is_empty());
    }
    let (s, b) = call(
        &a,
        "POST",
        "/api/uploads?name=..%2F..%2Fmine.binary",
        good.clone(),
    )
    .await;
    assert_eq!(s, StatusCode::CREATED);
    let name = json(&b)["name"].as_str().unwrap().to_string();
    assert!(
        name.starts_with("upload-") && name.ends_with("-mine"),
        "{name}"
    );
    // The upload is listed, viewable and exports the same bytes.
    let (_, b) = call(&a, "GET", "/api/materials?q=mine", vec![]).await;
    assert_eq!(json(&b)["materials"][0]["origin"], "upload");
    let (s, b) = call(
        &a,
        "GET",
        &format!("/api/materials/{name}/export.binary"),
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(b, good);
    assert_eq!(corpus_listing(&f.corpus), before);
    assert!(!f.corpus.parent().unwrap().join("mine.binary").exists());
}

#[tokio::test]
async fn views_answer_with_images_and_curves() {
    let a = app(false, serve::DEFAULT_UPLOAD_LIMIT);
    let (s, b) = call(
        &a,
        "GET",
        "/api/materials/ggx-5/sphere.png?size=64&lx=0&ly=0&exposure=-2",
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK);
    let img = decode(&b);
    assert_eq!(img.dimensions(), (64, 64));
    assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
    assert!(img.get_pixel(32, 32).0[0] > 0);
    // Glossier (smaller α) → a higher, narrower peak in the plane of incidence.
    let peak = |v: &serde_json::Value| {
        let rgb = v["rgb"].as_array().unwrap();
        let g: Vec<f64> = rgb.iter().map(|p| p[1].as_f64().unwrap()).collect();
        let m = g.iter().copied().fold(0.0, f64::max);
        (m, g.iter().filter(|x| **x > 0.5 * m).count())
    };
    let (_, b0) = call(
        &a,
        "GET",
        "/api/materials/ggx-0/incidence?theta_i=30",
        vec![],
    )
    .await;
    let (_, b5) = call(
        &a,
        "GET",
        "/api/materials/ggx-5/incidence?theta_i=30",
        vec![],
    )
    .await;
    let ((m0, w0), (m5, w5)) = (peak(&json(&b0)), peak(&json(&b5)));
    assert!(m5 > m0 && w5 < w0, "{m0} {w0} {m5} {w5}");
    let (_, b) = call(&a, "GET", "/api/materials/ggx-0/albedo", vec![]).await;
    let al = json(&b);
    assert_eq!(al["theta_i_deg"].as_array().unwrap().len(), 18);
    assert!(al["albedo"]
        .as_array()
        .unwrap()
        .iter()
        .all(|p| p[0].as_f64().unwrap() < 1.0));
    let (_, b) = call(&a, "GET", "/api/materials/ggx-0/slice?phi_d=90", vec![]).await;
    assert_eq!(json(&b)["rgb"].as_array().unwrap().len(), 90 * 90);
    let (s, _) = call(&a, "GET", "/api/materials/ggx-0/slice?phi_d=400", vec![]).await;
    assert_eq!(s, StatusCode::BAD_REQUEST);
    // Comparison: a material with itself differs by nothing, with another by something.
    let (_, b) = call(&a, "GET", "/api/compare?a=ggx-1&b=ggx-1&size=32", vec![]).await;
    assert_eq!(json(&b)["comparison"]["rms_log"], 0.0);
    let (_, b) = call(&a, "GET", "/api/compare?a=ggx-1&b=ggx-4&size=32", vec![]).await;
    assert!(json(&b)["comparison"]["rms_log"].as_f64().unwrap() > 0.0);
    let (s, b) = call(
        &a,
        "GET",
        "/api/compare/difference.png?a=ggx-1&b=ggx-4&size=32",
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(decode(&b).dimensions(), (32, 32));
    let (s, b) = call(
        &a,
        "GET",
        "/api/materials/ggx-3/environment.png?size=24&spp=2",
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let env = decode(&b);
    assert!(env.get_pixel(12, 12).0.iter().any(|c| *c > 0));
    // Without a model, editing is refused with a clear kind.
    editing_is_refused(&a).await;
}

/// Opening an edit session is refused with a clear kind.
async fn editing_is_refused(a: &Arc<App>) {
    let (s, b) = call(
        a,
        "POST",
        "/api/sessions",
        br#"{"material":"ggx-0"}"#.to_vec(),
    )
    .await;
    assert_eq!(s, StatusCode::CONFLICT);
    assert_eq!(json(&b)["kind"], "editing-disabled");
}

/// Brightest green value and the count of pixels above half of it.
fn highlight(img: &image::RgbImage) -> (u8, usize) {
    let m = img.pixels().map(|p| p.0[1]).max().unwrap();
    (
        m,
        img.pixels()
            .filter(|p| p.0[1] as u32 * 2 > m as u32)
            .count(),
    )
}

#[tokio::test]
async fn editing_steps_stop_at_checks_undo_redo_and_export() {
    let a = app(true, serve::DEFAULT_UPLOAD_LIMIT);
    let (_, b) = call(&a, "GET", "/api/info", vec![]).await;
    let info = json(&b);
    assert_eq!(info["editing"], true);
    assert_eq!(info["spaces"][0]["traits"][0]["name"], "glossiness");
    let (s, b) = call(
        &a,
        "POST",
        "/api/sessions",
        br#"{"material":"ggx-1"}"#.to_vec(),
    )
    .await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let st = json(&b);
    let id = st["id"].as_u64().unwrap();
    let score0 = st["scores"][0].as_f64().unwrap();
    let sphere =
        |v: &str| format!("/api/sessions/{id}/sphere.png?size=96&lx=-0.3&ly=0.3&exposure=-1&v={v}");
    let (_, png0) = call(&a, "GET", &sphere("0"), vec![]).await;

    // A small step goes through in full and moves the score by exactly the amount.
    let (s, b) = call(
        &a,
        "POST",
        &format!("/api/sessions/{id}/nudge"),
        br#"{"trait":"glossiness","amount":0.3}"#.to_vec(),
    )
    .await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let r = json(&b);
    let applied = r["applied"].as_f64().unwrap();
    assert!(r["stopped_by"].is_null(), "{r}");
    assert!((applied - 0.3).abs() < 1e-9);
    let score1 = r["state"]["scores"][0].as_f64().unwrap();
    assert!(
        (score1 - score0 - applied).abs() < 1e-6,
        "{score0} {score1}"
    );
    let (_, png1) = call(&a, "GET", &sphere("1"), vec![]).await;
    assert_ne!(png0, png1);
    // Glossier: a higher, narrower highlight (measured on the image).
    let (h0, w0) = highlight(&decode(&png0));
    let (h1, w1) = highlight(&decode(&png1));
    assert!(h1 > h0 && w1 < w0, "peak {h0} → {h1}, area {w0} → {w1}");

    // A huge step is stopped by a named check.
    let (_, b) = call(
        &a,
        "POST",
        &format!("/api/sessions/{id}/nudge"),
        br#"{"trait":"glossiness","amount":500}"#.to_vec(),
    )
    .await;
    let r = json(&b);
    let check = r["stopped_by"]
        .as_str()
        .unwrap_or_else(|| panic!("not stopped: {r}"));
    assert!(
        ["non-negativity", "energy-conservation"].contains(&check),
        "{check}"
    );
    assert!(r["applied"].as_f64().unwrap() < 500.0);
    assert!(r["message"].as_str().unwrap().contains("stopped by"));
    let (_, b) = call(&a, "GET", &format!("/api/sessions/{id}/validity"), vec![]).await;
    assert_eq!(json(&b)["valid"], true);

    // Undo twice → the start, bit for bit; redo → the first step.
    let (_, b) = call(&a, "POST", &format!("/api/sessions/{id}/undo"), vec![]).await;
    assert_eq!(json(&b)["redo"], 1);
    call(&a, "POST", &format!("/api/sessions/{id}/undo"), vec![]).await;
    let (_, back) = call(&a, "GET", &sphere("u"), vec![]).await;
    assert_eq!(back, png0);
    let (_, b) = call(&a, "POST", &format!("/api/sessions/{id}/redo"), vec![]).await;
    assert!((json(&b)["scores"][0].as_f64().unwrap() - score1).abs() < 1e-9);
    let (_, again) = call(&a, "GET", &sphere("r"), vec![]).await;
    assert_eq!(again, png1);
    // Redo → the point where the huge step stopped, on the border: it is returned to even
    // though a fresh start there can fail by rounding.
    let (s, b) = call(&a, "POST", &format!("/api/sessions/{id}/redo"), vec![]).await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    assert_eq!(json(&b)["redo"], 0);
    let (_, b) = call(&a, "POST", &format!("/api/sessions/{id}/undo"), vec![]).await;
    assert!((json(&b)["scores"][0].as_f64().unwrap() - score1).abs() < 1e-9);

    // Export → read back: the .binary parses, and as an upload it shows the same sphere.
    let (s, bin) = call(
        &a,
        "GET",
        &format!("/api/materials/edit:{id}/export.binary"),
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(bin.len(), 34_992_012);
    brdf::merl::parse(&bin, Path::new("export")).unwrap();
    let (_, b) = call(&a, "POST", "/api/uploads?name=edited.binary", bin).await;
    let up = json(&b)["name"].as_str().unwrap().to_string();
    let (_, png_up) = call(
        &a,
        "GET",
        &format!("/api/materials/{up}/sphere.png?size=96&lx=-0.3&ly=0.3&exposure=-1"),
        vec![],
    )
    .await;
    let (x, y) = (decode(&png1), decode(&png_up));
    let worst = x
        .pixels()
        .zip(y.pixels())
        .flat_map(|(p, q)| (0..3).map(move |c| (p.0[c] as i32 - q.0[c] as i32).abs()))
        .max()
        .unwrap();
    assert!(
        worst <= 1,
        "export differs from the session by {worst} levels"
    );
    // The spec names the net amount and reproduces with gantry edit.
    let (_, b) = call(&a, "GET", &format!("/api/sessions/{id}/spec.json"), vec![]).await;
    let spec = json(&b);
    assert_eq!(spec["start"], "ggx-1");
    assert!((spec["add"][0][1].as_f64().unwrap() - 0.3).abs() < 1e-9);
    assert!(spec["command"]
        .as_str()
        .unwrap()
        .contains("--add glossiness=0.300000"));

    // Interpolation toward another material ends at its coordinates when nothing stops it.
    let (_, b) = call(
        &a,
        "POST",
        &format!("/api/sessions/{id}/interpolate"),
        br#"{"other":"ggx-4","t":1.0}"#.to_vec(),
    )
    .await;
    let r = json(&b);
    assert!(r["stopped_by"].is_null(), "{r}");
    let (_, b) = call(&a, "GET", "/api/materials?trait=glossiness", vec![]).await;
    let list = json(&b);
    let want = list["materials"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["name"] == "ggx-4")
        .unwrap()["scores"][0]
        .as_f64()
        .unwrap();
    assert!((r["state"]["scores"][0].as_f64().unwrap() - want).abs() < 1e-6);

    // Unknown traits and sessions are typed errors.
    let (s, b) = call(
        &a,
        "POST",
        &format!("/api/sessions/{id}/nudge"),
        br#"{"trait":"shininess","amount":1}"#.to_vec(),
    )
    .await;
    assert_eq!(
        (s, json(&b)["kind"].clone()),
        (StatusCode::BAD_REQUEST, "unknown-trait".into())
    );
    let (s, _) = call(&a, "GET", "/api/sessions/999999/sphere.png", vec![]).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    // Search by trait score: only glossy ones above 0.5, sorted by score.
    let (_, b) = call(
        &a,
        "GET",
        "/api/materials?trait=glossiness&min=0.5&sort=score",
        vec![],
    )
    .await;
    let l = json(&b);
    let scores: Vec<f64> = l["materials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["scores"][0].as_f64().unwrap())
        .collect();
    assert!(!scores.is_empty() && scores.iter().all(|s| *s >= 0.5));
    assert!(scores.windows(2).all(|w| w[0] >= w[1]));
}

/// 20 clients at once over loopback TCP, each making 15 requests (page, list, spheres of
/// several sizes and lights, thumbnails, curves, and slider steps on shared sessions).
/// Every response must be a 200, and the whole run must finish within 120 s.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn twenty_concurrent_clients_are_served_without_errors() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let a = app(true, serve::DEFAULT_UPLOAD_LIMIT);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let server = tokio::spawn(serve::serve(a.clone(), listener));
    let mut ids = Vec::new();
    for m in ["ggx-1", "ggx-2", "ggx-3", "ggx-4"] {
        let (_, b) = call(
            &a,
            "POST",
            "/api/sessions",
            format!(r#"{{"material":"{m}"}}"#).into_bytes(),
        )
        .await;
        ids.push(json(&b)["id"].as_u64().unwrap());
    }
    async fn request(
        addr: std::net::SocketAddr,
        method: &str,
        path: &str,
        body: &str,
    ) -> (u16, f64) {
        let t = std::time::Instant::now();
        let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
        let req = format!(
            "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
            body.len()
        );
        s.write_all(req.as_bytes()).await.unwrap();
        let mut out = Vec::new();
        s.read_to_end(&mut out).await.unwrap();
        let head = String::from_utf8_lossy(&out[..out.len().min(12)]).to_string();
        (
            head[9..12].parse().unwrap_or(0),
            t.elapsed().as_secs_f64() * 1e3,
        )
    }
    let start = std::time::Instant::now();
    let clients: Vec<_> = (0..20)
        .map(|c| {
            let id = ids[c % ids.len()];
            tokio::spawn(async move {
                let mut res = Vec::new();
                for k in 0..15 {
                    let (m, p, b) = match k % 5 {
                        0 => (
                            "GET",
                            "/api/materials?q=ggx&trait=glossiness".to_string(),
                            String::new(),
                        ),
                        1 => (
                            "GET",
                            format!(
                                "/api/materials/ggx-{}/sphere.png?size=128&lx={:.2}&ly=0.2",
                                k % 6,
                                0.1 * (c % 5) as f64
                            ),
                            String::new(),
                        ),
                        2 => (
                            "POST",
                            format!("/api/sessions/{id}/nudge"),
                            format!(
                                r#"{{"trait":"glossiness","amount":{}}}"#,
                                if k % 2 == 0 { 0.05 } else { -0.05 }
                            ),
                        ),
                        3 => (
                            "GET",
                            format!("/api/sessions/{id}/sphere.png?size=256&lx=-0.3&ly=0.3"),
                            String::new(),
                        ),
                        _ => (
                            "GET",
                            format!("/api/materials/ggx-{}/thumbnail.png", c % 6),
                            String::new(),
                        ),
                    };
                    res.push((p.clone(), request(addr, m, &p, &b).await));
                }
                res
            })
        })
        .collect();
    let mut lat = Vec::new();
    for c in clients {
        for (path, (status, ms)) in tokio::time::timeout(std::time::Duration::from_secs(120), c)
            .await
            .expect("load test over 120 s")
            .unwrap()
        {
            assert_eq!(status, 200, "{path}");
            lat.push(ms);
        }
    }
    lat.sort_by(f64::total_cmp);
    let p95 = lat[lat.len() * 95 / 100];
    eprintln!(
        "load: 20 clients × 15 requests = {} responses, all 200, in {:.2} s; latency median {:.0} ms, p95 {:.0} ms",
        lat.len(),
        start.elapsed().as_secs_f64(),
        lat[lat.len() / 2],
        p95
    );
    server.abort();
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[tokio::test]
async fn real_time_view_assets_agree_with_the_model_and_the_offline_renderer() {
    let a = app(true, serve::DEFAULT_UPLOAD_LIMIT);
    let model = reduce::Model::load(&fixture().model).unwrap();
    let grid = serve::GpuGrid::default();
    let block = grid.bins() * 3 * 2;

    // The basis file: header, k + 1 blocks, and the first k components are a prefix of all.
    let (s, b3) = call(&a, "GET", "/api/gpu/basis.bin?k=3", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(&b3[..4], serve::GPU_BASIS_MAGIC);
    let header: Vec<u32> = (4..24).step_by(4).map(|o| u32_at(&b3, o)).collect();
    assert_eq!(
        header,
        [
            1,
            grid.theta_h as u32,
            grid.theta_d as u32,
            grid.phi_d as u32,
            3
        ]
    );
    assert_eq!(b3.len(), 28 + 4 * block);
    let (_, b5) = call(&a, "GET", "/api/gpu/basis.bin", vec![]).await;
    assert_eq!(u32_at(&b5, 20) as usize, model.components());
    assert_eq!(b5.len(), 28 + (model.components() + 1) * block);
    assert_eq!(&b5[28..28 + 4 * block], &b3[28..]);

    // A corpus material's coefficients are its model coordinates; the shader's lookup of
    // them agrees with the model's full-grid reconstruction.
    let (s, b) = call(&a, "GET", "/api/gpu/materials/ggx-2/coefficients", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    let c: Vec<f64> = json(&b)["coefficients"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let row = model.names.iter().position(|n| n == "ggx-2").unwrap();
    assert_eq!(c.len(), model.components());
    for (j, v) in c.iter().enumerate() {
        assert_eq!(*v, model.pca.coords[(row, j)]);
    }
    let basis = Arc::new(serve::GpuBasis::from_model(&model, grid).unwrap());
    let e = serve::gpu_reduction_error(&model, &basis, &c).unwrap();
    assert!(
        e.median_abs_log < 0.01 && e.cosine_weighted_relative_rms < 0.03,
        "{e:?}"
    );

    // The offline reference of the view's scene, and the same scene rendered with the
    // shader's lookup: equal means within 2 %.
    let size = 48;
    let (s, b) = call(
        &a,
        "GET",
        &format!("/api/gpu/materials/ggx-2/reference.bin?size={size}&spp=8"),
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK);
    let reference = f32s(&b);
    assert_eq!(reference.len(), size * size * 3);
    assert!(reference.iter().all(|v| v.is_finite() && *v >= 0.0));
    let scene = render::sphere_scene(
        render::Material::new(Arc::new(basis.brdf(&c))).into(),
        size,
        size,
    )
    .unwrap();
    let options = render::RenderOptions {
        spp: 8,
        integrator: render::Integrator::Direct,
        ..Default::default()
    };
    let gpu = render::render_scene(&scene, &options).unwrap();
    for ch in 0..3 {
        let r: f64 = reference
            .iter()
            .skip(ch)
            .step_by(3)
            .map(|&v| v as f64)
            .sum();
        let g: f64 = gpu.pixels().iter().map(|p| p[ch] as f64).sum();
        assert!(
            r > 0.0 && (g / r - 1.0).abs() < 0.02,
            "channel {ch}: {g} vs {r}"
        );
    }

    // An edit session's state carries its coefficients, and the route gives the same.
    let (_, b) = call(
        &a,
        "POST",
        "/api/sessions",
        br#"{"material":"ggx-1"}"#.to_vec(),
    )
    .await;
    let id = json(&b)["id"].as_u64().unwrap();
    let (_, b) = call(
        &a,
        "POST",
        &format!("/api/sessions/{id}/nudge"),
        br#"{"trait":"glossiness","amount":0.2}"#.to_vec(),
    )
    .await;
    let state = json(&b)["state"].clone();
    let (s, b) = call(
        &a,
        "GET",
        &format!("/api/gpu/materials/edit:{id}/coefficients"),
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(json(&b)["coefficients"], state["coefficients"]);
    let start = model.names.iter().position(|n| n == "ggx-1").unwrap();
    assert_ne!(
        state["coefficients"][0].as_f64().unwrap(),
        model.pca.coords[(start, 0)],
        "the nudge moved the point"
    );

    // The probe: header and one RGB half float per pixel.
    let (s, b) = call(&a, "GET", "/api/gpu/environment.bin", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(&b[..4], b"GPUE");
    let (w, h) = (u32_at(&b, 4) as usize, u32_at(&b, 8) as usize);
    assert_eq!(b.len(), 12 + w * h * 6);
    assert_eq!(
        (w, h),
        (
            a.environment.image().width(),
            a.environment.image().height()
        )
    );

    // Bad requests get typed errors.
    for (uri, status, kind) in [
        (
            "/api/gpu/basis.bin?k=99",
            StatusCode::BAD_REQUEST,
            "invalid-parameter",
        ),
        (
            "/api/gpu/materials/ggx-2/coefficients?k=99",
            StatusCode::BAD_REQUEST,
            "invalid-parameter",
        ),
        (
            "/api/gpu/materials/ggx-2/reference.bin?size=0",
            StatusCode::BAD_REQUEST,
            "invalid-parameter",
        ),
        (
            "/api/gpu/materials/ggx-2/reference.bin?size=64&spp=100000",
            StatusCode::BAD_REQUEST,
            "invalid-parameter",
        ),
        (
            "/api/gpu/materials/nothing/coefficients",
            StatusCode::NOT_FOUND,
            "unknown-material",
        ),
        (
            "/api/gpu/materials/edit:999/coefficients",
            StatusCode::NOT_FOUND,
            "unknown-session",
        ),
    ] {
        let (s, b) = call(&a, "GET", uri, vec![]).await;
        assert_eq!(s, status, "{uri}: {}", String::from_utf8_lossy(&b));
        assert_eq!(json(&b)["kind"], kind, "{uri}");
    }
    let viewer = app(false, serve::DEFAULT_UPLOAD_LIMIT);
    for uri in [
        "/api/gpu/basis.bin",
        "/api/gpu/materials/ggx-2/coefficients",
    ] {
        let (s, b) = call(&viewer, "GET", uri, vec![]).await;
        assert_eq!(s, StatusCode::CONFLICT, "{uri}");
        assert_eq!(json(&b)["kind"], "no-model");
    }
    assert!(serve::GpuBasis::from_model(
        &model,
        serve::GpuGrid {
            theta_h: 90,
            theta_d: 7,
            phi_d: 20
        }
    )
    .is_err());
}

#[tokio::test]
async fn the_mesh_routes_ship_the_offline_figures() {
    let a = app(true, serve::DEFAULT_UPLOAD_LIMIT);
    // The mesh, camera and light are the offline figure's.
    let (s, b) = call(&a, "GET", "/api/gpu/meshes/teapot", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(&b[..4], b"GPUM");
    let mesh = render::figure_teapot_mesh();
    let (n, t) = (u32_at(&b, 8) as usize, u32_at(&b, 12) as usize);
    assert_eq!((n, t), (mesh.positions.len(), mesh.triangles.len()));
    assert_eq!(b.len(), 16 + 64 + n * 32 + t * 12);
    let head = f32s(&b[16..80]);
    let camera = render::teapot_camera(4, 3);
    assert_eq!(head[0] as f64, camera.position.x as f32 as f64);
    assert_eq!(head[9] as f64, camera.fov_degrees as f32 as f64);
    let light = render::teapot_point_light();
    assert_eq!(head[10] as f64, light.position.x as f32 as f64);
    assert_eq!(head[13] as f64, light.intensity[0] as f32 as f64);
    let positions = f32s(&b[80..80 + 12 * n]);
    assert_eq!(positions[3 * 7 + 1], mesh.positions[7].y as f32);
    let last = u32_at(&b, b.len() - 4);
    assert_eq!(last, mesh.triangles[t - 1][2]);

    // The rust field is render::rust_selector's.
    let (s, b) = call(&a, "GET", "/api/gpu/rust.bin?width=64&seed=3", vec![]).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!((u32_at(&b, 4), u32_at(&b, 8)), (64, 32));
    assert_eq!(f32s(&b[12..]), render::rust_selector(64, 32, 3));

    // The offline teapot: lit, finite, and the rusted end changes it.
    let reference = |to: &str| {
        format!(
            "/api/gpu/meshes/teapot/reference.bin?from=ggx-0&to={to}&k=3&width=24&spp=2&texture_width=32"
        )
    };
    let (s, b) = call(&a, "GET", &reference("ggx-5"), vec![]).await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let rusty = f32s(&b);
    assert_eq!(rusty.len(), 24 * 18 * 3);
    assert!(rusty.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(rusty.iter().any(|v| *v > 0.0));
    let (_, b) = call(&a, "GET", &reference("ggx-0"), vec![]).await;
    assert_ne!(f32s(&b), rusty);

    for uri in [
        "/api/gpu/rust.bin?width=1",
        "/api/gpu/rust.bin?width=100000",
        "/api/gpu/meshes/teapot/reference.bin?from=ggx-0&to=ggx-5&k=99",
        "/api/gpu/meshes/teapot/reference.bin?from=ggx-0&to=ggx-5&width=2",
    ] {
        let (s, b) = call(&a, "GET", uri, vec![]).await;
        assert_eq!(s, StatusCode::BAD_REQUEST, "{uri}");
        assert_eq!(json(&b)["kind"], "invalid-parameter");
    }
    let (s, _) = call(
        &a,
        "GET",
        "/api/gpu/meshes/teapot/reference.bin?from=ggx-0&to=nothing&k=3",
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    let (s, b) = call(&a, "GET", "/api/gpu/meshes/dragon", vec![]).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    assert!(String::from_utf8_lossy(&b).contains("teapot or bunny"));

    // The bunny of the shared data, placed and textured like the teapot.
    let (s, b) = call(&a, "GET", "/api/gpu/meshes/bunny", vec![]).await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let bunny = render::figure_bunny_mesh().expect("the shared bunny (set BRDF_DATA_DIR)");
    let (n, t) = (u32_at(&b, 8) as usize, u32_at(&b, 12) as usize);
    assert_eq!((n, t), (bunny.positions.len(), bunny.triangles.len()));
    assert_eq!(b.len(), 16 + 64 + n * 32 + t * 12);
    let uvs = f32s(&b[80 + 24 * n..80 + 32 * n]);
    assert!(uvs.iter().all(|v| v.is_finite() && (0.0..1.5).contains(v)));
    let (s, b) = call(
        &a,
        "GET",
        "/api/gpu/meshes/bunny/reference.bin?from=ggx-0&to=ggx-5&k=3&width=24&spp=1&texture_width=32",
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let lit = f32s(&b);
    assert_eq!(lit.len(), 24 * 18 * 3);
    assert!(lit.iter().all(|v| v.is_finite() && *v >= 0.0) && lit.iter().any(|v| *v > 0.0));
}

#[tokio::test]
async fn the_progression_routes_lay_out_and_render_the_grid() {
    let a = app(true, serve::DEFAULT_UPLOAD_LIMIT);
    let (s, b) = call(
        &a,
        "GET",
        "/api/gpu/grid?count=7&columns=4&sphere_pixels=8",
        vec![],
    )
    .await;
    assert_eq!(s, StatusCode::OK);
    let g = json(&b);
    let grid = render::SphereGrid::new(7, 4).unwrap();
    assert_eq!(
        (g["columns"].as_u64(), g["rows"].as_u64()),
        (Some(4), Some(2))
    );
    assert_eq!(g["centres"].as_array().unwrap().len(), 7);
    assert_eq!(g["centres"][5][1].as_f64().unwrap(), grid.sphere(5).y);
    assert_eq!(g["camera"]["width"].as_u64(), Some(32));
    assert_eq!(
        g["camera"]["fov_degrees"].as_f64().unwrap(),
        grid.camera(8).fov_degrees
    );
    assert_eq!(
        g["light"]["intensity"][0].as_f64().unwrap(),
        grid.light().intensity[0]
    );

    // Each sphere is its stage of the path: the two ends are the two materials' own spheres.
    let uri = |nodes: &str| {
        format!(
            "/api/gpu/grid-reference.bin?nodes={nodes}&count=3&columns=3&sphere_pixels=8&k=3&spp=1"
        )
    };
    let (s, b) = call(&a, "GET", &uri("ggx-0,ggx-5"), vec![]).await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let path = f32s(&b);
    assert_eq!(path.len(), 24 * 8 * 3);
    let cell = |img: &[f32], i: usize| -> Vec<f32> {
        (0..8)
            .flat_map(|y| (0..8).flat_map(move |x| (0..3).map(move |c| (y, x, c))))
            .map(|(y, x, c)| img[(y * 24 + i * 8 + x) * 3 + c])
            .collect()
    };
    let (_, b) = call(&a, "GET", &uri("ggx-0,ggx-0"), vec![]).await;
    let start = f32s(&b);
    let (_, b) = call(&a, "GET", &uri("ggx-5,ggx-5"), vec![]).await;
    let end = f32s(&b);
    assert_eq!(cell(&path, 0), cell(&start, 0));
    assert_eq!(cell(&path, 2), cell(&end, 2));
    assert_ne!(cell(&path, 1), cell(&start, 1));
    for bad in [
        "/api/gpu/grid?count=1",
        "/api/gpu/grid?count=40",
        "/api/gpu/grid?columns=0",
        "/api/gpu/grid-reference.bin?nodes=ggx-0",
        "/api/gpu/grid-reference.bin?nodes=ggx-0,ggx-1&k=0",
    ] {
        let (s, b) = call(&a, "GET", bad, vec![]).await;
        assert_eq!(s, StatusCode::BAD_REQUEST, "{bad}");
        assert_eq!(json(&b)["kind"], "invalid-parameter");
    }
}

#[tokio::test]
async fn an_uploaded_probe_comes_back_in_half_floats() {
    let a = app(false, serve::DEFAULT_UPLOAD_LIMIT);
    let path = brdf::data_dir().join("real/envmap/venice_sunset_1k.hdr");
    let bytes = std::fs::read(&path).expect("the shared probe (set BRDF_DATA_DIR)");
    let (s, b) = call(&a, "POST", "/api/gpu/environment", bytes.clone()).await;
    assert_eq!(s, StatusCode::OK, "{}", String::from_utf8_lossy(&b));
    let image = render::Image::read(&path).unwrap();
    assert_eq!(&b[..4], b"GPUE");
    let (w, h) = (u32_at(&b, 4) as usize, u32_at(&b, 8) as usize);
    assert_eq!((w, h), (image.width(), image.height()));
    // every value to half-float precision
    let i = (h / 3) * w + w / 5;
    for c in 0..3 {
        let at = 12 + (3 * i + c) * 2;
        let v = half::f16::from_bits(u16::from_le_bytes([b[at], b[at + 1]])).to_f32();
        let want = image.pixels()[i][c];
        assert!((v - want).abs() <= want.abs() * 1e-3 + 1e-6, "{v} {want}");
    }
    // Not a probe, cut short, too large: typed errors.
    let (s, b) = call(&a, "POST", "/api/gpu/environment", b"hello".to_vec()).await;
    assert_eq!(
        s,
        StatusCode::UNPROCESSABLE_ENTITY,
        "{}",
        String::from_utf8_lossy(&b)
    );
    assert_eq!(json(&b)["kind"], "bad-probe");
    let (s, _) = call(
        &a,
        "POST",
        "/api/gpu/environment",
        bytes[..bytes.len() / 2].to_vec(),
    )
    .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    let small = app(false, 1000);
    let (s, b) = call(&small, "POST", "/api/gpu/environment", bytes).await;
    assert_eq!(
        s,
        StatusCode::PAYLOAD_TOO_LARGE,
        "{}",
        String::from_utf8_lossy(&b)
    );
}

/// Waits while the editing preparation runs.
async fn settled(a: &Arc<App>) -> serve::PreparationStatus {
    for _ in 0..1200 {
        let s = a.preparation();
        if s.state != serve::PreparationState::Running {
            return s;
        }
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
    panic!(
        "the preparation still runs after 120 s: {:?}",
        a.preparation()
    );
}

#[tokio::test]
async fn editing_is_prepared_from_the_corpus_on_request_and_cached() {
    let f = fixture();
    let cache = tempfile::tempdir().unwrap();
    let a = Arc::new(
        App::new(Config {
            corpus: Some(f.corpus.clone()),
            cache: Some(cache.path().to_path_buf()),
            ..Config::default()
        })
        .unwrap(),
    );
    let (_, b) = call(&a, "GET", "/api/info", vec![]).await;
    let i = json(&b);
    assert_eq!(i["editing"], false);
    assert_eq!(i["preparation"]["state"], "buildable");
    assert!(i["preparation"]["message"]
        .as_str()
        .unwrap()
        .starts_with(serve::EDITING_NEEDS));
    // What the server does at start: look for a cached build only. There is none, and
    // nothing is written.
    a.prepare_editing(false);
    assert_eq!(settled(&a).await.state, serve::PreparationState::Buildable);
    assert_eq!(std::fs::read_dir(cache.path()).unwrap().count(), 0);
    // Asked to build: 202 while it runs.
    let (s, b) = call(&a, "POST", "/api/editing/prepare", vec![]).await;
    assert_eq!(s, StatusCode::ACCEPTED, "{}", String::from_utf8_lossy(&b));
    assert_eq!(json(&b)["state"], "running");
    let done = settled(&a).await;
    // The six GGX materials carry none of the thesis's labels and none of the ratings: the
    // model is built and cached under the corpus's key, but no trait can be fitted, and the
    // message says so.
    assert_eq!(done.state, serve::PreparationState::Failed, "{done:?}");
    assert!(done
        .message
        .contains("no trait has enough labelled materials"));
    let entry = cache.path().join(serve::corpus_key(&f.corpus).unwrap());
    assert_eq!(done.cache.as_deref(), Some(entry.as_path()));
    let built = reduce::Model::load(entry.join("model.bin")).unwrap();
    let mut names = built.names.clone();
    names.sort();
    assert_eq!(
        names,
        (0..6).map(|i| format!("ggx-{i}")).collect::<Vec<_>>()
    );
    editing_is_refused(&a).await;
    // A server with a model is ready at once; one without a corpus cannot build.
    assert_eq!(
        app(true, serve::DEFAULT_UPLOAD_LIMIT).preparation().state,
        serve::PreparationState::Ready
    );
    let bare = Arc::new(App::new(Config::default()).unwrap());
    let (s, b) = call(&bare, "POST", "/api/editing/prepare", vec![]).await;
    assert_eq!(s, StatusCode::CONFLICT, "{}", String::from_utf8_lossy(&b));
    assert_eq!(
        bare.preparation().state,
        serve::PreparationState::Unavailable
    );
}
