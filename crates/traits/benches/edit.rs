//! Timing of validity-checked edits on the shared 96-material model: an editor slider move
//! (`Session::nudge`) with its lit-sphere preview, an edit from scratch in each space.
//!
//! `cargo bench -p traits --bench edit` (model from `TRAITS_MODEL`, default
//! `target/traits-data/model.bin`, built by
//! `gantry model build --corpus $BRDF_DATA_DIR/nbrdf/merl --out model.bin`). Prints medians.

use std::time::Instant;

use traits::thesis_labels;
use traits::SetFit;
use traits::SpherePreview;
use traits::{FitOptions, Method};
use traits::{Navigator, NavigatorOptions, Space};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn time<T>(n: usize, mut f: impl FnMut(usize) -> T) -> (f64, T) {
    let mut ts = Vec::with_capacity(n);
    let mut last = None;
    for i in 0..n {
        let t = Instant::now();
        last = Some(f(i));
        ts.push(1e3 * t.elapsed().as_secs_f64());
    }
    (median(ts), last.expect("n > 0"))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::var("TRAITS_MODEL").unwrap_or_else(|_| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../target/traits-data/model.bin"
        )
        .into()
    });
    if !std::path::Path::new(&path).exists() {
        return Err(format!("no model at {path}: set TRAITS_MODEL").into());
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("load average at start: {}", load.trim());
    let model = reduce::Model::load(&path)?;
    let labels = thesis_labels();
    let mut sets = Vec::new();
    for space in [Space::Linear, Space::Chart] {
        let nav = Navigator::new(&model, space, NavigatorOptions::default())?;
        let coords = nav.embedding.corpus()?;
        let fit = SetFit {
            coords: &coords,
            names: &model.names,
            space,
            options: FitOptions::default(),
            cross_validate: false,
        };
        sets.push(fit.binary(&labels, Method::Svm)?);
    }
    let reps: usize = std::env::var("TRAITS_BENCH_REPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(21);

    // Editor session, linear 45-D: slider moves of glossiness on yellow-paint.
    let nav = Navigator::new(&model, Space::Linear, NavigatorOptions::default())?;
    let x = nav.embedding.of_name("yellow-paint")?;
    let g = sets[0].get("glossiness")?;
    let mut session = traits::Session::new(&nav, &x)?;
    let (ms, _) = time(1, |_| session.nudge(g, 0.0));
    println!("session: first use of a trait (its back-projection): {ms:.1} ms");
    let (ms, _) = time(reps, |i| {
        session.nudge(g, if i % 2 == 0 { 0.1 } else { -0.05 })
    });
    println!("session.nudge (linear 45-D, all checks): median {ms:.1} ms");
    let preview = SpherePreview::new(256, [0.5, 0.5, std::f64::consts::FRAC_1_SQRT_2]);
    let (ms, img) = time(reps, |_| session.preview(&preview));
    println!(
        "session.preview (256x256 lit sphere, {} pixels): median {ms:.1} ms",
        img.len()
    );
    let (ms, _) = time(reps, |i| {
        let r = session.nudge(g, if i % 2 == 0 { 0.1 } else { -0.05 });
        (r, session.preview(&preview))
    });
    println!("slider move = nudge + preview: median {ms:.1} ms");
    let (ms, _) = time(5.min(reps), |_| session.table());
    println!("session.table (full f64 table + validate): median {ms:.1} ms");

    {
        let nav = Navigator::new(&model, Space::Chart, NavigatorOptions::default())?;
        let x = nav.embedding.of_name("blue-acrylic")?;
        let (ms, _) = time(3, |_| nav.embedding.to_pca(&x));
        println!("chart back-projection to PCA coordinates: median {ms:.1} ms");
        let pca = nav.embedding.to_pca(&x)?;
        let (ms, _) = time(3, |_| traits::reconstruct_log(&model, &pca));
        println!("reconstruct_log (45 coordinates): median {ms:.1} ms");
    }
    // Edits from scratch.
    for (space, set) in [(Space::Linear, &sets[0]), (Space::Chart, &sets[1])] {
        let nav = Navigator::new(&model, space, NavigatorOptions::default())?;
        for (mat, tr, a) in [
            ("blue-acrylic", "metallic-like", 0.5),
            ("gold-metallic-paint", "redness", 2.0),
        ] {
            let x = nav.embedding.of_name(mat)?;
            let tv = set.get(tr)?;
            let n = if space == Space::Chart { 3 } else { 5 }.min(reps);
            let (ms, o) = time(n, |_| nav.edit(&x, tv, a));
            let o = o?;
            println!(
                "{space:?} edit {mat} {tr} +{a}: median {ms:.0} ms (applied {:.3}, stopped {:?})",
                o.applied,
                o.stopped_by.map(|c| c.to_string())
            );
        }
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!("load average at end: {}", load.trim());
    Ok(())
}
