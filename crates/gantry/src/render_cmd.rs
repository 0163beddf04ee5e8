//! `gantry render`: scene files and the thesis's figure types.

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use render::material::{BasisGrid, LinearBasis, Material, MaterialResolver, SurfaceMaterial};
use render::scene_file::SpecResolver;
use render::{EnvironmentMap, Image, Integrator, RenderOptions, Tonemap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Arguments of `gantry render`: a scene file, or one of the figure subcommands.
#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct RenderArgs {
    #[command(subcommand)]
    figure: Option<Figure>,
    /// Scene file (TOML; see docs/render.md).
    scene: Option<PathBuf>,
    #[command(flatten)]
    common: Common,
}

/// Options shared by every render.
#[derive(Args, Debug, Clone)]
pub struct Common {
    /// Samples per pixel.
    #[arg(long)]
    spp: Option<u32>,
    /// Output OpenEXR file (a tonemapped PNG is written beside it).
    #[arg(long, default_value = "render.exr")]
    out: PathBuf,
    /// Seed of the random streams.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// The thesis's figure types.
#[derive(Subcommand, Debug)]
enum Figure {
    /// A sphere of the material under a point light.
    Sphere {
        /// Material spec.
        spec: String,
        /// Image size in pixels (square).
        #[arg(long, default_value_t = 256)]
        size: usize,
        #[command(flatten)]
        common: Common,
    },
    /// The Utah teapot in the material under an environment map.
    Teapot {
        /// Material spec.
        spec: String,
        /// Light probe (lat-long OpenEXR); a procedural probe when absent.
        #[arg(long)]
        env: Option<PathBuf>,
        /// Image width (height is 3/4 of it).
        #[arg(long, default_value_t = 320)]
        width: usize,
        #[command(flatten)]
        common: Common,
    },
    /// A row of spheres: the given materials, or a PCA truncation series of one material.
    Strip {
        /// Material specs, left to right.
        specs: Vec<String>,
        /// With --model: reconstruct this material with 5, 10, 20, 30, 45, 60 and all components.
        #[arg(long, requires = "model")]
        series: Option<String>,
        /// PCA model file (from `gantry model build`).
        #[arg(long)]
        model: Option<PathBuf>,
        /// Pixels per sphere.
        #[arg(long, default_value_t = 96)]
        sphere_pixels: usize,
        #[command(flatten)]
        common: Common,
    },
}

/// Resolves material specs (every registered form, `wavelet:` files included) through
/// `render::scene_file::SpecResolver`, plus the linear bases of PCA models through `reduce`.
struct Resolver;

fn render_err(msg: String) -> render::RenderError {
    render::RenderError::InvalidArgument(msg)
}

fn load_basis(model: &Path) -> Result<(Arc<LinearBasis>, reduce::model::Model)> {
    let m = reduce::model::Model::load(model)
        .with_context(|| format!("cannot load model {}", model.display()))?;
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

impl MaterialResolver for Resolver {
    fn spec(&self, spec: &str) -> render::Result<Arc<dyn brdf::Brdf>> {
        SpecResolver.spec(spec)
    }
    fn tabulated(
        &self,
        spec: &str,
        brdf: &Arc<dyn brdf::Brdf>,
    ) -> render::Result<Option<Arc<dyn brdf::Brdf>>> {
        SpecResolver.tabulated(spec, brdf)
    }
    fn linear_basis(&self, model: &Path) -> render::Result<Arc<LinearBasis>> {
        load_basis(model)
            .map(|(b, _)| b)
            .map_err(|e| render_err(format!("{e:#}")))
    }
}

/// A figure material: evaluated as loaded, importance-sampled from its MERL-grid table.
fn material(spec: &str) -> Result<SurfaceMaterial> {
    let loaded =
        brdf::spec::load(spec).with_context(|| format!("cannot load material '{spec}'"))?;
    let table = loaded.tabulate();
    let brdf: Arc<dyn brdf::Brdf> = Arc::new(loaded);
    Ok(Material::with_importance_from(brdf, &table, Default::default()).into())
}

fn options(common: &Common, default_spp: u32, integrator: Integrator) -> RenderOptions {
    let mut o = RenderOptions {
        spp: common.spp.unwrap_or(default_spp),
        seed: common.seed,
        integrator,
        ..Default::default()
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} tiles, ETA {eta}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    o.progress = Some(Arc::new(move |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        if done == total {
            bar.finish_and_clear();
        }
    }));
    o
}

fn write(img: &Image, out: &Path) -> Result<()> {
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    img.write_exr(out)?;
    let png = out.with_extension("png");
    img.write_png(&png, &Tonemap::default())?;
    println!("wrote {} and {}", out.display(), png.display());
    Ok(())
}

/// Runs `gantry render`.
pub fn run(args: RenderArgs) -> Result<()> {
    match args.figure {
        None => {
            let Some(scene) = args.scene else {
                bail!("give a scene file, or one of: sphere, teapot, strip");
            };
            let loaded = render::scene_file::load_scene(&scene, &Resolver)
                .with_context(|| format!("cannot load scene {}", scene.display()))?;
            let mut o = options(&args.common, 64, Integrator::PathTracing);
            loaded.defaults.apply(&mut o)?;
            if let Some(spp) = args.common.spp {
                o.spp = spp;
            }
            write(&render::render_scene(&loaded.scene, &o)?, &args.common.out)
        }
        Some(Figure::Sphere { spec, size, common }) => {
            let scene = render::figures::sphere_scene(material(&spec)?, size, size)?;
            let o = options(&common, 16, Integrator::Direct);
            write(&render::render_scene(&scene, &o)?, &common.out)
        }
        Some(Figure::Teapot {
            spec,
            env,
            width,
            common,
        }) => {
            let env = match env {
                Some(p) => EnvironmentMap::read(&p)
                    .with_context(|| format!("cannot read light probe {}", p.display()))?,
                None => EnvironmentMap::procedural_probe(1024, 512, 7)?,
            };
            let ground: SurfaceMaterial =
                Material::new(Arc::new(render::Lambert { kd: [0.5; 3] })).into();
            let scene = render::figures::teapot_scene(
                material(&spec)?,
                Some(env),
                Some(ground),
                width,
                width * 3 / 4,
            )?;
            let o = options(&common, 64, Integrator::PathTracing);
            write(&render::render_scene(&scene, &o)?, &common.out)
        }
        Some(Figure::Strip {
            specs,
            series,
            model,
            sphere_pixels,
            common,
        }) => {
            let materials: Vec<SurfaceMaterial> = if let Some(target) = series {
                let model = model.context("--series needs --model")?;
                let (basis, m) = load_basis(&model)?;
                let table = brdf::spec::load(&target)?.tabulate();
                let coeffs = m.project_values(&table.values(), m.pca.components)?;
                render::figures::truncation_strip(
                    &basis,
                    &coeffs,
                    &[5, 10, 20, 30, 45, 60, usize::MAX],
                )?
            } else {
                if specs.is_empty() {
                    bail!("give material specs, or --series SPEC --model model.bin");
                }
                specs.iter().map(|s| material(s)).collect::<Result<_>>()?
            };
            let scene = render::figures::strip_scene(materials, sphere_pixels)?;
            let o = options(&common, 16, Integrator::Direct);
            write(&render::render_scene(&scene, &o)?, &common.out)
        }
    }
}
