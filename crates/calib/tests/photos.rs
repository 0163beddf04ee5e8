//! Calibration from real photographs: OpenCV's sample chessboard photos
//! (`$BRDF_DATA_DIR/real/chessboard/left*.jpg`, 13 photos, 640 × 480, 9 × 6 inner corners of
//! 25 mm, strong barrel distortion), against OpenCV's own figures on the same photos.
//!
//! The peer's figures (OpenCV 5.0.0 from PyPI's opencv-python-headless, `findChessboardCorners` + `cornerSubPix` 11 × 11 +
//! `calibrateCamera`, RMS per point) are reproduced by
//! `tools/calib/opencv_compare.py --model k1k2` and `--model k1k2p1p2k3` (docs/calib.md).

use calib::{calibrate_photos, BoardGeometry, DistortionModel, PhotoOptions, ViewStatus};
use std::path::PathBuf;

struct Peer {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    rms: f64,
}

/// OpenCV, `CALIB_FIX_K3 | CALIB_ZERO_TANGENT_DIST`.
const OPENCV_K1K2: Peer = Peer {
    fx: 536.4564,
    fy: 536.7446,
    cx: 342.3853,
    cy: 234.3278,
    rms: 0.41820,
};

/// OpenCV, all five terms.
const OPENCV_FIVE: Peer = Peer {
    fx: 536.0734,
    fy: 536.0163,
    cx: 342.3705,
    cy: 235.5369,
    rms: 0.40869,
};

fn photos() -> Vec<PathBuf> {
    let dir = brdf::data_dir().join("real/chessboard");
    let mut p: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| {
            panic!(
                "the sample photographs are missing ({}: {e}); set BRDF_DATA_DIR to the shared data",
                dir.display()
            )
        })
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("left") && n.ends_with(".jpg"))
        })
        .collect();
    p.sort();
    assert_eq!(
        p.len(),
        13,
        "expected 13 photos left*.jpg in {}",
        dir.display()
    );
    p
}

fn check(model: DistortionModel, peer: &Peer) {
    let board = BoardGeometry::from_inner_corners(9, 6, 0.025);
    let mut opts = PhotoOptions::new(board);
    opts.intrinsics.model = model;
    let (cal, fit) = calibrate_photos(&photos(), &opts).unwrap();
    let used = cal
        .views
        .iter()
        .filter(|v| matches!(v.status, ViewStatus::Used { .. }))
        .count();
    assert_eq!(used, 13, "{:#?}", cal.views);
    let c = &cal.camera;
    eprintln!(
        "{model:?}: fx {:.4} fy {:.4} cx {:.4} cy {:.4} RMS {:.4} px per point; distortion {:?}",
        c.fx,
        c.fy,
        c.cx,
        c.cy,
        cal.rms_point_px,
        c.distortion()
    );
    assert!(
        (c.fx / peer.fx - 1.0).abs() < 0.005,
        "fx {} vs {}",
        c.fx,
        peer.fx
    );
    assert!(
        (c.fy / peer.fy - 1.0).abs() < 0.005,
        "fy {} vs {}",
        c.fy,
        peer.fy
    );
    assert!((c.cx - peer.cx).abs() < 2.0, "cx {} vs {}", c.cx, peer.cx);
    assert!((c.cy - peer.cy).abs() < 2.0, "cy {} vs {}", c.cy, peer.cy);
    assert!(
        cal.rms_point_px <= 1.05 * peer.rms,
        "RMS {} vs OpenCV {}",
        cal.rms_point_px,
        peer.rms
    );
    // Per point is √2 × per coordinate.
    assert!((fit.rms_point_px - fit.rms_px * std::f64::consts::SQRT_2).abs() < 1e-12);
}

#[test]
fn sample_photos_calibrate_like_opencv_with_two_radial_terms() {
    check(DistortionModel::K1K2, &OPENCV_K1K2);
}

#[test]
fn sample_photos_calibrate_like_opencv_with_five_terms() {
    check(DistortionModel::K1K2P1P2K3, &OPENCV_FIVE);
}
