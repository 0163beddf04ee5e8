//! The checkerboard target's layout.

use crate::error::{check_finite, CalibError, CalibResult};
use serde::{Deserialize, Serialize};

/// Layout of a checkerboard target: `squares_x × squares_y` squares of side `square_m`; its
/// inner corners are at (i·s, j·s, 0), i = 1..squares_x−1, j = 1..squares_y−1, listed row-major
/// (j outer), the order of every corner list in this crate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardGeometry {
    /// Squares along x.
    pub squares_x: usize,
    /// Squares along y.
    pub squares_y: usize,
    /// Square side, metres.
    pub square_m: f64,
}

impl BoardGeometry {
    /// Inner corners per row (x).
    pub fn corners_x(&self) -> usize {
        self.squares_x.saturating_sub(1)
    }

    /// Inner corners per column (y).
    pub fn corners_y(&self) -> usize {
        self.squares_y.saturating_sub(1)
    }

    /// Inner corners in target coordinates (z = 0), row-major.
    pub fn inner_corners(&self) -> Vec<[f64; 2]> {
        let s = self.square_m;
        (1..self.squares_y)
            .flat_map(|j| (1..self.squares_x).map(move |i| [i as f64 * s, j as f64 * s]))
            .collect()
    }

    /// Checks that the board has at least 3 × 3 squares of positive size.
    pub fn validate(&self) -> CalibResult<()> {
        check_finite("board square size", &[self.square_m])?;
        if self.squares_x < 3 || self.squares_y < 3 || !(self.square_m > 0.0) {
            return Err(CalibError::Invalid(format!(
                "checkerboard {}x{} squares of {} m",
                self.squares_x, self.squares_y, self.square_m
            )));
        }
        Ok(())
    }
}

impl BoardGeometry {
    /// The board with `cols × rows` inner corners (OpenCV's `patternSize`, e.g. 9 × 6 on its
    /// sample photographs) of side `square_m`.
    pub fn from_inner_corners(cols: usize, rows: usize, square_m: f64) -> Self {
        Self {
            squares_x: cols + 1,
            squares_y: rows + 1,
            square_m,
        }
    }
}
