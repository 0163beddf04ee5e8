//! Checkerboard detection time on one 640 × 480 image (goal: ≤ 50 ms): a real photograph
//! (OpenCV's sample `left01.jpg` from the shared data) and a rendered board.
//!
//! `cargo bench -p calib --bench detect`

use calib::{detect_board_gray, BoardGeometry, CornerOptions, GrayImage};
use std::time::Instant;

fn time(name: &str, img: &GrayImage, board: &BoardGeometry) {
    let opts = CornerOptions::default();
    let n = 20;
    let mut times = Vec::with_capacity(n);
    for _ in 0..n {
        let t = Instant::now();
        let c = detect_board_gray(img, board, &opts, 0).expect("board found");
        times.push(t.elapsed().as_secs_f64() * 1e3);
        assert_eq!(c.len(), board.corners_x() * board.corners_y());
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{name}: {}x{} detection median {:.1} ms, min {:.1} ms, max {:.1} ms ({n} runs)",
        img.width,
        img.height,
        times[n / 2],
        times[0],
        times[n - 1]
    );
}

fn main() {
    let path = brdf::data_dir().join("real/chessboard/left01.jpg");
    let photo = image::open(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (set BRDF_DATA_DIR to the shared data)",
            path.display()
        )
    });
    time(
        "photo left01.jpg",
        &GrayImage::from_dynamic(&photo),
        &BoardGeometry::from_inner_corners(9, 6, 0.025),
    );
    // A 10 × 7-square board of 40-pixel squares, rotated by 0.3 rad, on a grey background.
    let board = BoardGeometry::from_inner_corners(9, 6, 0.025);
    let (w, h) = (640usize, 480usize);
    let (s, a) = (40.0f64, 0.3f64);
    let data = (0..w * h)
        .map(|k| {
            let (x, y) = ((k % w) as f64 - 320.0, (k / w) as f64 - 240.0);
            let (u, v) = (a.cos() * x + a.sin() * y, -a.sin() * x + a.cos() * y);
            let (i, j) = ((u / s + 5.0).floor(), (v / s + 3.5).floor());
            if !(0.0..10.0).contains(&i) || !(0.0..7.0).contains(&j) {
                0.5
            } else if (i + j) as i64 % 2 == 0 {
                0.1
            } else {
                0.9
            }
        })
        .collect();
    time(
        "rendered board",
        &GrayImage {
            width: w,
            height: h,
            data,
        },
        &board,
    );
}
