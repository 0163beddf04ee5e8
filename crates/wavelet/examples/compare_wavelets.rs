//! Haar versus smooth wavelets (CDF 5/3, Daubechies-4) at equal coefficient count on measured
//! materials: keep the N largest coefficients of each colour channel, inverse transform, and
//! report the relative L2 error over the 90 × 90 × 180 table (mean over R, G, B).
//!
//! ```text
//! cargo run --release -p wavelet --example compare_wavelets -- [options]
//!   --set nielsen|merl     materials (default nielsen, the 8 held-out materials)
//!   --limit N              first N materials of the set
//!   --mode linear|log      BRDF in 1/sr, or ln(max(f, 0) + floor) as in `reduce` (default linear)
//!   --floor F              log floor in 1/sr (default 1e-3)
//!   --counts a,b,c         coefficient counts (default 10000,30000,69000,150000)
//! ```

use brdf::nbrdf::Nbrdf;
use brdf::BINS;
use wavelet::error_at_equal_counts;
use wavelet::{Layout, Wavelet};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| {
        argv.iter()
            .position(|a| a == flag)
            .and_then(|i| argv.get(i + 1))
            .cloned()
    };
    let set = get("--set").unwrap_or_else(|| "nielsen".into());
    let log = get("--mode").as_deref() == Some("log");
    let floor: f32 = get("--floor")
        .map(|v| v.parse())
        .transpose()?
        .unwrap_or(1e-3);
    let counts: Vec<usize> = get("--counts")
        .unwrap_or_else(|| "10000,30000,69000,150000".into())
        .split(',')
        .map(|v| v.trim().parse())
        .collect::<Result<_, _>>()?;
    let dir = brdf::data_dir().join("nbrdf").join(&set);
    let mut names = brdf::nbrdf::list(&dir)?;
    if let Some(n) = get("--limit") {
        names.truncate(n.parse()?);
    }
    println!(
        "relative L2 error over the table, {} space, mean of R G B; best-N coefficients of a 256^3 zero-padded cube",
        if log { "log" } else { "linear" }
    );
    print!("{:<28} {:>8}", "material", "N");
    for w in Wavelet::ALL {
        print!(" {:>9}", w.name());
    }
    println!();
    let nw = Wavelet::ALL.len();
    let mut mean = vec![0.0f64; counts.len() * nw];
    for name in &names {
        let table = Nbrdf::load(&dir, name)?.tabulate_f32();
        let mut err = vec![0.0f64; counts.len() * nw];
        for c in 0..3 {
            let ch = &table[c * BINS..(c + 1) * BINS];
            let values: Vec<f32> = if log {
                ch.iter().map(|v| (v.max(0.0) + floor).ln()).collect()
            } else {
                ch.to_vec()
            };
            let r = error_at_equal_counts(Layout::MERL_HAAR, &values, &Wavelet::ALL, &counts)?;
            for (e, x) in err.iter_mut().zip(&r) {
                *e += x.relative_error / 3.0;
            }
        }
        for (i, n) in counts.iter().enumerate() {
            print!("{name:<28} {n:>8}");
            for w in 0..nw {
                let e = err[w * counts.len() + i];
                mean[w * counts.len() + i] += e / names.len() as f64;
                print!(" {:>8.3}%", 100.0 * e);
            }
            println!();
        }
    }
    for (i, n) in counts.iter().enumerate() {
        print!("{:<28} {n:>8}", "MEAN");
        for w in 0..nw {
            print!(" {:>8.3}%", 100.0 * mean[w * counts.len() + i]);
        }
        println!();
    }
    Ok(())
}
