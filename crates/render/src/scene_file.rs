//! The TOML scene format.

use crate::envmap::EnvironmentMap;
use crate::error::{RenderError, Result};
use crate::image::Image;
use crate::importance::{BrdfImportance, ImportanceResolution};
use crate::integrator::{Integrator, RenderOptions};
use crate::material::{BasisBrdf, LinearBasis, Mask, Material, MaterialResolver, SurfaceMaterial};
use crate::mesh::{read_obj, utah_teapot, utah_teapot_wrapped, Transform};
use crate::scene::{AreaLight, Camera, PointLight, Scene, SceneBuilder};
use crate::varying::{CoefficientTexture, ProcessPath};
use brdf::{Brdf, Vec3};
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    camera: CameraDesc,
    #[serde(default)]
    render: Option<RenderDesc>,
    #[serde(default)]
    materials: BTreeMap<String, MaterialDesc>,
    #[serde(default)]
    objects: Vec<ObjectDesc>,
    #[serde(default)]
    lights: Vec<LightDesc>,
    #[serde(default)]
    environment: Option<EnvDesc>,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
fn default_fov() -> f64 {
    40.0
}
fn default_true() -> bool {
    true
}
fn default_scale() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDesc {
    position: [f64; 3],
    look_at: [f64; 3],
    #[serde(default = "default_up")]
    up: [f64; 3],
    #[serde(default = "default_fov")]
    fov: f64,
    width: usize,
    height: usize,
}

/// Rendering defaults stored in a scene file (`[render]`).
#[derive(Debug, Clone, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RenderDefaults {
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Maximum path depth.
    pub max_depth: Option<u32>,
    /// `"path"` or `"direct"`.
    pub integrator: Option<String>,
    /// Random seed.
    pub seed: Option<u64>,
}

type RenderDesc = RenderDefaults;

impl RenderDefaults {
    /// Applies these defaults to `options`.
    pub fn apply(&self, options: &mut RenderOptions) -> Result<()> {
        if let Some(s) = self.spp {
            options.spp = s;
        }
        if let Some(d) = self.max_depth {
            options.max_depth = d;
        }
        if let Some(s) = self.seed {
            options.seed = s;
        }
        if let Some(i) = &self.integrator {
            options.integrator = match i.as_str() {
                "path" | "path_tracing" => Integrator::PathTracing,
                "direct" => Integrator::Direct,
                other => return Err(RenderError::Scene(format!("unknown integrator `{other}`"))),
            };
        }
        Ok(())
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialDesc {
    spec: Option<String>,
    model: Option<PathBuf>,
    coefficients: Option<Vec<f64>>,
    wavelet: Option<PathBuf>,
    blend: Option<[String; 2]>,
    mask: Option<MaskDesc>,
    #[serde(default = "default_true")]
    importance: bool,
    #[serde(default = "default_true")]
    tabulate: bool,
    importance_resolution: Option<[usize; 3]>,
    /// Spatially varying: `"rust"` or an image whose luminance is the position along the path.
    selector: Option<String>,
    /// Spatially varying: the process path file (JSON nodes).
    path: Option<PathBuf>,
    /// Spatially varying: the clean end, projected on `model`.
    from: Option<String>,
    /// Spatially varying: the other end, projected on `model`.
    to: Option<String>,
    /// Spatially varying: components used.
    k: Option<usize>,
    /// Spatially varying, `selector = "rust"`: texture width and height.
    texture_size: Option<[usize; 2]>,
    /// Spatially varying, `selector = "rust"`: seed of the rust field.
    seed: Option<u64>,
}

impl MaterialDesc {
    /// Whether the material is spatially varying (has any of its keys).
    fn is_varying(&self) -> bool {
        self.selector.is_some()
            || self.path.is_some()
            || self.from.is_some()
            || self.to.is_some()
            || self.texture_size.is_some()
            || self.seed.is_some()
            || self.k.is_some()
    }
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum MaskDesc {
    Constant {
        value: f64,
    },
    Noise {
        scale: f64,
        #[serde(default)]
        seed: u64,
        #[serde(default = "half")]
        threshold: f64,
        #[serde(default = "tenth")]
        softness: f64,
    },
    Checker {
        scale: f64,
    },
    Texture {
        path: PathBuf,
    },
}

fn half() -> f64 {
    0.5
}
fn tenth() -> f64 {
    0.1
}
fn default_tess() -> usize {
    12
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum ObjectDesc {
    Sphere {
        center: [f64; 3],
        radius: f64,
        material: String,
    },
    Mesh {
        path: PathBuf,
        material: String,
        #[serde(default = "default_scale")]
        scale: f64,
        #[serde(default)]
        rotate_y: f64,
        #[serde(default)]
        translate: [f64; 3],
    },
    Teapot {
        material: String,
        #[serde(default = "default_scale")]
        scale: f64,
        #[serde(default)]
        rotate_y: f64,
        #[serde(default)]
        translate: [f64; 3],
        #[serde(default = "default_tess")]
        tessellation: usize,
        #[serde(default)]
        uvs: TeapotUvs,
    },
    Ground {
        #[serde(default)]
        y: f64,
        #[serde(default = "ground_size")]
        size: f64,
        material: String,
    },
}

/// Texture coordinates of a teapot object.
#[derive(Debug, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
enum TeapotUvs {
    /// The patch parameters ([`utah_teapot`]).
    #[default]
    Patch,
    /// Around and down the teapot ([`utah_teapot_wrapped`]).
    Wrapped,
}

fn ground_size() -> f64 {
    100.0
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum LightDesc {
    Point {
        position: [f64; 3],
        intensity: [f64; 3],
    },
    Area {
        corner: [f64; 3],
        edge_u: [f64; 3],
        edge_v: [f64; 3],
        radiance: [f64; 3],
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EnvDesc {
    path: Option<PathBuf>,
    procedural: Option<u64>,
    constant: Option<[f64; 3]>,
    #[serde(default = "default_scale")]
    scale: f64,
    #[serde(default)]
    rotation: f64,
}

/// A linear basis and the importance table of its mean, shared by the materials using it.
type SharedBasis = (Arc<LinearBasis>, Option<Arc<BrdfImportance>>);

fn v3(a: [f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// A scene loaded from a file, with the file's rendering defaults.
#[derive(Debug)]
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene,
    /// `[render]` section.
    pub defaults: RenderDefaults,
}

/// Reads and builds a TOML scene (the format is described at [`parse_scene`]).
pub fn load_scene(path: &Path, resolver: &dyn MaterialResolver) -> Result<LoadedScene> {
    let text = std::fs::read_to_string(path).map_err(|e| RenderError::io(path, e))?;
    let base = path.parent().unwrap_or(Path::new("."));
    parse_scene(&text, base, resolver)
}

/// Builds a scene from TOML text; relative paths are resolved against `base_dir`.
///
/// The format, every key shown ([`load_scene`] reads the same from a file):
///
/// ```toml
/// [camera]
/// position = [0.0, 2.0, 6.0]
/// look_at = [0.0, 0.7, 0.0]
/// up = [0.0, 1.0, 0.0]        # default
/// fov = 35.0                  # vertical, degrees; default 40
/// width = 320
/// height = 240
///
/// [render]                    # optional defaults for the CLI
/// spp = 64
/// max_depth = 8
/// integrator = "path"         # or "direct"
/// seed = 0
///
/// [materials.steel]
/// spec = "merl:steel"         # any brdf material spec; tabulated NBRDFs are used for speed
/// importance = true           # importance sampling (default true): A.2.4 tables, or the
///                             # model's own sampler (lambert, ggx, ggx2 evaluated as models)
/// [materials.pca]
/// model = "model.bin"         # shared linear basis (resolved by the MaterialResolver)
/// coefficients = [0.1, -0.3]
/// [materials.compressed]
/// wavelet = "tree.bin"        # wavelet tree (resolved by the MaterialResolver)
/// [materials.rusty]
/// blend = ["steel", "rust"]   # two other materials
/// mask = { kind = "noise", scale = 3.0, seed = 1, threshold = 0.45, softness = 0.1 }
/// # or { kind = "checker", scale = 2.0 }, { kind = "texture", path = "mask.png" },
/// #    { kind = "constant", value = 0.5 }
/// [materials.rusting]          # spatially varying (thesis §7.2.2): a BRDF per point
/// model = "model.bin"         # the shared linear basis
/// from = "merl:aluminium"     # clean end, projected on the model ...
/// to = "merl:red-metallic-paint"  # ... and the rusted end
/// # path = "rust.json"        # or a process path: {"nodes": [[c1, c2, ...], ...]}
/// k = 20                      # optional: components used (default all)
/// selector = "rust"           # the rust field (render::rust_selector), or an image
///                             # ("mask.png" | "mask.exr") whose luminance is the position
///                             # along the path, one texel per pixel, top row at v = 0
/// texture_size = [256, 128]   # selector = "rust" only (default 256 × 128)
/// seed = 1                    # selector = "rust" only (default 1)
///
/// [[objects]]
/// kind = "sphere"
/// center = [0.0, 1.0, 0.0]
/// radius = 1.0
/// material = "steel"
/// [[objects]]
/// kind = "mesh"               # Wavefront OBJ
/// path = "bunny.obj"
/// material = "pca"
/// scale = 1.0                 # optional transform: scale, rotate_y (degrees), translate
/// [[objects]]
/// kind = "teapot"             # the built-in Utah teapot (3.15 units tall at scale 1)
/// material = "rusty"
/// scale = 0.5
/// tessellation = 12
/// uvs = "patch"               # default: patch parameters; "wrapped": u around the
///                             # teapot, v down it (render::utah_teapot_wrapped)
/// [[objects]]
/// kind = "ground"
/// y = 0.0
/// size = 40.0
/// material = "steel"
///
/// [[lights]]
/// kind = "point"
/// position = [-3.0, 5.0, 4.0]
/// intensity = [50.0, 50.0, 50.0]   # W/sr
/// [[lights]]
/// kind = "area"
/// corner = [-1.0, 4.0, -1.0]
/// edge_u = [2.0, 0.0, 0.0]
/// edge_v = [0.0, 0.0, 2.0]          # emits towards edge_u × edge_v (here −y)
/// radiance = [5.0, 5.0, 5.0]
///
/// [environment]                      # one of path / procedural / constant
/// path = "probe.exr"                 # lat-long OpenEXR or Radiance .hdr
/// # procedural = 1                   # seed of the procedural probe
/// # constant = [1.0, 1.0, 1.0]
/// scale = 1.0
/// rotation = 0.0                     # degrees about +y
/// ```
///
/// Relative paths are resolved against the scene file's directory.
pub fn parse_scene(
    text: &str,
    base_dir: &Path,
    resolver: &dyn MaterialResolver,
) -> Result<LoadedScene> {
    let file: SceneFile =
        toml::from_str(text).map_err(|e| RenderError::Scene(e.message().to_string()))?;
    let rel = |p: &Path| -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base_dir.join(p)
        }
    };
    let c = &file.camera;
    let camera = Camera {
        position: v3(c.position),
        look_at: v3(c.look_at),
        up: v3(c.up),
        fov_degrees: c.fov,
        width: c.width,
        height: c.height,
    };
    camera.validate()?;
    let mut builder = SceneBuilder::new(camera);

    // plain materials first, blends second
    let mut plain: HashMap<String, Material> = HashMap::new();
    let mut bases: HashMap<PathBuf, SharedBasis> = HashMap::new();
    for (name, d) in &file.materials {
        if d.blend.is_some() || d.is_varying() {
            continue;
        }
        let merr = |message: String| RenderError::Material {
            name: name.clone(),
            message,
        };
        let res = match d.importance_resolution {
            Some([r, i, p]) => ImportanceResolution {
                theta_r: r,
                theta_i: i,
                phi_diff: p,
                ..Default::default()
            },
            None => ImportanceResolution::default(),
        };
        let kinds = [d.spec.is_some(), d.model.is_some(), d.wavelet.is_some()];
        if kinds.iter().filter(|&&k| k).count() != 1 {
            return Err(merr(
                "exactly one of spec, model, wavelet or blend is required".into(),
            ));
        }
        let material = if let Some(spec) = &d.spec {
            let brdf = resolver.spec(spec)?;
            // A model evaluated as itself that samples its own lobes needs no tables.
            let own_sampler = !d.tabulate && brdf.has_importance_sampler();
            let table = if d.tabulate || (d.importance && !own_sampler) {
                resolver.tabulated(spec, &brdf)?
            } else {
                None
            };
            let eval: Arc<dyn Brdf> = match (&table, d.tabulate) {
                (Some(t), true) => t.clone(),
                _ => brdf,
            };
            if d.importance && !own_sampler {
                let src: &dyn Brdf = table.as_deref().unwrap_or(eval.as_ref());
                Material::with_importance_from(eval.clone(), src, res)
            } else {
                Material::new(eval)
            }
        } else if let Some(model) = &d.model {
            let p = rel(model);
            let (basis, shared) = match bases.get(&p) {
                Some(b) => b.clone(),
                None => {
                    let b = resolver.linear_basis(&p)?;
                    bases.insert(p.clone(), (b.clone(), None));
                    (b, None)
                }
            };
            let coeffs = d
                .coefficients
                .as_ref()
                .ok_or_else(|| merr("`model` needs `coefficients`".into()))?;
            let brdf: Arc<dyn Brdf> = Arc::new(BasisBrdf::new(basis.clone(), coeffs, name)?);
            // one importance table per model, built from the mean BRDF and shared by all of
            // its materials (unbiased for each of them thanks to the defensive mixture)
            let importance = if d.importance {
                let table = match shared {
                    Some(t) => t,
                    None => {
                        let mean = BasisBrdf::new(basis.clone(), &[], "mean")?;
                        let t = Arc::new(BrdfImportance::build(&mean, res));
                        bases.insert(p.clone(), (basis, Some(t.clone())));
                        t
                    }
                };
                Some(table)
            } else {
                None
            };
            Material {
                name: name.clone(),
                brdf,
                importance,
            }
        } else if let Some(tree) = &d.wavelet {
            let brdf = resolver.wavelet(&rel(tree), d.coefficients.as_deref())?;
            Material::new(brdf)
        } else {
            unreachable!("checked above")
        };
        plain.insert(name.clone(), material);
    }
    let mut ids: HashMap<String, usize> = HashMap::new();
    for (name, d) in &file.materials {
        if d.blend.is_some() && d.is_varying() {
            return Err(RenderError::Material {
                name: name.clone(),
                message: "a blend is not spatially varying: drop selector, path, from, to, k, \
                          texture_size and seed"
                    .into(),
            });
        }
        let surface = match &d.blend {
            None if d.is_varying() => varying_material(name, d, &rel, &mut bases, resolver)?,
            None => SurfaceMaterial::Single(plain[name].clone()),
            Some([a, b]) => {
                let get = |n: &String| {
                    plain.get(n).cloned().ok_or_else(|| RenderError::Material {
                        name: name.clone(),
                        message: format!("blend refers to unknown or blended material `{n}`"),
                    })
                };
                let mask = match &d.mask {
                    None => Mask::Constant(0.5),
                    Some(MaskDesc::Constant { value }) => Mask::Constant(*value),
                    Some(MaskDesc::Checker { scale }) => Mask::Checker { scale: *scale },
                    Some(MaskDesc::Noise {
                        scale,
                        seed,
                        threshold,
                        softness,
                    }) => Mask::Noise {
                        scale: *scale,
                        seed: *seed,
                        threshold: *threshold,
                        softness: *softness,
                    },
                    Some(MaskDesc::Texture { path }) => {
                        Mask::Texture(Arc::new(read_mask(&rel(path))?))
                    }
                };
                SurfaceMaterial::Blend {
                    a: get(a)?,
                    b: get(b)?,
                    mask,
                }
            }
        };
        ids.insert(name.clone(), builder.add_material(surface));
    }
    let mat = |n: &String| {
        ids.get(n)
            .copied()
            .ok_or_else(|| RenderError::Scene(format!("unknown material `{n}`")))
    };
    for o in &file.objects {
        match o {
            ObjectDesc::Sphere {
                center,
                radius,
                material,
            } => builder.add_sphere(v3(*center), *radius, mat(material)?)?,
            ObjectDesc::Mesh {
                path,
                material,
                scale,
                rotate_y,
                translate,
            } => {
                let mesh = read_obj(&rel(path))?;
                let t = Transform {
                    scale: *scale,
                    rotate_y_degrees: *rotate_y,
                    translate: v3(*translate),
                };
                builder.add_mesh(&mesh, &t, mat(material)?)?
            }
            ObjectDesc::Teapot {
                material,
                scale,
                rotate_y,
                translate,
                tessellation,
                uvs,
            } => {
                let t = Transform {
                    scale: *scale,
                    rotate_y_degrees: *rotate_y,
                    translate: v3(*translate),
                };
                let n = (*tessellation).clamp(1, 64);
                let mesh = match uvs {
                    TeapotUvs::Patch => utah_teapot(n),
                    TeapotUvs::Wrapped => utah_teapot_wrapped(n),
                };
                builder.add_mesh(&mesh, &t, mat(material)?)?
            }
            ObjectDesc::Ground { y, size, material } => {
                builder.add_ground(*y, *size, [0.0, 0.0], mat(material)?)?
            }
        }
    }
    for l in &file.lights {
        match l {
            LightDesc::Point {
                position,
                intensity,
            } => builder.add_point_light(PointLight {
                position: v3(*position),
                intensity: *intensity,
            })?,
            LightDesc::Area {
                corner,
                edge_u,
                edge_v,
                radiance,
            } => builder.add_area_light(AreaLight {
                corner: v3(*corner),
                edge_u: v3(*edge_u),
                edge_v: v3(*edge_v),
                radiance: *radiance,
            })?,
        }
    }
    if let Some(e) = &file.environment {
        let given = [
            e.path.is_some(),
            e.procedural.is_some(),
            e.constant.is_some(),
        ];
        if given.iter().filter(|&&g| g).count() != 1 {
            return Err(RenderError::Scene(
                "environment needs exactly one of path, procedural, constant".into(),
            ));
        }
        let env = if let Some(p) = &e.path {
            EnvironmentMap::read(&rel(p))?
        } else if let Some(seed) = e.procedural {
            EnvironmentMap::procedural_probe(512, 256, seed)?
        } else {
            EnvironmentMap::constant(e.constant.unwrap_or([1.0; 3]))?
        };
        builder.set_environment(env.with_scale(e.scale).with_rotation_degrees(e.rotation));
    }
    Ok(LoadedScene {
        scene: builder.build()?,
        defaults: file.render.unwrap_or_default(),
    })
}

/// A spatially varying material (`model` + `path` or `from`/`to` + `selector`).
fn varying_material(
    name: &str,
    d: &MaterialDesc,
    rel: &dyn Fn(&Path) -> PathBuf,
    bases: &mut HashMap<PathBuf, SharedBasis>,
    resolver: &dyn MaterialResolver,
) -> Result<SurfaceMaterial> {
    let merr = |message: &str| RenderError::Material {
        name: name.to_string(),
        message: message.to_string(),
    };
    if d.spec.is_some() || d.wavelet.is_some() || d.coefficients.is_some() {
        return Err(merr(
            "a spatially varying material (selector, path, from/to) takes `model`, not \
             spec, wavelet or coefficients",
        ));
    }
    let model = rel(d
        .model
        .as_deref()
        .ok_or_else(|| merr("a spatially varying material needs `model`"))?);
    let selector = d
        .selector
        .as_deref()
        .ok_or_else(|| merr("a spatially varying material needs `selector`"))?;
    let process = match (&d.path, &d.from, &d.to) {
        (Some(p), None, None) => {
            let process = ProcessPath::read(&rel(p))?;
            match d.k {
                Some(k) => process.truncated(k)?,
                None => process,
            }
        }
        (None, Some(from), Some(to)) => {
            ProcessPath::new(resolver.project(&model, &[from.as_str(), to.as_str()], d.k)?)?
        }
        _ => return Err(merr("give either `path`, or `from` and `to`")),
    };
    let (width, height, values) = if selector == "rust" {
        let [w, h] = d.texture_size.unwrap_or([256, 128]);
        (
            w,
            h,
            crate::varying::rust_selector(w, h, d.seed.unwrap_or(1)),
        )
    } else {
        if d.texture_size.is_some() || d.seed.is_some() {
            return Err(merr(
                "`texture_size` and `seed` belong to selector = \"rust\"; an image selector \
                 has its own size",
            ));
        }
        let img = read_mask(&rel(Path::new(selector)))?;
        let values = img
            .pixels()
            .iter()
            .map(|p| (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]).clamp(0.0, 1.0))
            .collect();
        (img.width(), img.height(), values)
    };
    let texture = CoefficientTexture::from_selector(&process, width, height, &values)?;
    let basis = match bases.get(&model) {
        Some((b, _)) => b.clone(),
        None => {
            let b = resolver.linear_basis(&model)?;
            bases.insert(model, (b.clone(), None));
            b
        }
    };
    SurfaceMaterial::varying(basis, Arc::new(texture))
}

/// Reads a blend mask: OpenEXR (linear) or any 8-bit image format (values / 255).
fn read_mask(path: &Path) -> Result<Image> {
    let is_exr = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if is_exr {
        return Image::read_exr(path);
    }
    let img = image::open(path).map_err(|e| RenderError::Png {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let rgb = img.to_rgb32f();
    let (w, h) = rgb.dimensions();
    let pixels = rgb.pixels().map(|p| [p[0], p[1], p[2]]).collect();
    Image::from_pixels(w as usize, h as usize, pixels)
}

/// The default resolver: material specs through `brdf::spec` (with every form registered
/// there, e.g. `wavelet:` and `pca:`), NBRDFs and registered forms tabulated on the MERL grid
/// for evaluation and importance tables. Wavelet files resolve through the `wavelet:` spec;
/// linear models (`model` + `coefficients`) are not available (wrap this resolver to add
/// them).
#[derive(Debug, Default, Clone, Copy)]
pub struct SpecResolver;

fn brdf_err(spec: &str, e: brdf::BrdfError) -> RenderError {
    RenderError::Material {
        name: spec.to_string(),
        message: e.to_string(),
    }
}

impl MaterialResolver for SpecResolver {
    fn spec(&self, spec: &str) -> Result<Arc<dyn Brdf>> {
        let m = brdf::load(spec).map_err(|e| brdf_err(spec, e))?;
        Ok(Arc::new(m))
    }

    fn tabulated(&self, spec: &str, brdf: &Arc<dyn Brdf>) -> Result<Option<Arc<dyn Brdf>>> {
        match brdf::parse(spec).map_err(|e| brdf_err(spec, e))? {
            brdf::MaterialSpec::Nbrdf { .. } => {
                // the NBRDF's own f32 decoder is much faster than evaluating it per bin
                let m = brdf::load(spec).map_err(|e| brdf_err(spec, e))?;
                Ok(Some(Arc::new(m.tabulate())))
            }
            brdf::MaterialSpec::Registered { .. } => {
                Ok(Some(Arc::new(brdf::MerlTable::tabulate(brdf.as_ref()))))
            }
            brdf::MaterialSpec::Table(_) => Ok(None),
            brdf::MaterialSpec::Analytic { .. } => Ok(None),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct TinyModels;
    impl MaterialResolver for TinyModels {
        fn spec(&self, spec: &str) -> Result<Arc<dyn Brdf>> {
            SpecResolver.spec(spec)
        }
        fn linear_basis(&self, model: &Path) -> Result<Arc<LinearBasis>> {
            assert!(model.ends_with("model.bin"));
            let grid = crate::material::BasisGrid {
                theta_h: 4,
                theta_d: 4,
                phi_d: 8,
            };
            let n = 3 * grid.bins();
            let mean = vec![-2.0f32; n];
            let comp: Vec<f32> = (0..n).map(|i| (i % 5) as f32 * 0.1).collect();
            Ok(Arc::new(LinearBasis::new(grid, &mean, &[comp], 0.0)?))
        }
        fn project(&self, model: &Path, specs: &[&str], k: Option<usize>) -> Result<Vec<Vec<f64>>> {
            assert!(model.ends_with("model.bin"));
            assert_eq!(k, None);
            // a stand-in projection: the clean material at -1, anything else at +2
            Ok(specs
                .iter()
                .map(|s| vec![if *s == "merl:aluminium" { -1.0 } else { 2.0 }])
                .collect())
        }
    }

    #[test]
    fn varying_materials_take_a_path_and_a_selector() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("rust.json"), r#"{"nodes": [[0.0], [4.0]]}"#).unwrap();
        // a 2 × 2 selector image: black, white / grey, white (top row first)
        let png = image::RgbImage::from_raw(
            2,
            2,
            vec![0, 0, 0, 255, 255, 255, 51, 51, 51, 255, 255, 255],
        )
        .unwrap();
        png.save(dir.path().join("sel.png")).unwrap();
        let text = r#"
            [camera]
            position = [0.0, 1.0, 6.0]
            look_at = [0.0, 0.7, 0.0]
            width = 8
            height = 6
            [materials.rusting]
            model = "model.bin"
            from = "merl:aluminium"
            to = "merl:red-metallic-paint"
            selector = "rust"
            texture_size = [16, 8]
            seed = 3
            [materials.painted]
            model = "model.bin"
            path = "rust.json"
            selector = "sel.png"
            [[objects]]
            kind = "teapot"
            material = "rusting"
            scale = 0.4
            tessellation = 2
            uvs = "wrapped"
            [[objects]]
            kind = "sphere"
            center = [1.5, 0.5, 0.0]
            radius = 0.5
            material = "painted"
        "#;
        let loaded = parse_scene(text, dir.path(), &TinyModels).unwrap();
        let textures: Vec<_> = loaded
            .scene
            .materials
            .iter()
            .map(|m| match m {
                SurfaceMaterial::Varying { basis, texture } => (basis.clone(), texture.clone()),
                other => panic!("{other:?}"),
            })
            .collect();
        // one basis for both (materials in name order: painted, rusting)
        assert!(Arc::ptr_eq(&textures[0].0, &textures[1].0));
        let (painted, rusting) = (&textures[0].1, &textures[1].1);
        // the image: one texel per pixel, the top row at v = 0, luminance along the path
        assert_eq!((painted.width(), painted.height()), (2, 2));
        assert_eq!(painted.data(), [0.0, 4.0, 0.8, 4.0]);
        // the rust field between the projected ends, as render::rust_selector has it
        assert_eq!((rusting.width(), rusting.height()), (16, 8));
        let field = crate::varying::rust_selector(16, 8, 3);
        for (c, t) in rusting.data().iter().zip(field) {
            assert!((c - (-1.0 + 3.0 * t)).abs() < 1e-6, "{c} {t}");
        }

        let bad = |from: &str, to: &str| {
            let t = text.replace(from, to);
            match parse_scene(&t, dir.path(), &TinyModels) {
                Err(e) => e,
                Ok(_) => panic!("accepted {to}"),
            }
        };
        let material_error = |e: RenderError| matches!(e, RenderError::Material { .. });
        assert!(material_error(bad(
            "model = \"model.bin\"\n            from",
            "from"
        )));
        assert!(material_error(bad("selector = \"rust\"", "")));
        assert!(material_error(bad(
            "to = \"merl:red-metallic-paint\"",
            "path = \"rust.json\""
        )));
        assert!(material_error(bad("to = \"merl:red-metallic-paint\"", "")));
        assert!(material_error(bad(
            "selector = \"sel.png\"",
            "selector = \"sel.png\"\n            seed = 2"
        )));
        assert!(material_error(bad(
            "selector = \"sel.png\"",
            "selector = \"sel.png\"\n            coefficients = [1.0]"
        )));
        assert!(material_error(bad(
            "[materials.painted]",
            "[materials.mix]\n            blend = [\"a\", \"b\"]\n            selector = \"rust\"\n            [materials.painted]"
        )));
        // a missing selector image, a malformed path, nodes longer than the basis
        assert!(matches!(
            bad("sel.png", "none.png"),
            RenderError::Png { .. }
        ));
        std::fs::write(dir.path().join("bad.json"), r#"{"nodes": [[1.0]]}"#).unwrap();
        assert!(matches!(
            bad("rust.json", "bad.json"),
            RenderError::ProcessPath { .. }
        ));
        let long = r#"{"nodes": [[1.0, 2.0], [0.0, 0.0]]}"#;
        std::fs::write(dir.path().join("long.json"), long).unwrap();
        assert!(matches!(
            bad("rust.json", "long.json"),
            RenderError::InvalidArgument(_)
        ));
        assert!(matches!(
            bad("uvs = \"wrapped\"", "uvs = \"spiral\""),
            RenderError::Scene(_)
        ));
    }

    #[test]
    fn model_materials_share_one_basis_and_one_importance_table() {
        let text = r#"
            [camera]
            position = [0.0, 0.0, 5.0]
            look_at = [0.0, 0.0, 0.0]
            width = 8
            height = 8
            [materials.a]
            model = "models/model.bin"
            coefficients = [0.5]
            importance_resolution = [4, 8, 16]
            [materials.b]
            model = "models/model.bin"
            coefficients = [-1.0]
            importance_resolution = [4, 8, 16]
            [[objects]]
            kind = "sphere"
            center = [0.0, 0.0, 0.0]
            radius = 1.0
            material = "a"
        "#;
        let loaded = parse_scene(text, Path::new("/scenes"), &TinyModels).unwrap();
        let tables: Vec<_> = loaded
            .scene
            .materials
            .iter()
            .map(|m| match m {
                SurfaceMaterial::Single(m) => m.importance.clone().unwrap(),
                _ => panic!("blend"),
            })
            .collect();
        assert!(Arc::ptr_eq(&tables[0], &tables[1]));
        // the default resolver has no model support: a typed error, not a panic
        assert!(matches!(
            parse_scene(text, Path::new("/scenes"), &SpecResolver),
            Err(RenderError::Scene(_))
        ));
    }

    #[test]
    fn parses_documented_features_and_rejects_bad_input() {
        let text = r#"
            [camera]
            position = [0.0, 1.0, 5.0]
            look_at = [0.0, 0.5, 0.0]
            width = 16
            height = 12
            [render]
            spp = 4
            integrator = "direct"
            [materials.white]
            spec = "lambert:kd=0.8"
            importance = false
            [materials.glossy]
            spec = "ward:kd=0.1,ks=0.3,alpha=0.1"
            importance_resolution = [8, 16, 32]
            [materials.mix]
            blend = ["white", "glossy"]
            mask = { kind = "checker", scale = 2.0 }
            [[objects]]
            kind = "teapot"
            material = "mix"
            scale = 0.3
            tessellation = 3
            [[objects]]
            kind = "sphere"
            center = [1.5, 0.5, 0.0]
            radius = 0.5
            material = "glossy"
            [[objects]]
            kind = "ground"
            material = "white"
            [[lights]]
            kind = "area"
            corner = [-1.0, 4.0, -1.0]
            edge_u = [2.0, 0.0, 0.0]
            edge_v = [0.0, 0.0, 2.0]
            radiance = [5.0, 5.0, 5.0]
            [environment]
            constant = [0.2, 0.2, 0.2]
        "#;
        let loaded = parse_scene(text, Path::new("."), &SpecResolver).unwrap();
        assert_eq!(loaded.defaults.spp, Some(4));
        assert_eq!(loaded.scene.materials.len(), 3);
        assert_eq!(loaded.scene.area_lights.len(), 1);
        let n = loaded.scene.primitive_count();
        assert!(n > 500 && n <= 32 * 9 * 2 + 5, "{n}");
        let mut o = RenderOptions::default();
        loaded.defaults.apply(&mut o).unwrap();
        assert_eq!(o.integrator, Integrator::Direct);

        let bad_material =
            text.replace("\"mix\"\n            scale", "\"nope\"\n            scale");
        assert!(parse_scene(&bad_material, Path::new("."), &SpecResolver).is_err());
        let bad_field = text.replace("radius = 0.5", "radius = 0.5\n            colour = 1");
        assert!(parse_scene(&bad_field, Path::new("."), &SpecResolver).is_err());
        let bad_radius = text.replace("radius = 0.5", "radius = nan");
        assert!(parse_scene(&bad_radius, Path::new("."), &SpecResolver).is_err());
        let no_model = text.replace(
            "spec = \"lambert:kd=0.8\"",
            "model = \"m.bin\"\n            coefficients = [1.0]",
        );
        assert!(matches!(
            parse_scene(&no_model, Path::new("."), &SpecResolver),
            Err(RenderError::Scene(_))
        ));
    }
}
