//! One simulated lamp position end to end, as `gantry capture` would do it: dark frame →
//! defect map → exposure series → merge → `DIR/hdr/NNN.exr` and `DIR/truth/NNN.exr`.
//!
//! `cargo run --release -p hdr --example capture_position -- DIR [angle] [scale]`
//! (defaults 90°, 0.15). The files can be checked with an independent reader:
//! `python3 tools/hdr/check_exr.py DIR/hdr/000.exr DIR/truth/000.exr`.

use hal_sim::{SimConfig, SimRig};
use hdr::{
    check_frames, hdr_path, inconsistent_frames, merge, thesis_ladder, truth_path, write_hdr_exr,
    write_truth_exr, DarkFrameOptions, DefectMap, ExrOptions, MergeOptions, PositionInfo,
};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(args.first().map(String::as_str).unwrap_or("hdr-sample"));
    let angle: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(90.0);
    let scale: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.15);
    let t = Duration::from_secs(3600);
    let mut cfg = SimConfig::with_scale(scale);
    cfg.lamp.warm_up_s = 0.0;
    cfg.lamp.radiant_intensity = cfg.lamp.radiant_intensity.map(|i| i * 10.0);
    let material = brdf::load("phong:kd=0.2,ks=0.6,n=60").expect("phong");
    let sim = SimRig::new(cfg, Arc::new(material)).expect("rig");
    let mut rig = sim.rig();
    rig.turntable.home(t).unwrap();
    rig.lamp.set_on(true).unwrap();
    rig.lamp.wait_stable(t).unwrap();
    let dark = rig.camera.capture_dark(60.0, t).unwrap();
    let defects = DefectMap::from_dark_frame(&dark, &DarkFrameOptions::default()).unwrap();
    rig.turntable.move_to(angle, t).unwrap();
    let start = sim.clock().seconds();
    let frames: Vec<_> = thesis_ladder()
        .iter()
        .map(|&e| {
            rig.camera.set_exposure(e).unwrap();
            rig.camera.capture(t).unwrap()
        })
        .collect();
    let img = merge(&frames, Some(&defects), &MergeOptions::default()).unwrap();
    let checks = check_frames(&frames, &img).unwrap();
    let info = PositionInfo {
        index: Some(0),
        angle_deg: Some(angle),
        sensor_temperature_c: Some(frames[0].sensor_temperature_c),
        timestamp_s: Some(start),
    };
    let hp = hdr_path(&dir, 0);
    write_hdr_exr(&hp, &img, &info, &ExrOptions::default()).unwrap();
    let truth = sim.position_truth(angle);
    let tp = truth_path(&dir, 0);
    write_truth_exr(
        &tp,
        img.width,
        img.height,
        &truth.signal_rate_dn_per_s,
        &info,
    )
    .unwrap();
    println!(
        "{}x{}: {} valid pixels, {} hot; inconsistent frames: {:?}\nwrote {} and {}",
        img.width,
        img.height,
        img.valid_count(),
        defects.hot_count(),
        inconsistent_frames(&checks, 0.02, 200),
        hp.display(),
        tp.display()
    );
}
