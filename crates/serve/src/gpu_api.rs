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
        self.editor
            .as_ref()
            .map(|e| e.model)
            .ok_or(ServeError::NoModel)
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
        let options = render::RenderOptions {
            spp,
            seed: q.seed.unwrap_or(1),
            integrator: render::Integrator::Direct,
            ..Default::default()
        };
        let image = render::render_scene(&scene, &options)?;
        let mut out = Vec::with_capacity(size * size * 12);
        for p in image.pixels() {
            for v in p {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        Ok(out)
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
}

/// `GET /api/gpu/environment.bin`: the light probe of the environment views for the real-time
/// view: `GPUE`, little-endian `u32` width and height, then `width × height` RGB half floats,
/// rows from the zenith down (the lat-long mapping of `render::EnvironmentMap`).
pub(crate) async fn environment(State(app): AppState) -> Result<Response> {
    let bytes = blocking(move || {
        let image = app.environment.image();
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
        Ok(out)
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
}
