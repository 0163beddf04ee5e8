//! Routes of the real-time view: the reduced basis, a material's coefficients and the CPU
//! reference of the same scene.

use crate::api::blocking;
use crate::error::{Result, ServeError};
use crate::gpu::GpuBasis;
use crate::library::{check_name, lock};
use crate::App;
use axum::extract::{Path, Query, State};
use axum::http::header;
use axum::response::{IntoResponse, Json, Response};
use serde::Deserialize;
use std::sync::Arc;

type AppState = State<Arc<App>>;

/// Largest reference image side.
const MAX_REFERENCE_SIZE: usize = 1024;
/// Most samples per pixel of a reference image.
const MAX_REFERENCE_SPP: u32 = 1024;

impl App {
    /// The model, when the server has one.
    pub fn model(&self) -> Result<&reduce::Model> {
        self.editor().map(|e| e.model).ok_or(ServeError::NoModel)
    }

    /// The model's reduced basis for the real-time view, built on first use.
    pub fn gpu_basis(&self) -> Result<Arc<GpuBasis>> {
        if let Some(b) = self.gpu_basis.get() {
            return Ok(b.clone());
        }
        let b = Arc::new(GpuBasis::from_model(self.model()?, Default::default())?);
        Ok(self.gpu_basis.get_or_init(|| b).clone())
    }

    /// The first `k` (all when `None`) model coefficients of a named material: an edit
    /// session's own point, a model material's coordinates, otherwise the projection of its
    /// table.
    pub fn coefficients(&self, name: &str, k: Option<usize>) -> Result<Vec<f64>> {
        check_name(name)?;
        let model = self.model()?;
        let k = k.unwrap_or(model.components());
        if k > model.components() {
            return Err(ServeError::InvalidParameter(format!(
                "k = {k}: the model has {} components",
                model.components()
            )));
        }
        if let Some(found) = self.session_named(name) {
            let (ed, s) = found?;
            let mut c = ed.state_of(&lock(&s)).coefficients;
            c.truncate(k);
            return Ok(c);
        }
        if let Some(i) = model.names.iter().position(|n| n == name) {
            if self.library.upload_table(name).is_none() {
                return Ok((0..k).map(|j| model.pca.coords[(i, j)]).collect());
            }
        }
        Ok(model.project_values(&self.values(name)?, k)?)
    }
}

#[derive(Deserialize)]
pub(crate) struct BasisQuery {
    k: Option<usize>,
}

/// `GET /api/gpu/basis.bin?k=K`: the mean and the first `k` components (all by default).
pub(crate) async fn basis(State(app): AppState, Query(q): Query<BasisQuery>) -> Result<Response> {
    let bytes = blocking(move || {
        let b = app.gpu_basis()?;
        b.encode(q.k.unwrap_or(b.components()))
    })
    .await?;
    Ok((
        [
            (header::CONTENT_TYPE, "application/octet-stream"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        bytes,
    )
        .into_response())
}

/// `GET /api/gpu/materials/{name}/coefficients?k=K`.
pub(crate) async fn coefficients(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<BasisQuery>,
) -> Result<Json<serde_json::Value>> {
    blocking(move || {
        let c = app.coefficients(&name, q.k)?;
        Ok(Json(serde_json::json!({
            "name": name,
            "k": c.len(),
            "components": app.model()?.components(),
            "coefficients": c,
        })))
    })
    .await
}

#[derive(Deserialize)]
pub(crate) struct ReferenceQuery {
    k: Option<usize>,
    size: Option<usize>,
    spp: Option<u32>,
    seed: Option<u64>,
}

/// `GET /api/gpu/materials/{name}/reference.bin?k=&size=&spp=`: the offline renderer's image of
/// the real-time view's default scene (`render::sphere_scene`, direct lighting, the scene of
/// `gantry render sphere`) for the model's full-grid reconstruction of the same `k`
/// coefficients: `size² × 3` little-endian `f32`, rows top to bottom.
pub(crate) async fn reference(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<ReferenceQuery>,
) -> Result<Response> {
    let size = q.size.unwrap_or(256);
    let spp = q.spp.unwrap_or(16);
    if size == 0 || size > MAX_REFERENCE_SIZE || spp == 0 || spp > MAX_REFERENCE_SPP {
        return Err(ServeError::InvalidParameter(format!(
            "reference size {size} (1 to {MAX_REFERENCE_SIZE}) and spp {spp} (1 to {MAX_REFERENCE_SPP})"
        )));
    }
    let bytes = blocking(move || {
        let c = app.coefficients(&name, q.k)?;
        let model = app.model()?;
        let table = brdf::MerlTable::from_values(model.synthesize(&c)?)?;
        let material = render::Material::new(Arc::new(table));
        let scene = render::sphere_scene(material.into(), size, size)?;
        direct_render_bytes(&scene, spp, q.seed.unwrap_or(1))
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
}

/// `GET /api/gpu/environment.bin`: the light probe of the environment views for the real-time
/// view: `GPUE`, little-endian `u32` width and height, then `width × height` RGB half floats,
/// rows from the zenith down (the lat-long mapping of `render::EnvironmentMap`).
pub(crate) async fn environment(State(app): AppState) -> Result<Response> {
    let bytes = blocking(move || Ok(environment_bytes(app.environment.image()))).await?;
    Ok(binary(bytes))
}

/// A scene rendered with direct lighting (the offline references of the real-time view), as
/// little-endian `f32` RGB, rows from the top.
fn direct_render_bytes(scene: &render::Scene, spp: u32, seed: u64) -> Result<Vec<u8>> {
    let options = render::RenderOptions {
        spp,
        seed,
        integrator: render::Integrator::Direct,
        ..Default::default()
    };
    let image = render::render_scene(scene, &options)?;
    let mut out = Vec::with_capacity(image.pixels().len() * 12);
    push_f32s(
        &mut out,
        image
            .pixels()
            .iter()
            .flat_map(|p| p.iter().map(|&v| v as f64)),
    );
    Ok(out)
}

fn binary(bytes: Vec<u8>) -> Response {
    ([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response()
}

fn push_f32s(out: &mut Vec<u8>, values: impl IntoIterator<Item = f64>) {
    for v in values {
        out.extend_from_slice(&(v as f32).to_le_bytes());
    }
}

/// A mesh of the real-time view, placed like the figure teapot: `teapot`
/// (`render::figure_teapot_mesh`) or `bunny` (`render::figure_bunny_mesh`, from the shared
/// data).
fn figure_mesh(name: &str) -> Result<render::Mesh> {
    match name {
        "teapot" => Ok(render::figure_teapot_mesh()),
        "bunny" => render::figure_bunny_mesh().map_err(|e| {
            ServeError::NotFound(format!(
                "the bunny mesh ({e}); it comes with the shared data (set BRDF_DATA_DIR)"
            ))
        }),
        _ => Err(ServeError::NotFound(format!(
            "mesh `{name}` (teapot or bunny)"
        ))),
    }
}

/// `GET /api/gpu/meshes/{name}`: a mesh of the figures (`teapot`, `bunny`) with the teapot
/// figures' camera and point light (`render::teapot_camera`, `teapot_point_light`): `GPUM`,
/// little-endian `u32` version (1), vertex count n, triangle count t; `f32` camera position,
/// look-at, up (3 each) and vertical field of view in degrees; `f32` light position and
/// intensity (3 each); then `f32` positions (3n), normals (3n), uvs (2n) and `u32` vertex
/// indices (3t).
pub(crate) async fn mesh(Path(name): Path<String>) -> Result<Response> {
    let bytes = blocking(move || {
        let mesh = figure_mesh(&name)?;
        let n = mesh.positions.len();
        if mesh.normals.len() != n || mesh.uvs.len() != n {
            return Err(ServeError::Internal(format!(
                "the figure's {name} lacks normals or uvs"
            )));
        }
        let camera = render::teapot_camera(1, 1);
        let light = render::teapot_point_light();
        let mut out = Vec::with_capacity(64 + n * 32 + mesh.triangles.len() * 12);
        out.extend_from_slice(b"GPUM");
        for v in [1, n, mesh.triangles.len()] {
            out.extend_from_slice(&(v as u32).to_le_bytes());
        }
        push_f32s(&mut out, camera.position.iter().copied());
        push_f32s(&mut out, camera.look_at.iter().copied());
        push_f32s(&mut out, camera.up.iter().copied());
        push_f32s(&mut out, [camera.fov_degrees]);
        push_f32s(&mut out, light.position.iter().copied());
        push_f32s(&mut out, light.intensity);
        push_f32s(
            &mut out,
            mesh.positions.iter().flat_map(|p| p.iter().copied()),
        );
        push_f32s(
            &mut out,
            mesh.normals.iter().flat_map(|p| p.iter().copied()),
        );
        push_f32s(&mut out, mesh.uvs.iter().flat_map(|p| p.iter().copied()));
        for t in &mesh.triangles {
            for i in t {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
        Ok(out)
    })
    .await?;
    Ok(binary(bytes))
}

#[derive(Deserialize)]
pub(crate) struct RustQuery {
    width: Option<usize>,
    seed: Option<u64>,
}

/// Largest side of a coefficient or selector texture.
const MAX_TEXTURE: usize = 2048;

fn texture_size(width: Option<usize>) -> Result<(usize, usize)> {
    let w = width.unwrap_or(256);
    if !(2..=MAX_TEXTURE).contains(&w) {
        return Err(ServeError::InvalidParameter(format!(
            "texture width {w} (2 to {MAX_TEXTURE})"
        )));
    }
    Ok((w, w / 2))
}

/// `GET /api/gpu/rust.bin?width=W&seed=S`: the rust teapot's field (`render::rust_selector`,
/// W × W/2): `GPUS`, `u32` width and height, then `f32` values in [0, 1], row 0 at v = 0.
pub(crate) async fn rust(Query(q): Query<RustQuery>) -> Result<Response> {
    let (w, h) = texture_size(q.width)?;
    let bytes = blocking(move || {
        let field = render::rust_selector(w, h, q.seed.unwrap_or(1));
        let mut out = Vec::with_capacity(12 + field.len() * 4);
        out.extend_from_slice(b"GPUS");
        out.extend_from_slice(&(w as u32).to_le_bytes());
        out.extend_from_slice(&(h as u32).to_le_bytes());
        push_f32s(&mut out, field.iter().map(|&v| v as f64));
        Ok(out)
    })
    .await?;
    Ok(binary(bytes))
}

#[derive(Deserialize)]
pub(crate) struct MeshReferenceQuery {
    from: String,
    to: String,
    k: Option<usize>,
    width: Option<usize>,
    texture_width: Option<usize>,
    seed: Option<u64>,
    spp: Option<u32>,
}

/// Most components of a spatially varying reference (its full-grid basis holds 17.5 MB per
/// component).
const MAX_REFERENCE_K: usize = 16;

/// `GET /api/gpu/meshes/{name}/reference.bin?from=A&to=B&k=K&width=W&texture_width=T&seed=S&spp=N`:
/// the offline renderer's rust-covered mesh (the teapot of fig. 5-8, or the bunny) under the
/// teapot figures' point light (`render::figure_point_scene`, direct lighting), every point
/// its own BRDF: the process path from A's to B's first k coefficients spread by
/// `render::rust_selector(T, T/2, S)` over a coefficient texture, on the model's full-grid
/// basis. W × 3W/4 × 3 little-endian `f32`, rows from the top.
pub(crate) async fn mesh_reference(
    State(app): AppState,
    Path(name): Path<String>,
    Query(q): Query<MeshReferenceQuery>,
) -> Result<Response> {
    let width = q.width.unwrap_or(320);
    let spp = q.spp.unwrap_or(16);
    let k = q.k.unwrap_or(10);
    if !(4..=MAX_REFERENCE_SIZE).contains(&width)
        || spp == 0
        || spp > MAX_REFERENCE_SPP
        || k == 0
        || k > MAX_REFERENCE_K
    {
        return Err(ServeError::InvalidParameter(format!(
            "reference width {width} (4 to {MAX_REFERENCE_SIZE}), spp {spp} (1 to {MAX_REFERENCE_SPP}), k {k} (1 to {MAX_REFERENCE_K})"
        )));
    }
    let (tw, th) = texture_size(q.texture_width)?;
    let bytes = blocking(move || {
        let mesh = figure_mesh(&name)?;
        let model = app.model()?;
        let nodes = vec![
            app.coefficients(&q.from, Some(k))?,
            app.coefficients(&q.to, Some(k))?,
        ];
        let path = render::ProcessPath::new(nodes)?;
        let field = render::rust_selector(tw, th, q.seed.unwrap_or(1));
        let texture = render::CoefficientTexture::from_selector(&path, tw, th, &field)?;
        let material =
            render::SurfaceMaterial::varying(Arc::new(full_basis(model, k)?), Arc::new(texture))?;
        let height = width * 3 / 4;
        let scene = render::figure_point_scene(&mesh, material, width, height)?;
        direct_render_bytes(&scene, spp, q.seed.unwrap_or(1))
    })
    .await?;
    Ok(binary(bytes))
}

/// The model's first `k` components on the full table grid, for the offline references.
fn full_basis(model: &reduce::Model, k: usize) -> Result<render::LinearBasis> {
    Ok(render::LinearBasis::from_dimension_major(
        render::BasisGrid::MERL,
        &model.pca.mean,
        &model.pca.basis,
        model.pca.components,
        k,
        model.log_floor,
    )?)
}

/// Most spheres in a progression (the shader's array of centres).
const MAX_GRID: usize = 16;

#[derive(Deserialize)]
pub(crate) struct GridQuery {
    count: Option<usize>,
    columns: Option<usize>,
    sphere_pixels: Option<usize>,
}

fn grid_of(q: &GridQuery) -> Result<(render::SphereGrid, usize, usize)> {
    let count = q.count.unwrap_or(8);
    let columns = q.columns.unwrap_or(4);
    let px = q.sphere_pixels.unwrap_or(128);
    if !(2..=MAX_GRID).contains(&count) || columns == 0 || !(4..=512).contains(&px) {
        return Err(ServeError::InvalidParameter(format!(
            "a progression of {count} spheres (2 to {MAX_GRID}) in {columns} columns, {px} pixels each (4 to 512)"
        )));
    }
    Ok((render::SphereGrid::new(count, columns)?, count, px))
}

/// `GET /api/gpu/grid?count=N&columns=C&sphere_pixels=P`: the layout of a progression of
/// spheres (thesis fig. 5-7; `render::SphereGrid`): JSON with `columns`, `rows`, the sphere
/// `centres`, the `camera` (position, look_at, up, fov_degrees, width, height) and the point
/// `light` (position, intensity).
pub(crate) async fn grid(Query(q): Query<GridQuery>) -> Result<Json<serde_json::Value>> {
    let (grid, count, px) = grid_of(&q)?;
    let camera = grid.camera(px);
    let light = grid.light();
    let v = |p: &brdf::Vec3| [p.x, p.y, p.z];
    Ok(Json(serde_json::json!({
        "columns": grid.columns,
        "rows": grid.rows,
        "centres": (0..count).map(|i| v(&grid.sphere(i))).collect::<Vec<_>>(),
        "camera": {
            "position": v(&camera.position),
            "look_at": v(&camera.look_at),
            "up": v(&camera.up),
            "fov_degrees": camera.fov_degrees,
            "width": camera.width,
            "height": camera.height,
        },
        "light": { "position": v(&light.position), "intensity": light.intensity },
    })))
}

#[derive(Deserialize)]
pub(crate) struct GridReferenceQuery {
    nodes: String,
    count: Option<usize>,
    columns: Option<usize>,
    sphere_pixels: Option<usize>,
    k: Option<usize>,
    spp: Option<u32>,
    seed: Option<u64>,
}

/// `GET /api/gpu/grid-reference.bin?nodes=A,B,…&count=N&columns=C&sphere_pixels=P&k=K&spp=S`:
/// the offline renderer's progression (`render::sphere_grid_scene`, direct lighting): sphere
/// i made of the process path through the named materials' first k coefficients at
/// t = i / (N − 1), on the model's full-grid basis. C·P × rows·P × 3 little-endian `f32`,
/// rows from the top.
pub(crate) async fn grid_reference(
    State(app): AppState,
    Query(q): Query<GridReferenceQuery>,
) -> Result<Response> {
    let (grid, count, px) = grid_of(&GridQuery {
        count: q.count,
        columns: q.columns,
        sphere_pixels: q.sphere_pixels,
    })?;
    let spp = q.spp.unwrap_or(16);
    let k = q.k.unwrap_or(10);
    if spp == 0 || spp > MAX_REFERENCE_SPP || k == 0 || k > MAX_REFERENCE_K {
        return Err(ServeError::InvalidParameter(format!(
            "spp {spp} (1 to {MAX_REFERENCE_SPP}), k {k} (1 to {MAX_REFERENCE_K})"
        )));
    }
    let names: Vec<String> = q.nodes.split(',').map(|n| n.trim().to_string()).collect();
    if names.len() < 2 || names.len() > MAX_GRID {
        return Err(ServeError::InvalidParameter(format!(
            "a process path of {} materials (2 to {MAX_GRID})",
            names.len()
        )));
    }
    let bytes = blocking(move || {
        let model = app.model()?;
        let nodes = names
            .iter()
            .map(|n| app.coefficients(n, Some(k)))
            .collect::<Result<Vec<_>>>()?;
        let path = render::ProcessPath::new(nodes)?;
        let basis = Arc::new(full_basis(model, k)?);
        let materials = (0..count)
            .map(|i| {
                let c = path.at(i as f64 / (count - 1) as f64);
                let brdf = render::BasisBrdf::new(basis.clone(), &c, &format!("stage {i}"))?;
                Ok(render::Material::new(Arc::new(brdf)).into())
            })
            .collect::<Result<Vec<render::SurfaceMaterial>>>()?;
        let scene = render::sphere_grid_scene(materials, grid.columns, px)?;
        direct_render_bytes(&scene, spp, q.seed.unwrap_or(1))
    })
    .await?;
    Ok(binary(bytes))
}

/// The `GPUE` bytes of a lat-long probe (see [`environment`]).
fn environment_bytes(image: &render::Image) -> Vec<u8> {
    let (w, h) = (image.width(), image.height());
    let mut out = Vec::with_capacity(12 + w * h * 6);
    out.extend_from_slice(b"GPUE");
    out.extend_from_slice(&(w as u32).to_le_bytes());
    out.extend_from_slice(&(h as u32).to_le_bytes());
    for p in image.pixels() {
        for &v in p {
            let v = if v.is_finite() {
                v.clamp(0.0, 65000.0)
            } else {
                0.0
            };
            out.extend_from_slice(&half::f16::from_f32(v).to_bits().to_le_bytes());
        }
    }
    out
}

/// Largest side of a probe sent to the real-time view (larger uploads are box-filtered down).
const MAX_PROBE_WIDTH: usize = 2048;

/// `POST /api/gpu/environment`: a lat-long light probe uploaded from the page (OpenEXR or
/// Radiance `.hdr`, at most the server's upload limit), returned as the `GPUE` bytes of
/// [`environment`] for the real-time view; the server keeps nothing. Probes wider than 2,048
/// pixels are halved (2 × 2 means) until they fit.
pub(crate) async fn upload_environment(
    State(app): AppState,
    headers: axum::http::HeaderMap,
    body: axum::body::Body,
) -> Result<Response> {
    let bytes = crate::api::read_upload(&app, &headers, body).await?;
    let out = blocking(move || {
        let bad = |message: String| ServeError::BadUpload {
            message,
            kind: "bad-probe",
        };
        let mut image = render::Image::decode(&bytes, std::path::Path::new("uploaded probe"))
            .map_err(|e| bad(e.to_string()))?;
        let (w, h) = (image.width(), image.height());
        if h < 2 || w.abs_diff(2 * h) > 2 {
            return Err(bad(format!(
                "a {w}×{h} image is not a lat-long probe (its width twice its height)"
            )));
        }
        while image.width() > MAX_PROBE_WIDTH {
            image = image.halved()?;
        }
        Ok(environment_bytes(&image))
    })
    .await?;
    Ok(binary(out))
}
