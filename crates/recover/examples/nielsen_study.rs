//! Validation on the 8 Nielsen materials (outside the MERL-trained model), the noise study and
//! the leave-one-in recognition of the corpus. Prints the markdown tables of docs/recover.md.
//!
//! ```text
//! cargo run --release -p recover --example nielsen_study -- MODEL.bin OUT_DIR [--quick]
//! ```
//! `MODEL.bin` comes from `gantry model build --corpus <data>/nbrdf/merl --components 60
//! --chart-dim 0`. Photos are rendered by `render` (direct light); the Mitsuba 3 photos of
//! `tools/recover/` are read from `OUT_DIR/mitsuba/` when present.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use brdf::MerlTable;
use rand::SeedableRng;
use rand_distr::{Distribution, Poisson};
use recover::{cosine_weighted_relative_rms, log_relative_rms};
use recover::{Components, FunctionalOptions, Functionals, Photo, RecoverOptions, RecoveryScene};
use recover::{LocalModel, Observation, Problem};

/// Weight of the table prior (`--table-prior`).
static TABLE_PRIOR: std::sync::OnceLock<f64> = std::sync::OnceLock::new();

/// With `--family combination`: the corpus whose non-negative combination is fitted instead
/// of the PCA coefficients (thesis §6.5).
static COMBINATION_CORPUS: std::sync::OnceLock<reduce::Corpus> = std::sync::OnceLock::new();

/// `--family auto`: choose between the PCA fit and the combination by cross-validation.
static FAMILY_AUTO: std::sync::OnceLock<bool> = std::sync::OnceLock::new();

/// `--family corpus-choice`: whether the combination is used for the point lights ([0]) and
/// the probe ([1]), chosen by recovering corpus materials left out of model and corpus.
static CHOICE: std::sync::OnceLock<[bool; 2]> = std::sync::OnceLock::new();

/// `--family hybrid`: the PCA fit started from the combination.
static FAMILY_HYBRID: std::sync::OnceLock<bool> = std::sync::OnceLock::new();

/// Lighting of a recovery: the three point lights or the probe.
const POINTS: usize = 0;
const PROBE: usize = 1;

const NIELSEN: [&str; 8] = [
    "bindercover",
    "bluebook",
    "cardboard",
    "glossyredpaper",
    "greencloth",
    "notebook",
    "paintedmetal",
    "yellowpaper",
];

fn probe() -> PathBuf {
    brdf::data_dir().join("real/envmap/venice_sunset_1k.exr")
}

fn env_scene(size: usize) -> RecoveryScene {
    let lights = format!("[environment]\npath = {:?}", probe().display().to_string());
    RecoveryScene::unit_sphere(size, &lights).unwrap()
}

fn point_scenes(size: usize) -> Vec<RecoveryScene> {
    [[2.0, 2.0, 4.0], [-3.0, 0.5, 2.5], [0.5, -2.5, 3.0]]
        .iter()
        .map(|p| {
            RecoveryScene::unit_sphere(size, &RecoveryScene::point_light_toml(*p, 25.0)).unwrap()
        })
        .collect()
}

fn render_photo(s: &RecoveryScene, table: &MerlTable, spp: u32, seed: u64) -> Photo {
    let m = render::Material::with_importance(
        Arc::new(table.clone()),
        render::ImportanceResolution::default(),
    );
    let scene = s.with_material(m);
    let ro = render::RenderOptions {
        spp,
        seed,
        integrator: render::Integrator::Direct,
        ..Default::default()
    };
    Photo::from_image(&render::render_scene(&scene, &ro).unwrap())
}

/// Photon noise with `photons` expected counts at the mean object radiance.
fn photon_noise(p: &Photo, f: &Functionals, photons: f64, seed: u64) -> Photo {
    let mean: f64 = f
        .pixels
        .iter()
        .map(|&i| p.pixels[i as usize].iter().map(|&v| v as f64).sum::<f64>() / 3.0)
        .sum::<f64>()
        / f.len() as f64;
    let s = photons / mean;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let pixels = p
        .pixels
        .iter()
        .map(|px| {
            px.map(|v| {
                let lam = (v as f64 * s).max(0.0);
                if lam <= 0.0 {
                    0.0
                } else {
                    (Poisson::new(lam).unwrap().sample(&mut rng) / s) as f32
                }
            })
        })
        .collect();
    Photo::new(p.width, p.height, pixels).unwrap()
}

/// 8-bit sRGB: the 99th-percentile object radiance maps to 1, values above clip.
fn quantise_8bit(p: &Photo, f: &Functionals) -> Photo {
    let mut l: Vec<f32> = f
        .pixels
        .iter()
        .map(|&i| p.pixels[i as usize].iter().fold(0.0f32, |a, &b| a.max(b)))
        .collect();
    let k = l.len() * 99 / 100;
    l.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    let scale = 1.0 / l[k];
    let pixels = p
        .pixels
        .iter()
        .map(|px| {
            px.map(|v| {
                let e = recover::srgb_encode(v * scale);
                recover::srgb_decode((e * 255.0).round() / 255.0) / scale
            })
        })
        .collect();
    Photo::new(p.width, p.height, pixels)
        .unwrap()
        .with_saturation(0.999 / scale)
}

struct Errs {
    cw: f64,
    log: f64,
    secs: f64,
    /// The recovered table.
    table: MerlTable,
    /// The bins the photographs constrain.
    constrained: Vec<bool>,
}

fn errs(truth: &MerlTable, table: &MerlTable, obs: &[Observation], secs: f64) -> Errs {
    Errs {
        cw: cosine_weighted_relative_rms(truth, table),
        log: log_relative_rms(truth, table),
        secs,
        table: table.clone(),
        constrained: Observation::constrained_bins(obs),
    }
}

/// Cosine-weighted errors of the recovery and of the floor over the constrained bins and
/// over the rest, and the number of constrained bins.
fn regions(truth: &MerlTable, floor: &MerlTable, e: &Errs) -> ([f64; 4], usize) {
    use brdf::metrics::cosine_weighted_relative_rms_where as cw;
    let c = &e.constrained;
    (
        [
            cw(truth, &e.table, |b| c[b]),
            cw(truth, floor, |b| c[b]),
            cw(truth, &e.table, |b| !c[b]),
            cw(truth, floor, |b| !c[b]),
        ],
        c.iter().filter(|&&b| b).count(),
    )
}

/// One observation per photo, every pixel used.
fn observations(fs: &[Functionals], photos: &[Photo]) -> Vec<Observation> {
    fs.iter()
        .zip(photos)
        .enumerate()
        .map(|(i, (f, p))| Observation::checked(i, f.clone(), p, None, false).unwrap())
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn run_recovery(
    model: &reduce::Model,
    fs: &[Functionals],
    photos: &[Photo],
    truth: &MerlTable,
    k: usize,
    prior: f64,
    lighting: usize,
) -> Errs {
    let t = Instant::now();
    let obs = observations(fs, photos);
    let auto = FAMILY_AUTO.get().copied().unwrap_or(false);
    let copts = recover::CombinationOptions {
        convex: std::env::var_os("STUDY_CONVEX").is_some(),
        ..Default::default()
    };
    // `--family auto`: the family with the lower held-out residual over pixel blocks.
    if auto {
        let folds = recover::block_folds(&obs);
        let c = COMBINATION_CORPUS.get().expect("corpus");
        let comb = recover::cross_validate_combination(c, &obs, &copts, &folds).unwrap();
        let pca = recover::recover(
            model,
            &obs,
            &RecoverOptions {
                components: Components::CrossValidate(vec![k]),
                fit: recover::FitOptions {
                    prior_weight: prior,
                    ..Default::default()
                },
                ..Default::default()
            },
        )
        .unwrap();
        let p = pca.cross_validation[0].held_out;
        eprintln!("  held out: pca {p:.4}, combination {comb:.4}");
        if p <= comb {
            return errs(truth, &pca.table, &obs, t.elapsed().as_secs_f64());
        }
    }
    // `--family hybrid`: the PCA fit started from the combination's projection.
    if let (true, Some(corpus)) = (
        FAMILY_HYBRID.get().copied().unwrap_or(false),
        COMBINATION_CORPUS.get(),
    ) {
        let found = recover::fit_combination(corpus, &obs, &copts).unwrap();
        let start = model.project_values(&found.table.values(), k).unwrap();
        let fs_ref: Vec<&Functionals> = obs.iter().map(|o| &o.functionals).collect();
        let local = LocalModel::new(model, k, &fs_ref).unwrap();
        let fopts = recover::FitOptions {
            prior_weight: prior,
            ..Default::default()
        };
        let problem = Problem::new(&local, &obs, &fopts).unwrap();
        let fit = problem.fit(&start, &fopts).unwrap();
        let table = recover::synthesize_table(model, &fit.coefficients).unwrap();
        let start_table = recover::synthesize_table(model, &start).unwrap();
        eprintln!(
            "  hybrid: start {:.4}, fitted {:.4} (cos-w.)",
            cosine_weighted_relative_rms(truth, &start_table),
            cosine_weighted_relative_rms(truth, &table)
        );
        return errs(truth, &table, &obs, t.elapsed().as_secs_f64());
    }
    let combine = match CHOICE.get() {
        Some(choice) => choice[lighting],
        None => COMBINATION_CORPUS.get().is_some(),
    };
    if let (true, Some(corpus)) = (combine, COMBINATION_CORPUS.get()) {
        let found = recover::fit_combination(corpus, &obs, &copts).unwrap();
        let secs = t.elapsed().as_secs_f64();
        eprintln!(
            "  combination of {:?}",
            found
                .used(corpus.names())
                .iter()
                .take(6)
                .map(|(n, c)| format!("{n} {c:.3}"))
                .collect::<Vec<_>>()
        );
        return errs(truth, &found.table, &obs, secs);
    }
    let rec = recover::recover(
        model,
        &obs,
        &RecoverOptions {
            components: Components::Fixed(k),
            fit: recover::FitOptions {
                prior_weight: prior,
                table_prior: TABLE_PRIOR.get().copied().unwrap_or(0.0),
                ..Default::default()
            },
            ..Default::default()
        },
    )
    .unwrap();
    let secs = t.elapsed().as_secs_f64();
    errs(truth, &rec.table, &obs, secs)
}

/// A comma-separated list after flag `name`, or `default`.
fn list<T: std::str::FromStr + Clone>(args: &[String], name: &str, default: &[T]) -> Vec<T> {
    match flag::<String>(args, name) {
        Some(v) => v
            .split(',')
            .map(|x| {
                x.parse()
                    .unwrap_or_else(|_| panic!("{name}: cannot read {x:?}"))
            })
            .collect(),
        None => default.to_vec(),
    }
}

/// A prior weight as the sweep's tables print it: `cv` where it is chosen per photo set.
fn prior_label(prior: f64) -> String {
    if prior.is_nan() {
        "cv".into()
    } else {
        prior.to_string()
    }
}

/// One setting of the sweep: components, prior weight `τ` (NaN: chosen by cross-validation
/// over pixel blocks among `--sweep-cv-prior`), refinement iterations.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Variant {
    k: usize,
    prior: f64,
    refine: usize,
}

/// `--sweep`: every variant on the same photos of every material (rendered once per photo
/// seed), and the variant chosen by nested leave-one-material-out selection: for each
/// material, the variant with the lowest mean error ratio over the *other* materials (all
/// their seeds), scored on the one left out. Writes `OUT_DIR/sweep.tsv` (every recovery) and
/// prints the tables of docs/results/recover.md.
fn sweep(model: &reduce::Model, args: &[String], out: &std::path::Path, quick: bool) {
    let ks = list(args, "--sweep-k", &[45usize]);
    let priors = list(args, "--sweep-prior", &[1.0f64]);
    let refines = list(
        args,
        "--sweep-refine",
        &[RecoverOptions::default().refine_iterations],
    );
    let seeds = list(args, "--sweep-seeds", &[1u64]);
    let materials: Vec<String> = flag::<String>(args, "--materials")
        .map(|m| m.split(',').map(str::to_string).collect())
        .unwrap_or_else(|| NIELSEN.iter().map(|s| s.to_string()).collect());
    let (env_size, pt_size) = if quick { (128, 96) } else { (256, 128) };
    let env = env_scene(flag(args, "--env-size").unwrap_or(env_size));
    let pts = point_scenes(pt_size);
    let fopts = FunctionalOptions::default();
    let env_f = Functionals::build(&env, &fopts).unwrap();
    let pt_f: Vec<Functionals> = pts
        .iter()
        .map(|s| Functionals::build(s, &fopts).unwrap())
        .collect();
    let mut variants = Vec::new();
    let cv = flag::<String>(args, "--sweep-cv-prior").is_some();
    for &k in &ks {
        for &prior in priors.iter().chain(cv.then_some(&f64::NAN)) {
            for &refine in &refines {
                variants.push(Variant { k, prior, refine });
            }
        }
    }
    // Refinement only happens above twice the coarse row count: below it, variants that
    // differ only in `refine` are the same recovery, made once.
    let coarse = flag(args, "--coarse-rows").unwrap_or(RecoverOptions::default().coarse_rows);
    let refines_at = |rows: usize| rows > 2 * coarse;
    let pt_rows: usize = pt_f.iter().map(|f| f.len()).sum();
    eprintln!(
        "sweep: {} variants × {} seeds; probe {} rows (refined: {}), points {} rows (refined: {})",
        variants.len(),
        seeds.len(),
        env_f.len(),
        refines_at(env_f.len()),
        pt_rows,
        refines_at(pt_rows)
    );
    // A variant with a NaN prior weight chooses it per photo set, among `--sweep-cv-prior`,
    // by the held-out residual of the cross-validation over 8 × 8 pixel blocks (the choice
    // `recover` makes for k); its table is the recovery with the chosen weight.
    let cv_priors = list(args, "--sweep-cv-prior", &[] as &[f64]);
    let recover_with = |fs: &[Functionals], photos: &[Photo], v: Variant| -> MerlTable {
        let obs = observations(fs, photos);
        let run = |prior: f64, components: Components| {
            recover::recover(
                model,
                &obs,
                &RecoverOptions {
                    components,
                    fit: recover::FitOptions {
                        prior_weight: prior,
                        ..Default::default()
                    },
                    refine_iterations: v.refine,
                    coarse_rows: coarse,
                    ..Default::default()
                },
            )
            .unwrap()
        };
        if !v.prior.is_nan() {
            return run(v.prior, Components::Fixed(v.k)).table;
        }
        let (held, prior, rec) = cv_priors
            .iter()
            .map(|&prior| {
                let rec = run(prior, Components::CrossValidate(vec![v.k]));
                (rec.cross_validation[0].held_out, prior, rec)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .expect("--sweep-cv-prior lists the candidate weights");
        eprintln!("  prior chosen by cross-validation: {prior} (held out {held:.4})");
        rec.table
    };
    // ratio[lighting][material][seed][variant]: error over the 45-component floor
    let mut ratio =
        vec![vec![vec![vec![f64::NAN; variants.len()]; seeds.len()]; materials.len()]; 2];
    let mut tsv = String::from(
        "material\tseed\tlighting\tk\tprior\trefine\tcosine_weighted\tfloor_45\tratio\n",
    );
    for (mi, name) in materials.iter().enumerate() {
        let t = Instant::now();
        let truth = brdf::load(&format!("nielsen:{name}")).unwrap().tabulate();
        let floor =
            MerlTable::from_values(model.reconstruct_values(&truth.values(), 45).unwrap()).unwrap();
        let floor = cosine_weighted_relative_rms(&truth, &floor);
        for (si, &seed) in seeds.iter().enumerate() {
            // seed 1 (and 2 for the points) are the photos of the main study
            let pt_photos: Vec<Photo> = pts
                .iter()
                .map(|s| render_photo(s, &truth, 4, seed + 1))
                .collect();
            let env_photo = render_photo(&env, &truth, if quick { 16 } else { 32 }, seed);
            for lighting in [PROBE, POINTS] {
                let (fs, photos, rows) = if lighting == PROBE {
                    (
                        std::slice::from_ref(&env_f),
                        std::slice::from_ref(&env_photo),
                        env_f.len(),
                    )
                } else {
                    (&pt_f[..], &pt_photos[..], pt_rows)
                };
                for (vi, &v) in variants.iter().enumerate() {
                    let same = (!refines_at(rows))
                        .then(|| {
                            variants[..vi]
                                .iter()
                                .position(|w| w.k == v.k && w.prior == v.prior)
                        })
                        .flatten();
                    let r = if let Some(wi) = same {
                        ratio[lighting][mi][si][wi]
                    } else {
                        let table = recover_with(fs, photos, v);
                        let cw = cosine_weighted_relative_rms(&truth, &table);
                        tsv.push_str(&format!(
                            "{name}\t{seed}\t{}\t{}\t{}\t{}\t{cw:.6}\t{floor:.6}\t{:.6}\n",
                            if lighting == PROBE { "probe" } else { "points" },
                            v.k,
                            prior_label(v.prior),
                            v.refine,
                            cw / floor
                        ));
                        cw / floor
                    };
                    ratio[lighting][mi][si][vi] = r;
                }
            }
        }
        eprintln!("{name}: {:.0} s", t.elapsed().as_secs_f64());
    }
    let tmp = out.join("sweep.tsv.tmp");
    std::fs::write(&tmp, &tsv).unwrap();
    std::fs::rename(&tmp, out.join("sweep.tsv")).unwrap();
    let default = RecoverOptions::default();
    let default_v = variants.iter().position(|v| {
        v.k == 45 && v.prior == default.fit.prior_weight && v.refine == default.refine_iterations
    });
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    for (lighting, label) in [(PROBE, "probe"), (POINTS, "3 points")] {
        let r = &ratio[lighting];
        // per material and variant: mean over the seeds, and the range
        let per: Vec<Vec<f64>> = r
            .iter()
            .map(|m| {
                (0..variants.len())
                    .map(|vi| mean(&m.iter().map(|s| s[vi]).collect::<Vec<_>>()))
                    .collect()
            })
            .collect();
        println!(
            "\n{label}: error / 45-component floor per variant (k, τ, refinement iterations), \
             mean over {} photo seed(s) [range]\n",
            seeds.len()
        );
        print!("| material |");
        for v in &variants {
            print!(" {}, {}, {} |", v.k, prior_label(v.prior), v.refine);
        }
        println!();
        println!("|---|{}", "---|".repeat(variants.len()));
        for (mi, name) in materials.iter().enumerate() {
            print!("| {name} |");
            for vi in 0..variants.len() {
                let s: Vec<f64> = r[mi].iter().map(|s| s[vi]).collect();
                let lo = s.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = s.iter().copied().fold(0.0, f64::max);
                if s.len() > 1 {
                    print!(" {:.2} [{lo:.2}–{hi:.2}] |", per[mi][vi]);
                } else {
                    print!(" {:.2} |", per[mi][vi]);
                }
            }
            println!();
        }
        print!("| **mean** |");
        let means: Vec<f64> = (0..variants.len())
            .map(|vi| mean(&per.iter().map(|m| m[vi]).collect::<Vec<_>>()))
            .collect();
        for m in &means {
            print!(" **{m:.2}** |");
        }
        println!();
        // nested: the choice is made without the material it is scored on
        let mut held = Vec::new();
        println!(
            "\n| left out | chosen on the other materials (k, τ, refinement) | its error / floor |"
        );
        println!("|---|---|---|");
        for (mi, name) in materials.iter().enumerate() {
            let score = |vi: usize| {
                mean(
                    &(0..materials.len())
                        .filter(|&o| o != mi)
                        .map(|o| per[o][vi])
                        .collect::<Vec<_>>(),
                )
            };
            let best = (0..variants.len())
                .min_by(|&a, &b| score(a).total_cmp(&score(b)))
                .expect("variants");
            let v = variants[best];
            held.push(per[mi][best]);
            println!(
                "| {name} | {}, {}, {} | {:.2} |",
                v.k,
                prior_label(v.prior),
                v.refine,
                per[mi][best]
            );
        }
        println!(
            "| **mean** | | **{:.2}** (the default setting: {}) |",
            mean(&held),
            default_v.map_or("not in the sweep".into(), |d| format!("{:.2}", means[d]))
        );
    }
}

/// The value after flag `name`, parsed.
fn flag<T: std::str::FromStr>(args: &[String], name: &str) -> Option<T> {
    let i = args.iter().position(|a| a == name)?;
    args.get(i + 1).and_then(|v| v.parse().ok())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!(
            "usage: nielsen_study MODEL.bin OUT_DIR [--quick] [--recognition-only] [--no-recognition] \
             [--no-noise] [--materials a,b,..] [--env-samples N] [--env-size N] [--prior TAU] [--k K] \
             [--family pca|combination|auto|corpus-choice|hybrid] [--choice-materials N] \
             [--env-sampling stratified|independent] [--write-tables] \
             [--sweep [--sweep-k 10,45] [--sweep-prior 0.25,1] [--sweep-refine 0,25] [--sweep-seeds 1,2,3] [--sweep-cv-prior 0.3,1,3] [--coarse-rows N]]"
        );
        std::process::exit(2);
    }
    let quick = args.iter().any(|a| a == "--quick");
    let has = |f: &str| args.iter().any(|a| a == f);
    let out = PathBuf::from(&args[2]);
    std::fs::create_dir_all(&out).unwrap();
    let t = Instant::now();
    let model = reduce::Model::load(&args[1]).expect("model");
    eprintln!("model loaded in {:.1} s", t.elapsed().as_secs_f64());
    if has("--recognition-only") {
        recognition(&model, quick);
        return;
    }
    if has("--sweep") {
        sweep(&model, &args, &out, quick);
        return;
    }
    let k: usize = flag(&args, "--k").unwrap_or(45);
    let family = flag::<String>(&args, "--family");
    FAMILY_AUTO.set(family.as_deref() == Some("auto")).ok();
    FAMILY_HYBRID.set(family.as_deref() == Some("hybrid")).ok();
    if matches!(
        family.as_deref(),
        Some("combination" | "auto" | "corpus-choice" | "hybrid")
    ) {
        let t = Instant::now();
        let corpus =
            reduce::Corpus::from_nbrdf_dir(brdf::data_dir().join("nbrdf/merl")).expect("corpus");
        eprintln!(
            "corpus of {} materials loaded in {:.1} s",
            corpus.len(),
            t.elapsed().as_secs_f64()
        );
        COMBINATION_CORPUS.set(corpus).ok();
    }
    let prior: f64 = flag(&args, "--prior").unwrap_or(1.0);
    TABLE_PRIOR
        .set(flag(&args, "--table-prior").unwrap_or(0.0))
        .unwrap();
    let (env_size, pt_size) = if quick { (128, 96) } else { (256, 128) };
    let env_size = flag(&args, "--env-size").unwrap_or(env_size);
    let env = env_scene(env_size);
    let pts = point_scenes(pt_size);
    let fopts = FunctionalOptions::default();
    let env_fopts = FunctionalOptions {
        env_samples: flag(&args, "--env-samples").unwrap_or(fopts.env_samples),
        env_sampling: env_sampling(&args),
        ..fopts.clone()
    };
    let materials: Vec<String> = flag::<String>(&args, "--materials")
        .map(|m| m.split(',').map(str::to_string).collect())
        .unwrap_or_else(|| NIELSEN.iter().map(|s| s.to_string()).collect());
    let t = Instant::now();
    let env_f = Functionals::build(&env, &env_fopts).unwrap();
    let env_build = t.elapsed().as_secs_f64();
    let pt_f: Vec<Functionals> = pts
        .iter()
        .map(|s| Functionals::build(s, &fopts).unwrap())
        .collect();
    eprintln!(
        "env functionals: {} rows, {} entries, {:.1} s",
        env_f.len(),
        env_f.bins.len(),
        env_build
    );
    if family.as_deref() == Some("corpus-choice") {
        let corpus = COMBINATION_CORPUS.get().expect("corpus");
        let n = flag(&args, "--choice-materials").unwrap_or(8);
        let choice = choose_on_corpus(corpus, n, &env, &pts, &env_f, &pt_f, k, prior);
        CHOICE.set(choice).ok();
    }
    let mut main_rows = Vec::new();
    let mut region_rows = Vec::new();
    let mut mitsuba_rows = Vec::new();
    let mut noise_rows = Vec::new();
    let mut times = Vec::new();
    let mitsuba = out.join("mitsuba");
    for name in &materials {
        let truth = brdf::load(&format!("nielsen:{name}")).unwrap().tabulate();
        let floor =
            MerlTable::from_values(model.reconstruct_values(&truth.values(), k).unwrap()).unwrap();
        let fl = (
            cosine_weighted_relative_rms(&truth, &floor),
            log_relative_rms(&truth, &floor),
        );
        let pt_photos: Vec<Photo> = pts.iter().map(|s| render_photo(s, &truth, 4, 2)).collect();
        let e_pt = run_recovery(&model, &pt_f, &pt_photos, &truth, k, prior, POINTS);
        if has("--no-env") {
            eprintln!(
                "{name}: floor {:.4}/{:.4} points {:.4}/{:.4} ({:.1} s) ratio {:.2}",
                fl.0,
                fl.1,
                e_pt.cw,
                e_pt.log,
                e_pt.secs,
                e_pt.cw / fl.0
            );
            main_rows.push((name, fl, f64::NAN, f64::NAN, e_pt.cw, e_pt.log));
            region_rows.push((name, "3 points", regions(&truth, &floor, &e_pt)));
            continue;
        }
        let env_photo = render_photo(&env, &truth, if quick { 16 } else { 32 }, 1);
        let e_env = run_recovery(
            &model,
            std::slice::from_ref(&env_f),
            std::slice::from_ref(&env_photo),
            &truth,
            k,
            prior,
            PROBE,
        );
        times.push(e_env.secs + env_build);
        eprintln!(
            "{name}: floor {:.4}/{:.4} env {:.4}/{:.4} ({:.1} s) points {:.4}/{:.4} ({:.1} s)",
            fl.0, fl.1, e_env.cw, e_env.log, e_env.secs, e_pt.cw, e_pt.log, e_pt.secs
        );
        if has("--write-tables") {
            // The recovered tables, for inspection (`gantry info`, `gantry compare`).
            for (what, e) in [("probe", &e_env), ("points", &e_pt)] {
                let path = out.join(format!("{name}-{what}.binary"));
                brdf::merl::write(&path, &e.table).unwrap();
            }
        }
        main_rows.push((name, fl, e_env.cw, e_env.log, e_pt.cw, e_pt.log));
        region_rows.push((name, "probe", regions(&truth, &floor, &e_env)));
        region_rows.push((name, "3 points", regions(&truth, &floor, &e_pt)));
        // The same recoveries from Mitsuba 3's photos (tools/recover/mitsuba_render.py --study).
        if let Some((m_env, m_pts)) = mitsuba_photos(&mitsuba, name, &env_f, &pt_f) {
            let me = run_recovery(
                &model,
                std::slice::from_ref(&env_f),
                std::slice::from_ref(&m_env),
                &truth,
                k,
                prior,
                PROBE,
            );
            let mp = run_recovery(&model, &pt_f, &m_pts, &truth, k, prior, POINTS);
            eprintln!(
                "{name} (Mitsuba photos): env {:.4} ({:.2}×) points {:.4} ({:.2}×)",
                me.cw,
                me.cw / fl.0,
                mp.cw,
                mp.cw / fl.0
            );
            mitsuba_rows.push((name, fl, me.cw, mp.cw));
        }
        // noise study on the environment image (first three materials: each costs three fits)
        if noise_rows.len() >= 3 || has("--no-noise") {
            continue;
        }
        let mut nr = vec![];
        for photons in [1000.0, 100.0] {
            let p = photon_noise(&env_photo, &env_f, photons, 7);
            let e = run_recovery(
                &model,
                std::slice::from_ref(&env_f),
                &[p],
                &truth,
                k,
                prior,
                PROBE,
            );
            nr.push(e.cw / fl.0);
        }
        let q = quantise_8bit(&env_photo, &env_f);
        let e = run_recovery(
            &model,
            std::slice::from_ref(&env_f),
            &[q],
            &truth,
            k,
            prior,
            PROBE,
        );
        nr.push(e.cw / fl.0);
        noise_rows.push((name, e_env.cw / fl.0, nr));
    }
    println!("\n| material | floor (cos-w.) | env (cos-w.) | env / floor | 3 points (cos-w.) | points / floor | floor (log) | env (log) | points (log) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let (mut se, mut sp) = (0.0, 0.0);
    for (n, fl, ec, el, pc, pl) in &main_rows {
        println!(
            "| {n} | {:.4} | {:.4} | {:.2} | {:.4} | {:.2} | {:.4} | {:.4} | {:.4} |",
            fl.0,
            ec,
            ec / fl.0,
            pc,
            pc / fl.0,
            fl.1,
            el,
            pl
        );
        se += ec / fl.0;
        sp += pc / fl.0;
    }
    println!(
        "| **mean ratio** | | | **{:.2}** | | **{:.2}** | | | |",
        se / main_rows.len() as f64,
        sp / main_rows.len() as f64
    );
    if !mitsuba_rows.is_empty() {
        println!("\nPhotos by Mitsuba 3 through the plugin (`tools/recover/mitsuba_render.py --study OUT_DIR`):\n");
        println!("| material | floor (cos-w.) | env (cos-w.) | env / floor | 3 points (cos-w.) | points / floor |");
        println!("|---|---|---|---|---|---|");
        let (mut se, mut sp) = (0.0, 0.0);
        for (n, fl, ec, pc) in &mitsuba_rows {
            println!(
                "| {n} | {:.4} | {:.4} | {:.2} | {:.4} | {:.2} |",
                fl.0,
                ec,
                ec / fl.0,
                pc,
                pc / fl.0
            );
            se += ec / fl.0;
            sp += pc / fl.0;
        }
        let n = mitsuba_rows.len() as f64;
        println!(
            "| **mean ratio** | | | **{:.2}** | | **{:.2}** |",
            se / n,
            sp / n
        );
    }
    println!("\nWhere the error lives (cosine-weighted relative RMS over the bins the photos constrain and over the rest):\n");
    println!("| material | light | bins constrained | constrained: recovered | constrained: floor | ratio | rest: recovered | rest: floor | ratio |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (n, light, (r, count)) in &region_rows {
        println!(
            "| {n} | {light} | {count} | {:.4} | {:.4} | {:.2} | {:.4} | {:.4} | {:.2} |",
            r[0],
            r[1],
            r[0] / r[1],
            r[2],
            r[3],
            r[2] / r[3]
        );
    }
    for light in ["probe", "3 points"] {
        let rs: Vec<_> = region_rows.iter().filter(|r| r.1 == light).collect();
        if rs.is_empty() {
            continue;
        }
        let m = |i: usize, j: usize| {
            rs.iter().map(|r| r.2 .0[i] / r.2 .0[j]).sum::<f64>() / rs.len() as f64
        };
        println!(
            "| **mean ratio** | {light} | | | | **{:.2}** | | | **{:.2}** |",
            m(0, 1),
            m(2, 3)
        );
    }
    println!("\n| material | noise-free | 1000 photons | 100 photons | 8-bit sRGB |");
    println!("|---|---|---|---|---|");
    let mut sums = [0.0; 4];
    let nn = noise_rows.len().max(1) as f64;
    for (n, base, nr) in &noise_rows {
        println!(
            "| {n} | {:.2} | {:.2} | {:.2} | {:.2} |",
            base, nr[0], nr[1], nr[2]
        );
        sums[0] += base;
        for i in 0..3 {
            sums[i + 1] += nr[i];
        }
    }
    println!(
        "| **mean** | {:.2} | {:.2} | {:.2} | {:.2} |",
        sums[0] / nn,
        sums[1] / nn,
        sums[2] / nn,
        sums[3] / nn
    );
    let tm = times.iter().sum::<f64>() / times.len() as f64;
    println!("\nmean time of one env-map recovery (functionals + fit): {tm:.1} s");
    if !has("--no-recognition") {
        recognition(&model, quick);
    }
}

/// Chooses, for the point lights and for the probe, the family with the lower mean table
/// error (cosine-weighted, over the floor) on `n` corpus materials, each recovered from its
/// own rendered photos with a model and a corpus that leave it out. Nothing of the materials
/// the study then scores is used.
#[allow(clippy::too_many_arguments)]
fn choose_on_corpus(
    corpus: &reduce::Corpus,
    n: usize,
    env: &RecoveryScene,
    pts: &[RecoveryScene],
    env_f: &Functionals,
    pt_f: &[Functionals],
    k: usize,
    prior: f64,
) -> [bool; 2] {
    let mut sums = [[0.0f64; 2]; 2];
    eprintln!(
        "choosing the family on {n} corpus materials (ratios to the floor, PCA / combination):"
    );
    for j in 0..n {
        let i = j * corpus.len() / n;
        let t = Instant::now();
        let mut rest = reduce::Corpus::new(corpus.dim());
        for m in (0..corpus.len()).filter(|&m| m != i) {
            rest.push_log(corpus.names()[m].clone(), corpus.row(m))
                .unwrap();
        }
        let model = reduce::build_model(&rest, 60, None, None).unwrap();
        let values: Vec<f64> = corpus
            .row(i)
            .iter()
            .map(|&y| reduce::from_log(y).max(0.0))
            .collect();
        let truth = MerlTable::from_values(values).unwrap();
        let floor =
            MerlTable::from_values(model.reconstruct_values(&truth.values(), k).unwrap()).unwrap();
        let floor = cosine_weighted_relative_rms(&truth, &floor);
        let pt_photos: Vec<Photo> = pts.iter().map(|s| render_photo(s, &truth, 4, 2)).collect();
        let env_photo = render_photo(env, &truth, 32, 1);
        let mut line = format!("  {}:", corpus.names()[i]);
        for (lighting, (fs, photos)) in [
            (pt_f, pt_photos),
            (std::slice::from_ref(env_f), vec![env_photo]),
        ]
        .into_iter()
        .enumerate()
        {
            let obs: Vec<Observation> = fs
                .iter()
                .zip(&photos)
                .enumerate()
                .map(|(o, (f, p))| Observation::checked(o, f.clone(), p, None, false).unwrap())
                .collect();
            let pca = recover::recover(
                &model,
                &obs,
                &RecoverOptions {
                    components: Components::Fixed(k),
                    fit: recover::FitOptions {
                        prior_weight: prior,
                        ..Default::default()
                    },
                    ..Default::default()
                },
            )
            .unwrap();
            let comb =
                recover::fit_combination(&rest, &obs, &recover::CombinationOptions::default())
                    .unwrap();
            let r = [
                cosine_weighted_relative_rms(&truth, &pca.table) / floor,
                cosine_weighted_relative_rms(&truth, &comb.table) / floor,
            ];
            sums[lighting][0] += r[0];
            sums[lighting][1] += r[1];
            line += &format!(
                " {} {:.2} / {:.2}",
                ["points", "probe"][lighting],
                r[0],
                r[1]
            );
        }
        eprintln!("{line} ({:.0} s)", t.elapsed().as_secs_f64());
    }
    let choice = [sums[0][1] < sums[0][0], sums[1][1] < sums[1][0]];
    eprintln!(
        "mean ratios: points {:.2} / {:.2}, probe {:.2} / {:.2}: points use {}, the probe {}",
        sums[0][0] / n as f64,
        sums[0][1] / n as f64,
        sums[1][0] / n as f64,
        sums[1][1] / n as f64,
        if choice[0] {
            "the combination"
        } else {
            "the PCA fit"
        },
        if choice[1] {
            "the combination"
        } else {
            "the PCA fit"
        },
    );
    choice
}

/// Mitsuba's photos of material `name` in `dir` (`NAME-probe.exr`, `NAME-point{0,1,2}.exr`),
/// when all four are there with the sizes of the study's functionals.
fn mitsuba_photos(
    dir: &std::path::Path,
    name: &str,
    env_f: &Functionals,
    pt_f: &[Functionals],
) -> Option<(Photo, Vec<Photo>)> {
    let read = |file: String, f: &Functionals| -> Option<Photo> {
        let path = dir.join(file);
        if !path.exists() {
            return None;
        }
        let p = Photo::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        if (p.width, p.height) != (f.width, f.height) {
            eprintln!(
                "{}: {}×{}, the study's scene is {}×{}; skipped",
                path.display(),
                p.width,
                p.height,
                f.width,
                f.height
            );
            return None;
        }
        Some(p)
    };
    let env = read(format!("{name}-probe.exr"), env_f)?;
    let pts = pt_f
        .iter()
        .enumerate()
        .map(|(i, f)| read(format!("{name}-point{i}.exr"), f))
        .collect::<Option<Vec<_>>>()?;
    Some((env, pts))
}

/// `--env-sampling independent` (the earlier sampler) or stratified (the default).
fn env_sampling(args: &[String]) -> recover::EnvSampling {
    match flag::<String>(args, "--env-sampling").as_deref() {
        Some("independent") => recover::EnvSampling::Independent,
        Some("stratified") | None => recover::EnvSampling::Stratified,
        Some(other) => panic!("--env-sampling {other}: independent or stratified"),
    }
}

fn recognition(model: &reduce::Model, quick: bool) {
    let size = if quick { 48 } else { 64 };
    let s = env_scene(size);
    let args: Vec<String> = std::env::args().collect();
    let defaults = FunctionalOptions::default();
    let build = |seed| {
        Functionals::build(
            &s,
            &FunctionalOptions {
                seed,
                env_sampling: env_sampling(&args),
                env_samples: flag(&args, "--env-samples").unwrap_or(defaults.env_samples),
                ..defaults.clone()
            },
        )
        .unwrap()
    };
    // photos through functionals A, recognition through functionals B (independent MC)
    let (fa, fb) = (build(11), build(12));
    let names = model.names.clone();
    let t = Instant::now();
    let mut photos = Vec::new();
    let mut through_b = Vec::new();
    for n in &names {
        let tab = brdf::load(&format!("merl:{n}")).unwrap().tabulate();
        photos.push(
            Photo::new(
                fa.width,
                fa.height,
                fa.to_image(&fa.apply_table(&tab), None),
            )
            .unwrap(),
        );
        through_b.push(fb.apply_table(&tab));
        if photos.len().is_multiple_of(16) {
            eprintln!("recognition: {} tables ({:.0} s)", photos.len(), t0(&t));
        }
    }
    let fs = [&fb];
    let local1 = LocalModel::new(model, 1, &fs).unwrap();
    let local45 = LocalModel::new(model, 45, &fs).unwrap();
    let cls: Vec<&str> = names.iter().map(|n| recover::class_of(n)).collect();
    let n = names.len();
    let (mut first, mut first45, mut share1, mut share3, mut chance) = (0, 0, 0, 0, 0.0);
    let (mut multi, mut share1_multi) = (0, 0);
    let mut misses = Vec::new();
    for i in 0..n {
        let obs = vec![Observation::new(fb.clone(), &photos[i], None).unwrap()];
        let p = Problem::new(&local1, &obs, &Default::default()).unwrap();
        let mut r: Vec<(usize, f64)> = (0..n)
            .map(|j| (j, p.rms_of(&[through_b[j].clone()])[0]))
            .collect();
        r.sort_by(|a, b| a.1.total_cmp(&b.1));
        if r[0].0 == i {
            first += 1;
        } else {
            let pos = r.iter().position(|x| x.0 == i).unwrap();
            misses.push(format!(
                "{} (rank {}, first {})",
                names[i],
                pos + 1,
                names[r[0].0]
            ));
        }
        let p45 = Problem::new(&local45, &obs, &Default::default()).unwrap();
        let r45 = recover::rank_model_corpus(&p45, model, &local45);
        if r45[0].name == names[i] {
            first45 += 1;
        }
        let others: Vec<usize> = r.iter().map(|x| x.0).filter(|&j| j != i).take(3).collect();
        let same = (0..n).filter(|&j| j != i && cls[j] == cls[i]).count();
        chance += same as f64 / (n - 1) as f64;
        if cls[others[0]] == cls[i] {
            share1 += 1;
        }
        if others.iter().any(|&j| cls[j] == cls[i]) {
            share3 += 1;
        }
        if same > 0 {
            multi += 1;
            if cls[others[0]] == cls[i] {
                share1_multi += 1;
            }
        }
    }
    let mut classes: Vec<&str> = cls.clone();
    classes.sort();
    classes.dedup();
    println!(
        "\nrecognition ({size}² probe images, {n} materials, {} classes, {:.0} s): full tables ranked first {first}/{n}; \
         45-component representations ranked first {first45}/{n}; nearest other material shares the class \
         {share1}/{n} (chance {:.1}/{n}; {share1_multi}/{multi} of the materials whose class has another member); \
         one of the 3 nearest shares it {share3}/{n}",
        classes.len(),
        t0(&t),
        chance,
    );
    for m in misses {
        println!("  not first: {m}");
    }
}

fn t0(t: &Instant) -> f64 {
    t.elapsed().as_secs_f64()
}
