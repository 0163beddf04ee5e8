//! The inputs of a calibration read from an operator's files (`DIR/targets/*.png`,
//! `DIR/flats/*.png`, `digitizer.csv`, the layout [`crate::write_run`] writes), and a
//! calibration compared with a known truth.

use crate::board::BoardGeometry;
use crate::error::{CalibError, CalibResult};
use crate::io::{read_digitizer_csv, read_frame_png16, DigitizerLog};
use crate::pipeline::CalibrationInputs;
use crate::schema::Calibration;
use gantry_hal::{BayerFrame, BayerPattern};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// Parses `COLSxROWS` (two positive integers joined by `x`).
pub fn parse_grid(text: &str) -> CalibResult<(usize, usize)> {
    let bad = || CalibError::Invalid(format!("`{text}`: expected COLSxROWS, e.g. 9x6"));
    let (a, b) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    ))
}

/// The files `dir/*.EXT` (extensions compared case-insensitively), sorted by name; an empty
/// list if `dir` does not exist and `optional`.
pub fn list_files(dir: &Path, extensions: &[&str], optional: bool) -> CalibResult<Vec<PathBuf>> {
    if optional && !dir.exists() {
        return Ok(Vec::new());
    }
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(crate::io::io_err(dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| extensions.iter().any(|x| e.eq_ignore_ascii_case(x)))
        })
        .collect();
    paths.sort();
    Ok(paths)
}

/// The files matching a pattern `DIR/*.ext` or `DIR/prefix*.ext` (one `*`, in the file name),
/// sorted by name.
pub fn glob_files(pattern: &str) -> CalibResult<Vec<PathBuf>> {
    let p = Path::new(pattern);
    let dir = p
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = p
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| CalibError::Invalid(format!("image pattern `{pattern}`")))?;
    let (pre, post) = name.split_once('*').unwrap_or((name, ""));
    let exact = !name.contains('*');
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(crate::io::io_err(dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|f| {
            f.file_name().and_then(|n| n.to_str()).is_some_and(|n| {
                if exact {
                    n == name
                } else {
                    n.len() >= pre.len() + post.len() && n.starts_with(pre) && n.ends_with(post)
                }
            })
        })
        .collect();
    paths.sort();
    if paths.is_empty() {
        return Err(CalibError::Invalid(format!("no file matches `{pattern}`")));
    }
    Ok(paths)
}

/// The 16-bit PNG frames `dir/*.png` (`what` they are, for errors), sorted by name (see
/// [`read_frame_png16`]); an empty list if `dir` does not exist and `optional`, an error if
/// there are none otherwise.
pub fn read_frames_dir(
    dir: &Path,
    what: &str,
    optional: bool,
    bit_depth: u8,
    pattern: BayerPattern,
) -> CalibResult<Vec<BayerFrame>> {
    let paths = list_files(dir, &["png"], optional)?;
    if paths.is_empty() && !optional {
        return Err(CalibError::Invalid(format!(
            "{}: no {what} (*.png)",
            dir.display()
        )));
    }
    paths
        .iter()
        .map(|p| read_frame_png16(p, bit_depth, pattern))
        .collect()
}

/// Calibration inputs from target frames, flat frames and a digitizer log.
pub fn inputs_from(
    board: BoardGeometry,
    target_frames: Vec<BayerFrame>,
    flat_frames: Vec<BayerFrame>,
    log: DigitizerLog,
) -> CalibrationInputs {
    CalibrationInputs {
        board,
        target_frames,
        flat_frames,
        tips: log.tips,
        lamp: log.lamp,
        sphere_points: log.sphere_points,
        sphere_diameter_m: log.sphere_diameter_m,
    }
}

/// The inputs an operator collected in `dir` (`targets/*.png`, optional `flats/*.png`, and
/// `digitizer.csv` unless `digitizer` names another log).
pub fn read_session(
    dir: &Path,
    board: BoardGeometry,
    digitizer: Option<&Path>,
    bit_depth: u8,
    pattern: BayerPattern,
) -> CalibResult<CalibrationInputs> {
    let frames = read_frames_dir(
        &dir.join("targets"),
        "target images",
        false,
        bit_depth,
        pattern,
    )?;
    let flats = read_frames_dir(&dir.join("flats"), "flat frames", true, bit_depth, pattern)?;
    let log = match digitizer {
        Some(p) => read_digitizer_csv(p)?,
        None => read_digitizer_csv(&dir.join("digitizer.csv"))?,
    };
    Ok(inputs_from(board, frames, flats, log))
}

/// How far a calibration is from a known truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthComparison {
    /// fx / fx_true − 1.
    pub fx_rel: f64,
    /// fy / fy_true − 1.
    pub fy_rel: f64,
    /// Principal point distance, pixels.
    pub principal_point_px: f64,
    /// k1 / k1_true − 1.
    pub k1_rel: f64,
    /// Camera rotation error, radians.
    pub rotation_rad: f64,
    /// Camera translation error, metres.
    pub translation_m: f64,
    /// Lamp centre error, metres.
    pub lamp_centre_m: f64,
    /// Lamp radius error, metres.
    pub lamp_radius_m: f64,
    /// Sphere centre error, metres.
    pub sphere_centre_m: f64,
}

impl TruthComparison {
    /// Compares `c` with `truth`.
    pub fn new(c: &Calibration, truth: &Calibration) -> Self {
        let (a, t) = (&c.camera, &truth.camera);
        Self {
            fx_rel: a.fx / t.fx - 1.0,
            fy_rel: a.fy / t.fy - 1.0,
            principal_point_px: (a.cx - t.cx).hypot(a.cy - t.cy),
            k1_rel: a.k1 / t.k1 - 1.0,
            rotation_rad: crate::rotation_angle_between(
                &c.pose.rotation_matrix(),
                &truth.pose.rotation_matrix(),
            ),
            translation_m: (c.pose.translation_vector() - truth.pose.translation_vector()).norm(),
            lamp_centre_m: (Vector3::from(c.lamp.centre) - Vector3::from(truth.lamp.centre)).norm(),
            lamp_radius_m: (c.lamp.radius - truth.lamp.radius).abs(),
            sphere_centre_m: (Vector3::from(c.sphere.centre) - Vector3::from(truth.sphere.centre))
                .norm(),
        }
    }
}

impl std::fmt::Display for TruthComparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "against the simulator's truth: fx {:+.4}%, fy {:+.4}%, principal point {:.2} px, k1 {:+.2}%",
            100.0 * self.fx_rel,
            100.0 * self.fy_rel,
            self.principal_point_px,
            100.0 * self.k1_rel
        )?;
        write!(
            f,
            "  rotation {:.4}°, translation {:.3} mm, lamp centre {:.3} mm, lamp radius {:.3} mm, sphere centre {:.3} mm",
            self.rotation_rad.to_degrees(),
            1e3 * self.translation_m,
            1e3 * self.lamp_centre_m,
            1e3 * self.lamp_radius_m,
            1e3 * self.sphere_centre_m
        )
    }
}
