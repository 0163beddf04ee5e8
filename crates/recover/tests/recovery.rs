//! Recovery on a small synthetic model: exactness in the model's span, the analytic Jacobian,
//! agreement with the renderer, recognition, and the bad-input errors.

mod common;

use std::sync::Arc;

use recover::{Components, FitOptions, Photo, RecoverError, RecoverOptions};
use recover::{EnvSampling, FunctionalOptions, Functionals};
use recover::{LocalModel, Observation, Problem};

fn photo_of(f: &Functionals, rows: &[[f64; 3]]) -> Photo {
    Photo::new(f.width, f.height, f.to_image(rows, None)).unwrap()
}

#[test]
fn material_in_the_span_is_recovered_up_to_noise_and_ranked_by_recognition() {
    let tables = common::corpus_tables();
    for mapping in [reduce::Mapping::Log, reduce::Mapping::COSINE] {
        recovered_in_the_span(&common::mapped_model(&tables, mapping));
    }
}

fn recovered_in_the_span(model: &reduce::Model) {
    // a point inside the span, between two corpus materials
    let x_true: Vec<f64> = (0..5)
        .map(|j| 0.6 * model.pca.coords[(2, j)] + 0.4 * model.pca.coords[(3, j)])
        .collect();
    let truth = recover::synthesize_table(model, &x_true).unwrap();
    let opts = FunctionalOptions::default();
    let mut obs = Vec::new();
    for (i, s) in common::point_light_scenes(40).iter().enumerate() {
        let f = Functionals::build(s, &opts).unwrap();
        let rows = f.apply_table(&truth);
        // 0.5 % multiplicative noise, seeded
        let noisy: Vec<[f64; 3]> = rows
            .iter()
            .enumerate()
            .map(|(r, v)| {
                let u = (((r * 7919 + i * 104729) % 1000) as f64 / 1000.0 - 0.5) * 0.01;
                v.map(|x| x * (1.0 + u))
            })
            .collect();
        let photo = photo_of(&f, &noisy);
        obs.push(Observation::checked(i, f, &photo, None, true).unwrap());
    }
    let rec = recover::recover(
        model,
        &obs,
        &RecoverOptions {
            components: Components::Fixed(5),
            ..Default::default()
        },
    )
    .unwrap();
    let scale: f64 = x_true.iter().map(|v| v * v).sum::<f64>().sqrt();
    let err: f64 = rec
        .fit
        .coefficients
        .iter()
        .zip(&x_true)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(
        err < 0.02 * scale,
        "{:?}: coefficient error {err} of {scale}",
        model.mapping
    );
    assert!(
        rec.fit.residual_rms.iter().all(|&r| r < 0.01),
        "{:?}",
        rec.fit.residual_rms
    );
    assert!(rec
        .fit
        .uncertainty
        .iter()
        .all(|u| u.is_finite() && *u > 0.0));
    let e = recover::cosine_weighted_relative_rms(&truth, &rec.table);
    assert!(e < 0.02, "table error {e}");
    // recognition: the two materials the truth is made of rank first
    let top: Vec<&str> = rec
        .ranking
        .iter()
        .take(2)
        .map(|r| r.name.as_str())
        .collect();
    assert!(top.contains(&"blue-ggx"), "{top:?}");
}

#[test]
fn jacobian_matches_finite_differences() {
    let tables = common::corpus_tables();
    for mapping in [reduce::Mapping::Log, reduce::Mapping::COSINE] {
        jacobian_in(&tables, &common::mapped_model(&tables, mapping));
    }
}

fn jacobian_in(tables: &[(String, brdf::MerlTable)], model: &reduce::Model) {
    let s = &common::point_light_scenes(20)[0];
    let f = Functionals::build(s, &FunctionalOptions::default()).unwrap();
    let rows = f.apply_table(&tables[4].1);
    let photo = photo_of(&f, &rows);
    let obs = vec![Observation::new(f, &photo, None).unwrap()];
    let fs: Vec<&Functionals> = obs.iter().map(|o| &o.functionals).collect();
    let local = LocalModel::new(model, 5, &fs).unwrap();
    let p = Problem::new(&local, &obs, &FitOptions::default()).unwrap();
    let x: Vec<f64> = (0..5)
        .map(|j| 0.5 * model.pca.coords[(2, j)] + 0.2 * model.pca.coords[(4, j)])
        .collect();
    let scale = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    let j = p.jacobian(&x);
    let n = p.residuals(&x).len();
    assert_eq!(j.len(), n * 5);
    let h = 1e-3 * scale;
    let mut worst: f64 = 0.0;
    let mut norm: f64 = 0.0;
    for k in 0..5 {
        let mut a = x.clone();
        let mut b = x.clone();
        a[k] += h;
        b[k] -= h;
        let ra = p.residuals(&a);
        let rb = p.residuals(&b);
        for i in 0..n {
            let fd = (ra[i] - rb[i]) / (2.0 * h);
            worst = worst.max((fd - j[i * 5 + k]).abs());
            norm = norm.max(fd.abs());
        }
    }
    assert!(norm * scale > 0.1, "derivatives vanish: {norm}");
    assert!(
        worst < 2e-3 * norm,
        "max |J − FD| = {worst} (max |FD| = {norm})"
    );
}

#[test]
fn functionals_reproduce_the_renderer_for_tables() {
    // independent of the functional code: the path tracer's direct-light estimate
    let tables = common::corpus_tables();
    let table = &tables[2].1;
    // The relative RMS of two builds' rows against each other, over √2: one build's own
    // Monte Carlo error per pixel.
    let own_error = |a: &[[f64; 3]], b: &[[f64; 3]]| {
        let (mut n, mut d) = (0.0, 0.0);
        for (a, b) in a.iter().zip(b) {
            for c in 0..3 {
                n += (a[c] - b[c]).powi(2);
                d += b[c] * b[c];
            }
        }
        (n / d / 2.0).sqrt()
    };
    let mut own_by_sampling = Vec::new();
    for (lights, sampling) in [
        (
            "[[lights]]\nkind = \"point\"\nposition = [2.0, 2.0, 4.0]\nintensity = [25.0, 25.0, 25.0]",
            EnvSampling::Stratified,
        ),
        ("[environment]\nprocedural = 3", EnvSampling::Independent),
        ("[environment]\nprocedural = 3", EnvSampling::Stratified),
    ] {
        let s = common::sphere_scene(24, lights);
        let opts = FunctionalOptions {
            subpixels: 4,
            env_samples: 512,
            env_sampling: sampling,
            ..Default::default()
        };
        let f = Functionals::build(&s, &opts).unwrap();
        let rows = f.apply_table(table);
        let scene = s.with_material(render::Material::with_importance(
            Arc::new(table.clone()),
            render::ImportanceResolution::default(),
        ));
        let ro = render::RenderOptions {
            spp: 256,
            integrator: render::Integrator::Direct,
            ..Default::default()
        };
        let img = render::render_scene(&scene, &ro).unwrap();
        let (mut num, mut den) = (0.0, 0.0);
        for (p, v) in f.pixels.iter().zip(&rows) {
            let q = img.pixels()[*p as usize];
            for c in 0..3 {
                num += (v[c] - q[c] as f64).powi(2);
                den += (q[c] as f64).powi(2);
            }
        }
        let rel = (num / den).sqrt();
        let bias = rows.iter().map(|v| v[0] + v[1] + v[2]).sum::<f64>()
            / f.pixels
                .iter()
                .map(|p| {
                    img.pixels()[*p as usize]
                        .iter()
                        .map(|&q| q as f64)
                        .sum::<f64>()
                })
                .sum::<f64>();
        let f2 = Functionals::build(
            &s,
            &FunctionalOptions {
                seed: 99,
                ..opts.clone()
            },
        )
        .unwrap();
        let own = own_error(&rows, &f2.apply_table(table));
        eprintln!("{lights} ({sampling:?}): rel {rel} ratio of sums {bias} own MC error {own}");
        assert!((bias - 1.0).abs() < 0.01, "{lights}: ratio of sums {bias}");
        assert!(
            rel < 0.15,
            "{lights}: functional vs renderer relative RMS {rel}"
        );
        if s.scene.environment.is_some() {
            own_by_sampling.push((sampling, own));
        }
    }
    // Stratified samples carry less Monte Carlo error than independent ones, same count.
    let [(_, independent), (_, stratified)] = own_by_sampling[..] else {
        panic!("{own_by_sampling:?}");
    };
    assert!(
        stratified < 0.8 * independent,
        "stratified {stratified} vs independent {independent}"
    );
}

#[test]
fn bad_inputs_give_typed_errors() {
    let tables = common::corpus_tables();
    let s = &common::point_light_scenes(16)[0];
    let f = Functionals::build(s, &FunctionalOptions::default()).unwrap();
    let rows = f.apply_table(&tables[0].1);
    // wrong size
    let small = Photo::new(8, 8, vec![[0.1; 3]; 64]).unwrap();
    assert!(matches!(
        Observation::checked(0, f.clone(), &small, None, true),
        Err(RecoverError::CameraMismatch {
            width: 16,
            got_width: 8,
            ..
        })
    ));
    // dark
    let dark = Photo::new(16, 16, vec![[0.0; 3]; 256]).unwrap();
    assert!(matches!(
        Observation::checked(1, f.clone(), &dark, None, true),
        Err(RecoverError::AllDark { index: 1, .. })
    ));
    // saturated
    let sat = photo_of(&f, &rows.iter().map(|_| [2.0; 3]).collect::<Vec<_>>()).with_saturation(1.0);
    assert!(matches!(
        Observation::checked(2, f.clone(), &sat, None, true),
        Err(RecoverError::AllSaturated { index: 2, .. })
    ));
    // saturated wherever the light reaches, dark in the shadow: still nothing to fit
    let side = &common::point_light_scenes(16)[1];
    let fs = Functionals::build(side, &FunctionalOptions::default()).unwrap();
    let white = fs.white_response();
    let shadow = |r: usize| white[r].iter().sum::<f64>() == 0.0;
    assert!(
        (0..fs.len()).any(shadow),
        "the side light leaves some of the sphere in shadow"
    );
    let burnt: Vec<[f64; 3]> = (0..fs.len())
        .map(|r| if shadow(r) { [0.0; 3] } else { [2.0; 3] })
        .collect();
    let burnt = photo_of(&fs, &burnt).with_saturation(1.0);
    assert!(matches!(
        Observation::checked(4, fs.clone(), &burnt, None, true),
        Err(RecoverError::AllSaturated { index: 4, .. })
    ));
    // over-exposed: the object a million times brighter than its material under these lights
    let bright = photo_of(
        &f,
        &rows.iter().map(|r| r.map(|v| v * 1e6)).collect::<Vec<_>>(),
    );
    assert!(matches!(
        Observation::checked(5, f.clone(), &bright, None, true),
        Err(RecoverError::Overexposed { index: 5, .. })
    ));
    // the pixels used are those fitted: lit, unmasked, unsaturated
    let photo = photo_of(&fs, &fs.apply_table(&tables[0].1));
    let mask: Vec<bool> = (0..photo.pixels.len()).map(|i| i % 2 == 0).collect();
    let obs = Observation::checked(6, fs.clone(), &photo, Some(&mask), true).unwrap();
    let expected = (0..fs.len())
        .filter(|&r| !shadow(r) && mask[fs.pixels[r] as usize])
        .count();
    assert!(expected > 0 && expected < fs.len());
    assert_eq!(obs.fitted_pixels(), expected);
    // the light lies beside the object: a photo of another camera
    let mut shifted = vec![[0.0f32; 3]; 256];
    for (i, p) in shifted.iter_mut().enumerate() {
        if !f.coverage[i] {
            *p = [0.5; 3];
        }
    }
    let shifted = Photo::new(16, 16, shifted).unwrap();
    assert!(matches!(
        Observation::checked(3, f.clone(), &shifted, None, true),
        Err(RecoverError::Silhouette { index: 3, .. })
    ));
    // a model of another grid
    let mut c = reduce::Corpus::new(12);
    c.push_values("a", &[0.1; 12]).unwrap();
    c.push_values("b", &[0.2; 12]).unwrap();
    c.push_values(
        "c",
        &[0.1, 0.3, 0.2, 0.1, 0.3, 0.2, 0.1, 0.3, 0.2, 0.1, 0.3, 0.2],
    )
    .unwrap();
    let tiny = reduce::build_model(&c, 2, None, None).unwrap();
    let good = photo_of(&f, &rows);
    let obs = vec![Observation::checked(0, f.clone(), &good, None, true).unwrap()];
    assert!(matches!(
        recover::recover(&tiny, &obs, &RecoverOptions::default()),
        Err(RecoverError::ModelGrid { got: 12, .. })
    ));
    // a scene without unknown material
    let text = "[camera]\nposition=[0.0,0.0,4.0]\nlook_at=[0.0,0.0,0.0]\nwidth=8\nheight=8\n[materials.m]\nspec=\"lambert:kd=0.5\"\n[[objects]]\nkind=\"sphere\"\ncenter=[0.0,0.0,0.0]\nradius=1.0\nmaterial=\"m\"\n";
    assert!(matches!(
        recover::RecoveryScene::parse(text, std::path::Path::new(".")),
        Err(RecoverError::Scene(_))
    ));
}

#[test]
fn class_names() {
    use recover::class_of;
    assert_eq!(class_of("blue-metallic-paint2"), "paint");
    assert_eq!(class_of("cherry-235"), "wood");
    assert_eq!(class_of("black-oxidized-steel"), "metal");
    assert_eq!(class_of("two-layer-gold"), "metal");
    assert_eq!(class_of("red-specular-plastic"), "plastic");
    assert_eq!(class_of("merl:red-fabric"), "fabric");
}

#[test]
fn table_prior_is_the_per_bin_penalty_over_unobserved_bins() {
    let tables = common::corpus_tables();
    let model = common::model(&tables);
    let s = &common::point_light_scenes(16)[0];
    let f = Functionals::build(s, &FunctionalOptions::default()).unwrap();
    let fs = [&f];
    let k = 4;
    let local = LocalModel::new(&model, k, &fs).unwrap();
    let step = 97;
    let prior = recover::TablePrior::new(&model, &local, step).unwrap();
    // brute force: k / M Σ_b (U x)_b² / v_b over every step-th unobserved bin
    let kk = model.components();
    let nb = brdf::BINS;
    let n = model.names.len() as f64;
    let trunc: f64 =
        model.pca.eigenvalues[kk..].iter().sum::<f64>() / (n - 1.0) / model.pca.dim as f64;
    let x: Vec<f64> = (0..k)
        .map(|j| 0.7 * model.pca.coords[(1, j)] - 0.3 * model.pca.coords[(3, j)])
        .collect();
    let (mut sum, mut m) = (0.0, 0usize);
    for d in (0..3 * nb).step_by(step) {
        if local.local((d % nb) as u32).is_some() {
            continue;
        }
        let u = &model.pca.basis[d * kk..(d + 1) * kk];
        let v: f64 = (0..kk)
            .map(|j| (u[j] as f64).powi(2) * model.pca.eigenvalues[j] / (n - 1.0))
            .sum::<f64>()
            + trunc;
        let dev: f64 = (0..k).map(|j| u[j] as f64 * x[j]).sum();
        sum += dev * dev / v;
        m += 1;
    }
    assert_eq!(m, prior.bins);
    assert!(m > 1000, "{m} bins sampled");
    let brute = k as f64 * sum / m as f64;
    let xv = nalgebra::DVector::from_column_slice(&x);
    let quad = xv.dot(&(&prior.precision * &xv));
    assert!(
        (quad - brute).abs() <= 1e-9 * brute.abs().max(1e-300),
        "xᵀPx = {quad}, brute force {brute}"
    );
    assert!(brute > 0.0);
}

#[test]
fn coarse_to_fine_recovers_what_the_full_fit_does() {
    let tables = common::corpus_tables();
    let model = common::model(&tables);
    let truth = &tables[2].1;
    let s = &common::point_light_scenes(32)[1];
    let f = Functionals::build(s, &FunctionalOptions::default()).unwrap();
    let photo = photo_of(&f, &f.apply_table(truth));
    let obs = vec![Observation::new(f, &photo, None).unwrap()];
    let run = |coarse_rows, refine_iterations| {
        recover::recover(
            &model,
            &obs,
            &RecoverOptions {
                components: Components::Fixed(5),
                coarse_rows,
                refine_iterations,
                ..Default::default()
            },
        )
        .unwrap()
    };
    let rows = obs[0].functionals.len();
    let refine = RecoverOptions::default().refine_iterations;
    let (full, coarse) = (run(0, refine), run(rows / 8, refine));
    // without refinement: the coarse fit's coefficients, scored on all rows
    let unrefined = run(rows / 8, 0);
    assert_eq!(unrefined.fit.iterations, 0);
    assert!(coarse.fit.iterations > 0);
    assert_eq!(unrefined.predictions[0].len(), rows);
    assert_eq!(unrefined.fit.residual_rms.len(), 1);
    assert_eq!(unrefined.ranking[0].name, coarse.ranking[0].name);
    assert_ne!(unrefined.fit.coefficients, coarse.fit.coefficients);
    let e_full = recover::cosine_weighted_relative_rms(truth, &full.table);
    let e_coarse = recover::cosine_weighted_relative_rms(truth, &coarse.table);
    assert!(
        (e_coarse - e_full).abs() < 0.01 + 0.05 * e_full,
        "full {e_full}, coarse-to-fine {e_coarse}"
    );
    assert_eq!(full.ranking[0].name, coarse.ranking[0].name);
}

#[test]
fn constrained_bins_are_the_bins_of_the_usable_pixels() {
    let tables = common::corpus_tables();
    let s = &common::point_light_scenes(16)[0];
    let f = Functionals::build(s, &FunctionalOptions::default()).unwrap();
    let photo = photo_of(&f, &f.apply_table(&tables[0].1));
    let o = Observation::checked(0, f.clone(), &photo, None, true).unwrap();
    let seen = Observation::constrained_bins(std::slice::from_ref(&o));
    // Independently: the bins of the entries of lit rows (one point light: one bin per
    // sub-pixel position).
    let mut want = std::collections::BTreeSet::new();
    for r in 0..f.len() {
        for e in f.row_ptr[r]..f.row_ptr[r + 1] {
            if f.weights[e].iter().any(|&w| w > 0.0) {
                want.insert(f.bins[e] as usize);
            }
        }
    }
    let got: std::collections::BTreeSet<usize> = (0..seen.len()).filter(|&b| seen[b]).collect();
    assert_eq!(got, want);
    assert!(!got.is_empty() && got.len() <= 4 * f.len());
    // A table that differs from the truth only outside them gives the photo exactly.
    let truth = &tables[0].1;
    let mut v = truth.values();
    for c in 0..3 {
        for b in (0..brdf::BINS).filter(|&b| !seen[b]) {
            v[c * brdf::BINS + b] *= 3.0;
        }
    }
    let other = brdf::MerlTable::from_values(v).unwrap();
    assert_eq!(f.apply_table(&other), f.apply_table(truth));
    // Masked out entirely, the photo constrains nothing.
    let none = Observation {
        usable: vec![[false; 3]; o.usable.len()],
        ..o
    };
    assert!(Observation::constrained_bins(&[none]).iter().all(|&b| !b));
}

/// The per-pixel Monte Carlo error of the environment functionals under the shared light
/// probe (a sun), as quantiles of |Δ ln I| between two builds of different seeds, for three
/// corpus materials and both samplers: `BRDF_DATA_DIR=<data> cargo test --release -p recover
/// --test recovery -- --ignored per_pixel --nocapture` (figures in docs/results/recover.md).
#[test]
#[ignore]
fn per_pixel_error_under_the_shared_probe() {
    let probe = brdf::data_dir().join("real/envmap/venice_sunset_1k.exr");
    assert!(
        probe.is_file(),
        "the shared probe is missing at {}",
        probe.display()
    );
    let lights = format!("[environment]\npath = {:?}", probe.display().to_string());
    let s = recover::RecoveryScene::unit_sphere(32, &lights).unwrap();
    for name in ["blue-acrylic", "chrome", "maroon-plastic"] {
        let t = brdf::load(&format!("merl:{name}")).unwrap().tabulate();
        let mut medians = Vec::new();
        for sampling in [EnvSampling::Independent, EnvSampling::Stratified] {
            for n in [64, 256] {
                let o = |seed| FunctionalOptions {
                    env_samples: n,
                    env_sampling: sampling,
                    seed,
                    ..Default::default()
                };
                let (a, b) = (
                    Functionals::build(&s, &o(1)).unwrap(),
                    Functionals::build(&s, &o(2)).unwrap(),
                );
                let (ra, rb) = (a.apply_table(&t), b.apply_table(&t));
                let at: std::collections::HashMap<u32, usize> =
                    b.pixels.iter().enumerate().map(|(i, &p)| (p, i)).collect();
                let mut d: Vec<f64> = Vec::new();
                for (i, p) in a.pixels.iter().enumerate() {
                    if let Some(&j) = at.get(p) {
                        for c in 0..3 {
                            d.push(((ra[i][c] + 1e-3) / (rb[j][c] + 1e-3)).ln().abs());
                        }
                    }
                }
                d.sort_by(f64::total_cmp);
                let q = |p: f64| d[((d.len() - 1) as f64 * p) as usize];
                eprintln!(
                    "{name} {sampling:?} {n}: |Δ ln I| median {:.3} p90 {:.3} p99 {:.3} max {:.2}",
                    q(0.5),
                    q(0.9),
                    q(0.99),
                    q(1.0)
                );
                medians.push(q(0.5));
            }
        }
        // Stratified samples halve the typical pixel's error at least, at either count.
        assert!(
            medians[2] < 0.5 * medians[0] && medians[3] < 0.5 * medians[1],
            "{name}: {medians:?}"
        );
    }
}
