//! Linear RGB images: OpenEXR input/output and tonemapped sRGB PNG output (atomic writes).

use crate::error::{RenderError, Result};
use std::path::Path;

/// A linear-RGB image, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    width: usize,
    height: usize,
    pixels: Vec<[f32; 3]>,
}

/// How linear radiance becomes display values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tonemap {
    /// Multiplier applied before the curve.
    pub exposure: f64,
    /// The curve.
    pub operator: TonemapOperator,
}

/// Tone curves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TonemapOperator {
    /// Clip to [0, 1].
    #[default]
    Clamp,
    /// `x / (1 + x)` per channel.
    Reinhard,
}

impl Default for Tonemap {
    fn default() -> Self {
        Self {
            exposure: 1.0,
            operator: TonemapOperator::Clamp,
        }
    }
}

/// sRGB transfer function of a linear value in [0, 1].
pub fn srgb_encode(x: f64) -> f64 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

impl Image {
    /// A black image. Errors on zero or absurd dimensions.
    pub fn new(width: usize, height: usize) -> Result<Self> {
        if width == 0 || height == 0 || width.saturating_mul(height) > 1 << 28 {
            return Err(RenderError::InvalidArgument(format!(
                "image size {width}×{height}"
            )));
        }
        Ok(Self {
            width,
            height,
            pixels: vec![[0.0; 3]; width * height],
        })
    }

    /// Builds an image from row-major pixels.
    pub fn from_pixels(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Result<Self> {
        if width == 0 || height == 0 || pixels.len() != width * height {
            return Err(RenderError::InvalidArgument(format!(
                "{} pixels for a {width}×{height} image",
                pixels.len()
            )));
        }
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row-major pixels.
    pub fn pixels(&self) -> &[[f32; 3]] {
        &self.pixels
    }

    /// Mutable row-major pixels.
    pub fn pixels_mut(&mut self) -> &mut [[f32; 3]] {
        &mut self.pixels
    }

    /// Pixel at column `x`, row `y` (panics out of range, like slice indexing).
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.pixels[y * self.width + x]
    }

    /// Sets a pixel.
    pub fn set(&mut self, x: usize, y: usize, v: [f32; 3]) {
        self.pixels[y * self.width + x] = v;
    }

    /// Mean of each channel over the rectangle `[x0, x1) × [y0, y1)` (clipped to the image).
    pub fn region_mean(&self, x0: usize, y0: usize, x1: usize, y1: usize) -> [f64; 3] {
        let (x1, y1) = (x1.min(self.width), y1.min(self.height));
        let mut s = [0.0; 3];
        let mut n = 0usize;
        for y in y0..y1 {
            for x in x0..x1 {
                let p = self.get(x, y);
                for c in 0..3 {
                    s[c] += p[c] as f64;
                }
                n += 1;
            }
        }
        s.map(|v| v / n.max(1) as f64)
    }

    /// 8-bit sRGB bytes (RGB interleaved) after tonemapping.
    pub fn to_srgb8(&self, tonemap: &Tonemap) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pixels.len() * 3);
        for p in &self.pixels {
            for &c in p {
                let mut x = c as f64 * tonemap.exposure;
                if !x.is_finite() || x < 0.0 {
                    x = 0.0;
                }
                let y = match tonemap.operator {
                    TonemapOperator::Clamp => x.min(1.0),
                    TonemapOperator::Reinhard => x / (1.0 + x),
                };
                out.push((srgb_encode(y) * 255.0 + 0.5).clamp(0.0, 255.0) as u8);
            }
        }
        out
    }

    /// Writes linear float RGB OpenEXR, atomically (temporary file + rename).
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        use exr::prelude::{Image as ExrImage, SpecificChannels, WritableImage};
        let channels = SpecificChannels::rgb(|pos: exr::math::Vec2<usize>| {
            let p = self.pixels[pos.y() * self.width + pos.x()];
            (p[0], p[1], p[2])
        });
        let image = ExrImage::from_channels((self.width, self.height), channels);
        let mut encoder_error = None;
        brdf::write_atomic_with(path, |w| {
            image.write().to_buffered(w).map_err(|e| {
                encoder_error = Some(e.to_string());
                std::io::Error::other(e.to_string())
            })
        })
        .map_err(|e| match encoder_error.take() {
            Some(message) => RenderError::Exr {
                path: path.to_path_buf(),
                message,
            },
            None => RenderError::io(path, e),
        })
    }

    /// Reads the first RGB(A) layer of an OpenEXR file (alpha ignored).
    pub fn read_exr(path: &Path) -> Result<Self> {
        let to_err = |e: exr::error::Error| RenderError::Exr {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let img = exr::prelude::read_first_rgba_layer_from_file(
            path,
            |res, _| (res.width(), vec![[0f32; 3]; res.width() * res.height()]),
            |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                px[pos.y() * *w + pos.x()] = [r, g, b];
            },
        )
        .map_err(to_err)?;
        let size = img.layer_data.size;
        let (_, pixels) = img.layer_data.channel_data.pixels;
        let pixels: Vec<[f32; 3]> = pixels
            .into_iter()
            .map(|p| p.map(|c| if c.is_finite() { c } else { 0.0 }))
            .collect();
        Self::from_pixels(size.width(), size.height(), pixels)
    }

    /// Writes a tonemapped 8-bit sRGB PNG, atomically.
    pub fn write_png(&self, path: &Path, tonemap: &Tonemap) -> Result<()> {
        let png_error = |e: image::ImageError| RenderError::Png {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let buf = image::RgbImage::from_raw(
            self.width as u32,
            self.height as u32,
            self.to_srgb8(tonemap),
        )
        .ok_or_else(|| RenderError::Png {
            path: path.to_path_buf(),
            message: "pixel buffer does not match the image size".into(),
        })?;
        let mut bytes = std::io::Cursor::new(Vec::new());
        buf.write_to(&mut bytes, image::ImageFormat::Png)
            .map_err(png_error)?;
        brdf::write_atomic_with(path, |w| std::io::Write::write_all(w, bytes.get_ref()))
            .map_err(|e| RenderError::io(path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_is_exact_and_png_is_written() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = Image::new(7, 5).unwrap();
        for y in 0..5 {
            for x in 0..7 {
                img.set(x, y, [x as f32 * 0.25, y as f32 * 1e3, 1e-4]);
            }
        }
        let p = dir.path().join("a.exr");
        img.write_exr(&p).unwrap();
        let back = Image::read_exr(&p).unwrap();
        assert_eq!(back, img);
        let q = dir.path().join("a.png");
        img.write_png(&q, &Tonemap::default()).unwrap();
        let png = image::open(&q).unwrap().to_rgb8();
        assert_eq!(png.dimensions(), (7, 5));
        // x = 4 → 1.0 → 255; x = 0 → 0
        assert_eq!(png.get_pixel(4, 0)[0], 255);
        assert_eq!(png.get_pixel(0, 0)[0], 0);
        assert!(Image::read_exr(&q).is_err());
        // no temporary files left behind
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }
}
