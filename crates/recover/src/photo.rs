//! Linear HDR photographs: OpenEXR, Radiance `.hdr`, and 8-bit images (PNG, treated as linear
//! values in [0, 1] after sRGB decoding), plus masks.

use std::path::Path;

use crate::error::{RecoverError, Result};

/// A linear RGB photograph, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Photo {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear radiance per pixel.
    pub pixels: Vec<[f32; 3]>,
    /// Values at or above this level (any channel) are saturated and left out; `None` for
    /// HDR images.
    pub saturation: Option<f32>,
}

impl Photo {
    /// A photograph from pixels (row-major).
    pub fn new(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Result<Photo> {
        if width == 0 || height == 0 || pixels.len() != width * height {
            return Err(RecoverError::InvalidParameter(format!(
                "{} pixels for a {width}×{height} image",
                pixels.len()
            )));
        }
        Ok(Photo {
            width,
            height,
            pixels,
            saturation: None,
        })
    }

    /// The same photograph with a saturation level.
    pub fn with_saturation(mut self, level: f32) -> Photo {
        self.saturation = Some(level);
        self
    }

    /// A rendered image as a photograph.
    pub fn from_image(image: &render::Image) -> Photo {
        Photo {
            width: image.width(),
            height: image.height(),
            pixels: image.pixels().to_vec(),
            saturation: None,
        }
    }

    /// Reads an image by extension: `.exr` (linear), `.hdr` (Radiance RGBE, linear), anything
    /// else through `image` as 8-bit sRGB, decoded to linear with saturation level 1.
    pub fn read(path: &Path) -> Result<Photo> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "exr" => Ok(Photo::from_image(&render::Image::read_exr(path)?)),
            "hdr" | "pic" => Ok(Photo::from_image(&render::Image::read_hdr(path)?)),
            _ => {
                let img = open(path)?.to_rgb8();
                let (w, h) = img.dimensions();
                let pixels = img
                    .pixels()
                    .map(|p| p.0.map(|v| srgb_decode(v as f32 / 255.0)))
                    .collect();
                Ok(Photo::new(w as usize, h as usize, pixels)?.with_saturation(1.0))
            }
        }
    }

    /// Whether pixel `i` is saturated.
    pub fn saturated(&self, i: usize) -> bool {
        match self.saturation {
            Some(s) => self.pixels[i].iter().any(|&v| v >= s),
            None => false,
        }
    }
}

fn open(path: &Path) -> Result<image::DynamicImage> {
    image::open(path).map_err(|e| RecoverError::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// sRGB transfer function, decoded to linear.
pub fn srgb_decode(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// sRGB transfer function, encoded from linear.
pub fn srgb_encode(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Reads a mask image: pixels whose mean value is below one half are left out.
pub fn read_mask(path: &Path) -> Result<Vec<bool>> {
    let img = open(path)?.to_luma32f();
    Ok(img.pixels().map(|p| p[0] >= 0.5).collect())
}

/// Reads a mask and checks its size against a photograph.
pub fn read_mask_for(path: &Path, photo: &Photo) -> Result<Vec<bool>> {
    let img = open(path)?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w != photo.width || h != photo.height {
        return Err(RecoverError::MaskMismatch {
            width: photo.width,
            height: photo.height,
            got_width: w,
            got_height: h,
        });
    }
    read_mask(path)
}
