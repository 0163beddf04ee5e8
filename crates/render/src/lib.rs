//! # render — physically based rendering of measured and modelled BRDFs
//!
//! ```
//! use render::{sphere_scene, render_scene, Integrator, Lambert, Material, RenderOptions};
//! use std::sync::Arc;
//!
//! // a white Lambertian sphere under the figure's point light, 24 × 24 pixels, direct lighting
//! let white = Material::new(Arc::new(Lambert { kd: [1.0; 3] }));
//! let scene = sphere_scene(white.into(), 24, 24).unwrap();
//! let options = RenderOptions { spp: 4, integrator: Integrator::Direct, ..Default::default() };
//! let image = render_scene(&scene, &options).unwrap();
//! assert_eq!(image.width(), 24);
//! // the corner sees the black background, the lit sphere is bright but physical
//! assert_eq!(image.get(0, 0), [0.0; 3]);
//! let brightest = image.pixels().iter().map(|p| p[0]).fold(0.0f32, f32::max);
//! assert!(brightest > 0.5 && brightest <= 1.01, "{brightest}");
//! ```
//!
//! Implements appendix A of the thesis: rendering measured and modelled BRDFs. In the order of
//! the work:
//!
//! 1. **Materials.** A [`Material`] wraps any [`brdf::Brdf`] (a MERL table, an analytic model, a
//!    model's reconstruction) with optional importance tables, [`BrdfImportance`] (thesis
//!    A.2.4: per θr a marginal over θi and a conditional over φdiff, drawn by CDF inversion or
//!    by rejection). [`SurfaceMaterial`] adds per-point blends of two BRDFs under a [`Mask`]; a
//!    [`LinearBasis`] with k coefficients per material ([`BasisBrdf`]) is the many-materials
//!    shader of a log-space model, and [`SurfaceMaterial::Varying`] gives every point its own
//!    coefficients from a [`CoefficientTexture`] (thesis §7.2.2: a [`ProcessPath`] such as
//!    clean → rusted, driven by a selector such as [`rust_selector`]).
//! 2. **Scenes.** A [`Scene`] ([`SceneBuilder`]) holds the [`Camera`], spheres, triangle
//!    [`Mesh`]es (OBJ, the built-in [`utah_teapot`]), [`PointLight`]s, [`AreaLight`]s and an
//!    [`EnvironmentMap`] (lat-long OpenEXR probes, or a procedural one, with importance
//!    sampling), over a BVH. [`load_scene`]/[`parse_scene`] read the TOML scene format;
//!    [`sphere_scene`], [`teapot_scene`] (its mesh [`figure_teapot_mesh`] and camera
//!    [`teapot_camera`]), [`teapot_point_scene`] and [`strip_scene`] set up the thesis's figures.
//! 3. **Rendering.** [`render_scene`] (and [`render_with_variance`]) runs the chosen
//!    [`Integrator`] over [`RenderOptions`]: direct illumination (thesis A.1) or Monte Carlo path
//!    tracing (thesis A.2) with next-event estimation, environment sampling and multiple
//!    importance sampling, in parallel over tiles with seeded per-tile random streams.
//! 4. **Images.** The result is a linear [`Image`], written as OpenEXR or as a tonemapped sRGB
//!    PNG ([`Tonemap`]).
//! 5. **The job.** [`RenderJob`] is `gantry render`: a scene file or a [`Figure`], written as
//!    OpenEXR and PNG with a [`RenderReport`]; [`ModelResolver`] adds the linear bases of model
//!    files ([`load_basis`]) to scene files.

#![warn(missing_docs)]

mod distribution;
mod envmap;
mod error;
mod figures;
mod geometry;
mod image;
mod importance;
mod integrator;
mod job;
mod material;
mod mesh;
mod sampling;
mod scene;
mod scene_file;
mod varying;

pub use distribution::{AliasTable, Distribution1D, Distribution2D};
pub use figures::{
    figure_bunny_mesh, figure_mesh_from_obj, figure_point_scene, figure_scene, figure_teapot_mesh,
    shared_bunny_path, sphere_grid_scene, sphere_scene, strip_scene, teapot_camera,
    teapot_point_light, teapot_point_scene, teapot_scene, SphereGrid, BUNNY_HEIGHT,
    BUNNY_ROTATION_DEGREES, TEAPOT_LOOK_AT, TEAPOT_POINT_LIGHT_POSITION,
};
pub use geometry::{Aabb, Bvh, BvhHit, Ray, Shape};
pub use image::{srgb_encode, MAX_HDR_PIXELS};
pub use importance::{estimate_reflected_radiance, EstimatorStats};
pub use integrator::ProgressFn;
pub use material::fbm;
pub use mesh::parse_obj;
pub use sampling::{cosine_hemisphere, cosine_hemisphere_pdf, uniform, Frame, SampleRng};
pub use scene::{Hit, MaterialId};
pub use scene_file::{load_scene, parse_scene, LoadedScene, RenderDefaults, SpecResolver};

pub use envmap::EnvironmentMap;
pub use error::{RenderError, Result};
pub use image::{Image, Tonemap, TonemapOperator};
pub use importance::{
    BrdfImportance, DirectionSampler, ImportanceAliasTables, ImportanceResolution, PhiSampling,
};
pub use integrator::{
    render_scene, render_with_variance, BsdfSampling, Integrator, RenderOptions, RenderOutput,
};
pub use job::{
    load_basis, mesh_figure, project_materials, render_scene_file, teapot_figure, Common, Figure,
    FigureMesh, ModelResolver, RenderJob, RenderReport, TeapotLight,
};
pub use material::{
    BasisBrdf, BasisGrid, Lambert, LinearBasis, Mask, Material, MaterialResolver, SurfaceMaterial,
};
pub use mesh::{utah_teapot, utah_teapot_wrapped, Mesh, Transform};
pub use scene::{AreaLight, Camera, PointLight, Scene, SceneBuilder};
pub use varying::{rust_selector, CoefficientTexture, ProcessPath};
