//! Material specs: the one string syntax every command uses to name a BRDF.

use crate::analytic::*;
use crate::coords::{HalfDiff, Vec3};
use crate::error::{BrdfError, Result};
use crate::nbrdf::Nbrdf;
use crate::table::MerlTable;
use crate::{Brdf, DirectionSample, Rgb};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, RwLock};

/// A parsed material spec, not yet loaded: what [`parse`] makes of the one string syntax every
/// command uses to name a BRDF (and [`load`] turns into a [`Material`]).
///
/// | form | meaning |
/// |---|---|
/// | `path/to/file.binary` | a MERL table file |
/// | `nbrdf:<dir>/<name>` | the six neural-BRDF weight files `<dir>/<name>_{fc1,b1,...}.npy` |
/// | `merl:<name>` / `nielsen:<name>` | shorthand for `nbrdf:<data>/nbrdf/merl/<name>` (resp. `nielsen`), `<data>` being [`crate::data_dir`] |
/// | `<model>:<key>=<value>,...` | an analytic model |
///
/// Analytic values are numbers; colour parameters accept either one number (grey) or three
/// joined by `/` (`kd=0.8/0.5/0.2`). Models and keys (defaults in parentheses):
///
/// * `lambert`: `kd` (0.5)
/// * `phong` (modified, energy conserving): `kd` (0.5), `ks` (0.5), `n` (20)
/// * `blinn`: `kd` (0.5), `ks` (0.5), `n` (20)
/// * `lafortune`: `kd` (0), lobes `cxK`, `cyK` (= cxK), `czK`, `nK`, `rhoK` for K = 1, 2, ...
/// * `ward`: `kd` (0.1), `ks` (0.2), `alpha` (0.1) or `ax`, `ay`
/// * `cook-torrance` (alias `ct`): `kd` (0.1), `ks` (0.9), `m` (0.2), `ior` (1.5)
/// * `ggx`: `kd` (0.1), `ks` (0.9), `alpha` (0.2), `ior` (1.5)
/// * `oren-nayar` (alias `on`): `albedo` (alias `kd`) (0.8), `sigma` (0.3) (radians)
/// * `ashikhmin-shirley` (alias `as`): `rd` (0.5), `rs` (0.05), `n` (100) or `nu`, `nv`
/// * `ggx2` (two GGX lobes, shared Fresnel): `kd` (0.1), `ks1` (0.5), `alpha1` (0.05), `ks2`
///   (0.4), `alpha2` (0.3), `ior` (1.5)
/// * `ct2` (alias `cook-torrance2`, two Beckmann lobes): `kd` (0.1), `ks1` (0.5), `m1` (0.05),
///   `ks2` (0.4), `m2` (0.3), `ior` (1.5)
/// * `htsg` (He-Torrance-Sillion-Greenberg, [`crate::analytic::htsg`]): `kd` (0.1), `ks` (1),
///   `sigma` (0.2, µm), `tau` (3, µm), `ior` (1.5)
///
/// Unknown models or keys, malformed numbers and out-of-range values are errors.
///
/// # Examples
///
/// ```
/// use brdf::{Brdf, MaterialSpec};
///
/// let spec = brdf::parse("ggx:alpha=0.2,kd=0.1").unwrap();
/// let MaterialSpec::Analytic { model, params } = &spec else { panic!("{spec:?}") };
/// assert_eq!(model, "ggx");
/// assert_eq!(params["alpha"], "0.2");
/// assert!(matches!(brdf::parse("paint.binary").unwrap(), MaterialSpec::Table(_)));
/// // an unknown key or an out-of-range value is an error
/// assert!(brdf::load("ggx:alfa=0.2").is_err());
/// assert!(brdf::load("lambert:kd=-1").is_err());
/// // a grey Lambertian surface reflects kd/π everywhere above the horizon
/// let m = brdf::load("lambert:kd=0.5").unwrap();
/// let z = brdf::Vec3::z();
/// assert!((m.eval(&z, &z)[1] - 0.5 / std::f64::consts::PI).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum MaterialSpec {
    /// A MERL `.binary` file.
    Table(PathBuf),
    /// A neural BRDF: directory and material name.
    Nbrdf {
        /// Directory holding the weight files.
        dir: PathBuf,
        /// Material name (file prefix).
        name: String,
    },
    /// An analytic model with its parameters.
    Analytic {
        /// Model name as written.
        model: String,
        /// Parameters as written.
        params: BTreeMap<String, String>,
    },
    /// A form owned by a registered [`SpecResolver`].
    Registered {
        /// The resolver's prefix (without the colon).
        prefix: String,
        /// Everything after `prefix:`.
        rest: String,
    },
}

/// A loaded material.
pub enum Material {
    /// A tabulated BRDF.
    Table(MerlTable),
    /// A neural BRDF.
    Nbrdf(Nbrdf),
    /// An analytic model.
    Analytic(Box<dyn Brdf>),
    /// Any other BRDF, loaded by a registered [`SpecResolver`] (a resolver whose material is a
    /// table returns [`Material::Table`] instead).
    Resolved(Box<dyn Brdf>),
}

impl std::fmt::Debug for Material {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Material({})", self.name())
    }
}

impl Material {
    /// Tabulates the material on the MERL grid (a copy for tables, the fast path for NBRDFs).
    pub fn tabulate(&self) -> MerlTable {
        match self {
            Material::Table(t) => t.clone(),
            Material::Nbrdf(n) => n.tabulate(),
            Material::Analytic(b) | Material::Resolved(b) => MerlTable::tabulate(b.as_ref()),
        }
    }

    /// The material as a trait object.
    pub fn as_brdf(&self) -> &dyn Brdf {
        match self {
            Material::Table(t) => t,
            Material::Nbrdf(n) => n,
            Material::Analytic(b) | Material::Resolved(b) => b.as_ref(),
        }
    }
}

impl Brdf for Material {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        self.as_brdf().eval(wi, wo)
    }
    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        self.as_brdf().eval_half_diff(hd)
    }
    fn name(&self) -> String {
        self.as_brdf().name()
    }
    fn is_isotropic(&self) -> bool {
        self.as_brdf().is_isotropic()
    }
    fn sample(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
        self.as_brdf().sample(wo, u)
    }
    fn pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
        self.as_brdf().pdf(wi, wo)
    }
    fn has_importance_sampler(&self) -> bool {
        self.as_brdf().has_importance_sampler()
    }
}

/// A [`BrdfError::Spec`] for `spec` (for resolvers reporting a malformed spec).
pub fn spec_error(spec: &str, reason: impl Into<String>) -> BrdfError {
    BrdfError::Spec {
        spec: spec.into(),
        reason: reason.into(),
    }
}

use spec_error as spec_err;

/// Loads the materials of one `<prefix>:<rest>` spec form that lives outside this crate.
///
/// Implementations are registered with [`register`]; [`parse`] and [`load`] then accept the
/// form everywhere. Errors of the resolver's own crate are wrapped with
/// [`resolver_error`] (or reported as [`BrdfError::Spec`] through [`spec_error`] for a
/// malformed spec).
///
/// Materials whose formats live in other crates (compressed wavelet materials, PCA
/// coefficients, ...) are named `<prefix>:<rest>` and loaded by a [`SpecResolver`] registered
/// for `<prefix>` with [`register`]. Every spec function of this crate — and so every command,
/// corpus loader and scene file that takes a spec — sees the registered forms. Built-in prefixes
/// (`nbrdf`, `merl`, `nielsen` and the analytic model names) cannot be taken over. A front end
/// installs the workspace's list of resolvers at start-up (the `catalogue` crate's
/// `Catalogue::workspace().install()`); `docs/material-spec.md` lists the workspace's forms.
///
/// # Examples
///
/// ```
/// use brdf::{Material, SpecResolver};
/// use brdf::Brdf;
/// use std::sync::Arc;
///
/// /// `grey:<albedo>`: a Lambertian surface of one albedo.
/// struct Grey;
/// impl SpecResolver for Grey {
///     fn prefix(&self) -> &str {
///         "grey"
///     }
///     fn form(&self) -> &str {
///         "grey:<albedo>"
///     }
///     fn load(&self, spec: &str, rest: &str) -> brdf::Result<Material> {
///         let kd: f64 = rest.parse().map_err(|_| brdf::spec_error(spec, "albedo is not a number"))?;
///         let m = brdf::analytic::Lambert { kd: [kd; 3] };
///         m.validate()?;
///         Ok(Material::Resolved(Box::new(m)))
///     }
/// }
///
/// brdf::register(Arc::new(Grey)).unwrap();
/// let m = brdf::load("grey:0.5").unwrap();
/// let z = brdf::Vec3::z();
/// assert!((m.eval(&z, &z)[0] - 0.5 / std::f64::consts::PI).abs() < 1e-12);
/// assert!(brdf::load("grey:dark").is_err());
/// assert!(brdf::register(Arc::new(BuiltIn)).is_err()); // `merl:` is built in
/// # struct BuiltIn;
/// # impl SpecResolver for BuiltIn {
/// #     fn prefix(&self) -> &str { "merl" }
/// #     fn load(&self, spec: &str, _: &str) -> brdf::Result<Material> {
/// #         Err(brdf::spec_error(spec, "never"))
/// #     }
/// # }
/// ```
pub trait SpecResolver: Send + Sync {
    /// The prefix this resolver owns, without the colon (`"wavelet"` for `wavelet:<file>`):
    /// ASCII letters, digits, `-` and `_`, matched case-insensitively.
    fn prefix(&self) -> &str;

    /// The form as users write it, for error messages and listings (e.g.
    /// `wavelet:<file.wtree>`). Empty (the default) lists it as `<prefix>:...`.
    fn form(&self) -> &str {
        ""
    }

    /// File extensions (without the dot, lower case) whose files this resolver reads, so that
    /// a path such as `x.bsdf` is a spec of its own without the prefix. None by default.
    fn extensions(&self) -> &[&str] {
        &[]
    }

    /// Loads the material of `spec` (the whole spec, trimmed); `rest` is the part after
    /// `prefix:`, trimmed.
    fn load(&self, spec: &str, rest: &str) -> Result<Material>;
}

/// Wraps an error of a resolver's own crate as a [`BrdfError::Resolver`] of `spec`.
pub fn resolver_error(
    spec: &str,
    source: impl std::error::Error + Send + Sync + 'static,
) -> BrdfError {
    BrdfError::Resolver {
        spec: spec.into(),
        source: Box::new(source),
    }
}

static RESOLVERS: RwLock<Vec<Arc<dyn SpecResolver>>> = RwLock::new(Vec::new());

fn resolvers() -> std::sync::RwLockReadGuard<'static, Vec<Arc<dyn SpecResolver>>> {
    RESOLVERS.read().unwrap_or_else(|e| e.into_inner())
}

const BUILT_IN_PREFIXES: [&str; 3] = ["nbrdf", "merl", "nielsen"];

/// The spec forms this crate reads itself, as users write them (the registered ones are
/// [`registered_forms`]).
pub const BUILT_IN_FORMS: [&str; 5] = [
    "<file>.binary",
    "nbrdf:<dir>/<name>",
    "merl:<name>",
    "nielsen:<name>",
    "<model>:<params>",
];

/// Registers `resolver` for its prefix, process-wide. Registering a prefix again replaces the
/// earlier resolver (so registration functions may be called more than once). A built-in
/// prefix or a prefix with characters other than ASCII letters, digits, `-` and `_` is a
/// [`BrdfError::Spec`] error.
pub fn register(resolver: Arc<dyn SpecResolver>) -> Result<()> {
    let prefix = resolver.prefix().to_ascii_lowercase();
    let valid = !prefix.is_empty()
        && prefix
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    if !valid {
        return Err(spec_err(
            resolver.prefix(),
            "a resolver prefix is ASCII letters, digits, '-' and '_'",
        ));
    }
    if BUILT_IN_PREFIXES.contains(&prefix.as_str()) || MODELS.contains(&prefix.as_str()) {
        return Err(spec_err(
            resolver.prefix(),
            "this prefix is a built-in spec form",
        ));
    }
    let mut all = RESOLVERS.write().unwrap_or_else(|e| e.into_inner());
    all.retain(|r| !r.prefix().eq_ignore_ascii_case(&prefix));
    all.push(resolver);
    Ok(())
}

/// The resolver registered for `prefix` (case-insensitive), if any.
pub fn resolver(prefix: &str) -> Option<Arc<dyn SpecResolver>> {
    resolvers()
        .iter()
        .find(|r| r.prefix().eq_ignore_ascii_case(prefix))
        .cloned()
}

/// The forms of the registered resolvers ([`SpecResolver::form`]), in registration order.
pub fn registered_forms() -> Vec<String> {
    resolvers()
        .iter()
        .map(|r| match r.form() {
            "" => format!("{}:...", r.prefix()),
            f => f.to_string(),
        })
        .collect()
}

const MODELS: [&str; 17] = [
    "lambert",
    "phong",
    "blinn",
    "lafortune",
    "ward",
    "cook-torrance",
    "ct",
    "ggx",
    "oren-nayar",
    "on",
    "ashikhmin-shirley",
    "as",
    "blinn-phong",
    "ggx2",
    "ct2",
    "cook-torrance2",
    "htsg",
];

/// Parses a material spec string (the syntax is listed at [`MaterialSpec`]).
pub fn parse(spec: &str) -> Result<MaterialSpec> {
    let s = spec.trim();
    if s.is_empty() {
        return Err(spec_err(spec, "empty"));
    }
    if let Some(rest) = s.strip_prefix("nbrdf:") {
        let p = PathBuf::from(rest);
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .filter(|n| !n.is_empty())
            .ok_or_else(|| spec_err(spec, "expected nbrdf:<dir>/<name>"))?;
        let dir = p
            .parent()
            .map(|d| d.to_path_buf())
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or_else(|| PathBuf::from("."));
        return Ok(MaterialSpec::Nbrdf { dir, name });
    }
    for (prefix, sub) in [("merl:", "merl"), ("nielsen:", "nielsen")] {
        if let Some(name) = s.strip_prefix(prefix) {
            if name.is_empty() || name.contains('/') {
                return Err(spec_err(spec, format!("expected {prefix}<material name>")));
            }
            return Ok(MaterialSpec::Nbrdf {
                dir: crate::data_dir().join("nbrdf").join(sub),
                name: name.into(),
            });
        }
    }
    if let Some((model, rest)) = s.split_once(':') {
        let model = model.to_ascii_lowercase();
        if MODELS.contains(&model.as_str()) {
            let mut params = BTreeMap::new();
            for kv in rest.split(',').map(str::trim).filter(|kv| !kv.is_empty()) {
                let (k, v) = kv
                    .split_once('=')
                    .ok_or_else(|| spec_err(spec, format!("'{kv}' is not key=value")))?;
                if params
                    .insert(k.trim().to_ascii_lowercase(), v.trim().to_string())
                    .is_some()
                {
                    return Err(spec_err(
                        spec,
                        format!("parameter '{}' given twice", k.trim()),
                    ));
                }
            }
            return Ok(MaterialSpec::Analytic { model, params });
        }
        if let Some(r) = resolver(&model) {
            return Ok(MaterialSpec::Registered {
                prefix: r.prefix().to_string(),
                rest: rest.trim().to_string(),
            });
        }
    }
    if MODELS.contains(&s.to_ascii_lowercase().as_str()) {
        return Ok(MaterialSpec::Analytic {
            model: s.to_ascii_lowercase(),
            params: BTreeMap::new(),
        });
    }
    let p = PathBuf::from(s);
    if let Some(ext) = p.extension().and_then(|e| e.to_str()) {
        let ext = ext.to_ascii_lowercase();
        if let Some(r) = resolvers()
            .iter()
            .find(|r| r.extensions().contains(&ext.as_str()))
        {
            return Ok(MaterialSpec::Registered {
                prefix: r.prefix().to_string(),
                rest: s.to_string(),
            });
        }
    }
    if p.extension().is_some_and(|e| e == "binary") || p.is_file() {
        return Ok(MaterialSpec::Table(p));
    }
    let mut forms = String::from("not ");
    forms.push_str(&BUILT_IN_FORMS.join(", "));
    for f in registered_forms() {
        forms.push_str(", ");
        forms.push_str(&f);
    }
    if let Some((prefix, _)) = s.split_once(':').filter(|(p, _)| p.len() > 1) {
        forms.push_str(&format!(
            " (no resolver is registered for '{prefix}:' in this program)"
        ));
    }
    Err(spec_err(spec, forms))
}

/// Loads an NBRDF material; a `merl:` material of [`crate::nbrdf::EMBEDDED_MERL`] comes from the
/// copy embedded in this crate when the shared data directory does not hold it.
fn load_nbrdf(dir: &std::path::Path, name: &str) -> Result<Nbrdf> {
    let shared_merl = crate::data_dir().join("nbrdf").join("merl");
    let missing = !dir.join(format!("{name}_fc1.npy")).exists();
    if missing && dir == shared_merl {
        if let Some(embedded) = Nbrdf::embedded(name) {
            tracing::debug!(name, "shared data not found: using the embedded material");
            return embedded;
        }
    }
    Nbrdf::load(dir, name)
}

/// Parses and loads a material spec (the syntax is listed at [`MaterialSpec`]).
///
/// # Examples
///
/// ```
/// use brdf::{Brdf, Material, Spherical};
///
/// let m = brdf::load("ggx:alpha=0.2,kd=0.1").unwrap();
/// assert!(matches!(m, Material::Analytic(_)));
/// let wi = Spherical::new(0.4, 0.0).to_vector();
/// let wo = Spherical::new(0.4, std::f64::consts::PI).to_vector();
/// // the mirror configuration is brighter than a grazing off-specular one
/// let off = Spherical::new(1.3, 1.0).to_vector();
/// assert!(m.eval(&wi, &wo)[0] > m.eval(&wi, &off)[0]);
/// assert!(brdf::load("no-such-model:x=1").is_err());
/// ```
pub fn load(spec: &str) -> Result<Material> {
    match parse(spec)? {
        MaterialSpec::Table(p) => Ok(Material::Table(crate::merl::read(p)?)),
        MaterialSpec::Nbrdf { dir, name } => Ok(Material::Nbrdf(load_nbrdf(&dir, &name)?)),
        MaterialSpec::Analytic { model, params } => {
            Ok(Material::Analytic(build_analytic(spec, &model, &params)?))
        }
        MaterialSpec::Registered { prefix, rest } => match resolver(&prefix) {
            Some(r) => r.load(spec.trim(), &rest),
            None => Err(spec_err(spec, format!("no resolver for '{prefix}:'"))),
        },
    }
}

struct Params<'a> {
    spec: &'a str,
    map: &'a BTreeMap<String, String>,
    used: std::cell::RefCell<Vec<String>>,
}

impl Params<'_> {
    fn raw(&self, key: &str) -> Option<&String> {
        let v = self.map.get(key);
        if v.is_some() {
            self.used.borrow_mut().push(key.into());
        }
        v
    }
    fn num(&self, key: &str, default: f64) -> Result<f64> {
        match self.raw(key) {
            None => Ok(default),
            Some(v) => v
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| spec_err(self.spec, format!("{key}={v}: not a finite number"))),
        }
    }
    fn opt_num(&self, key: &str) -> Result<Option<f64>> {
        if self.map.contains_key(key) {
            self.num(key, 0.0).map(Some)
        } else {
            Ok(None)
        }
    }
    fn rgb(&self, key: &str, default: f64) -> Result<Rgb> {
        match self.raw(key) {
            None => Ok([default; 3]),
            Some(v) => {
                let parts: Vec<&str> = v.split('/').collect();
                let nums: Option<Vec<f64>> = parts
                    .iter()
                    .map(|p| p.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
                    .collect();
                match nums.as_deref() {
                    Some([x]) => Ok([*x; 3]),
                    Some([r, g, b]) => Ok([*r, *g, *b]),
                    _ => Err(spec_err(
                        self.spec,
                        format!("{key}={v}: expected one number or r/g/b"),
                    )),
                }
            }
        }
    }
    fn finish(&self) -> Result<()> {
        let used = self.used.borrow();
        for k in self.map.keys() {
            if !used.contains(k) {
                return Err(spec_err(self.spec, format!("unknown parameter '{k}'")));
            }
        }
        Ok(())
    }
}

fn build_analytic(
    spec: &str,
    model: &str,
    params: &BTreeMap<String, String>,
) -> Result<Box<dyn Brdf>> {
    let p = Params {
        spec,
        map: params,
        used: Default::default(),
    };
    let b: Box<dyn Brdf> = match model {
        "lambert" => {
            let m = Lambert {
                kd: p.rgb("kd", 0.5)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "phong" => {
            let m = Phong {
                kd: p.rgb("kd", 0.5)?,
                ks: p.rgb("ks", 0.5)?,
                exponent: p.num("n", 20.0)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "blinn" | "blinn-phong" => {
            let m = BlinnPhong {
                kd: p.rgb("kd", 0.5)?,
                ks: p.rgb("ks", 0.5)?,
                exponent: p.num("n", 20.0)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "lafortune" => {
            let mut lobes = Vec::new();
            for k in 1.. {
                let Some(cx) = p.opt_num(&format!("cx{k}"))? else {
                    break;
                };
                let cy = p.opt_num(&format!("cy{k}"))?.unwrap_or(cx);
                lobes.push(LafortuneLobe {
                    cx,
                    cy,
                    cz: p.num(&format!("cz{k}"), 1.0)?,
                    exponent: p.num(&format!("n{k}"), 10.0)?,
                    rho: p.rgb(&format!("rho{k}"), 1.0)?,
                });
            }
            let m = Lafortune {
                kd: p.rgb("kd", 0.0)?,
                lobes,
            };
            m.validate()?;
            Box::new(m)
        }
        "ward" => {
            let alpha = p.num("alpha", 0.1)?;
            let m = Ward {
                kd: p.rgb("kd", 0.1)?,
                ks: p.rgb("ks", 0.2)?,
                alpha_x: p.num("ax", alpha)?,
                alpha_y: p.num("ay", alpha)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "cook-torrance" | "ct" => {
            let m = CookTorrance {
                kd: p.rgb("kd", 0.1)?,
                ks: p.rgb("ks", 0.9)?,
                m: p.num("m", 0.2)?,
                ior: p.num("ior", 1.5)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "ggx" => {
            let m = Ggx {
                kd: p.rgb("kd", 0.1)?,
                ks: p.rgb("ks", 0.9)?,
                alpha: p.num("alpha", 0.2)?,
                ior: p.num("ior", 1.5)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "oren-nayar" | "on" => {
            let albedo = match p.raw("albedo") {
                Some(_) => p.rgb("albedo", 0.8)?,
                None => p.rgb("kd", 0.8)?,
            };
            let m = OrenNayar {
                albedo,
                sigma: p.num("sigma", 0.3)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "ashikhmin-shirley" | "as" => {
            let n = p.num("n", 100.0)?;
            let m = AshikhminShirley {
                rd: p.rgb("rd", 0.5)?,
                rs: p.rgb("rs", 0.05)?,
                nu: p.num("nu", n)?,
                nv: p.num("nv", n)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "ggx2" => {
            let m = GgxTwoLobe {
                kd: p.rgb("kd", 0.1)?,
                ks: [p.rgb("ks1", 0.5)?, p.rgb("ks2", 0.4)?],
                alpha: [p.num("alpha1", 0.05)?, p.num("alpha2", 0.3)?],
                ior: p.num("ior", 1.5)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "ct2" | "cook-torrance2" => {
            let m = CookTorranceTwoLobe {
                kd: p.rgb("kd", 0.1)?,
                ks: [p.rgb("ks1", 0.5)?, p.rgb("ks2", 0.4)?],
                m: [p.num("m1", 0.05)?, p.num("m2", 0.3)?],
                ior: p.num("ior", 1.5)?,
            };
            m.validate()?;
            Box::new(m)
        }
        "htsg" => {
            let m = Htsg {
                kd: p.rgb("kd", 0.1)?,
                ks: p.rgb("ks", 1.0)?,
                sigma: p.num("sigma", 0.2)?,
                tau: p.num("tau", 3.0)?,
                ior: p.num("ior", 1.5)?,
            };
            m.validate()?;
            Box::new(m)
        }
        other => return Err(spec_err(spec, format!("unknown model '{other}'"))),
    };
    p.finish()?;
    Ok(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_form() {
        assert_eq!(
            parse("nbrdf:/data/merl/chrome").unwrap(),
            MaterialSpec::Nbrdf {
                dir: "/data/merl".into(),
                name: "chrome".into()
            }
        );
        assert!(matches!(
            parse("x/y.binary").unwrap(),
            MaterialSpec::Table(_)
        ));
        assert!(matches!(
            parse("merl:chrome").unwrap(),
            MaterialSpec::Nbrdf { .. }
        ));
        match parse("ggx:alpha=0.3, kd=0.1/0.2/0.3").unwrap() {
            MaterialSpec::Analytic { model, params } => {
                assert_eq!(model, "ggx");
                assert_eq!(params["alpha"], "0.3");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn analytic_specs_build_the_right_models() {
        let m = load("lambert:kd=0.8/0.5/0.2").unwrap();
        let f = m.eval(&Vec3::z(), &Vec3::z());
        assert!((f[0] - 0.8 / std::f64::consts::PI).abs() < 1e-12);
        assert!((f[2] - 0.2 / std::f64::consts::PI).abs() < 1e-12);
        for s in [
            "phong:n=30",
            "blinn:kd=0.1,ks=0.3,n=100",
            "lafortune:kd=0.1,cx1=-1,cz1=0.9,n1=20,rho1=0.5,cx2=0.5,cz2=0.5,n2=2,rho2=0.1",
            "ward:ax=0.1,ay=0.3",
            "ct:m=0.3",
            "ggx:alpha=0.05,ior=2",
            "on:sigma=0.4",
            "as:nu=10,nv=1000",
            "ggx2:ks1=0.3,alpha1=0.02,ks2=0.2,alpha2=0.4",
            "ct2:kd=0.2/0.1/0,m1=0.1,m2=0.5,ior=3",
        ] {
            let m = load(s).unwrap_or_else(|e| panic!("{s}: {e}"));
            let wi = crate::Spherical::new(0.3, 0.1).to_vector();
            let wo = crate::Spherical::new(0.4, 3.0).to_vector();
            let v = m.eval(&wi, &wo);
            assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{s}");
        }
        assert!(!load("ward:ax=0.1,ay=0.3").unwrap().is_isotropic());
    }

    struct Scaled;
    impl SpecResolver for Scaled {
        fn prefix(&self) -> &str {
            "Scaled-Test"
        }
        fn load(&self, spec: &str, rest: &str) -> Result<Material> {
            let inner = load(rest)?;
            if matches!(inner, Material::Resolved(_)) {
                return Err(spec_error(spec, "nested"));
            }
            Ok(Material::Resolved(Box::new(inner)))
        }
    }

    #[test]
    fn registered_resolvers_extend_every_entry_point() {
        assert!(
            load("scaled-test:lambert:kd=0.3").is_err(),
            "not yet registered"
        );
        register(Arc::new(Scaled)).unwrap();
        register(Arc::new(Scaled)).unwrap(); // again: replaces, no duplicate
        assert_eq!(
            registered_forms()
                .iter()
                .filter(|f| f.as_str() == "Scaled-Test:...")
                .count(),
            1
        );
        assert_eq!(
            parse(" scaled-test: lambert:kd=0.3 ").unwrap(),
            MaterialSpec::Registered {
                prefix: "Scaled-Test".into(),
                rest: "lambert:kd=0.3".into()
            }
        );
        let m = load("SCALED-TEST:lambert:kd=0.3").unwrap();
        let direct = load("lambert:kd=0.3").unwrap();
        let (wi, wo) = (
            crate::Spherical::new(0.3, 0.1).to_vector(),
            crate::Spherical::new(0.5, 2.0).to_vector(),
        );
        assert_eq!(m.eval(&wi, &wo), direct.eval(&wi, &wo));
        assert!(matches!(m, Material::Resolved(_)));
        // the resolver's own errors come through
        assert!(matches!(
            load("scaled-test:lambert:kd=7"),
            Err(BrdfError::Parameter { .. })
        ));
        // built-in forms and malformed prefixes cannot be registered
        struct Named(&'static str);
        impl SpecResolver for Named {
            fn prefix(&self) -> &str {
                self.0
            }
            fn load(&self, spec: &str, _: &str) -> Result<Material> {
                Err(spec_error(spec, "unused"))
            }
        }
        for p in ["merl", "NBRDF", "ggx", "", "a:b", "sp ace"] {
            assert!(register(Arc::new(Named(p))).is_err(), "{p}");
        }
        // built-in forms are unaffected
        assert!(matches!(
            parse("merl:chrome"),
            Ok(MaterialSpec::Nbrdf { .. })
        ));
    }

    #[test]
    fn unknown_prefixes_say_no_resolver_is_registered() {
        let e = load("nowhere-registered:file.bin").unwrap_err().to_string();
        assert!(
            e.contains("no resolver is registered for 'nowhere-registered:'"),
            "{e}"
        );
    }

    #[test]
    fn bad_specs_are_errors() {
        for s in [
            "",
            "lambert:kd=abc",
            "lambert:kd=1/2",
            "lambert:kd=-1",
            "lambert:kd=0.5,kd=0.4",
            "lambert:foo=1",
            "ggx:alpha=nan",
            "nbrdf:",
            "merl:",
            "nothing-like-this",
            "phong:n",
        ] {
            assert!(
                matches!(
                    load(s),
                    Err(BrdfError::Spec { .. } | BrdfError::Parameter { .. })
                ),
                "{s} should fail"
            );
        }
        assert!(matches!(
            load("/nonexistent/x.binary"),
            Err(BrdfError::Io { .. })
        ));
        assert!(matches!(
            load("nbrdf:/nonexistent/chrome"),
            Err(BrdfError::Io { .. })
        ));
    }
}
