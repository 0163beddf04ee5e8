//! A lit-sphere preview for an editor.

use brdf::Vec3;
use brdf::{reference_bin, BINS};

/// The precomputed lookups of a lit-sphere image.
///
/// A lit-sphere preview for an editor: the bins a `size × size` image of a sphere under one
/// directional light reads, found once, so each slider move shades the image from the kept
/// back-projection at those bins only (no full table).
///
/// The sphere is seen orthographically along `+z`; the light direction is in the same frame.
/// Each pixel's BRDF value is the table's nearest-bin lookup with the MERL reference reader's
/// arithmetic ([`brdf::MerlTable::lookup_reference`]); the pixel value is `f · cos θi`.
///
/// # Examples
///
/// ```
/// use traits::SpherePreview;
/// // Lit from the viewer: a Lambertian sphere is brightest (kd/π) where it faces the light.
/// let preview = SpherePreview::new(33, [0.0, 0.0, 1.0]);
/// assert!(!preview.pixels.is_empty() && preview.pixels.len() <= 33 * 33);
/// let table = brdf::load("lambert:kd=0.5").unwrap().tabulate();
/// let image = preview.shade_table(&table);
/// assert_eq!(image.len(), 33 * 33);
/// let peak = image.iter().map(|p| p[0]).fold(0.0f32, f32::max);
/// assert!((peak - 0.5 / std::f32::consts::PI).abs() < 2e-3, "{peak}");
/// // Shading the log-space values gives the same image.
/// let log = reduce::log_vector(&table.values()).unwrap();
/// let from_log = preview.shade_log(&log);
/// assert!(image.iter().zip(&from_log).all(|(a, b)| (0..3).all(|c| (a[c] - b[c]).abs() < 1e-4)));
/// ```
#[derive(Debug, Clone)]
pub struct SpherePreview {
    /// Image side in pixels.
    pub size: usize,
    /// Lit pixels: `(pixel index, bin, cos θi)`; other pixels are black.
    pub pixels: Vec<(usize, usize, f32)>,
}

impl SpherePreview {
    /// The preview of a `size × size` sphere lit from `light` (normalised here; a zero vector
    /// lights from the viewer).
    pub fn new(size: usize, light: [f64; 3]) -> SpherePreview {
        let mut l = Vec3::new(light[0], light[1], light[2]);
        if l.norm() > 0.0 {
            l /= l.norm();
        } else {
            l = Vec3::z();
        }
        let v = Vec3::z();
        let mut pixels = Vec::new();
        for pixel in brdf::sphere_pixels(size) {
            let (wi, wo) = (pixel.to_local(&l), pixel.to_local(&v));
            if wi.z <= 0.0 || wo.z <= 0.0 {
                continue;
            }
            let bin = reference_bin(&wi, &wo);
            pixels.push((pixel.index, bin, wi.z as f32));
        }
        SpherePreview { size, pixels }
    }

    /// RGB image (`size²` pixels, row-major) of channel-major log-space values
    /// (`3 × BINS`, as [`crate::navigate::State::log`] keeps them), clamped at 0.
    pub fn shade_log(&self, log: &[f32]) -> Vec<[f32; 3]> {
        let mut img = vec![[0.0f32; 3]; self.size * self.size];
        if log.len() < 3 * BINS {
            return img;
        }
        for &(p, bin, cos) in &self.pixels {
            for c in 0..3 {
                let f = reduce::from_log(log[c * BINS + bin]).max(0.0) as f32;
                img[p][c] = f * cos;
            }
        }
        img
    }

    /// The same image of a table (its values at the preview's bins; missing bins black).
    pub fn shade_table(&self, table: &brdf::MerlTable) -> Vec<[f32; 3]> {
        let mut img = vec![[0.0f32; 3]; self.size * self.size];
        for &(p, bin, cos) in &self.pixels {
            if let Some(rgb) = table.bin_rgb(bin) {
                for c in 0..3 {
                    img[p][c] = rgb[c] as f32 * cos;
                }
            }
        }
        img
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf::analytic::Ggx;
    use brdf::MerlTable;

    #[test]
    fn preview_agrees_with_the_reference_lookup() {
        let g = Ggx {
            kd: [0.3, 0.2, 0.1],
            ks: [0.5; 3],
            alpha: 0.2,
            ior: 1.5,
        };
        let table = MerlTable::tabulate(&g);
        let light = [0.3, 0.4, 0.866];
        let p = SpherePreview::new(32, light);
        let img = p.shade_table(&table);
        let l = Vec3::new(light[0], light[1], light[2]).normalize();
        let mut lit = 0;
        for py in 0..32 {
            for px in 0..32 {
                let x = 2.0 * (px as f64 + 0.5) / 32.0 - 1.0;
                let y = 1.0 - 2.0 * (py as f64 + 0.5) / 32.0;
                if x * x + y * y >= 1.0 {
                    continue;
                }
                let n = Vec3::new(x, y, (1.0 - x * x - y * y).sqrt());
                // Independent frame: any tangent works for an isotropic table.
                let t = n.cross(&Vec3::new(0.3, -0.7, 0.2)).normalize();
                let b = n.cross(&t);
                let loc = |w: &Vec3| Vec3::new(w.dot(&t), w.dot(&b), w.dot(&n));
                let (wi, wo) = (loc(&l), loc(&Vec3::z()));
                let want = if wi.z > 0.0 {
                    lit += 1;
                    let f = table.lookup_reference(&wi, &wo).unwrap();
                    [f[0] * wi.z, f[1] * wi.z, f[2] * wi.z]
                } else {
                    [0.0; 3]
                };
                let got = img[py * 32 + px];
                for c in 0..3 {
                    let tol = 1e-4 * (1.0 + want[c].abs());
                    assert!(
                        (got[c] as f64 - want[c]).abs() < tol,
                        "{px},{py}: {got:?} {want:?}"
                    );
                }
            }
        }
        assert_eq!(lit, p.pixels.len());
        // From log values: the same image up to the log round trip.
        let log = reduce::log_vector(&table.values()).unwrap();
        let from_log = p.shade_log(&log);
        for (a, b) in from_log.iter().zip(&img) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-4 * (1.0 + b[c].abs()));
            }
        }
    }
}
