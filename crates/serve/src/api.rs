//! The HTTP routes: the embedded page and the JSON/PNG API.

use crate::editor::EditSession;
use crate::error::{Result, ServeError};
use crate::library::{check_name, lock, Origin, Shared};
use crate::views::{self, Shape};
use crate::App;
use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{delete, get, post, MethodRouter};
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex};

type AppState = State<Arc<App>>;
/// An open edit session, shared between requests.
type SharedSession = Arc<std::sync::Mutex<EditSession>>;

/// Every route: method, path (axum syntax) and handler. The router is built from this table,
/// and a test checks that the OpenAPI file lists exactly these routes.
pub fn routes() -> Vec<(&'static str, &'static str, MethodRouter<Arc<App>>)> {
    vec![
        ("get", "/", get(index)),
        ("get", "/assets/app.js", get(app_js)),
        ("get", "/assets/app.css", get(app_css)),
        ("get", "/api/openapi.json", get(openapi)),
        ("get", "/api/info", get(info)),
        ("post", "/api/editing/prepare", post(prepare_editing)),
        ("get", "/api/materials", get(materials)),
        ("get", "/api/materials/{name}/scores", get(scores)),
        ("get", "/api/materials/{name}/thumbnail.png", get(thumbnail)),
        ("get", "/api/materials/{name}/sphere.png", get(sphere)),
        ("get", "/api/materials/{name}/incidence", get(incidence)),
        ("get", "/api/materials/{name}/slice", get(slice)),
        ("get", "/api/materials/{name}/slice.png", get(slice_png)),
        ("get", "/api/materials/{name}/albedo", get(albedo)),
        (
            "get",
            "/api/materials/{name}/environment.png",
            get(environment),
        ),
        (
            "get",
            "/api/materials/{name}/export.binary",
            get(export_binary),
        ),
        ("get", "/api/materials/{name}/export.bsdf", get(export_bsdf)),
        ("get", "/api/compare", get(compare)),
        ("get", "/api/compare/difference.png", get(difference_png)),
        ("post", "/api/uploads", post(upload)),
        ("post", "/api/sessions", post(open_session)),
        ("get", "/api/sessions/{id}", get(session_state)),
        ("delete", "/api/sessions/{id}", delete(close_session)),
        ("post", "/api/sessions/{id}/nudge", post(nudge)),
        ("post", "/api/sessions/{id}/interpolate", post(interpolate)),
        ("post", "/api/sessions/{id}/undo", post(undo)),
        ("post", "/api/sessions/{id}/redo", post(redo)),
        ("get", "/api/sessions/{id}/sphere.png", get(session_sphere)),
        ("get", "/api/sessions/{id}/validity", get(validity)),
        ("get", "/api/sessions/{id}/spec.json", get(session_spec)),
        ("get", "/assets/gpu.js", get(gpu_js)),
        ("get", "/api/gpu/basis.bin", get(crate::gpu_api::basis)),
        ("get", "/api/gpu/meshes/{name}", get(crate::gpu_api::mesh)),
        (
            "get",
            "/api/gpu/meshes/{name}/reference.bin",
            get(crate::gpu_api::mesh_reference),
        ),
        ("get", "/api/gpu/rust.bin", get(crate::gpu_api::rust)),
        ("get", "/api/gpu/grid", get(crate::gpu_api::grid)),
        (
            "get",
            "/api/gpu/grid-reference.bin",
            get(crate::gpu_api::grid_reference),
        ),
        (
            "get",
            "/api/gpu/environment.bin",
            get(crate::gpu_api::environment),
        ),
        (
            "post",
            "/api/gpu/environment",
            post(crate::gpu_api::upload_environment),
        ),
        (
            "get",
            "/api/gpu/materials/{name}/coefficients",
            get(crate::gpu_api::coefficients),
        ),
        (
            "get",
            "/api/gpu/materials/{name}/reference.bin",
            get(crate::gpu_api::reference),
        ),
    ]
}

/// The router of the application (from [`routes`]); unknown paths get a JSON 404.
///
/// It serves the embedded page and the JSON/PNG API (docs/serve.md,
/// docs/serve.openapi.json); every computation runs on the blocking pool.
pub fn router(app: Arc<App>) -> Router {
    let mut by_path: Vec<(&str, MethodRouter<Arc<App>>)> = Vec::new();
    for (_, path, m) in routes() {
        match by_path.iter_mut().find(|(p, _)| *p == path) {
            Some(e) => e.1 = std::mem::take(&mut e.1).merge(m),
            None => by_path.push((path, m)),
        }
    }
    let mut r = Router::new();
    for (path, m) in by_path {
        r = r.route(path, m);
    }
    r.fallback(|uri: axum::http::Uri| async move { ServeError::NotFound(uri.path().to_string()) })
        .with_state(app)
}

pub(crate) async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T> + Send + 'static,
) -> Result<T> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ServeError::Internal(e.to_string()))?
}

fn png_response(bytes: Vec<u8>) -> Response {
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static("image/png")),
            (header::CACHE_CONTROL, HeaderValue::from_static("no-store")),
        ],
        bytes,
    )
        .into_response()
}

async fn index() -> Response {
    (
        [(header::CONTENT_TYPE, "text/html; charset=utf-8")],
        crate::assets::INDEX_HTML,
    )
        .into_response()
}

async fn app_js() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        crate::assets::APP_JS,
    )
        .into_response()
}

async fn gpu_js() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        crate::assets::GPU_JS,
    )
        .into_response()
}

async fn app_css() -> Response {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        crate::assets::APP_CSS,
    )
        .into_response()
}

async fn openapi() -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        crate::assets::OPENAPI_JSON,
    )
        .into_response()
}

/// One trait of `/api/info`.
#[derive(Serialize)]
struct TraitInfo {
    name: String,
    cross_validated: Option<f64>,
    /// In the linear space, the move of the model coefficients per unit of score
    /// (`w / ‖w‖²`): the real-time view draws a slider's step before the server confirms it.
    unit_step: Option<Vec<f64>>,
}

/// One trait space of `/api/info`.
#[derive(Serialize)]
struct SpaceInfo {
    index: usize,
    space: traits::Space,
    dim: usize,
    method: traits::Method,
    traits: Vec<TraitInfo>,
}

async fn info(State(app): AppState) -> Json<serde_json::Value> {
    let spaces: Vec<SpaceInfo> = app
        .editor()
        .map(|e| {
            e.spaces
                .iter()
                .enumerate()
                .map(|(index, s)| SpaceInfo {
                    index,
                    space: s.set.space,
                    dim: s.set.dim,
                    method: s.set.method,
                    traits: s
                        .set
                        .traits
                        .iter()
                        .map(|t| TraitInfo {
                            name: t.name.clone(),
                            cross_validated: t.cross_validated,
                            unit_step: (s.set.space == traits::Space::Linear)
                                .then(|| t.direction.unit_step()),
                        })
                        .collect(),
                })
                .collect()
        })
        .unwrap_or_default();
    Json(serde_json::json!({
        "name": "gantry serve",
        "version": env!("CARGO_PKG_VERSION"),
        "materials": app.library.corpus_names().len(),
        "editing": app.editor().is_some() && !spaces.is_empty(),
        "model_components": app.editor().map(|e| e.model.components()),
        "spaces": spaces,
        "preparation": app.preparation(),
        "upload_limit": app.config.upload_limit,
        "environment": app.environment_name,
    }))
}

/// Starts building (or loading the cached) model and trait sets of the corpus; 202 with the
/// status while it runs, 200 once editing works, 409 without a corpus.
async fn prepare_editing(State(app): AppState) -> Result<Response> {
    let status = app.prepare_editing(true);
    let code = match status.state {
        crate::PreparationState::Ready => StatusCode::OK,
        crate::PreparationState::Unavailable => return Err(ServeError::EditingDisabled),
        _ => StatusCode::ACCEPTED,
    };
    Ok((code, Json(status)).into_response())
}

#[derive(Deserialize)]
struct ListQuery {
    /// Substring of the name (case-insensitive).
    q: Option<String>,
    /// Trait whose score filters the list.
    #[serde(rename = "trait")]
    trait_name: Option<String>,
    min: Option<f64>,
    max: Option<f64>,
    /// Trait space index (default 0).
    space: Option<usize>,
    /// `name` (default) or `score` (descending by the trait's score).
    sort: Option<String>,
}

#[derive(Serialize)]
struct ListItem {
    name: String,
    origin: Origin,
    /// Scores per trait of the chosen space (model materials only).
    scores: Option<Vec<f64>>,
}

async fn materials(
    State(app): AppState,
    Query(q): Query<ListQuery>,
) -> Result<Json<serde_json::Value>> {
    let space = q.space.unwrap_or(0);
    let editor = app.editor();
    let sp = editor.and_then(|e| e.spaces.get(space));
    let trait_index = match (&q.trait_name, sp) {
        (Some(t), Some(sp)) => Some(
            sp.set
                .traits
                .iter()
                .position(|x| &x.name == t)
                .ok_or_else(|| ServeError::UnknownTrait(t.clone()))?,
        ),
        (Some(t), None) => return Err(ServeError::UnknownTrait(t.clone())),
        _ => None,
    };
    let needle = q.q.as_deref().unwrap_or("").to_lowercase();
    let mut items: Vec<ListItem> = app
        .library
        .corpus_names()
        .into_iter()
        .map(|n| (n, Origin::Corpus))
        .chain(
            app.library
                .upload_names()
                .into_iter()
                .map(|n| (n, Origin::Upload)),
        )
        .filter(|(n, _)| n.to_lowercase().contains(&needle))
        .map(|(name, origin)| {
            let scores = sp.and_then(|s| s.corpus_scores(&name));
            ListItem {
                name,
                origin,
                scores,
            }
        })
        .filter(|it| match trait_index {
            None => true,
            Some(k) => it.scores.as_ref().is_some_and(|s| {
                q.min.is_none_or(|m| s[k] >= m) && q.max.is_none_or(|m| s[k] <= m)
            }),
        })
        .collect();
    if let (Some(k), Some("score")) = (trait_index, q.sort.as_deref()) {
        items.sort_by(|a, b| {
            let s = |x: &ListItem| x.scores.as_ref().map_or(f64::NEG_INFINITY, |v| v[k]);
            s(b).total_cmp(&s(a))
        });
    }
    Ok(Json(serde_json::json!({
        "traits": sp.map(|s| s.set.traits.iter().map(|t| t.name.clone()).collect::<Vec<_>>()),
        "materials": items,
    })))
}

impl App {
    /// The material of a name: a corpus material, an upload, or `edit:<id>` (the current
    /// table of an edit session).
    pub fn resolve(&self, name: &str) -> Result<Shared> {
        check_name(name)?;
        if let Some(found) = self.session_named(name) {
            let (ed, s) = found?;
            let (t, _) = ed.table(&mut lock(&s))?;
            return Ok(t);
        }
        self.library.get(name)
    }

    /// The edit session a name `edit:<id>` stands for, with its editor; `None` for other names.
    pub(crate) fn session_named(
        &self,
        name: &str,
    ) -> Option<Result<(&crate::editor::Editor, SharedSession)>> {
        let id = name.strip_prefix("edit:")?;
        Some((|| {
            let id: u64 = id
                .parse()
                .map_err(|_| ServeError::InvalidName(name.to_string()))?;
            let ed = self.editor().ok_or(ServeError::EditingDisabled)?;
            Ok((ed, ed.get(id)?))
        })())
    }

    /// The table behind a name, when it is one (uploads and edit sessions).
    pub fn table_of(&self, name: &str) -> Option<Arc<brdf::MerlTable>> {
        if let Some(t) = self.library.upload_table(name) {
            return Some(t);
        }
        let id: u64 = name.strip_prefix("edit:")?.parse().ok()?;
        let ed = self.editor()?;
        let s = ed.get(id).ok()?;
        let (t, _) = ed.table(&mut lock(&s)).ok()?;
        Some(t)
    }

    /// The lit sphere of a named material.
    pub fn sphere_of(&self, name: &str, p: &traits::SpherePreview) -> Result<views::Pixels> {
        if let Some(t) = self.table_of(name) {
            return Ok(views::sphere(t.as_ref(), Some(&t), p));
        }
        let m = self.resolve(name)?;
        Ok(views::sphere(m.as_ref(), None, p))
    }

    /// Channel-major BRDF values of a material on the MERL grid (for projections).
    pub fn values(&self, name: &str) -> Result<Vec<f64>> {
        if let Some(t) = self.library.upload_table(name) {
            return Ok(t.values());
        }
        if let Some(src) = self.library.source(name) {
            return Ok(src.values_f32()?.into_iter().map(f64::from).collect());
        }
        let m = self.resolve(name)?;
        Ok(brdf::MerlTable::tabulate(m.as_ref()).values())
    }
}

async fn scores(State(app): AppState, Path(name): Path<String>) -> Result<Json<serde_json::Value>> {
    check_name(&name)?;
    blocking(move || {
        let ed = app.editor().ok_or(ServeError::EditingDisabled)?;
        let mut out = Vec::new();
        for (i, sp) in ed.spaces.iter().enumerate() {
            let x = ed.coords_of(i, &name, || app.values(&name))?;
            out.push(serde_json::json!({
                "space": sp.set.space,
                "traits": sp.set.traits.iter().map(|t| t.name.clone()).collect::<Vec<_>>(),
                "scores": sp.scores(&x),
            }));
        }
        Ok(Json(serde_json::json!({ "name": name, "spaces": out })))
    })
    .await
}

#[derive(Deserialize)]
struct SphereQuery {
    size: Option<usize>,
    lx: Option<f64>,
    ly: Option<f64>,
    /// Stops (log2 of the multiplier).
    exposure: Option<f64>,
}

impl SphereQuery {
    fn light(&self) -> (f64, f64) {
        (self.lx.unwrap_or(-0.35), self.ly.unwrap_or(0.4))
    }
}

async fn thumbnail(State(app): AppState, Path(name): Path<String>) -> Result<Response> {
    check_name(&name)?;
    if let Some(b) = lock(&app.thumbnails).get(&name) {
        return Ok(png_response(b.as_ref().clone()));
    }
    let a = app.clone();
    let bytes = blocking(move || {
        let p = a.previews.get(72, -0.35, 0.4)?;
        let px = a.sphere_of(&name, &p)?;
        // Auto exposure: the 99th percentile of the lit pixels at 0.9.
        let mut lum: Vec<f32> = p.pixels.iter().map(|&(i, _, _)| px[i][1]).collect();
        lum.sort_by(f32::total_cmp);
        let ref_lum = lum
            .get(lum.len() * 99 / 100)
            .copied()
            .unwrap_or(1.0)
            .max(1e-6);
        let stops = (0.9 / ref_lum as f64).log2().clamp(-20.0, 20.0);
        let png = views::png(&px, p.size, p.size, stops)?;
        if !name.starts_with("edit:") {
            let mut t = lock(&a.thumbnails);
            if t.len() > 512 {
                t.clear();
            }
            t.insert(name, Arc::new(png.clone()));
        }
        Ok(png)
    })
    .await?;
    Ok(png_response(bytes))
}

async fn sphere(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<SphereQuery>,
) -> Result<Response> {
    check_name(&name)?;
    let bytes = blocking(move || {
        let (lx, ly) = q.light();
        let p = app.previews.get(q.size.unwrap_or(256), lx, ly)?;
        views::png(
            &app.sphere_of(&name, &p)?,
            p.size,
            p.size,
            q.exposure.unwrap_or(0.0),
        )
    })
    .await?;
    Ok(png_response(bytes))
}

#[derive(Deserialize)]
struct IncidenceQuery {
    theta_i: Option<f64>,
    n: Option<usize>,
}

async fn incidence(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<IncidenceQuery>,
) -> Result<Json<views::IncidencePlane>> {
    check_name(&name)?;
    blocking(move || {
        let m = app.resolve(&name)?;
        Ok(Json(views::incidence_plane(
            m.as_ref(),
            q.theta_i.unwrap_or(30.0),
            q.n.unwrap_or(361),
        )?))
    })
    .await
}

#[derive(Deserialize)]
struct SliceQuery {
    phi_d: Option<f64>,
}

async fn slice(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<SliceQuery>,
) -> Result<Json<views::Slice>> {
    check_name(&name)?;
    blocking(move || {
        let m = app.resolve(&name)?;
        Ok(Json(views::slice(m.as_ref(), q.phi_d.unwrap_or(90.0))?))
    })
    .await
}

async fn slice_png(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<SliceQuery>,
) -> Result<Response> {
    check_name(&name)?;
    let bytes = blocking(move || {
        let m = app.resolve(&name)?;
        let s = views::slice(m.as_ref(), q.phi_d.unwrap_or(90.0))?;
        views::png_rgb8(
            &views::slice_image(&s),
            s.theta_h_deg.len(),
            s.theta_d_deg.len(),
        )
    })
    .await?;
    Ok(png_response(bytes))
}

async fn albedo(
    State(app): AppState,
    Path(name): Path<String>,
) -> Result<Json<views::AlbedoCurve>> {
    check_name(&name)?;
    blocking(move || {
        let m = app.resolve(&name)?;
        Ok(Json(views::albedo(m.as_ref())))
    })
    .await
}

#[derive(Deserialize)]
struct EnvQuery {
    shape: Option<Shape>,
    size: Option<usize>,
    spp: Option<u32>,
    seed: Option<u64>,
    exposure: Option<f64>,
}

async fn environment(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<EnvQuery>,
) -> Result<Response> {
    check_name(&name)?;
    let gate = app.clone();
    let _turn = gate
        .env_gate
        .acquire()
        .await
        .map_err(|e| ServeError::Internal(e.to_string()))?;
    let bytes = blocking(move || {
        let m = app.resolve(&name)?;
        let size = q.size.unwrap_or(192);
        let px = app.env_pool.install(|| {
            views::environment(
                m,
                &app.environment,
                q.shape.unwrap_or(Shape::Sphere),
                size,
                q.spp.unwrap_or(4),
                q.seed.unwrap_or(1),
            )
        })?;
        views::png(&px, size, size, q.exposure.unwrap_or(0.0))
    })
    .await?;
    Ok(png_response(bytes))
}

fn binary_response(name: &str, bytes: Vec<u8>, extension: &str) -> Response {
    let file = name.replace(':', "-");
    (
        [
            (header::CONTENT_TYPE, "application/octet-stream".to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{file}.{extension}\""),
            ),
        ],
        bytes,
    )
        .into_response()
}

/// The MERL table of a corpus material, an upload or an edit (`edit:ID`).
fn material_table(app: &App, name: &str) -> Result<Arc<brdf::MerlTable>> {
    if let Some(t) = app.library.upload_table(name) {
        return Ok(t);
    }
    if let Some(id) = name.strip_prefix("edit:") {
        let id: u64 = id
            .parse()
            .map_err(|_| ServeError::InvalidName(name.to_string()))?;
        let ed = app.editor().ok_or(ServeError::EditingDisabled)?;
        let s = ed.get(id)?;
        let (t, _) = ed.table(&mut lock(&s))?;
        return Ok(t);
    }
    let src = app
        .library
        .source(name)
        .ok_or_else(|| ServeError::UnknownMaterial(name.to_string()))?;
    Ok(Arc::new(src.table()?))
}

async fn export_binary(State(app): AppState, Path(name): Path<String>) -> Result<Response> {
    check_name(&name)?;
    let n = name.clone();
    let bytes =
        blocking(move || Ok(brdf::merl::to_bytes(material_table(&app, &n)?.as_ref()))).await?;
    Ok(binary_response(&name, bytes, "binary"))
}

/// The material as an RGL tensor `.bsdf` file (for Mitsuba 3's `measured` BSDF and pbrt-v4),
/// written from its table read with trilinear interpolation.
async fn export_bsdf(State(app): AppState, Path(name): Path<String>) -> Result<Response> {
    check_name(&name)?;
    let n = name.clone();
    let bytes = blocking(move || {
        let table = material_table(&app, &n)?
            .as_ref()
            .clone()
            .with_interpolation(brdf::Interpolation::Trilinear);
        let options = rgl_bsdf::WriteOptions {
            description: n.clone(),
            ..Default::default()
        };
        rgl_bsdf::write(&table, &options)
            .map(|f| f.to_bytes())
            .map_err(|e| ServeError::Internal(e.to_string()))
    })
    .await?;
    Ok(binary_response(&name, bytes, "bsdf"))
}

#[derive(Deserialize)]
struct CompareQuery {
    a: String,
    b: String,
    size: Option<usize>,
    lx: Option<f64>,
    ly: Option<f64>,
}

fn compare_images(app: &App, q: &CompareQuery) -> Result<(Vec<u8>, views::Comparison, usize)> {
    let p = app.previews.get(
        q.size.unwrap_or(256),
        q.lx.unwrap_or(-0.35),
        q.ly.unwrap_or(0.4),
    )?;
    let (ia, ib) = rayon::join(|| app.sphere_of(&q.a, &p), || app.sphere_of(&q.b, &p));
    let (ia, ib) = (ia?, ib?);
    let (rgb, c) = views::difference(&ia, &ib);
    Ok((rgb, c, p.size))
}

async fn compare(
    State(app): AppState,
    Query(q): Query<CompareQuery>,
) -> Result<Json<serde_json::Value>> {
    check_name(&q.a)?;
    check_name(&q.b)?;
    blocking(move || {
        let (_, c, _) = compare_images(&app, &q)?;
        Ok(Json(
            serde_json::json!({ "a": q.a, "b": q.b, "comparison": c }),
        ))
    })
    .await
}

async fn difference_png(State(app): AppState, Query(q): Query<CompareQuery>) -> Result<Response> {
    check_name(&q.a)?;
    check_name(&q.b)?;
    let bytes = blocking(move || {
        let (rgb, _, size) = compare_images(&app, &q)?;
        views::png_rgb8(&rgb, size, size)
    })
    .await?;
    Ok(png_response(bytes))
}

#[derive(Deserialize)]
struct UploadQuery {
    /// The file's name (its stem names the upload).
    name: Option<String>,
}

/// An uploaded body, refused (413 `too-large`) past the server's upload limit: from its
/// Content-Length first, then while reading.
pub(crate) async fn read_upload(app: &App, headers: &HeaderMap, body: Body) -> Result<Bytes> {
    let limit = app.config.upload_limit;
    let announced = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if announced.is_some_and(|n| n > limit) {
        return Err(ServeError::UploadTooLarge { limit });
    }
    axum::body::to_bytes(body, limit as usize)
        .await
        .map_err(|_| ServeError::UploadTooLarge { limit })
}

async fn upload(
    State(app): AppState,
    Query(q): Query<UploadQuery>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response> {
    let bytes = read_upload(&app, &headers, body).await?;
    let file = q.name.unwrap_or_else(|| "upload.binary".into());
    let name = blocking(move || app.library.add_upload(&file, &bytes)).await?;
    Ok((
        StatusCode::CREATED,
        Json(serde_json::json!({ "name": name })),
    )
        .into_response())
}

#[derive(Deserialize)]
struct OpenSession {
    material: String,
    space: Option<usize>,
}

async fn open_session(
    State(app): AppState,
    Json(req): Json<OpenSession>,
) -> Result<Json<crate::editor::SessionState>> {
    check_name(&req.material)?;
    blocking(move || {
        let ed = app.editor().ok_or(ServeError::EditingDisabled)?;
        let space = req.space.unwrap_or(0);
        let x = ed.coords_of(space, &req.material, || app.values(&req.material))?;
        Ok(Json(ed.open(space, &req.material, &x)?))
    })
    .await
}

fn with_session<T: Send + 'static>(
    app: Arc<App>,
    id: u64,
    f: impl FnOnce(&App, &crate::editor::Editor, &mut EditSession) -> Result<T> + Send + 'static,
) -> impl std::future::Future<Output = Result<T>> {
    blocking(move || {
        let ed = app.editor().ok_or(ServeError::EditingDisabled)?;
        let s: Arc<Mutex<EditSession>> = ed.get(id)?;
        let mut s = lock(&s);
        f(&app, ed, &mut s)
    })
}

async fn session_state(
    State(app): AppState,
    Path(id): Path<u64>,
) -> Result<Json<crate::editor::SessionState>> {
    with_session(app, id, |_, ed, s| Ok(Json(ed.state_of(s)))).await
}

async fn close_session(State(app): AppState, Path(id): Path<u64>) -> Result<StatusCode> {
    let ed = app.editor().ok_or(ServeError::EditingDisabled)?;
    ed.close(id)?;
    Ok(StatusCode::NO_CONTENT)
}

#[derive(Deserialize)]
struct NudgeRequest {
    #[serde(rename = "trait")]
    trait_name: String,
    /// Units to add.
    amount: Option<f64>,
    /// Or the score to reach.
    target: Option<f64>,
}

async fn nudge(
    State(app): AppState,
    Path(id): Path<u64>,
    Json(req): Json<NudgeRequest>,
) -> Result<Json<crate::editor::StepResult>> {
    with_session(app, id, move |_, ed, s| {
        Ok(Json(match (req.amount, req.target) {
            (Some(a), None) => ed.nudge(s, &req.trait_name, a)?,
            (None, Some(t)) => ed.set_score(s, &req.trait_name, t)?,
            _ => {
                return Err(ServeError::InvalidParameter(
                    "give exactly one of amount and target".into(),
                ))
            }
        }))
    })
    .await
}

#[derive(Deserialize)]
struct InterpolateRequest {
    other: String,
    t: f64,
}

async fn interpolate(
    State(app): AppState,
    Path(id): Path<u64>,
    Json(req): Json<InterpolateRequest>,
) -> Result<Json<crate::editor::StepResult>> {
    check_name(&req.other)?;
    with_session(app, id, move |app, ed, s| {
        let space = s.space;
        let other = req.other.clone();
        let r = ed.interpolate(
            s,
            &req.other,
            || ed.coords_of(space, &other, || app.values(&other)),
            req.t,
        )?;
        Ok(Json(r))
    })
    .await
}

async fn undo(
    State(app): AppState,
    Path(id): Path<u64>,
) -> Result<Json<crate::editor::SessionState>> {
    with_session(app, id, |_, ed, s| Ok(Json(ed.undo(s)?))).await
}

async fn redo(
    State(app): AppState,
    Path(id): Path<u64>,
) -> Result<Json<crate::editor::SessionState>> {
    with_session(app, id, |_, ed, s| Ok(Json(ed.redo(s)?))).await
}

async fn session_sphere(
    State(app): AppState,
    Path(id): Path<u64>,
    Query(q): Query<SphereQuery>,
) -> Result<Response> {
    let bytes = with_session(app, id, move |app, ed, s| {
        let (lx, ly) = q.light();
        let p = app.previews.get(q.size.unwrap_or(256), lx, ly)?;
        views::png(
            &ed.preview(s, &p),
            p.size,
            p.size,
            q.exposure.unwrap_or(0.0),
        )
    })
    .await?;
    Ok(png_response(bytes))
}

async fn validity(State(app): AppState, Path(id): Path<u64>) -> Result<Json<serde_json::Value>> {
    with_session(app, id, |_, ed, s| {
        let (_, r) = ed.table(s)?;
        Ok(Json(serde_json::json!({
            "valid": r.is_valid(),
            "failed": r.failed,
            "min_value": r.min_value,
            "negative_values": r.negative_values,
            "albedo": r.albedo,
            "max_albedo": { "value": r.max_albedo.0, "theta_i_deg": r.max_albedo.1, "channel": r.max_albedo.2 },
            "reciprocity_residual": r.reciprocity_residual,
            "in_hull": r.in_hull,
        })))
    })
    .await
}

async fn session_spec(State(app): AppState, Path(id): Path<u64>) -> Result<Response> {
    let (spec, start) = with_session(app, id, |app, ed, s| {
        let m = app
            .config
            .model
            .as_ref()
            .map_or("model.bin".into(), |p| p.display().to_string());
        let t = app
            .config
            .traits
            .get(s.space)
            .map_or("traits.json".into(), |p| p.display().to_string());
        Ok((ed.spec(s, &m, &t), s.id))
    })
    .await?;
    let body = serde_json::to_vec_pretty(&spec).map_err(|e| ServeError::Internal(e.to_string()))?;
    Ok((
        [
            (header::CONTENT_TYPE, "application/json".to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"edit-{start}.json\""),
            ),
        ],
        body,
    )
        .into_response())
}
