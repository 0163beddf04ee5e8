// Shared fixtures: a small synthetic corpus of analytic BRDFs on a coarse grid.
#![allow(dead_code)]

use brdf::analytic::{BlinnPhong, CookTorrance, Lambert, Phong};
use brdf::Brdf;
use sampling::TrainingSet;
use sampling::{GridTable, SampleGrid};

pub fn small_grid() -> SampleGrid {
    SampleGrid::new(6, 6, 12).unwrap()
}

pub fn materials() -> Vec<Box<dyn Brdf>> {
    let mut out: Vec<Box<dyn Brdf>> = Vec::new();
    let colours = [
        [0.6, 0.3, 0.1],
        [0.1, 0.5, 0.2],
        [0.3, 0.3, 0.7],
        [0.8, 0.8, 0.8],
    ];
    for (i, kd) in colours.iter().enumerate() {
        // Lambert tables are constant per channel: more than three would be linearly dependent.
        if i < 3 {
            out.push(Box::new(Lambert { kd: *kd }));
        } else {
            out.push(Box::new(Phong {
                kd: kd.map(|v| 0.6 * v),
                ks: [0.2, 0.25, 0.3],
                exponent: 40.0,
            }));
        }
        out.push(Box::new(BlinnPhong {
            kd: kd.map(|v| 0.5 * v),
            ks: [0.3, 0.3, 0.3],
            exponent: 10.0 + 25.0 * i as f64,
        }));
        out.push(Box::new(CookTorrance {
            kd: kd.map(|v| 0.3 * v),
            ks: [0.5, 0.4, 0.3],
            m: 0.15 + 0.1 * i as f64,
            ior: 1.5,
        }));
    }
    out
}

pub fn corpus(grid: SampleGrid) -> (TrainingSet, Vec<GridTable>) {
    let mats = materials();
    let tables: Vec<GridTable> = mats
        .iter()
        .map(|m| GridTable::tabulate(m.as_ref(), grid))
        .collect();
    let names = mats.iter().map(|m| m.name()).collect();
    (TrainingSet::from_tables(names, &tables).unwrap(), tables)
}
