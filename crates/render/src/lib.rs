//! # render — physically based rendering of measured and modelled BRDFs
//!
//! ```
//! use render::{figures, render_scene, Integrator, Lambert, Material, RenderOptions};
//! use std::sync::Arc;
//!
//! // a white Lambertian sphere under the figure's point light, 24 × 24 pixels, direct lighting
//! let white = Material::new(Arc::new(Lambert { kd: [1.0; 3] }));
//! let scene = figures::sphere_scene(white.into(), 24, 24).unwrap();
//! let options = RenderOptions { spp: 4, integrator: Integrator::Direct, ..Default::default() };
//! let image = render_scene(&scene, &options).unwrap();
//! assert_eq!(image.width(), 24);
//! // the corner sees the black background, the lit sphere is bright but physical
//! assert_eq!(image.get(0, 0), [0.0; 3]);
//! let brightest = image.pixels().iter().map(|p| p[0]).fold(0.0f32, f32::max);
//! assert!(brightest > 0.5 && brightest <= 1.01, "{brightest}");
//! ```
//!
//! Implements appendix A of Matusik's thesis ("A Data-Driven Reflectance Model"):
//!
//! * [`integrator`]: direct illumination (A.1) and Monte Carlo path tracing (A.2) with
//!   next-event estimation, environment-map sampling and multiple importance sampling,
//!   rendered in parallel over tiles with seeded per-tile random streams.
//! * [`importance`]: importance sampling of tabulated isotropic BRDFs (A.2.4): per θr a
//!   marginal over θi and a conditional over φdiff, drawn by CDF inversion or by rejection.
//! * [`material`]: materials from any [`brdf::Brdf`], per-point blends of two BRDFs, and the
//!   many-materials shader: a shared log-space linear basis with k coefficients per material.
//! * [`scene`], [`geometry`], [`mesh`]: spheres, triangle meshes (OBJ), the built-in Utah
//!   teapot, ground plane, point and area lights, a BVH.
//! * [`envmap`]: lat-long OpenEXR light probes (and a procedural one) with importance sampling.
//! * [`scene_file`]: the TOML scene format; [`figures`]: the thesis' figure set-ups.
//! * [`image`]: linear OpenEXR and tonemapped sRGB PNG output.
//! * [`RenderJob`]: the job behind `gantry render` (a scene file or a figure, written as
//!   OpenEXR and PNG); [`ModelResolver`] adds the linear bases of model files to scene files.

#![warn(missing_docs)]

pub mod distribution;
pub mod envmap;
pub mod error;
pub mod figures;
pub mod geometry;
pub mod image;
pub mod importance;
pub mod integrator;
mod job;
pub mod material;
pub mod mesh;
pub mod sampling;
pub mod scene;
pub mod scene_file;

pub use envmap::EnvironmentMap;
pub use error::{RenderError, Result};
pub use image::{Image, Tonemap, TonemapOperator};
pub use importance::{BrdfImportance, DirectionSampler, ImportanceResolution, PhiSampling};
pub use integrator::{
    render_scene, render_with_variance, BsdfSampling, Integrator, RenderOptions, RenderOutput,
};
pub use job::{
    load_basis, render_scene_file, teapot_figure, Common, Figure, ModelResolver, RenderJob,
    RenderReport,
};
pub use material::{
    BasisBrdf, BasisGrid, Lambert, LinearBasis, Mask, Material, MaterialResolver, SurfaceMaterial,
};
pub use mesh::{utah_teapot, Mesh, Transform};
pub use scene::{AreaLight, Camera, PointLight, Scene, SceneBuilder};
