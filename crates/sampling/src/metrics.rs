//! The two error metrics (see docs/sampling.md).
//!
//! * [`log_rms_relative`]: `brdf::metrics::log_relative_rms` on sample grids,
//!   `‖ŷ − y‖ / ‖y − ln 10⁻³‖` over valid points with `y = ln(max(f,0) + 10⁻³)`; a black
//!   reconstruction of a material has error 1.
//! * [`image_rms_relative`]: `‖Î − I‖ / ‖I‖` over all pixels and channels of a sphere image
//!   rendered by [`render_sphere`].

use brdf::{HalfDiff, Rgb, Vec3};

use crate::error::{Result, SamplingError};
use crate::grid::GridTable;

/// Directions (world frame, z towards the orthographic camera) of the fixed point lights, each
/// of unit irradiance at normal incidence.
pub fn sphere_lights() -> [Vec3; 4] {
    [
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(1.0, 1.0, 1.0).normalize(),
        Vec3::new(-1.0, 0.3, 0.6).normalize(),
        Vec3::new(0.3, -1.0, 0.25).normalize(),
    ]
}

/// Relative RMS error in log space over the valid points of `reference`
/// ([`brdf::metrics::log_relative_rms`], the workspace's one definition).
pub fn log_rms_relative(reference: &GridTable, estimate: &GridTable) -> Result<f64> {
    Ok(brdf::metrics::log_relative_rms(reference, estimate)?)
}

/// Renders an orthographic `size × size` image of a unit sphere lit by [`sphere_lights`], with
/// the BRDF looked up (nearest grid point) in `table`. Radiance per pixel and channel is
/// `Σ_l f(l, v) max(n·l, 0)`; pixels off the sphere are 0. Row-major, row 0 at the top (+y).
pub fn render_sphere(table: &GridTable, size: usize) -> Vec<Rgb> {
    let lights = sphere_lights();
    let view = Vec3::new(0.0, 0.0, 1.0);
    let mut img = vec![[0.0; 3]; size * size];
    for pixel in brdf::sphere_pixels(size) {
        let n = pixel.normal;
        let local = |w: &Vec3| pixel.to_local(w);
        let wo = local(&view);
        let mut px = [0.0; 3];
        for l in &lights {
            let cos = l.dot(&n);
            if cos <= 0.0 || wo.z <= 0.0 {
                continue;
            }
            let hd = HalfDiff::from_directions(&local(l), &wo);
            let f = table.lookup(hd.theta_h, hd.theta_d, hd.phi_d);
            for c in 0..3 {
                px[c] += f[c].max(0.0) * cos;
            }
        }
        img[pixel.index] = px;
    }
    img
}

/// Relative RMS difference of the sphere images of `reference` and `estimate`.
pub fn image_rms_relative(reference: &GridTable, estimate: &GridTable, size: usize) -> Result<f64> {
    if reference.grid != estimate.grid {
        return Err(SamplingError::Dimension("tables on different grids".into()));
    }
    let a = render_sphere(reference, size);
    let b = render_sphere(estimate, size);
    let (mut num, mut den) = (0.0, 0.0);
    for (p, q) in a.iter().zip(&b) {
        for c in 0..3 {
            num += (q[c] - p[c]).powi(2);
            den += p[c] * p[c];
        }
    }
    if den <= 0.0 {
        return Err(SamplingError::InvalidParameter(
            "reference image is black".into(),
        ));
    }
    Ok((num / den).sqrt())
}
