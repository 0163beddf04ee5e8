//! A small synthetic corpus and model on the full MERL grid, and small scenes.

#![allow(dead_code)]

use brdf::analytic::{Ggx, Lambert};
use brdf::{Brdf, MerlTable};
use recover::RecoveryScene;

/// Six analytic materials tabulated on the MERL grid.
pub fn corpus_tables() -> Vec<(String, MerlTable)> {
    let lambert =
        |kd: f64, g: f64, b: f64| -> Box<dyn Brdf> { Box::new(Lambert { kd: [kd, g, b] }) };
    let ggx = |kd: [f64; 3], ks: f64, alpha: f64, ior: f64| -> Box<dyn Brdf> {
        Box::new(Ggx {
            kd,
            ks: [ks; 3],
            alpha,
            ior,
        })
    };
    let mats: Vec<(&str, Box<dyn Brdf>)> = vec![
        ("white-lambert", lambert(0.8, 0.8, 0.8)),
        ("red-lambert", lambert(0.6, 0.1, 0.1)),
        ("blue-ggx", ggx([0.05, 0.1, 0.4], 0.5, 0.15, 1.5)),
        ("grey-ggx", ggx([0.2, 0.2, 0.2], 0.6, 0.35, 1.5)),
        ("green-ggx", ggx([0.1, 0.4, 0.1], 0.3, 0.08, 1.6)),
        ("dark-ggx", ggx([0.02, 0.02, 0.03], 0.8, 0.25, 1.4)),
    ];
    mats.into_iter()
        .map(|(n, b)| (n.to_string(), MerlTable::tabulate(b.as_ref())))
        .collect()
}

/// The PCA model (all 5 components) of [`corpus_tables`].
pub fn model(tables: &[(String, MerlTable)]) -> reduce::Model {
    mapped_model(tables, reduce::Mapping::Log)
}

/// The PCA model (all 5 components) of [`corpus_tables`] in the given mapping.
pub fn mapped_model(tables: &[(String, MerlTable)], mapping: reduce::Mapping) -> reduce::Model {
    let mut corpus = reduce::Corpus::new(reduce::MATERIAL_DIM);
    for (n, t) in tables {
        corpus.push_values(n.clone(), &t.values()).unwrap();
    }
    reduce::build_mapped_model(&corpus, mapping, 5, None, None).unwrap()
}

/// A `size`² view of a unit sphere of unknown material, with the given lights TOML.
pub fn sphere_scene(size: usize, lights: &str) -> RecoveryScene {
    RecoveryScene::unit_sphere(size, lights).unwrap()
}

/// Three point-light scenes.
pub fn point_light_scenes(size: usize) -> Vec<RecoveryScene> {
    [[2.0, 2.0, 4.0], [-3.0, 0.5, 2.5], [0.5, -2.0, 3.5]]
        .iter()
        .map(|p| sphere_scene(size, &RecoveryScene::point_light_toml(*p, 25.0)))
        .collect()
}
