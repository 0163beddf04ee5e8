//! HDR + binning for a whole capture at full resolution (issue 6): 330 lamp positions of
//! 1300 × 1030 frames, the seed's 18 exposures each.
//!
//! `cargo bench -p gantry --bench hdr_binning [-- POSITIONS [MATERIAL]]`
//!
//! The simulator renders every position's frames first (not timed: on a real rig the camera
//! produces them). Timed per position, as `gantry capture` runs them: the HDR merge, the frame
//! consistency check, the BRDF samples of the sphere pixels and the atomic write of the position's
//! sample file. Then the robust binning of all sample files into the MERL table. The figure to
//! compare with the goal (≤ 60 s on 2 cores) is the sum of the per-position times plus binning; the
//! simulated capture clock is printed next to it.

use binning::{
    bin_samples, position_samples, BinningOptions, ForwardOptions, PositionSamples, Rates,
    SampleFiles, SphereView,
};
use gantry_hal::{BayerFrame, Rig};
use hal_sim::{SimConfig, SimRig};
use hdr::{merge, seed_ladder, DefectMap, MergeOptions};
use std::time::{Duration, Instant};

const T: Duration = Duration::from_secs(3600);

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let n: usize = args.first().map_or(Ok(330), |s| s.parse())?;
    let material = args
        .get(1)
        .cloned()
        .unwrap_or_else(|| "merl:blue-acrylic".to_string());
    let mut cfg = SimConfig::with_scale(1.0);
    cfg.material = material.clone();
    let sim = SimRig::from_config(cfg)?;
    let t = sim.truth();
    let c = &t.camera;
    let calibration = calib::sim::calibration_from_truth(t)?;
    let mut rig: Rig = sim.rig();
    let pattern = rig.camera.info().pattern;
    let view = SphereView::new(&calibration, move |x, y| pattern.channel_at(x, y), 85.0);
    rig.turntable.home(T)?;
    rig.lamp.set_on(true)?;
    rig.lamp.wait_stable(T)?;
    let dark = rig.camera.capture_dark(60.0, T)?;
    let defects = DefectMap::from_dark_frame(&dark, &Default::default())?;
    // The lamp constant from the true sensor response: the benchmark times the pipeline; the
    // white-standard estimate is a separate, one-off step of a capture.
    let lamp_constant = [1.0f64; 3];
    let dir = std::env::temp_dir().join(format!("gantry-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let exposures = seed_ladder();
    println!(
        "{material}: {n} positions of {}x{} px, {} exposures, {} sphere pixels, {} threads",
        c.width,
        c.height,
        exposures.len(),
        view.pixels.len(),
        rayon::current_num_threads()
    );
    let (mut t_merge, mut t_check, mut t_samples, mut t_write) = (vec![], vec![], vec![], vec![]);
    let mut paths = Vec::with_capacity(n);
    let mut t_sim = 0.0;
    for i in 0..n {
        let angle = 164.5 * i as f64 / (n.max(2) - 1) as f64;
        let t0 = Instant::now();
        sim.begin_position(i as u64);
        rig.turntable.move_to(angle, T)?;
        let frames: Vec<BayerFrame> = exposures
            .iter()
            .map(|&e| {
                rig.camera.set_exposure(e)?;
                rig.camera.capture(T)
            })
            .collect::<Result<_, _>>()?;
        t_sim += t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let image = merge(&frames, Some(&defects), &MergeOptions::default())?;
        let t2 = Instant::now();
        let odd = hdr::inconsistent_frames(&hdr::check_frames(&frames, &image)?, 0.05, 200);
        std::hint::black_box(odd);
        let t3 = Instant::now();
        let lamp = binning::geometry::RigGeometry::lamp_position(&calibration, angle);
        let samples = position_samples(
            &view,
            Rates {
                rate: &image.radiance,
                valid: &image.valid,
            },
            &lamp,
            &lamp_constant,
            &ForwardOptions::default(),
        )?;
        let t4 = Instant::now();
        let path = dir.join(format!("{i:03}.samples"));
        PositionSamples {
            position: i as u32,
            angle_deg: angle,
            samples,
        }
        .write(&path)?;
        let t5 = Instant::now();
        paths.push(path);
        t_merge.push((t2 - t1).as_secs_f64());
        t_check.push((t3 - t2).as_secs_f64());
        t_samples.push((t4 - t3).as_secs_f64());
        t_write.push((t5 - t4).as_secs_f64());
    }
    let per_position: Vec<f64> = (0..n)
        .map(|i| t_merge[i] + t_check[i] + t_samples[i] + t_write[i])
        .collect();
    let positions_total: f64 = per_position.iter().sum();
    let files = SampleFiles::new(paths);
    let t6 = Instant::now();
    let binned = bin_samples(&files, &BinningOptions::default())?;
    let t_bin = t6.elapsed().as_secs_f64();
    println!(
        "per position, median ms: merge {:.1}, consistency {:.1}, samples {:.1}, write {:.1}, total {:.1}",
        median(t_merge) * 1e3,
        median(t_check) * 1e3,
        median(t_samples) * 1e3,
        median(t_write) * 1e3,
        median(per_position) * 1e3
    );
    println!(
        "binning: {:.1} M samples in {:.2} s ({} passes), coverage {:.3}",
        binned.total_samples() as f64 / 1e6,
        t_bin,
        binned.passes,
        binned.coverage()
    );
    println!(
        "HDR + binning, {n} positions: {:.1} s wall (goal 60 s); simulator rendering (not timed): {:.1} s; simulated capture clock: {:.2} h",
        positions_total + t_bin,
        t_sim,
        rig.clock.now().as_secs_f64() / 3600.0
    );
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
