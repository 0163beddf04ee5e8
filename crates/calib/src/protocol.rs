//! The target protocol: which checkerboard the operator shows the camera, and in which poses;
//! and how the contact digitizer is used.

use crate::board::BoardGeometry;
use crate::error::{check_finite, CalibError, CalibResult};
use crate::intrinsics::BoardPose;
use gantry_hal::CameraIntrinsics;
use nalgebra::{Rotation3, Unit, Vector3};
use serde::{Deserialize, Serialize};

/// How the checkerboard is shown to the camera.
///
/// The gantry camera has a narrow field of view (about 6°). There a shift of the principal
/// point is almost the same image change as a small rotation of every board: only a term of
/// second order in the imaged field separates the two, whatever the board's orientation. The
/// principal point is therefore determined by how much of the image the boards cover (its
/// error grows as 1/fill²) and by the number of corners (1/√N); tilted views (here 20°–50°
/// about axes going round the optical axis) are what determines the focal lengths. The
/// default is a fine board (432 corners) in 30 views, each filling 92 % of the image. The
/// other factor is the corner error itself, which the protocol lowers by exposing every pose 4
/// times and taking 16 flat frames for the flat-field correction ([`crate::stack_frames`];
/// docs/calib.md has both studies).
///
/// [`plan_board_poses`] turns a [`TargetProtocol`] into concrete board poses for a camera:
/// pure geometry, used by the simulator-driven validation and as the operator's guide.
///
/// # Examples
///
/// ```
/// use calib::{plan_board_poses, CameraIntrinsics, TargetProtocol};
///
/// let camera = CameraIntrinsics::radial(1300, 1030, 12150.0, 12170.0, 650.0, 515.0, 0.0, 0.0);
/// let protocol = TargetProtocol::default();
/// let poses = plan_board_poses(&protocol, &camera, 1).unwrap();
/// assert_eq!(poses.len(), protocol.views);
/// // the boards face the camera from in front of it
/// assert!(poses.iter().all(|p| p.translation[2] > 0.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TargetProtocol {
    /// The checkerboard.
    pub board: BoardGeometry,
    /// Number of target images.
    pub views: usize,
    /// Smallest tilt of the board out of the image plane, radians.
    pub tilt_min_rad: f64,
    /// Largest tilt of the board out of the image plane, radians.
    pub tilt_max_rad: f64,
    /// Largest spin of the board about its own normal, radians.
    pub spin_max_rad: f64,
    /// Fraction of the image width and height the corners' bounding box may span; the board
    /// distance is chosen so that the bounding box reaches it in one direction.
    pub fill: f64,
    /// Exposures taken of each pose and summed ([`crate::stack_frames`]): photon noise falls
    /// as 1/√n.
    #[serde(default = "default_frames_per_view")]
    pub frames_per_view: usize,
    /// Exposures of a uniformly lit diffuser summed into the flat frame ([`crate::FlatField`]);
    /// 0 for no flat-field correction.
    #[serde(default = "default_flat_frames")]
    pub flat_frames: usize,
}

fn default_frames_per_view() -> usize {
    4
}

fn default_flat_frames() -> usize {
    16
}

impl Default for TargetProtocol {
    /// 30 views of a 25 × 19 board of 3 mm squares (24 × 18 = 432 inner corners), tilted by
    /// 20°–50°, filling 92 % of the image (for the full 1300 × 1030 sensor); each pose
    /// exposed 4 times, and a flat frame of 16 exposures.
    fn default() -> Self {
        Self {
            board: BoardGeometry {
                squares_x: 25,
                squares_y: 19,
                square_m: 0.003,
            },
            views: 30,
            tilt_min_rad: 20f64.to_radians(),
            tilt_max_rad: 50f64.to_radians(),
            spin_max_rad: 20f64.to_radians(),
            fill: 0.92,
            frames_per_view: default_frames_per_view(),
            flat_frames: default_flat_frames(),
        }
    }
}

impl TargetProtocol {
    /// The default protocol for a sensor `width` pixels wide: the fine board of
    /// [`TargetProtocol::default`] from 1000 px up; on smaller sensors, where its squares would
    /// shrink below ~15 px, a 13 × 10 board of 6 mm squares (12 × 9 inner corners). Below
    /// 160 px (a tenth of the full sensor) the board fills 80 % of the image instead of 92 %:
    /// at 92 % the outermost corners come within the detector's ring radius (about 5 px) of the
    /// image border and 28 of 30 simulated views lose one to three of them; at 80 %, 26 of 30
    /// views show the whole board.
    pub fn for_sensor(width: usize) -> Self {
        let fine = Self::default();
        if width >= 1000 {
            return fine;
        }
        Self {
            board: BoardGeometry {
                squares_x: 13,
                squares_y: 10,
                square_m: 0.006,
            },
            fill: if width < 160 { 0.8 } else { fine.fill },
            ..fine
        }
    }

    /// Checks the protocol's parameters.
    pub fn validate(&self) -> CalibResult<()> {
        self.board.validate()?;
        check_finite(
            "target protocol",
            &[
                self.tilt_min_rad,
                self.tilt_max_rad,
                self.spin_max_rad,
                self.fill,
            ],
        )?;
        if self.views < 3 {
            return Err(CalibError::TooFewPoints {
                what: "target images",
                got: self.views,
                need: 3,
            });
        }
        if !(0.0 <= self.tilt_min_rad
            && self.tilt_min_rad <= self.tilt_max_rad
            && self.tilt_max_rad < 85f64.to_radians())
        {
            return Err(CalibError::Invalid(format!(
                "board tilts {}..{} rad (need 0 ≤ min ≤ max < 85°)",
                self.tilt_min_rad, self.tilt_max_rad
            )));
        }
        if self.frames_per_view == 0 || self.frames_per_view > 64 || self.flat_frames > 64 {
            return Err(CalibError::Invalid(format!(
                "{} exposures per pose and {} flat exposures (need 1–64 and 0–64)",
                self.frames_per_view, self.flat_frames
            )));
        }
        if !(self.fill > 0.1 && self.fill < 1.0) {
            return Err(CalibError::Invalid(format!(
                "image fill {} (need 0.1 < fill < 1)",
                self.fill
            )));
        }
        Ok(())
    }
}

/// SplitMix64: a seeded, reproducible source of the protocol's small jitters.
fn splitmix(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Bounding box (min u, min v, max u, max v) of the board's corners at `pose`; `None` if a
/// corner is behind the camera.
fn corner_box(
    board: &BoardGeometry,
    camera: &CameraIntrinsics,
    pose: &BoardPose,
) -> Option<[f64; 4]> {
    let r = pose.rotation_matrix();
    let t = Vector3::from(pose.translation);
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in board.inner_corners() {
        let p = r * Vector3::new(c[0], c[1], 0.0) + t;
        let q = camera.project_camera_point(&p)?;
        b = [
            b[0].min(q[0]),
            b[1].min(q[1]),
            b[2].max(q[0]),
            b[3].max(q[1]),
        ];
    }
    Some(b)
}

/// Board poses (target → camera, as [`BoardPose`]) following `protocol` for `camera`, seeded.
///
/// View k is tilted about an in-image-plane axis at azimuth 360°·k/n (plus a seeded jitter),
/// by a tilt spread evenly over [`TargetProtocol::tilt_min_rad`, `tilt_max_rad`], spun about
/// its normal by up to ±`spin_max_rad`; its distance is chosen so that the corners span
/// `fill` of the image in width or height, and the board is centred in the image with a
/// seeded offset inside the margin that is left (which changes the span slightly). Every
/// corner of every pose lies inside the
/// image.
pub fn plan_board_poses(
    protocol: &TargetProtocol,
    camera: &CameraIntrinsics,
    seed: u64,
) -> CalibResult<Vec<BoardPose>> {
    protocol.validate()?;
    camera.validate()?;
    let board = &protocol.board;
    let (w, h) = (camera.width as f64, camera.height as f64);
    let centre = [
        0.5 * board.squares_x as f64 * board.square_m,
        0.5 * board.squares_y as f64 * board.square_m,
    ];
    let mut state = seed ^ 0x5EED_CA11_B0A2_D000;
    let n = protocol.views;
    let phase = splitmix(&mut state) * std::f64::consts::TAU;
    let mut poses = Vec::with_capacity(n);
    for k in 0..n {
        // Azimuth of the tilt axis goes round the optical axis; the tilt magnitudes are a
        // shuffled (by a golden-ratio stride) even spread over [min, max].
        let azimuth = phase
            + std::f64::consts::TAU * (k as f64 + 0.3 * (splitmix(&mut state) - 0.5)) / n as f64;
        let frac = if n > 1 {
            ((k as f64 * 0.618_033_988_75) % 1.0 + 0.1 * (splitmix(&mut state) - 0.5))
                .clamp(0.0, 1.0)
        } else {
            0.5
        };
        let tilt = protocol.tilt_min_rad + frac * (protocol.tilt_max_rad - protocol.tilt_min_rad);
        let spin = protocol.spin_max_rad * (2.0 * splitmix(&mut state) - 1.0);
        let axis = Unit::new_normalize(Vector3::new(azimuth.cos(), azimuth.sin(), 0.0));
        let rot = Rotation3::from_axis_angle(&axis, tilt)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), spin);
        let rc = rot * Vector3::new(centre[0], centre[1], 0.0);
        let pose_at = |dist: f64, du: f64, dv: f64| {
            // Board centre on the ray of the image point (cx + du, cy + dv) at depth `dist`.
            let c = Vector3::new(du / camera.fx * dist, dv / camera.fy * dist, dist);
            let t = c - rc;
            let rv = rot.scaled_axis();
            BoardPose {
                rotation: [rv.x, rv.y, rv.z],
                translation: [t.x, t.y, t.z],
            }
        };
        // Distance: the projected size scales about as 1/distance; iterate to the fill.
        let mut dist = 1.0;
        let mut pose = pose_at(dist, 0.0, 0.0);
        for _ in 0..30 {
            let b = corner_box(board, camera, &pose).ok_or_else(|| {
                CalibError::Degenerate("planned board pose is behind the camera".into())
            })?;
            let span = ((b[2] - b[0]) / w).max((b[3] - b[1]) / h);
            let ratio = span / protocol.fill;
            dist *= ratio;
            pose = pose_at(dist, 0.0, 0.0);
            if (ratio - 1.0).abs() < 1e-6 {
                break;
            }
        }
        // Centre the box, then offset it by a seeded fraction of the margin left.
        let mut shift = [0.0, 0.0];
        for _ in 0..10 {
            let b = corner_box(board, camera, &pose).ok_or_else(|| {
                CalibError::Degenerate("planned board pose is behind the camera".into())
            })?;
            let mid = [0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])];
            shift[0] += 0.5 * (w - 1.0) - mid[0];
            shift[1] += 0.5 * (h - 1.0) - mid[1];
            pose = pose_at(dist, shift[0], shift[1]);
        }
        let b = corner_box(board, camera, &pose).ok_or_else(|| {
            CalibError::Degenerate("planned board pose is behind the camera".into())
        })?;
        let margin = [
            0.5 * (w - (b[2] - b[0])) - 0.03 * w,
            0.5 * (h - (b[3] - b[1])) - 0.03 * h,
        ];
        shift[0] += margin[0].max(0.0) * (2.0 * splitmix(&mut state) - 1.0);
        shift[1] += margin[1].max(0.0) * (2.0 * splitmix(&mut state) - 1.0);
        pose = pose_at(dist, shift[0], shift[1]);
        let b = corner_box(board, camera, &pose).ok_or_else(|| {
            CalibError::Degenerate("planned board pose is behind the camera".into())
        })?;
        if !(b[0] > 0.0 && b[1] > 0.0 && b[2] < w - 1.0 && b[3] < h - 1.0) {
            return Err(CalibError::Degenerate(format!(
                "planned view {k} does not fit the {}x{} image",
                camera.width, camera.height
            )));
        }
        poses.push(pose);
    }
    Ok(poses)
}

/// How the contact digitizer is used: how many tip/pixel correspondences over which depth
/// range, which turntable angles for the lamp, how many sphere points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DigitizerProtocol {
    /// Number of digitizer-tip / pixel correspondences.
    pub tips: usize,
    /// The tips are spread over ± this depth (metres) about the sphere's distance: the depth
    /// spread is the lever arm that separates a camera rotation from a translation.
    pub tip_depth_m: f64,
    /// Turntable angles (degrees) at which the lamp is digitized.
    pub lamp_angles_deg: Vec<f64>,
    /// Number of digitized points on the sphere surface.
    pub sphere_points: usize,
}

impl Default for DigitizerProtocol {
    /// 30 tips over ±150 mm in depth, lamp at 0°, 6°, …, 174°, 30 sphere points.
    fn default() -> Self {
        Self {
            tips: 30,
            tip_depth_m: 0.15,
            lamp_angles_deg: (0..30).map(|k| k as f64 * 6.0).collect(),
            sphere_points: 30,
        }
    }
}
