//! The job behind `gantry render`: a scene file or one of the thesis's figure types, rendered
//! and written as OpenEXR with a tonemapped PNG beside it. With the `cli` feature the options
//! are also the command's arguments.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use crate::error::{RenderError, Result};
use crate::integrator::ProgressFn;
use crate::material::{BasisGrid, LinearBasis, Material, MaterialResolver, SurfaceMaterial};
use crate::scene_file::SpecResolver;
use crate::varying::{CoefficientTexture, ProcessPath};
use crate::{EnvironmentMap, Image, Integrator, RenderOptions, Tonemap};

/// Render a scene file, or one of the figure subcommands.
///
/// # Examples
///
/// ```
/// use render::{Common, Figure, Image, RenderJob};
///
/// let dir = tempfile::tempdir().unwrap();
/// let common = Common { spp: Some(2), out: dir.path().join("sphere.exr"), seed: 1 };
/// let job = RenderJob {
///     figure: Some(Figure::Sphere {
///         spec: "lambert:kd=0.5".into(),
///         size: 24,
///         common: common.clone(),
///     }),
///     scene: None,
///     common,
/// };
/// let report = job.run(None).unwrap();
/// assert_eq!(report.size, (24, 24));
/// assert!(report.png.exists());
/// // The EXR holds linear radiance: finite, non-negative, and the lit sphere stands out
/// // from the black corner.
/// let image = Image::read_exr(&report.exr).unwrap();
/// assert!(image.pixels().iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
/// assert_eq!(image.get(0, 0), [0.0; 3]);
/// assert!(image.get(12, 12)[0] > 0.0);
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "cli", command(args_conflicts_with_subcommands = true))]
pub struct RenderJob {
    /// A figure instead of a scene file.
    #[cfg_attr(feature = "cli", command(subcommand))]
    pub figure: Option<Figure>,
    /// Scene file (TOML; see docs/render.md).
    pub scene: Option<PathBuf>,
    /// Samples, output and seed.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub common: Common,
}

/// Options shared by every render.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct Common {
    /// Samples per pixel.
    #[cfg_attr(feature = "cli", arg(long))]
    pub spp: Option<u32>,
    /// Output OpenEXR file (a tonemapped PNG is written beside it).
    #[cfg_attr(feature = "cli", arg(long, default_value = "render.exr"))]
    pub out: PathBuf,
    /// Seed of the random streams.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1))]
    pub seed: u64,
}

/// The thesis's figure types.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Subcommand))]
pub enum Figure {
    /// A sphere of the material under a point light.
    Sphere {
        /// Material spec.
        spec: String,
        /// Image size in pixels (square).
        #[cfg_attr(feature = "cli", arg(long, default_value_t = 256))]
        size: usize,
        /// Samples, output and seed.
        #[cfg_attr(feature = "cli", command(flatten))]
        common: Common,
    },
    /// The Utah teapot in the material under an environment map.
    Teapot {
        /// Material spec.
        spec: String,
        /// Light probe (lat-long OpenEXR); a procedural probe when absent.
        #[cfg_attr(feature = "cli", arg(long))]
        env: Option<PathBuf>,
        /// Image width (height is 3/4 of it).
        #[cfg_attr(feature = "cli", arg(long, default_value_t = 320))]
        width: usize,
        /// Samples, output and seed.
        #[cfg_attr(feature = "cli", command(flatten))]
        common: Common,
    },
    /// The rust teapot (thesis §7.2.2, fig. 5-8): every point has its own BRDF, a point on a
    /// process path in the model's coefficient space (clean → rusted) chosen by a fractal
    /// rust field over the teapot's texture coordinates; --seed also seeds the rust field.
    RustTeapot {
        /// PCA model file (from `gantry model build`).
        #[cfg_attr(feature = "cli", arg(long))]
        model: PathBuf,
        /// Material spec of the clean end, projected on the model.
        #[cfg_attr(feature = "cli", arg(long, requires = "to", conflicts_with = "path"))]
        from: Option<String>,
        /// Material spec of the rusted end, projected on the model.
        #[cfg_attr(feature = "cli", arg(long, requires = "from"))]
        to: Option<String>,
        /// Process path file (`{"nodes": [[…], …]}`, clean first) instead of --from/--to.
        #[cfg_attr(feature = "cli", arg(long, required_unless_present = "from"))]
        path: Option<PathBuf>,
        /// Components used (default: all of the model's, or of the path's nodes).
        #[cfg_attr(feature = "cli", arg(long))]
        k: Option<usize>,
        /// Width of the coefficient texture in texels (its height is half of it).
        #[cfg_attr(feature = "cli", arg(long, default_value_t = 256))]
        texture_size: usize,
        /// Lighting: a point light (direct illumination) or a light probe (path tracing, on a
        /// grey ground).
        #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = TeapotLight::Env))]
        light: TeapotLight,
        /// The mesh: the teapot, or the shared data's Stanford bunny in its place.
        #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = FigureMesh::Teapot))]
        mesh: FigureMesh,
        /// Light probe (lat-long OpenEXR or .hdr) for --light env; a procedural probe when
        /// absent.
        #[cfg_attr(feature = "cli", arg(long))]
        env: Option<PathBuf>,
        /// Image width (height is 3/4 of it).
        #[cfg_attr(feature = "cli", arg(long, default_value_t = 320))]
        width: usize,
        /// Samples, output and seed (the seed also seeds the rust field).
        #[cfg_attr(feature = "cli", command(flatten))]
        common: Common,
    },
    /// A row of spheres: the given materials, or a PCA truncation series of one material.
    Strip {
        /// Material specs, left to right.
        specs: Vec<String>,
        /// With --model: reconstruct this material with 5, 10, 20, 30, 45, 60 and all components.
        #[cfg_attr(feature = "cli", arg(long, requires = "model"))]
        series: Option<String>,
        /// PCA model file (from `gantry model build`).
        #[cfg_attr(feature = "cli", arg(long))]
        model: Option<PathBuf>,
        /// Pixels per sphere.
        #[cfg_attr(feature = "cli", arg(long, default_value_t = 96))]
        sphere_pixels: usize,
        /// Samples, output and seed.
        #[cfg_attr(feature = "cli", command(flatten))]
        common: Common,
    },
}

/// The mesh of the rust figure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum FigureMesh {
    /// The figure's Utah teapot ([`crate::figure_teapot_mesh`]).
    #[default]
    Teapot,
    /// The Stanford bunny of the shared data in the teapot's place
    /// ([`crate::figure_bunny_mesh`]).
    Bunny,
}

impl FigureMesh {
    /// The mesh, placed for the teapot figures' camera and lights.
    pub fn mesh(self) -> Result<crate::Mesh> {
        match self {
            FigureMesh::Teapot => Ok(crate::figure_teapot_mesh()),
            FigureMesh::Bunny => crate::figure_bunny_mesh(),
        }
    }
}

/// How the rust teapot is lit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum TeapotLight {
    /// The point light of the teapot figure (`teapot_point_scene`), direct illumination (16 spp
    /// by default).
    Point,
    /// A light probe over a grey ground (`teapot_figure`), path tracing (64 spp by default).
    #[default]
    Env,
}

/// The files a render wrote.
#[derive(Debug, Clone, Serialize)]
pub struct RenderReport {
    /// The linear OpenEXR image.
    pub exr: PathBuf,
    /// The tonemapped PNG beside it.
    pub png: PathBuf,
    /// Image size in pixels.
    pub size: (usize, usize),
}

impl fmt::Display for RenderReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "wrote {} and {}", self.exr.display(), self.png.display())
    }
}

/// Resolves every material form a scene file names: specs through [`SpecResolver`], the
/// linear bases of `reduce` model files (`model` + `coefficients`) and projections of materials
/// on them (spatially varying `model` + `from`/`to` materials).
#[derive(Debug, Default, Clone, Copy)]
pub struct ModelResolver;

/// The log-PCA basis of a `reduce` model file, for per-point coefficients.
pub fn load_basis(model: &Path) -> Result<(Arc<LinearBasis>, reduce::Model)> {
    let m = reduce::Model::load(model)?;
    m.require_log_mapping("a spatially varying render")?;
    let basis = LinearBasis::from_dimension_major(
        BasisGrid::MERL,
        &m.pca.mean,
        &m.pca.basis,
        m.pca.components,
        m.pca.components,
        m.log_floor,
    )?;
    Ok((Arc::new(basis), m))
}

impl MaterialResolver for ModelResolver {
    fn spec(&self, spec: &str) -> Result<Arc<dyn brdf::Brdf>> {
        SpecResolver.spec(spec)
    }

    fn tabulated(
        &self,
        spec: &str,
        brdf: &Arc<dyn brdf::Brdf>,
    ) -> Result<Option<Arc<dyn brdf::Brdf>>> {
        SpecResolver.tabulated(spec, brdf)
    }

    fn linear_basis(&self, model: &Path) -> Result<Arc<LinearBasis>> {
        load_basis(model).map(|(b, _)| b)
    }

    fn project(&self, model: &Path, specs: &[&str], k: Option<usize>) -> Result<Vec<Vec<f64>>> {
        project_all(&reduce::Model::load(model)?, model, specs, k)
    }
}

/// A figure material: evaluated as loaded, importance-sampled from its MERL-grid table.
fn figure_material(spec: &str) -> Result<SurfaceMaterial> {
    let loaded = brdf::load(spec).map_err(|e| RenderError::Material {
        name: spec.to_string(),
        message: e.to_string(),
    })?;
    let table = loaded.tabulate();
    let brdf: Arc<dyn brdf::Brdf> = Arc::new(loaded);
    Ok(Material::with_importance_from(brdf, &table, Default::default()).into())
}

fn options(
    common: &Common,
    default_spp: u32,
    integrator: Integrator,
    progress: Option<ProgressFn>,
) -> RenderOptions {
    RenderOptions {
        spp: common.spp.unwrap_or(default_spp),
        seed: common.seed,
        integrator,
        progress,
        ..Default::default()
    }
}

/// Checks that `out` names an OpenEXR image (`x.exr`) or a PNG (`x.png`).
fn check_output(out: &Path) -> Result<()> {
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("exr" | "png")) {
        return Ok(());
    }
    Err(RenderError::InvalidArgument(format!(
        "{}: the output is an OpenEXR image (.exr) with a PNG beside it, or the PNG (.png) \
         with the OpenEXR image beside it",
        out.display()
    )))
}

/// Writes the linear OpenEXR image and its tonemapped PNG: `--out` names either (`x.exr` or
/// `x.png`), the other goes beside it.
fn write(image: &Image, out: &Path) -> Result<RenderReport> {
    check_output(out)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| RenderError::io(dir, e))?;
    }
    let exr = out.with_extension("exr");
    let png = out.with_extension("png");
    image.write_exr(&exr)?;
    image.write_png(&png, &Tonemap::default())?;
    Ok(RenderReport {
        exr,
        png,
        size: (image.width(), image.height()),
    })
}

/// Coordinates of the material named by `spec` on the first `k` components of `model`
/// (tabulated on the MERL grid, then projected in log space, as `gantry model reconstruct`
/// does).
fn project_spec(model: &reduce::Model, spec: &str, k: usize) -> Result<Vec<f64>> {
    let table = brdf::load(spec)
        .map_err(|e| RenderError::Material {
            name: spec.to_string(),
            message: e.to_string(),
        })?
        .tabulate();
    Ok(model.project_values(&table.values(), k)?)
}

/// The linear basis of the model file `model` and the coefficients of the materials `specs`
/// on its first `k` components (all of them when `None`): the nodes of a process path from
/// measured materials. The model is read once.
pub fn project_materials(
    model: &Path,
    specs: &[&str],
    k: Option<usize>,
) -> Result<(Arc<LinearBasis>, Vec<Vec<f64>>)> {
    let (basis, m) = load_basis(model)?;
    Ok((basis, project_all(&m, model, specs, k)?))
}

fn project_all(
    m: &reduce::Model,
    file: &Path,
    specs: &[&str],
    k: Option<usize>,
) -> Result<Vec<Vec<f64>>> {
    m.require_log_mapping("a spatially varying render")?;
    let k = k.unwrap_or(m.components());
    if k == 0 || k > m.components() {
        return Err(RenderError::InvalidArgument(format!(
            "k = {k}: the model {} has {} components",
            file.display(),
            m.components()
        )));
    }
    specs.iter().map(|s| project_spec(m, s, k)).collect()
}

/// The rust teapot's material: the process path (from `--path`, or from the projections of
/// `from` and `to`), truncated to `k` components, spread over a `texture_width × texture_width/2`
/// texture by [`crate::rust_selector`] seeded with `seed`.
fn rust_material(
    model: &Path,
    ends: Option<(&str, &str)>,
    path: Option<&Path>,
    k: Option<usize>,
    texture_width: usize,
    seed: u64,
) -> Result<SurfaceMaterial> {
    let (basis, process) = match (ends, path) {
        (Some((from, to)), None) => {
            let (basis, nodes) = project_materials(model, &[from, to], k)?;
            (basis, ProcessPath::new(nodes)?)
        }
        (None, Some(p)) => {
            let process = ProcessPath::read(p)?;
            let process = match k {
                Some(k) => process.truncated(k)?,
                None => process,
            };
            (load_basis(model)?.0, process)
        }
        _ => {
            return Err(RenderError::InvalidArgument(
                "give either --from and --to, or --path".into(),
            ))
        }
    };
    let (w, h) = (texture_width, (texture_width / 2).max(1));
    let selector = crate::rust_selector(w, h, seed);
    let texture = CoefficientTexture::from_selector(&process, w, h, &selector)?;
    SurfaceMaterial::varying(basis, Arc::new(texture))
}

/// The spheres of a strip: the given materials, or the truncation series of one.
fn strip_materials(
    specs: &[String],
    series: Option<&str>,
    model: Option<&Path>,
) -> Result<Vec<SurfaceMaterial>> {
    let Some(target) = series else {
        if specs.is_empty() {
            return Err(RenderError::InvalidArgument(
                "give material specs, or --series SPEC --model model.bin".into(),
            ));
        }
        return specs.iter().map(|s| figure_material(s)).collect();
    };
    let model =
        model.ok_or_else(|| RenderError::InvalidArgument("--series needs --model".into()))?;
    let (basis, m) = load_basis(model)?;
    let coeffs = project_spec(&m, target, m.pca.components)?;
    crate::figures::truncation_strip(&basis, &coeffs, &[5, 10, 20, 30, 45, 60, usize::MAX])
}

/// The teapot figure: the material on a grey Lambertian ground under a lat-long light probe
/// (OpenEXR or Radiance `.hdr`; the procedural probe when `None`), `width` pixels wide and 3/4
/// of that high.
pub fn teapot_figure(
    material: SurfaceMaterial,
    probe: Option<&Path>,
    width: usize,
) -> Result<crate::Scene> {
    mesh_figure(&crate::figure_teapot_mesh(), material, probe, width)
}

/// [`teapot_figure`] with another mesh in the teapot's place (one placed like it, such as
/// [`crate::figure_bunny_mesh`]).
pub fn mesh_figure(
    mesh: &crate::Mesh,
    material: SurfaceMaterial,
    probe: Option<&Path>,
    width: usize,
) -> Result<crate::Scene> {
    let env = match probe {
        Some(p) => EnvironmentMap::read(p)?,
        None => EnvironmentMap::procedural_probe(1024, 512, 7)?,
    };
    let ground: SurfaceMaterial = Material::new(Arc::new(crate::Lambert { kd: [0.5; 3] })).into();
    crate::figures::figure_scene(
        mesh,
        material,
        Some(env),
        Some(ground),
        width,
        width * 3 / 4,
    )
}

/// A scene file (docs/render.md) rendered with its `[render]` defaults (path tracing at 64
/// samples per pixel where it sets none); `spp` overrides them. Materials resolve through
/// [`ModelResolver`], so `model` + `coefficients` materials work.
pub fn render_scene_file(
    path: &Path,
    spp: Option<u32>,
    seed: u64,
    progress: Option<ProgressFn>,
) -> Result<Image> {
    let loaded = crate::scene_file::load_scene(path, &ModelResolver).map_err(|e| match e {
        RenderError::Scene(m) => RenderError::Scene(format!("{}: {m}", path.display())),
        other => other,
    })?;
    let mut o = RenderOptions {
        spp: 64,
        seed,
        integrator: Integrator::PathTracing,
        progress,
        ..Default::default()
    };
    loaded.defaults.apply(&mut o)?;
    if let Some(spp) = spp {
        o.spp = spp;
    }
    crate::render_scene(&loaded.scene, &o)
}

impl RenderJob {
    /// Renders the scene or figure and writes it; `progress` is told of finished tiles.
    pub fn run(&self, progress: Option<ProgressFn>) -> Result<RenderReport> {
        use crate::figures::{sphere_scene, strip_scene};
        // A bad output name is reported before the render, not after it.
        check_output(match &self.figure {
            None => &self.common.out,
            Some(Figure::Sphere { common, .. })
            | Some(Figure::Teapot { common, .. })
            | Some(Figure::RustTeapot { common, .. })
            | Some(Figure::Strip { common, .. }) => &common.out,
        })?;
        match &self.figure {
            None => {
                let scene = self.scene.as_ref().ok_or_else(|| {
                    RenderError::InvalidArgument(
                        "give a scene file, or one of: sphere, teapot, rust-teapot, strip".into(),
                    )
                })?;
                let c = &self.common;
                let image = render_scene_file(scene, c.spp, c.seed, progress)?;
                write(&image, &c.out)
            }
            Some(Figure::Sphere { spec, size, common }) => {
                let scene = sphere_scene(figure_material(spec)?, *size, *size)?;
                let o = options(common, 16, Integrator::Direct, progress);
                write(&crate::render_scene(&scene, &o)?, &common.out)
            }
            Some(Figure::Teapot {
                spec,
                env,
                width,
                common,
            }) => {
                let scene = teapot_figure(figure_material(spec)?, env.as_deref(), *width)?;
                let o = options(common, 64, Integrator::PathTracing, progress);
                write(&crate::render_scene(&scene, &o)?, &common.out)
            }
            Some(Figure::RustTeapot {
                model,
                from,
                to,
                path,
                k,
                texture_size,
                light,
                mesh,
                env,
                width,
                common,
            }) => {
                let ends = match (from, to) {
                    (Some(f), Some(t)) => Some((f.as_str(), t.as_str())),
                    (None, None) => None,
                    _ => {
                        return Err(RenderError::InvalidArgument(
                            "--from and --to go together".into(),
                        ))
                    }
                };
                if *light == TeapotLight::Point && env.is_some() {
                    return Err(RenderError::InvalidArgument(
                        "--env is the light probe of --light env".into(),
                    ));
                }
                let mesh = mesh.mesh()?;
                let material =
                    rust_material(model, ends, path.as_deref(), *k, *texture_size, common.seed)?;
                let (scene, o) = match light {
                    TeapotLight::Point => (
                        crate::figures::figure_point_scene(
                            &mesh,
                            material,
                            *width,
                            *width * 3 / 4,
                        )?,
                        options(common, 16, Integrator::Direct, progress),
                    ),
                    TeapotLight::Env => (
                        mesh_figure(&mesh, material, env.as_deref(), *width)?,
                        options(common, 64, Integrator::PathTracing, progress),
                    ),
                };
                write(&crate::render_scene(&scene, &o)?, &common.out)
            }
            Some(Figure::Strip {
                specs,
                series,
                model,
                sphere_pixels,
                common,
            }) => {
                let materials = strip_materials(specs, series.as_deref(), model.as_deref())?;
                let scene = strip_scene(materials, *sphere_pixels)?;
                let o = options(common, 16, Integrator::Direct, progress);
                write(&crate::render_scene(&scene, &o)?, &common.out)
            }
        }
    }
}
