//! Conditioning study of the target protocol without rendering: the true corner pixels of the
//! planned board poses plus Gaussian noise are fitted (intrinsics), then the digitizer tips
//! (extrinsics), for several seeds. Prints the errors against the calibration goals.
//!
//! `cargo run --profile test -p calib --example protocol_study -- [scale] [views] [sigma_px]
//!  [squares_x] [squares_y] [square_mm] [tilt_min_deg] [tilt_max_deg] [seeds] [fill] [tip_depth_m]`

#[path = "../tests/common/mod.rs"]
mod common;

use calib::{
    fit_extrinsics, fit_intrinsics, plan_board_poses, BoardGeometry, IntrinsicOptions,
    TargetProtocol, TipCorrespondence,
};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::sync::Arc;

fn main() {
    let a: Vec<f64> = std::env::args()
        .skip(1)
        .map(|s| s.parse().expect("numeric argument"))
        .collect();
    let arg = |i: usize, d: f64| a.get(i).copied().unwrap_or(d);
    let scale = arg(0, 1.0);
    let def = TargetProtocol::default();
    let dig_def = calib::DigitizerProtocol::default();
    let protocol = TargetProtocol {
        board: BoardGeometry {
            squares_x: arg(3, def.board.squares_x as f64) as usize,
            squares_y: arg(4, def.board.squares_y as f64) as usize,
            square_m: arg(5, def.board.square_m * 1e3) * 1e-3,
        },
        views: arg(1, def.views as f64) as usize,
        tilt_min_rad: arg(6, def.tilt_min_rad.to_degrees()).to_radians(),
        tilt_max_rad: arg(7, def.tilt_max_rad.to_degrees()).to_radians(),
        fill: arg(9, def.fill),
        ..def
    };
    let sigma = arg(2, 0.03);
    let seeds = arg(8, 6.0) as u64;
    let tip_depth = arg(10, dig_def.tip_depth_m);
    println!("scale {scale}, sigma {sigma} px, {protocol:?}");
    println!("seed | fx % | fy % | pp px (dx, dy) | k1 % | rot deg | |dt| mm | rms px");
    let mut worst = [0.0f64; 5];
    for seed in 1..=seeds {
        let cfg = hal_sim::SimConfig {
            seed,
            ..hal_sim::SimConfig::with_scale(scale)
        };
        let rig =
            hal_sim::SimRig::new(cfg, Arc::new(brdf::analytic::Lambert { kd: [0.5; 3] })).unwrap();
        let truth = calib::calibration_from_truth(rig.truth()).unwrap();
        let cam = truth.camera;
        let poses = plan_board_poses(&protocol, &cam, seed + 100).expect("poses");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 5);
        let n = Normal::new(0.0, sigma.max(1e-300)).unwrap();
        let views: Vec<Vec<[f64; 2]>> = poses
            .iter()
            .map(|p| {
                let r = p.rotation_matrix();
                let t = Vector3::from(p.translation);
                protocol
                    .board
                    .inner_corners()
                    .iter()
                    .map(|c| {
                        let q = cam
                            .project_camera_point(&(r * Vector3::new(c[0], c[1], 0.0) + t))
                            .unwrap();
                        [q[0] + n.sample(&mut rng), q[1] + n.sample(&mut rng)]
                    })
                    .collect()
            })
            .collect();
        let fit = fit_intrinsics(
            &protocol.board,
            &views,
            cam.width,
            cam.height,
            &IntrinsicOptions::default(),
        )
        .expect("intrinsics");
        let c = fit.camera;
        let noise = common::SimNoise::default();
        let mut dig = rig.digitizer(noise.digitizer_m, seed + 200);
        let tips: Vec<TipCorrespondence> = dig
            .tip_observations(dig_def.tips, tip_depth, noise.tip_pixel_px)
            .into_iter()
            .map(|o| TipCorrespondence {
                world: o.measured,
                pixel: o.pixel,
            })
            .collect();
        let ext = fit_extrinsics(&c, &tips).expect("extrinsics");
        let ext_true = fit_extrinsics(&cam, &tips).expect("extrinsics");
        let rot_true = calib::rotation_angle_between(
            &ext_true.pose.rotation_matrix(),
            &truth.pose.rotation_matrix(),
        )
        .to_degrees();
        let dt_true =
            (ext_true.pose.translation_vector() - truth.pose.translation_vector()).norm() * 1e3;
        let rot = calib::rotation_angle_between(
            &ext.pose.rotation_matrix(),
            &truth.pose.rotation_matrix(),
        )
        .to_degrees();
        let dt = (ext.pose.translation_vector() - truth.pose.translation_vector()).norm() * 1e3;
        let e = [
            100.0 * (c.fx / cam.fx - 1.0).abs(),
            100.0 * (c.fy / cam.fy - 1.0).abs(),
            (c.cx - cam.cx).hypot(c.cy - cam.cy),
            rot,
            dt,
        ];
        for (w, x) in worst.iter_mut().zip(e) {
            *w = w.max(x);
        }
        println!(
            "{seed} | {:.4} | {:.4} | {:.3} ({:+.3}, {:+.3}) | {:.3} | {:.4} | {:.3} | {:.4} | with true intrinsics: {:.4} deg {:.3} mm",
            e[0],
            e[1],
            e[2],
            c.cx - cam.cx,
            c.cy - cam.cy,
            100.0 * (c.k1 / cam.k1 - 1.0).abs(),
            rot,
            dt,
            fit.rms_px,
            rot_true,
            dt_true
        );
    }
    println!(
        "worst: fx {:.4} %, fy {:.4} %, pp {:.3} px, rotation {:.4} deg, |dt| {:.3} mm",
        worst[0], worst[1], worst[2], worst[3], worst[4]
    );
}
