//! Every shared material written as `.bsdf` and read back, measured on the MERL grid against
//! its own table: `BRDF_DATA_DIR=/work/shared/data cargo run --release -p rgl-bsdf --example
//! round_trip_study -- OUT.csv [RESOLUTION] [THETA_I] [VNDF_RESOLUTION] [BROAD_SHARE]`
//! (`ROUND_TRIP_ONLY=name1,name2` for some materials). Prints a summary; one CSV row per
//! material (log relative RMS, cosine-weighted relative RMS, median |ln(f̂/f)|, file bytes,
//! write seconds).
use brdf::{metrics::log_relative_rms, MerlTable};
use std::io::Write;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let out = args
        .get(1)
        .ok_or("usage: round_trip_study OUT.csv [RESOLUTION] [THETA_I]")?;
    let resolution: usize = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(32);
    let theta_i: usize = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(16);
    let vndf_resolution: usize = args
        .get(4)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(resolution);
    let broad_share: f64 = args.get(5).map(|s| s.parse()).transpose()?.unwrap_or(0.3);
    let options = rgl_bsdf::WriteOptions {
        resolution,
        vndf_resolution,
        theta_i,
        broad_share,
        ..Default::default()
    };
    let only: Option<Vec<String>> = std::env::var("ROUND_TRIP_ONLY")
        .ok()
        .map(|s| s.split(',').map(str::to_string).collect());
    let mut csv = String::from("set,material,log_relative_rms,cosine_weighted_relative_rms,median_abs_log,bytes,write_seconds\n");
    let mut rows = Vec::new();
    for material in brdf::nbrdf::shared_materials()? {
        let (set, dir, name) = &material;
        if only.as_ref().is_some_and(|o| !o.contains(name)) {
            continue;
        }
        let nbrdf = brdf::nbrdf::Nbrdf::load(dir, name)?;
        let reference = MerlTable::tabulate(&nbrdf);
        let start = Instant::now();
        let file = rgl_bsdf::write(&nbrdf, &options)?;
        let bytes = file.to_bytes();
        let seconds = start.elapsed().as_secs_f64();
        let back = rgl_bsdf::RglBsdf::from_tensor(&rgl_bsdf::TensorFile::parse(&bytes)?)?;
        let estimate = MerlTable::tabulate(&back);
        let log_rms = log_relative_rms(&reference, &estimate)?;
        let cos_rms = recover::cosine_weighted_relative_rms(&reference, &estimate);
        let mut logs: Vec<f64> = (0..3 * brdf::BINS)
            .filter_map(|k| {
                let (c, b) = (k / brdf::BINS, k % brdf::BINS);
                let (f, g) = (reference.get(c, b), estimate.get(c, b));
                (f > 0.0 && g > 0.0).then(|| (g / f).ln().abs())
            })
            .collect();
        logs.sort_by(f64::total_cmp);
        let median = logs.get(logs.len() / 2).copied().unwrap_or(f64::NAN);
        println!("{set}/{name}: log rms {log_rms:.4}, cos-weighted rms {cos_rms:.4}, median |log| {median:.4}, {} bytes, {seconds:.2} s", bytes.len());
        csv.push_str(&format!(
            "{set},{name},{log_rms:.6},{cos_rms:.6},{median:.6},{},{seconds:.3}\n",
            bytes.len()
        ));
        rows.push((log_rms, cos_rms, median, seconds));
    }
    let med = |k: usize| {
        let mut v: Vec<f64> = rows.iter().map(|r| [r.0, r.1, r.2, r.3][k]).collect();
        v.sort_by(f64::total_cmp);
        (v[v.len() / 2], v[v.len() * 9 / 10], v[v.len() - 1])
    };
    for (k, label) in [
        "log relative RMS",
        "cosine-weighted relative RMS",
        "median |log|",
        "write seconds",
    ]
    .iter()
    .enumerate()
    {
        let (m, p90, max) = med(k);
        println!("{label}: median {m:.4}, 90th percentile {p90:.4}, max {max:.4}");
    }
    std::fs::File::create(out)?.write_all(csv.as_bytes())?;
    Ok(())
}
