//! Seeded random edits in the linear and chart spaces of a small analytic corpus: every
//! written table passes the validity checks, and edits that stop do so at a real border.

use brdf::analytic::{Ggx, Lambert};
use brdf::{Brdf, MerlTable};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use reduce::Corpus;
use traits::{fit_binary, FitOptions, Method};
use traits::{validate, Check};
use traits::{Navigator, NavigatorOptions, Space, TraitVector, BISECTION_STEPS, CHART_MARCH_STEPS};

/// Edits per space (`TRAITS_EDITS` overrides).
fn edits(default: usize) -> usize {
    std::env::var("TRAITS_EDITS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Ten materials: Lambertian and GGX surfaces of different albedo, tint and roughness. Some
/// are near albedo 1, so that energy conservation binds; dark ones make non-negativity bind.
fn corpus() -> (Corpus, Vec<bool>, Vec<bool>) {
    let mats: Vec<(Box<dyn Brdf>, bool, bool)> = vec![
        (
            Box::new(Lambert {
                kd: [0.05, 0.05, 0.06],
            }),
            false,
            false,
        ),
        (
            Box::new(Lambert {
                kd: [0.8, 0.3, 0.2],
            }),
            false,
            true,
        ),
        (
            Box::new(Lambert {
                kd: [0.9, 0.9, 0.85],
            }),
            false,
            true,
        ),
        (
            Box::new(Lambert {
                kd: [0.2, 0.5, 0.3],
            }),
            false,
            false,
        ),
        (
            Box::new(Ggx {
                kd: [0.1, 0.1, 0.3],
                ks: [0.6; 3],
                alpha: 0.08,
                ior: 1.5,
            }),
            true,
            false,
        ),
        (
            Box::new(Ggx {
                kd: [0.6, 0.6, 0.6],
                ks: [0.4; 3],
                alpha: 0.15,
                ior: 1.5,
            }),
            true,
            true,
        ),
        (
            Box::new(Ggx {
                kd: [0.02, 0.02, 0.02],
                ks: [0.9, 0.8, 0.5],
                alpha: 0.05,
                ior: 2.5,
            }),
            true,
            false,
        ),
        (
            Box::new(Ggx {
                kd: [0.4, 0.2, 0.1],
                ks: [0.3; 3],
                alpha: 0.3,
                ior: 1.5,
            }),
            false,
            false,
        ),
        (
            Box::new(Ggx {
                kd: [0.7, 0.7, 0.2],
                ks: [0.5; 3],
                alpha: 0.1,
                ior: 1.6,
            }),
            true,
            true,
        ),
        (
            Box::new(Ggx {
                kd: [0.1, 0.3, 0.1],
                ks: [0.2; 3],
                alpha: 0.5,
                ior: 1.4,
            }),
            false,
            false,
        ),
    ];
    let mut c = Corpus::new(reduce::MATERIAL_DIM);
    let (mut glossy, mut bright) = (Vec::new(), Vec::new());
    for (i, (m, g, b)) in mats.into_iter().enumerate() {
        let t = MerlTable::tabulate(m.as_ref());
        c.push_values(format!("m{i}"), &t.values()).unwrap();
        glossy.push(g);
        bright.push(b);
    }
    (c, glossy, bright)
}

/// The corpus coordinates in the navigator's space and the two traits fitted on them (SVM).
fn fitted_traits(
    nav: &Navigator,
    glossy: &[bool],
    bright: &[bool],
) -> (DMatrix<f64>, Vec<TraitVector>) {
    let coords: DMatrix<f64> = nav.embedding.corpus().unwrap();
    let traits = [("glossy", glossy), ("bright", bright)]
        .iter()
        .map(|(n, y)| TraitVector {
            name: n.to_string(),
            direction: fit_binary(&coords, y, Method::Svm, &FitOptions::default()).unwrap(),
            cross_validated: None,
            variant: None,
        })
        .collect();
    (coords, traits)
}

fn run(space: Space, seed: u64, default_edits: usize) {
    let (c, glossy, bright) = corpus();
    let model = reduce::build_model(&c, 5, Some(2), None).unwrap();
    let opts = NavigatorOptions {
        linear_dim: 5,
        ..Default::default()
    };
    let nav = Navigator::new(&model, space, opts.clone()).unwrap();
    let (coords, traits) = fitted_traits(&nav, &glossy, &bright);
    // Start points: corpus materials that are valid themselves at this model size.
    let starts: Vec<usize> = (0..c.len())
        .filter(|&i| {
            let x: Vec<f64> = coords.row(i).iter().copied().collect();
            let s = nav.state(&x).unwrap();
            nav.failures(&s).unwrap().is_empty()
        })
        .collect();
    assert!(starts.len() >= 5, "only {} valid starts", starts.len());
    let (full, stopped) = check_edits(&nav, &coords, &traits, &starts, seed, edits(default_edits));
    // On this corpus both outcomes occur.
    assert!(full > 0);
    assert!(stopped > 0, "no edit reached a border");
}

/// `n` seeded random edits (random start among `starts`, random trait, amount in [−4, 4]),
/// each checked independently of the navigator. Returns the numbers of full and stopped
/// edits.
fn check_edits(
    nav: &Navigator,
    coords: &DMatrix<f64>,
    traits: &[TraitVector],
    starts: &[usize],
    seed: u64,
    n: usize,
) -> (usize, usize) {
    let space = nav.embedding.space;
    let opts = nav.options.clone();
    let t0 = std::time::Instant::now();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let dir = tempfile::tempdir().unwrap();
    let mut stopped = std::collections::HashMap::<Check, usize>::new();
    let mut full = 0;
    // The share of each requested move applied, and the values clamped at 0.
    let (mut fractions, mut clamped) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for e in 0..n {
        let i = starts[rng.gen_range(0..starts.len())];
        let tv = &traits[rng.gen_range(0..traits.len())];
        let amount: f64 = rng.gen_range(-4.0..4.0);
        let x: Vec<f64> = coords.row(i).iter().copied().collect();
        let out = nav
            .edit(&x, tv, amount)
            .unwrap_or_else(|err| panic!("edit {e} of material {i} by {amount}: {err}"));
        // The outcome's own report, recomputed independently of the navigator's caches.
        let r = validate(&out.table, nav.quadrature(), &opts.validity, None);
        assert!(r.is_valid(), "edit {e}: {:?}", r.failed);
        assert!(out.table.raw().iter().all(|&v| v >= 0.0));
        assert!(out.applied.abs() <= amount.abs() + 1e-12);
        fractions.push(out.applied / amount);
        clamped.push(out.clamped);
        // The clamp is counted: as many written zeros at least as values it clamped.
        assert!(out.table.raw().iter().filter(|&&v| v == 0.0).count() >= out.clamped);
        match out.stopped_by {
            None => {
                assert!((out.applied - amount).abs() < 1e-9);
                full += 1;
            }
            Some(c) => {
                *stopped.entry(c).or_default() += 1;
                let frac = out.applied / amount;
                let at = |f: f64| -> Vec<f64> {
                    x.iter()
                        .zip(tv.direction.unit_step())
                        .map(|(a, u)| a + f.min(1.0) * amount * u)
                        .collect()
                };
                let fails = |f: f64| {
                    !nav.failures(&nav.state(&at(f)).unwrap())
                        .unwrap()
                        .is_empty()
                };
                match space {
                    // Linear: the valid part of the line is an interval (affine non-negativity,
                    // convex albedo and hull), so a little further is no longer valid.
                    Space::Linear => assert!(
                        fails(frac + 0.05 * (1.0 - frac)) || frac > 0.95,
                        "edit {e}: stopped by {c} at {frac} but further is valid"
                    ),
                    // Chart: the back-projection is not linear and the valid part of the
                    // curve need not be an interval; the stop is at a border found by the
                    // march and bisection: an invalid point lies within the bisection's
                    // resolution beyond it.
                    Space::Chart => {
                        let res = 1.0
                            / (CHART_MARCH_STEPS as f64 * 2f64.powi(BISECTION_STEPS as i32 / 2));
                        assert!(
                            frac == 0.0 || (1..=4).any(|k| fails(frac + k as f64 * res * 0.3)),
                            "edit {e}: stopped by {c} at {frac}, no invalid point within {res}"
                        );
                    }
                }
            }
        }
        if e % 200 == 0 {
            // Written tables read back and still pass, with the summary's own albedo.
            let p = dir.path().join(format!("e{e}.binary"));
            brdf::merl::write(&p, &out.table).unwrap();
            let back = brdf::merl::read(&p).unwrap();
            // The one albedo rule (`brdf::ALBEDO_CELLS`, as `gantry info` and the checks use
            // it): a coarser quadrature of the same table can read a few tenths of a per cent
            // higher at a border reached by energy conservation.
            let (n_u, n_phi) = brdf::ALBEDO_CELLS;
            for deg in [0.0f64, 45.0, 80.0] {
                let a = brdf::directional_albedo(&back, deg.to_radians(), n_u, n_phi);
                assert!(a.iter().all(|&v| v <= 1.0), "edit {e} at {deg}°: {a:?}");
            }
        }
    }
    fractions.sort_by(f64::total_cmp);
    clamped.sort_unstable();
    let q = |v: &[f64], p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    let cq = |p: f64| clamped[((clamped.len() - 1) as f64 * p).round() as usize];
    eprintln!(
        "{space:?}: {n} edits in {:.1} s, {full} full, stopped: {stopped:?}; share applied: median {:.3}, quartiles {:.3} / {:.3}; values clamped at 0 per table: median {}, p90 {}, max {} (of {})",
        t0.elapsed().as_secs_f64(),
        q(&fractions, 0.5),
        q(&fractions, 0.25),
        q(&fractions, 0.75),
        cq(0.5),
        cq(0.9),
        cq(1.0),
        brdf::MATERIAL_DIM
    );
    (full, stopped.values().sum())
}

#[test]
fn random_edits_in_linear_space_stay_valid() {
    run(Space::Linear, 11, 40);
}

#[test]
fn random_edits_in_chart_space_stay_valid() {
    run(Space::Chart, 12, 25);
}

/// The full 1,000 edits per space: `cargo test --release -p traits --test edits -- --ignored`.
#[test]
#[ignore]
fn thousand_random_edits_in_each_space_stay_valid() {
    run(Space::Linear, 21, 1000);
    run(Space::Chart, 22, 1000);
}

/// 1,000 seeded edits per space on the shared 96-material model with the thesis traits (SVM):
/// `TRAITS_MODEL=model.bin cargo test --release -p traits --test edits -- --ignored real_model`
/// (default `target/traits-data/model.bin`; `TRAITS_EDITS` overrides the count).
#[test]
#[ignore]
fn random_edits_on_the_real_model_stay_valid() {
    let path = std::env::var("TRAITS_MODEL").unwrap_or_else(|_| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../target/traits-data/model.bin"
        )
        .into()
    });
    assert!(
        std::path::Path::new(&path).exists(),
        "no model at {path}: build one with `gantry model build --corpus $BRDF_DATA_DIR/nbrdf/merl --out model.bin` and set TRAITS_MODEL"
    );
    let model = reduce::Model::load(&path).unwrap();
    let labels = traits::thesis_labels();
    for (space, seed) in [(Space::Linear, 31), (Space::Chart, 32)] {
        let nav = Navigator::new(&model, space, NavigatorOptions::default()).unwrap();
        let coords = nav.embedding.corpus().unwrap();
        let set = traits::SetFit {
            coords: &coords,
            names: &model.names,
            space,
            options: FitOptions::default(),
            cross_validate: false,
        }
        .binary(&labels, Method::Svm)
        .unwrap();
        let starts: Vec<usize> = (0..coords.nrows())
            .filter(|&i| {
                let x: Vec<f64> = coords.row(i).iter().copied().collect();
                let s = nav.state(&x).unwrap();
                nav.failures(&s).unwrap().is_empty()
            })
            .collect();
        eprintln!(
            "{space:?}: {} of {} materials are valid starts",
            starts.len(),
            coords.nrows()
        );
        assert!(starts.len() >= 10);
        // Chart edits of up to 4 units on the real model nearly always stop at a border.
        let (_, stopped) = check_edits(&nav, &coords, &set.traits, &starts, seed, edits(1000));
        assert!(stopped > 0);
    }
}

/// A session returns to every point it held (what undo and redo do), including points where
/// a move stopped at a border, and the point it returns to is the one it held: the same
/// coordinates and, within f32 rounding, the same back-projection.
#[test]
fn a_session_returns_to_every_point_it_held() {
    let (c, glossy, bright) = corpus();
    let model = reduce::build_model(&c, 5, Some(2), None).unwrap();
    let opts = NavigatorOptions {
        linear_dim: 5,
        ..Default::default()
    };
    let nav = Navigator::new(&model, Space::Linear, opts).unwrap();
    let (coords, traits) = fitted_traits(&nav, &glossy, &bright);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
    let (mut held, mut borders, mut refused_afresh) = (0, 0, 0);
    for i in 0..c.len() {
        let x: Vec<f64> = coords.row(i).iter().copied().collect();
        let Ok(mut s) = traits::Session::new(&nav, &x) else {
            continue;
        };
        for _ in 0..12 {
            let tv = &traits[rng.gen_range(0..traits.len())];
            let (_, why) = s.nudge(tv, rng.gen_range(-6.0..6.0)).unwrap();
            let at = s.state().clone();
            let back = traits::Session::resume(&nav, &at.coords).unwrap();
            assert_eq!(back.state().coords, at.coords);
            let worst = back
                .state()
                .log
                .iter()
                .zip(&at.log)
                .map(|(a, b)| (a - b).abs())
                .fold(0f32, f32::max);
            assert!(worst < 1e-4, "material {i}: log values differ by {worst}");
            held += 1;
            if why.is_some() {
                borders += 1;
                refused_afresh += usize::from(traits::Session::new(&nav, &at.coords).is_err());
            }
        }
    }
    eprintln!("{held} points held, {borders} at a border, {refused_afresh} of them refused by a fresh start");
    assert!(borders > 0, "no move reached a border");
}
