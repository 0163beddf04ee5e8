//! Scenes whose object's material is unknown.

use std::path::Path;
use std::sync::Arc;

use brdf::{Brdf, Rgb, Vec3};
use render::MaterialResolver;
use render::SpecResolver;
use render::{Scene, SurfaceMaterial};

use crate::error::{RecoverError, Result};

/// Spec string of the placeholder material.
pub const UNKNOWN_SPEC: &str = "recover:unknown";
/// Name of the placeholder BRDF.
pub const UNKNOWN_NAME: &str = "unknown material (recover)";

/// The black placeholder BRDF standing for the unknown material.
#[derive(Debug, Clone, Copy, Default)]
pub struct UnknownBrdf;

impl Brdf for UnknownBrdf {
    fn eval(&self, _wi: &Vec3, _wo: &Vec3) -> Rgb {
        [0.0; 3]
    }
    fn name(&self) -> String {
        UNKNOWN_NAME.into()
    }
}

struct Resolver;

impl MaterialResolver for Resolver {
    fn spec(&self, spec: &str) -> render::Result<Arc<dyn Brdf>> {
        if spec == UNKNOWN_SPEC {
            Ok(Arc::new(UnknownBrdf))
        } else {
            SpecResolver.spec(spec)
        }
    }
    fn tabulated(&self, spec: &str, brdf: &Arc<dyn Brdf>) -> render::Result<Option<Arc<dyn Brdf>>> {
        if spec == UNKNOWN_SPEC {
            Ok(None)
        } else {
            SpecResolver.tabulated(spec, brdf)
        }
    }
}

/// A scene with the ids of its unknown materials.
///
/// A recovery scene is an ordinary `render` scene TOML in which the object to recover refers to
/// a material that is either not defined in `[materials]` or defined as `{ unknown = true }`.
/// Such materials are replaced by a black placeholder; every camera ray that hits a surface of
/// one of them is an observation of the unknown BRDF. Other objects keep their materials and
/// only cast shadows (interreflections are not modelled: the pixel model is direct light).
#[derive(Debug)]
pub struct RecoveryScene {
    /// The scene (unknown materials render black).
    pub scene: Scene,
    /// Material ids of the unknown material(s).
    pub unknown: Vec<usize>,
}

impl RecoveryScene {
    /// Reads a scene TOML file (relative paths against its directory).
    pub fn load(path: &Path) -> Result<RecoveryScene> {
        let text = std::fs::read_to_string(path).map_err(|e| RecoverError::io(path, e))?;
        Self::parse(&text, path.parent().unwrap_or(Path::new(".")))
    }

    /// The standard photograph of the thesis's recognition figures: a `size × size` view of a
    /// unit sphere of unknown material at the origin, from a camera 4 units up +z with a 32° field
    /// of view, lit by `lights` (TOML `[[lights]]` tables and/or an `[environment]` table;
    /// relative paths against the working directory).
    ///
    /// ```
    /// let lights = "[[lights]]\nkind = \"point\"\nposition = [2.0, 2.0, 4.0]\nintensity = [25.0, 25.0, 25.0]";
    /// let s = recover::RecoveryScene::unit_sphere(16, lights).unwrap();
    /// assert_eq!(s.unknown.len(), 1);
    /// ```
    pub fn unit_sphere(size: usize, lights: &str) -> Result<RecoveryScene> {
        let text = format!(
            "[camera]\nposition = [0.0, 0.0, 4.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 32.0\n\
             width = {size}\nheight = {size}\n\
             [[objects]]\nkind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\n\
             material = \"object\"\n{lights}\n"
        );
        Self::parse(&text, Path::new("."))
    }

    /// A point light `[[lights]]` TOML table (for [`RecoveryScene::unit_sphere`]).
    pub fn point_light_toml(position: [f64; 3], intensity: f64) -> String {
        format!(
            "[[lights]]\nkind = \"point\"\nposition = [{:?}, {:?}, {:?}]\nintensity = [{i:?}, {i:?}, {i:?}]\n",
            position[0],
            position[1],
            position[2],
            i = intensity
        )
    }

    /// Parses scene TOML text.
    pub fn parse(text: &str, base_dir: &Path) -> Result<RecoveryScene> {
        let mut doc: toml::Table = toml::from_str(text)
            .map_err(|e| RecoverError::Scene(format!("not a scene TOML: {}", e.message())))?;
        let mut unknown_names = Vec::new();
        let materials = doc
            .entry("materials")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let materials = materials
            .as_table_mut()
            .ok_or_else(|| RecoverError::Scene("`materials` is not a table".into()))?;
        for (name, m) in materials.iter_mut() {
            if let Some(t) = m.as_table_mut() {
                if t.get("unknown").and_then(|v| v.as_bool()) == Some(true) {
                    t.clear();
                    t.insert("spec".into(), UNKNOWN_SPEC.into());
                    t.insert("importance".into(), false.into());
                    unknown_names.push(name.clone());
                }
            }
        }
        let referenced: Vec<String> = doc
            .get("objects")
            .and_then(|o| o.as_array())
            .map(|a| {
                a.iter()
                    .filter_map(|o| o.get("material").and_then(|m| m.as_str()))
                    .map(String::from)
                    .collect()
            })
            .unwrap_or_default();
        let materials = doc
            .get_mut("materials")
            .and_then(|m| m.as_table_mut())
            .expect("inserted above");
        for name in referenced {
            if !materials.contains_key(&name) {
                let mut t = toml::Table::new();
                t.insert("spec".into(), UNKNOWN_SPEC.into());
                t.insert("importance".into(), false.into());
                materials.insert(name.clone(), toml::Value::Table(t));
                unknown_names.push(name);
            }
        }
        if unknown_names.is_empty() {
            return Err(RecoverError::Scene(
                "no object has an unknown material (refer to an undefined material or mark one \
                 `unknown = true`)"
                    .into(),
            ));
        }
        let text = toml::to_string(&doc).map_err(|e| RecoverError::Scene(e.to_string()))?;
        let loaded = render::parse_scene(&text, base_dir, &Resolver)?;
        let unknown: Vec<usize> = loaded
            .scene
            .materials
            .iter()
            .enumerate()
            .filter(|(_, m)| match m {
                SurfaceMaterial::Single(m) => m.name == UNKNOWN_NAME,
                SurfaceMaterial::Blend { .. } | SurfaceMaterial::Varying { .. } => false,
            })
            .map(|(i, _)| i)
            .collect();
        if unknown.is_empty() {
            return Err(RecoverError::Scene(
                "the unknown material is used only inside a blend".into(),
            ));
        }
        Ok(RecoveryScene {
            scene: loaded.scene,
            unknown,
        })
    }

    /// The same scene with the unknown material replaced by `material` (for rendering test
    /// images).
    pub fn with_material(&self, material: render::Material) -> Scene {
        let mut scene = self.scene.clone();
        for &id in &self.unknown {
            scene.materials[id] = SurfaceMaterial::Single(material.clone());
        }
        scene
    }
}
