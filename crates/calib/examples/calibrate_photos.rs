//! Calibrates a camera from checkerboard photographs, as `gantry calibrate intrinsics` does:
//! OpenCV's sample photos from the shared data by default.
//!
//! `cargo run --release -p calib --example calibrate_photos -- [MODEL] [PHOTO ...]`
//! (MODEL: k1, k1k2, k1k2k3 or k1k2p1p2k3; board 9 × 6 inner corners of 25 mm).

use calib::{calibrate_photos, BoardGeometry, DistortionModel, PhotoOptions, ViewStatus};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let model: DistortionModel = args.next().as_deref().unwrap_or("k1k2").parse()?;
    let mut photos: Vec<PathBuf> = args.map(PathBuf::from).collect();
    if photos.is_empty() {
        let dir = brdf::data_dir().join("real/chessboard");
        photos = calib::glob_files(&format!("{}/left*.jpg", dir.display()))?;
    }
    let mut options = PhotoOptions::new(BoardGeometry::from_inner_corners(9, 6, 0.025));
    options.intrinsics.model = model;
    let (cal, _) = calibrate_photos(&photos, &options)?;
    for v in &cal.views {
        match &v.status {
            ViewStatus::Used {
                rms_point_px,
                blur_px,
                ..
            } => println!(
                "{}: RMS {rms_point_px:.3} px, edge blur {blur_px:.2} px",
                v.path.display()
            ),
            rejected => println!("{}: rejected, {rejected:?}", v.path.display()),
        }
    }
    let c = &cal.camera;
    println!(
        "{} of {} views, model {}: fx {:.3} fy {:.3} cx {:.3} cy {:.3}, distortion {:?}, RMS {:.4} px per point",
        cal.views_used,
        cal.views.len(),
        model.name(),
        c.fx,
        c.fy,
        c.cx,
        c.cy,
        c.distortion(),
        cal.rms_point_px
    );
    println!("{}", cal.to_opencv().to_yaml());
    Ok(())
}
