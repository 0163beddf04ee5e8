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

/// Resolves every material form a scene file names: specs through [`SpecResolver`] and the
/// linear bases of `reduce` model files (`model` + `coefficients`).
#[derive(Debug, Default, Clone, Copy)]
pub struct ModelResolver;

/// The log-PCA basis of a `reduce` model file, for per-point coefficients.
pub fn load_basis(model: &Path) -> Result<(Arc<LinearBasis>, reduce::Model)> {
    let m = reduce::Model::load(model)?;
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
    let table = brdf::load(target)
        .map_err(|e| RenderError::Material {
            name: target.to_string(),
            message: e.to_string(),
        })?
        .tabulate();
    let coeffs = m.project_values(&table.values(), m.pca.components)?;
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
    let env = match probe {
        Some(p) => EnvironmentMap::read(p)?,
        None => EnvironmentMap::procedural_probe(1024, 512, 7)?,
    };
    let ground: SurfaceMaterial = Material::new(Arc::new(crate::Lambert { kd: [0.5; 3] })).into();
    crate::figures::teapot_scene(material, Some(env), Some(ground), width, width * 3 / 4)
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
            | Some(Figure::Strip { common, .. }) => &common.out,
        })?;
        match &self.figure {
            None => {
                let scene = self.scene.as_ref().ok_or_else(|| {
                    RenderError::InvalidArgument(
                        "give a scene file, or one of: sphere, teapot, strip".into(),
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
