//! Writes raw simulated frames as 8-bit PNGs for a visual check, and prints the simulated
//! duration of a full 330 × 18 capture.
//!
//! `cargo run --release -p hal-sim --example sim_frames -- <out_dir> [scale] [material spec]`

use hal_sim::{Checkerboard, SimConfig, SimRig, TargetPose};
use std::sync::Arc;
use std::time::Duration;

fn save(frame: &gantry_hal::BayerFrame, path: &std::path::Path) {
    // Raw mosaic, 10 bits → 8 bits with a square-root curve so dim regions stay visible.
    let px: Vec<u8> = frame
        .data
        .iter()
        .map(|&v| ((v as f64 / 1023.0).sqrt() * 255.0).round() as u8)
        .collect();
    let img = image::GrayImage::from_raw(frame.width as u32, frame.height as u32, px)
        .expect("frame size");
    let tmp = path.with_extension("png.tmp");
    img.save_with_format(&tmp, image::ImageFormat::Png)
        .expect("write png");
    std::fs::rename(&tmp, path).expect("rename png");
    println!("wrote {}", path.display());
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let out = std::path::PathBuf::from(args.get(1).map(String::as_str).unwrap_or("/tmp/hal-sim"));
    let scale: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.3);
    let spec = args
        .get(3)
        .cloned()
        .unwrap_or_else(|| "phong:kd=0.2,ks=0.5,n=60".into());
    std::fs::create_dir_all(&out).expect("output directory");
    let material = brdf::load(&spec).expect("material spec");
    let mut cfg = SimConfig::with_scale(scale);
    cfg.lamp.warm_up_s = 0.0;
    let sim = SimRig::new(cfg, Arc::new(material)).expect("rig");
    let long = Duration::from_secs(3600);
    let mut rig = sim.rig();
    rig.turntable.home(long).unwrap();
    rig.lamp.set_on(true).unwrap();
    for (angle, exposure) in [(30.0, 0.05), (90.0, 0.2), (150.0, 0.2)] {
        rig.turntable.move_to(angle, long).unwrap();
        rig.camera.set_exposure(exposure).unwrap();
        let f = rig.camera.capture(long).unwrap();
        save(&f, &out.join(format!("sphere_{angle:03.0}deg.png")));
    }
    let board = Checkerboard::default();
    let pose = TargetPose::facing(&board, 1.0, 0.4, -0.3, 0.0, 0.0);
    let cap = sim.capture_checkerboard(&board, &pose, 0.25).unwrap();
    save(&cap.frame, &out.join("checkerboard.png"));
    let dark = rig.camera.capture_dark(60.0, long).unwrap();
    println!(
        "60 s dark frame: {} photosites above 16 DN, ground truth lists {} hot pixels",
        dark.data.iter().filter(|&&v| v > 16).count(),
        sim.hot_pixels().len()
    );
    let t = sim.truth();
    println!(
        "ground truth: {}",
        serde_json::to_string(&t.camera).unwrap_or_default()
    );
}
