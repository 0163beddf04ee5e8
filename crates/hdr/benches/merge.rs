//! Throughput of the HDR merge on full-size simulated frames (1300 × 1030, 18 exposures).
//!
//! `cargo bench -p hdr --bench merge [-- runs]` prints the median merge time and throughput in
//! pixel-exposures per second with all rayon threads and with one thread, and the time to write
//! the result as OpenEXR. Goal: ≥ 300 M pixel-exposures/s on 2 cores.

#[path = "../tests/common/mod.rs"]
mod common;

use common::{capture_series, ready, T};
use gantry_hal::BayerFrame;
use hdr::ExrCompression;
use hdr::{merge, thesis_ladder, write_hdr_exr, DefectMap, ExrOptions, MergeOptions, PositionInfo};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// CPU time of the whole process (user + system, all threads), seconds, from /proc (Linux);
/// NaN elsewhere. Ticks are 10 ms, so it is read over many runs.
fn process_cpu_s() -> f64 {
    brdf::cpu_seconds().unwrap_or(f64::NAN)
}

fn time_merge(frames: &[BayerFrame], defects: &DefectMap, runs: usize) -> Vec<f64> {
    let opts = MergeOptions::default();
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            let img = merge(frames, Some(defects), &opts).expect("merge");
            let dt = t.elapsed().as_secs_f64();
            std::hint::black_box(img);
            dt
        })
        .collect()
}

fn main() {
    let runs: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(15);
    let sim = common::rig(common::config(1.0, 1, 10.0), common::GLOSSY);
    let mut rig = ready(&sim);
    let dark = rig.camera.capture_dark(60.0, T).unwrap();
    let defects = DefectMap::from_dark_frame(&dark, &Default::default()).unwrap();
    let frames: Vec<BayerFrame> = capture_series(&mut rig, 90.0, &thesis_ladder());
    let (w, h) = (frames[0].width, frames[0].height);
    let samples = (w * h * frames.len()) as f64;
    let threads = rayon::current_num_threads();
    println!(
        "merge of {} frames of {w}x{h} ({:.1} M pixel-exposures), {runs} runs",
        frames.len(),
        samples / 1e6
    );
    let cpu0 = process_cpu_s();
    let all = time_merge(&frames, &defects, runs);
    let cpu = process_cpu_s() - cpu0;
    let m = median(all.clone());
    println!(
        "{threads} threads: median {:.1} ms -> {:.0} M pixel-exposures/s (min {:.1} ms)",
        m * 1e3,
        samples / m / 1e6,
        all.iter().cloned().fold(f64::INFINITY, f64::min) * 1e3
    );
    println!(
        "CPU time: {:.2} s for {runs} runs -> {:.0} M pixel-exposures per CPU-second \
         (x2 = {:.0} M/s on 2 otherwise idle cores)",
        cpu,
        samples * runs as f64 / cpu / 1e6,
        2.0 * samples * runs as f64 / cpu / 1e6
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let one = pool.install(|| time_merge(&frames, &defects, runs.min(7)));
    let m1 = median(one);
    println!(
        "1 thread:  median {:.1} ms -> {:.0} M pixel-exposures/s",
        m1 * 1e3,
        samples / m1 / 1e6
    );
    let img = merge(&frames, Some(&defects), &MergeOptions::default()).unwrap();
    let dir = std::env::temp_dir().join(format!("hdr-bench-{}", std::process::id()));
    for (name, compression, fit_statistics) in [
        ("zip, all channels", ExrCompression::Zip, true),
        ("zip, radiance/valid/count", ExrCompression::Zip, false),
        ("rle, all channels", ExrCompression::Rle, true),
        ("rle, radiance/valid/count", ExrCompression::Rle, false),
        ("none, all channels", ExrCompression::None, true),
        ("none, radiance/valid/count", ExrCompression::None, false),
    ] {
        let opts = ExrOptions {
            fit_statistics,
            compression,
        };
        let path = hdr::hdr_path(&dir, 0);
        let dt = median(
            (0..5)
                .map(|_| {
                    let t = Instant::now();
                    write_hdr_exr(&path, &img, &PositionInfo::default(), &opts).unwrap();
                    t.elapsed().as_secs_f64()
                })
                .collect(),
        );
        let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
        println!(
            "EXR write ({name}): median {:.1} ms of 5, {:.1} MB",
            dt * 1e3,
            size as f64 / 1e6
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
