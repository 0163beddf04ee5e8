//! The lamp positions of a capture (thesis §3.4).

/// Number of lamp positions of the thesis's rig: 330 positions 0.5° apart.
pub const THESIS_POSITIONS: usize = 330;

/// Angle of the last lamp position, degrees from the point opposite the camera.
pub const LAST_POSITION_DEG: f64 = 164.5;

/// Angles of `n` lamp positions from the point opposite the camera (0°) to 164.5°: the thesis's
/// 330 positions 0.5° apart, or fewer positions spread over the same arc.
///
/// ```
/// let a = gantry_hal::position_angles(330);
/// assert_eq!(a.len(), 330);
/// assert!((a[1] - a[0] - 0.5).abs() < 1e-12 && a[329] == 164.5);
/// ```
pub fn position_angles(n: usize) -> Vec<f64> {
    match n {
        0 => Vec::new(),
        1 => vec![0.0],
        _ => (0..n)
            .map(|i| LAST_POSITION_DEG * i as f64 / (n - 1) as f64)
            .collect(),
    }
}
