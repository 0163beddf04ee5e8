//! Linear RGB images: OpenEXR input/output, Radiance `.hdr` input and tonemapped sRGB PNG
//! output (atomic writes).

use crate::error::{RenderError, Result};
use std::path::Path;

/// A linear-RGB image, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    width: usize,
    height: usize,
    pixels: Vec<[f32; 3]>,
}

/// Largest image [`Image::decode_hdr`] and [`Image::read_exr`] accept, in pixels (8192 × 4096, the size of the
/// largest common light probes). Run-length encoding lets a few bytes announce any size, so
/// this bounds the memory a file can make the reader take (16 bytes per pixel at the peak).
pub const MAX_HDR_PIXELS: usize = 8192 * 4096;

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

    /// Reads the first RGB(A) layer of an OpenEXR file (alpha ignored); see
    /// [`Image::decode_exr`].
    pub fn read_exr(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| RenderError::io(path, e))?;
        Self::decode_exr(&bytes, path)
    }

    /// Decodes the first RGB(A) layer of an OpenEXR file held in memory (alpha ignored;
    /// non-finite values read as 0); `path` only names the file in errors. The headers are
    /// read first: a layer of more than [`MAX_HDR_PIXELS`] pixels is refused before any pixel
    /// memory is taken.
    pub fn decode_exr(bytes: &[u8], path: &Path) -> Result<Self> {
        use exr::prelude::*;
        let to_err = |e: exr::error::Error| RenderError::Exr {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
            .map_err(to_err)?;
        if let Some(h) = meta
            .headers
            .iter()
            .find(|h| h.layer_size.width().saturating_mul(h.layer_size.height()) > MAX_HDR_PIXELS)
        {
            return Err(RenderError::Exr {
                path: path.to_path_buf(),
                message: format!(
                    "a {}×{} layer is more than the {MAX_HDR_PIXELS} pixels accepted",
                    h.layer_size.width(),
                    h.layer_size.height()
                ),
            });
        }
        let img = read()
            .no_deep_data()
            .largest_resolution_level()
            .rgba_channels(
                |res, _| (res.width(), vec![[0f32; 3]; res.width() * res.height()]),
                |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                    px[pos.y() * *w + pos.x()] = [r, g, b];
                },
            )
            .first_valid_layer()
            .all_attributes()
            .from_buffered(std::io::Cursor::new(bytes))
            .map_err(to_err)?;
        let size = img.layer_data.size;
        let (_, pixels) = img.layer_data.channel_data.pixels;
        let pixels: Vec<[f32; 3]> = pixels
            .into_iter()
            .map(|p| p.map(|c| if c.is_finite() { c } else { 0.0 }))
            .collect();
        Self::from_pixels(size.width(), size.height(), pixels)
    }

    /// Reads a Radiance `.hdr` (RGBE) image; see [`Image::decode_hdr`].
    pub fn read_hdr(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| RenderError::io(path, e))?;
        Self::decode_hdr(&bytes, path)
    }

    /// Decodes a Radiance `.hdr` (RGBE, flat or run-length encoded) image held in memory;
    /// `path` only names the file in errors. Images larger than [`MAX_HDR_PIXELS`] are
    /// refused before any pixel memory is taken.
    pub fn decode_hdr(bytes: &[u8], path: &Path) -> Result<Self> {
        use image::ImageDecoder;
        let fail = |message: String| RenderError::Hdr {
            path: path.to_path_buf(),
            message,
        };
        let decoder = image::codecs::hdr::HdrDecoder::new(std::io::Cursor::new(bytes))
            .map_err(|e| fail(e.to_string()))?;
        let (w, h) = decoder.dimensions();
        let (w, h) = (w as usize, h as usize);
        if w == 0 || h == 0 {
            return Err(fail(format!("empty image ({w}×{h})")));
        }
        if w.saturating_mul(h) > MAX_HDR_PIXELS {
            return Err(fail(format!(
                "{w}×{h} pixels is more than the {MAX_HDR_PIXELS} this reader accepts"
            )));
        }
        let mut raw = vec![0u8; decoder.total_bytes() as usize];
        decoder
            .read_image(&mut raw)
            .map_err(|e| fail(e.to_string()))?;
        // The decoder writes native-endian f32 RGB triples.
        let pixels: Vec<[f32; 3]> = raw
            .chunks_exact(12)
            .map(|c| {
                let v = |k: usize| {
                    let x = f32::from_ne_bytes([c[k], c[k + 1], c[k + 2], c[k + 3]]);
                    if x.is_finite() && x > 0.0 {
                        x
                    } else {
                        0.0
                    }
                };
                [v(0), v(4), v(8)]
            })
            .collect();
        Self::from_pixels(w, h, pixels)
    }

    /// The image at half the size: each pixel the mean of a 2 × 2 block (an odd last row or
    /// column is dropped). Errors on an image smaller than 2 × 2.
    pub fn halved(&self) -> Result<Self> {
        let (w, h) = (self.width / 2, self.height / 2);
        if w == 0 || h == 0 {
            return Err(RenderError::InvalidArgument(format!(
                "cannot halve a {}×{} image",
                self.width, self.height
            )));
        }
        let mut pixels = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0f32; 3];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let p = self.pixels[(2 * y + dy) * self.width + 2 * x + dx];
                    for c in 0..3 {
                        sum[c] += 0.25 * p[c];
                    }
                }
                pixels.push(sum);
            }
        }
        Self::from_pixels(w, h, pixels)
    }

    /// Decodes an OpenEXR or Radiance `.hdr` image held in memory, told apart by their
    /// magic numbers (`76 2f 31 01` and `#?`); `name` only names it in errors.
    pub fn decode(bytes: &[u8], name: &Path) -> Result<Self> {
        if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            Self::decode_exr(bytes, name)
        } else if bytes.starts_with(b"#?") {
            Self::decode_hdr(bytes, name)
        } else {
            Err(RenderError::InvalidArgument(format!(
                "{}: neither OpenEXR nor Radiance .hdr (unknown magic number)",
                name.display()
            )))
        }
    }

    /// Reads an image by extension: OpenEXR (`.exr`) or Radiance (`.hdr`, `.pic`).
    pub fn read(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        match ext.as_deref() {
            Some("exr") => Self::read_exr(path),
            Some("hdr" | "pic") => Self::read_hdr(path),
            _ => Err(RenderError::InvalidArgument(format!(
                "{}: a linear image must be OpenEXR (.exr) or Radiance (.hdr)",
                path.display()
            ))),
        }
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

    /// An independent RGBE encoder (Greg Ward's `float2rgbe`: mantissa bytes scaled by the
    /// largest channel's binary exponent), flat scanlines.
    fn rgbe_file(w: usize, h: usize, px: &[[f32; 3]]) -> Vec<u8> {
        let mut out = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n").into_bytes();
        for p in px {
            let m = p[0].max(p[1]).max(p[2]);
            if m < 1e-32 {
                out.extend_from_slice(&[0, 0, 0, 0]);
                continue;
            }
            let e = m.log2().floor() as i32 + 1; // m = f · 2^e with f in [0.5, 1)
            let scale = 256.0 / 2f32.powi(e);
            out.extend(p.iter().map(|&c| (c * scale) as u8));
            out.push((e + 128) as u8);
        }
        out
    }

    #[test]
    fn radiance_hdr_decodes_what_an_independent_encoder_wrote() {
        let (w, h) = (9, 4);
        let px: Vec<[f32; 3]> = (0..w * h)
            .map(|i| [0.01 * i as f32, 3.0 + i as f32, 1e3 / (1 + i) as f32])
            .collect();
        let img = Image::decode_hdr(&rgbe_file(w, h, &px), Path::new("t.hdr")).unwrap();
        assert_eq!((img.width(), img.height()), (w, h));
        for (got, want) in img.pixels().iter().zip(&px) {
            let m = want[0].max(want[1]).max(want[2]);
            for c in 0..3 {
                // One mantissa step of the largest channel.
                assert!((got[c] - want[c]).abs() <= m / 128.0, "{got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn run_length_encoded_radiance_scanlines_decode() {
        // Two 16-pixel scanlines, each channel one run of 16 equal bytes: (200, 100, 50) with
        // exponent 130, i.e. (m / 256) · 2² = (3.125, 1.5625, 0.78125) (half a step more where
        // the decoder centres the mantissa).
        let mut f = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 16\n".to_vec();
        for _ in 0..2 {
            f.extend_from_slice(&[2, 2, 0, 16]);
            for v in [200u8, 100, 50, 130] {
                f.extend_from_slice(&[0x80 + 16, v]);
            }
        }
        let img = Image::decode_hdr(&f, Path::new("rle.hdr")).unwrap();
        assert_eq!((img.width(), img.height()), (16, 2));
        for p in img.pixels() {
            for (got, m) in p.iter().zip([200.0f32, 100.0, 50.0]) {
                let want = m / 64.0;
                assert!((got - want).abs() <= 1.0 / 64.0, "{got} vs {want}");
            }
        }
    }

    #[test]
    fn malformed_radiance_files_are_typed_errors() {
        let px = vec![[1.0f32, 2.0, 3.0]; 64];
        let good = rgbe_file(8, 8, &px);
        let p = Path::new("bad.hdr");
        for bad in [
            &good[..good.len() - 10],     // truncated pixels
            &good[..20],                  // truncated header
            b"P6\n8 8\n255\n".as_slice(), // not Radiance
            b"".as_slice(),
        ] {
            match Image::decode_hdr(bad, p) {
                Err(RenderError::Hdr { path, .. }) => assert_eq!(path, p),
                other => panic!("{other:?}"),
            }
        }
        // A header announcing a huge image is refused before pixel memory is taken.
        let huge = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 60000 +X 60000\n\x02\x02";
        let e = Image::decode_hdr(huge, p).unwrap_err().to_string();
        assert!(e.contains("more than"), "{e}");
        assert!(Image::read(Path::new("x.png")).is_err());
        // An OpenEXR header announcing billions of lines (found by fuzzing the job's EXR
        // reader) is refused from its headers.
        let hostile = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../hdr/tests/fixtures/hostile_huge_window.exr");
        let e = Image::read_exr(&hostile).unwrap_err().to_string();
        assert!(e.contains("more than"), "{e}");
    }

    /// The shared Venice light probe ships as OpenEXR and as Radiance `.hdr` (made by others
    /// from the same capture): both readers must agree to RGBE precision.
    #[test]
    fn the_shared_probe_reads_the_same_from_hdr_and_exr() {
        let dir = brdf::data_dir().join("real/envmap");
        let exr = Image::read(&dir.join("venice_sunset_1k.exr")).expect("shared probe (.exr)");
        let hdr = Image::read(&dir.join("venice_sunset_1k.hdr")).expect("shared probe (.hdr)");
        assert_eq!((hdr.width(), hdr.height()), (exr.width(), exr.height()));
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (a, b) in hdr.pixels().iter().zip(exr.pixels()) {
            for c in 0..3 {
                num += ((a[c] - b[c]) as f64).powi(2);
                den += (b[c] as f64).powi(2);
            }
        }
        let rel = (num / den).sqrt();
        assert!(rel < 0.01, "relative RMS difference {rel}");
    }

    #[test]
    fn images_in_memory_decode_by_their_magic_number() {
        let dir = brdf::data_dir().join("real/envmap");
        for file in ["venice_sunset_1k.exr", "venice_sunset_1k.hdr"] {
            let path = dir.join(file);
            let bytes = std::fs::read(&path).expect("shared probe");
            let decoded = Image::decode(&bytes, Path::new("upload")).unwrap();
            let read = Image::read(&path).unwrap();
            assert_eq!(decoded.pixels(), read.pixels(), "{file}");
            // cut short: a typed error, no panic
            assert!(Image::decode(&bytes[..bytes.len() / 3], Path::new("cut")).is_err());
        }
        let e = Image::decode(b"P6 1 1 255\n...", Path::new("x.ppm")).unwrap_err();
        assert!(e.to_string().contains("magic"), "{e}");
        let hostile = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../hdr/tests/fixtures/hostile_huge_window.exr");
        let bytes = std::fs::read(hostile).unwrap();
        assert!(Image::decode(&bytes, Path::new("h"))
            .unwrap_err()
            .to_string()
            .contains("more than"));
    }

    #[test]
    fn halving_keeps_the_mean_radiance() {
        let px: Vec<[f32; 3]> = (0..6 * 4)
            .map(|i| [i as f32, 1.0, (i % 3) as f32])
            .collect();
        let img = Image::from_pixels(6, 4, px).unwrap();
        let half = img.halved().unwrap();
        assert_eq!((half.width(), half.height()), (3, 2));
        let mean = |im: &Image, c: usize| {
            im.pixels().iter().map(|p| p[c] as f64).sum::<f64>() / im.pixels().len() as f64
        };
        for c in 0..3 {
            assert!((mean(&img, c) - mean(&half, c)).abs() < 1e-5);
        }
        // pixel (1, 0) is the mean of (2, 0), (3, 0), (2, 1), (3, 1): 2, 3, 8, 9
        assert_eq!(half.pixels()[1][0], 5.5);
        assert!(Image::from_pixels(1, 3, vec![[0.0; 3]; 3])
            .unwrap()
            .halved()
            .is_err());
    }
}
