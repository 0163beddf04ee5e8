//! A small synthetic corpus and model on the full MERL grid, and small scenes.

#![allow(dead_code)]

use brdf::analytic::{Ggx, Lambert};
use brdf::{Brdf, MerlTable};
use recover::scene::RecoveryScene;

/// Six analytic materials tabulated on the MERL grid.
pub fn corpus_tables() -> Vec<(String, MerlTable)> {
    let mats: Vec<(&str, Box<dyn Brdf>)> = vec![
        (
            "white-lambert",
            Box::new(Lambert {
                kd: [0.8, 0.8, 0.8],
            }),
        ),
        (
            "red-lambert",
            Box::new(Lambert {
                kd: [0.6, 0.1, 0.1],
            }),
        ),
        (
            "blue-ggx",
            Box::new(Ggx {
                kd: [0.05, 0.1, 0.4],
                ks: [0.5; 3],
                alpha: 0.15,
                ior: 1.5,
            }),
        ),
        (
            "grey-ggx",
            Box::new(Ggx {
                kd: [0.2, 0.2, 0.2],
                ks: [0.6; 3],
                alpha: 0.35,
                ior: 1.5,
            }),
        ),
        (
            "green-ggx",
            Box::new(Ggx {
                kd: [0.1, 0.4, 0.1],
                ks: [0.3; 3],
                alpha: 0.08,
                ior: 1.6,
            }),
        ),
        (
            "dark-ggx",
            Box::new(Ggx {
                kd: [0.02, 0.02, 0.03],
                ks: [0.8; 3],
                alpha: 0.25,
                ior: 1.4,
            }),
        ),
    ];
    mats.into_iter()
        .map(|(n, b)| (n.to_string(), MerlTable::tabulate(b.as_ref())))
        .collect()
}

/// The PCA model (all 5 components) of [`corpus_tables`].
pub fn model(tables: &[(String, MerlTable)]) -> reduce::model::Model {
    let mut corpus = reduce::corpus::Corpus::new(reduce::corpus::MATERIAL_DIM);
    for (n, t) in tables {
        corpus.push_values(n.clone(), &t.values()).unwrap();
    }
    reduce::model::build_model(&corpus, 5, None, None).unwrap()
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
