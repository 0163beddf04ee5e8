//! Corner detector: exact synthetic renderings (independent of the simulator), simulator
//! frames against their true corner pixels, and the failure modes.

mod common;

use calib::{detect_board, BoardGeometry, CalibError, CornerOptions};
use gantry_hal::{BayerFrame, BayerPattern};
use nalgebra::{Matrix3, Vector3};

/// The sum of `f(u, v)` over the `ss × ss` sample positions of pixel `(x, y)` (pixel centres at
/// integer coordinates).
fn subpixel_sum(x: usize, y: usize, ss: usize, f: impl Fn(f64, f64) -> f64) -> f64 {
    let mut acc = 0.0;
    for j in 0..ss {
        for i in 0..ss {
            let u = x as f64 - 0.5 + (i as f64 + 0.5) / ss as f64;
            let v = y as f64 - 0.5 + (j as f64 + 0.5) / ss as f64;
            acc += f(u, v);
        }
    }
    acc
}

/// Renders a board seen through the plane homography `h` (target metres → pixels) into a
/// 10-bit Bayer frame, each pixel the mean of `ss × ss` samples (area coverage), on a mid-grey
/// background, noise-free.
fn render(board: &BoardGeometry, h: &Matrix3<f64>, w: usize, hgt: usize, ss: usize) -> BayerFrame {
    let hinv = h.try_inverse().unwrap();
    let (sx, sy, s) = (
        board.squares_x as f64,
        board.squares_y as f64,
        board.square_m,
    );
    let mut data = vec![0u16; w * hgt];
    for y in 0..hgt {
        for x in 0..w {
            let sum = subpixel_sum(x, y, ss, |u, v| {
                let q = hinv * Vector3::new(u, v, 1.0);
                let (bx, by) = (q.x / q.z / s, q.y / q.z / s);
                if bx < -0.7 || by < -0.7 || bx > sx + 0.7 || by > sy + 0.7 {
                    300.0
                } else if bx < 0.0 || by < 0.0 || bx >= sx || by >= sy {
                    900.0
                } else if (bx.floor() as i64 + by.floor() as i64) % 2 == 0 {
                    60.0
                } else {
                    900.0
                }
            });
            data[y * w + x] = (sum / (ss * ss) as f64).round() as u16;
        }
    }
    BayerFrame::new(w, hgt, 10, BayerPattern::Rggb, data, 0.1, 0.0, 25.0, 0).unwrap()
}

fn board() -> BoardGeometry {
    BoardGeometry {
        squares_x: 9,
        squares_y: 7,
        square_m: 0.008,
    }
}

/// Homography of a tilted board: K·[r1 r2 t].
fn view(f: f64, c: [f64; 2], tilt: [f64; 3], t: [f64; 3]) -> Matrix3<f64> {
    let r = nalgebra::Rotation3::new(Vector3::from(tilt)).into_inner();
    let k = Matrix3::new(f, 0.0, c[0], 0.0, f, c[1], 0.0, 0.0, 1.0);
    k * Matrix3::from_columns(&[
        r.column(0).into_owned(),
        r.column(1).into_owned(),
        Vector3::from(t),
    ])
}

#[test]
fn exact_renderings_are_located_to_a_few_hundredths_of_a_pixel() {
    let b = board();
    let views = [
        view(
            2400.0,
            [160.0, 120.0],
            [0.1, -0.2, 0.05],
            [-0.036, -0.028, 1.0],
        ),
        view(
            2400.0,
            [160.0, 120.0],
            [-0.5, 0.3, 1.2],
            [-0.01, -0.04, 1.0],
        ),
        view(
            2400.0,
            [160.0, 120.0],
            [0.6, 0.5, -0.3],
            [-0.03, -0.02, 1.05],
        ),
    ];
    for (n, h) in views.iter().enumerate() {
        let frame = render(&b, h, 320, 240, 12);
        let found = detect_board(&frame, &b, &CornerOptions::default(), n).unwrap();
        let truth: Vec<[f64; 2]> = b
            .inner_corners()
            .iter()
            .map(|p| {
                let q = h * Vector3::new(p[0], p[1], 1.0);
                [q.x / q.z, q.y / q.z]
            })
            .collect();
        let (rms, max) = common::corner_error(&found, &truth);
        println!("exact rendering, view {n}: rms {rms:.4} px, max {max:.4} px");
        assert!(
            rms < 0.03 && max < 0.08,
            "view {n}: rms {rms} px, max {max} px"
        );
    }
}

#[test]
fn simulator_frames_agree_with_the_true_corners() {
    let sim = common::simulate(0.25, 6, 3, common::SimNoise::default());
    let mut worst_rms: f64 = 0.0;
    for (i, (rms, max)) in common::detected_corner_errors(&sim, &CornerOptions::default(), true)
        .into_iter()
        .enumerate()
    {
        assert!(max < 0.3, "image {i}: max error {max} px");
        worst_rms = worst_rms.max(rms);
    }
    assert!(worst_rms < 0.1, "worst per-image rms {worst_rms} px");
}

#[test]
fn labelling_follows_the_board_axes() {
    // An upright board: corner (1, 1) at the top left, x to the right, y down.
    let b = board();
    let h = view(
        2400.0,
        [160.0, 120.0],
        [0.05, 0.05, 0.0],
        [-0.036, -0.028, 1.0],
    );
    let frame = render(&b, &h, 320, 240, 6);
    let found = detect_board(&frame, &b, &CornerOptions::default(), 0).unwrap();
    assert!(found[1][0] > found[0][0] + 10.0, "x grows to the right");
    assert!(found[8][1] > found[0][1] + 10.0, "y grows downwards");
}

#[test]
fn a_frame_without_a_board_is_a_typed_error() {
    let data: Vec<u16> = (0..160 * 120).map(|i| (i % 7) as u16 * 3 + 100).collect();
    let frame = BayerFrame::new(160, 120, 10, BayerPattern::Rggb, data, 0.1, 0.0, 25.0, 0).unwrap();
    let err = detect_board(&frame, &board(), &CornerOptions::default(), 4).unwrap_err();
    assert!(
        matches!(err, CalibError::BoardNotFound { image: 4, .. }),
        "{err}"
    );
    // A board with other dimensions than the one asked for is not accepted either.
    let h = view(
        2400.0,
        [160.0, 120.0],
        [0.1, -0.2, 0.05],
        [-0.036, -0.028, 1.0],
    );
    let frame = render(&board(), &h, 320, 240, 4);
    let other = BoardGeometry {
        squares_x: 8,
        ..board()
    };
    let err = detect_board(&frame, &other, &CornerOptions::default(), 0).unwrap_err();
    assert!(matches!(err, CalibError::BoardNotFound { .. }), "{err}");
}

/// A photograph-like grey image: a 10 × 7-square board seen through a homography and a lens
/// with strong barrel distortion (k1 = −0.27, f = 540 px), area-sampled, then vignetting,
/// uneven lighting, a cluttered background of bright and dark blobs and seeded noise.
fn render_photo(h: &Matrix3<f64>, square_m: f64, seed: u64) -> (calib::GrayImage, Vec<[f64; 2]>) {
    use rand::{Rng, SeedableRng};
    let (w, hgt, f, c, k1) = (640usize, 480usize, 540.0, [320.0, 240.0], -0.27);
    let hinv = h.try_inverse().unwrap();
    // Undistorted normalised point of a distorted pixel (fixed-point iteration).
    let undistort = |u: f64, v: f64| {
        let (xd, yd) = ((u - c[0]) / f, (v - c[1]) / f);
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let s = 1.0 + k1 * (x * x + y * y);
            x = xd / s;
            y = yd / s;
        }
        [x * f + c[0], y * f + c[1]]
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let blobs: Vec<[f64; 4]> = (0..40)
        .map(|_| {
            [
                rng.gen_range(0.0..640.0),
                rng.gen_range(0.0..480.0),
                rng.gen_range(3.0..20.0),
                rng.gen_range(0.2..0.8),
            ]
        })
        .collect();
    let ss = 3;
    let mut data = vec![0f32; w * hgt];
    for y in 0..hgt {
        for x in 0..w {
            let acc = subpixel_sum(x, y, ss, |u, v| {
                let p = undistort(u, v);
                let q = hinv * Vector3::new(p[0], p[1], 1.0);
                let (bx, by) = (q.x / q.z / square_m, q.y / q.z / square_m);
                if (-0.5..10.5).contains(&bx) && (-0.5..7.5).contains(&by) {
                    if (0.0..10.0).contains(&bx)
                        && (0.0..7.0).contains(&by)
                        && (bx.floor() as i64 + by.floor() as i64) % 2 == 0
                    {
                        0.08
                    } else {
                        0.85
                    }
                } else {
                    blobs
                        .iter()
                        .find(|b| (u - b[0]).hypot(v - b[1]) < b[2])
                        .map_or(0.45, |b| b[3])
                }
            });
            let r2 = ((x as f64 - 320.0).powi(2) + (y as f64 - 240.0).powi(2)) / 400.0f64.powi(2);
            let light = (1.0 - 0.5 * r2) * (0.8 + 0.2 * x as f64 / 640.0);
            let noise: f64 = rng.gen_range(-0.02..0.02);
            data[y * w + x] = (acc / (ss * ss) as f64 * light + noise) as f32;
        }
    }
    // True corner pixels: board (i, j) through the homography, then the distortion.
    let truth = (1..7)
        .flat_map(|j| (1..10).map(move |i| (i, j)))
        .map(|(i, j)| {
            let p = h * Vector3::new(i as f64 * square_m, j as f64 * square_m, 1.0);
            let (x, y) = ((p.x / p.z - c[0]) / f, (p.y / p.z - c[1]) / f);
            let s = 1.0 + k1 * (x * x + y * y);
            [x * s * f + c[0], y * s * f + c[1]]
        })
        .collect();
    let img = calib::GrayImage {
        width: w,
        height: hgt,
        data,
    };
    (img, truth)
}

#[test]
fn photograph_like_images_with_distortion_clutter_and_small_squares_are_found() {
    let b = BoardGeometry::from_inner_corners(9, 6, 0.025);
    let cases = [
        // Large board, tilted, near the image edge (strong distortion).
        (
            view(
                540.0,
                [320.0, 240.0],
                [0.35, -0.3, 0.1],
                [-0.12, -0.08, 0.36],
            ),
            1,
        ),
        // Small board: squares of about 11 px, grazing view.
        (
            view(540.0, [320.0, 240.0], [0.9, 0.2, -0.4], [-0.05, -0.05, 1.1]),
            2,
        ),
        // Upside down and rolled.
        (
            view(540.0, [320.0, 240.0], [0.2, 0.3, 2.8], [0.1, 0.06, 0.5]),
            3,
        ),
    ];
    for (k, (h, seed)) in cases.iter().enumerate() {
        let (img, truth) = render_photo(h, 0.025, *seed);
        let found = calib::detect_board_gray(&img, &b, &CornerOptions::default(), k)
            .unwrap_or_else(|e| panic!("case {k}: {e}"));
        let err: Vec<f64> = found
            .iter()
            .zip(&truth)
            .map(|(p, t)| (p[0] - t[0]).hypot(p[1] - t[1]))
            .collect();
        let rms = (err.iter().map(|e| e * e).sum::<f64>() / err.len() as f64).sqrt();
        let max = err.iter().cloned().fold(0.0, f64::max);
        eprintln!("case {k}: corner error rms {rms:.4} px, max {max:.4} px");
        assert!(rms < 0.15 && max < 0.4, "case {k}: rms {rms}, max {max}");
    }
}
