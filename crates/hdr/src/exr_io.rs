//! OpenEXR files of merged radiance images and of simulator ground truth.

use crate::error::{HdrError, HdrResult};
use crate::merge::{HdrImage, Intercept, MergeOptions};
use exr::prelude::*;
use std::path::{Path, PathBuf};

/// Where the HDR image of position `index` goes: `dir/hdr/NNN.exr` (zero-padded to 3 digits).
pub fn hdr_path(dir: &Path, index: usize) -> PathBuf {
    dir.join("hdr").join(format!("{index:03}.exr"))
}

/// Where the ground truth of position `index` goes: `dir/truth/NNN.exr`.
pub fn truth_path(dir: &Path, index: usize) -> PathBuf {
    dir.join("truth").join(format!("{index:03}.exr"))
}

/// What is known about the position a file belongs to (all optional).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PositionInfo {
    /// Position index in the capture.
    pub index: Option<u32>,
    /// Turntable angle, degrees.
    pub angle_deg: Option<f64>,
    /// Sensor temperature during the series, °C.
    pub sensor_temperature_c: Option<f64>,
    /// Rig-clock time at the start of the series, seconds.
    pub timestamp_s: Option<f64>,
}

/// Compression of the written files (all lossless).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExrCompression {
    /// No compression (largest, fastest).
    None,
    /// Run-length encoding.
    Rle,
    /// Deflate in blocks of 16 scan lines.
    #[default]
    Zip,
}

/// Options of [`write_hdr_exr`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExrOptions {
    /// Also write `std_error`, `correlation` and `flags`.
    pub fit_statistics: bool,
    /// Compression.
    pub compression: ExrCompression,
}

impl Default for ExrOptions {
    fn default() -> Self {
        Self {
            fit_statistics: true,
            compression: ExrCompression::Zip,
        }
    }
}

/// The content of an HDR or truth file.
///
/// One single-part scan-line file per lamp position, `DIR/hdr/NNN.exr` ([`hdr_path`]), with
/// the channels
///
/// | channel       | type | content                                                  |
/// |---------------|------|----------------------------------------------------------|
/// | `radiance`    | f32  | radiance estimate, DN/s (raw Bayer layout)               |
/// | `valid`       | f16  | 1 where the pixel passed every test, else 0              |
/// | `count`       | f16  | number of valid exposures in the fit                     |
/// | `std_error`   | f32  | standard error of the slope, DN/s (optional)             |
/// | `correlation` | f32  | correlation of the fit (optional)                        |
/// | `flags`       | f16  | bit set of [`crate::flags`] (optional)                   |
///
/// The whole-number channels are half floats, which hold them exactly (files written before
/// stored them as f32; the reader takes either).
///
/// and header attributes: `hdr_kind` (`radiance` or `truth`), `radiance_units` (`DN/s`),
/// `exposures_s` (the series, space-separated, shortest first), `exposure_count`, `low_dn`,
/// `high_dn`, `min_correlation`, `min_valid`, `intercept` (`fitted` or `black_level`),
/// `black_level_dn`, `hot_pixels`, and, when known, `position`, `angle_deg`, `sensor_temp_c`,
/// `timestamp_s`. Truth files ([`truth_path`], `DIR/truth/NNN.exr`) hold the `radiance` channel
/// only, in the same units.
///
/// Files are written to a temporary file in the destination directory and renamed into place,
/// so a reader never sees a partial file.
#[derive(Debug, Clone, PartialEq)]
pub struct HdrFile {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `hdr_kind` attribute: `radiance` for merged images, `truth` for ground truth.
    pub kind: String,
    /// Radiance, DN/s.
    pub radiance: Vec<f32>,
    /// `valid` channel, if present.
    pub valid: Option<Vec<bool>>,
    /// `count` channel, if present.
    pub count: Option<Vec<u16>>,
    /// `std_error` channel, if present.
    pub std_error: Option<Vec<f32>>,
    /// `correlation` channel, if present.
    pub correlation: Option<Vec<f32>>,
    /// `flags` channel, if present.
    pub flags: Option<Vec<u8>>,
    /// Exposure series (empty for truth files).
    pub exposures_s: Vec<f64>,
    /// Merge settings (radiance files).
    pub merge_options: Option<MergeOptions>,
    /// Number of hot photosites excluded, if recorded.
    pub hot_pixels: Option<usize>,
    /// Position metadata.
    pub position: PositionInfo,
}

fn text(s: &str) -> AttributeValue {
    // Only ASCII is ever written here.
    AttributeValue::Text(Text::new_or_panic(s))
}

fn position_attributes(attrs: &mut LayerAttributes, info: &PositionInfo) {
    let o = &mut attrs.other;
    if let Some(i) = info.index {
        o.insert(Text::from("position"), AttributeValue::I32(i as i32));
    }
    if let Some(a) = info.angle_deg {
        o.insert(Text::from("angle_deg"), AttributeValue::F64(a));
    }
    if let Some(t) = info.sensor_temperature_c {
        o.insert(Text::from("sensor_temp_c"), AttributeValue::F64(t));
    }
    if let Some(t) = info.timestamp_s {
        o.insert(Text::from("timestamp_s"), AttributeValue::F64(t));
    }
}

fn encoding(c: ExrCompression) -> Encoding {
    Encoding {
        compression: match c {
            ExrCompression::None => Compression::Uncompressed,
            ExrCompression::Rle => Compression::RLE,
            ExrCompression::Zip => Compression::ZIP16,
        },
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    }
}

fn write_atomic(path: &Path, image: &Image<Layer<AnyChannels<FlatSamples>>>) -> HdrResult<()> {
    let io_err = |source: std::io::Error| HdrError::Io {
        path: path.to_path_buf(),
        source,
    };
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(io_err)?;
    // The encoder's own error, kept apart from the file system's.
    let mut encoder_error = None;
    atomic_write::write_atomic_with(path, |w| {
        image.write().to_buffered(w).map_err(|e| {
            let detail = e.to_string();
            encoder_error = Some(detail.clone());
            std::io::Error::other(detail)
        })
    })
    .map_err(|e| match encoder_error.take() {
        Some(detail) => HdrError::Exr {
            path: path.to_path_buf(),
            detail,
        },
        None => io_err(e),
    })
}

fn check_len(what: &str, len: usize, width: usize, height: usize) -> HdrResult<()> {
    if width == 0 || height == 0 || width.checked_mul(height) != Some(len) {
        return Err(HdrError::Dimensions(format!(
            "{what}: {len} values for {width}x{height}"
        )));
    }
    Ok(())
}

/// Writes a merged image to `path` atomically (parent directories are created). The layout of
/// the file is described at [`HdrFile`].
///
/// # Examples
///
/// ```
/// use gantry_hal::{BayerFrame, BayerPattern};
/// use hdr::{hdr_path, merge, read_exr, write_hdr_exr, ExrOptions, MergeOptions, PositionInfo};
///
/// let frames: Vec<BayerFrame> = [0.1, 0.2, 0.4].iter().map(|&t| {
///     let data = [100.0, 2000.0].iter().map(|r| (20.0 + r * t) as u16).collect();
///     BayerFrame::new(2, 1, 10, BayerPattern::Rggb, data, t, 0.0, 25.0, 0).unwrap()
/// }).collect();
/// let image = merge(&frames, None, &MergeOptions::default()).unwrap();
///
/// let dir = tempfile::tempdir().unwrap();
/// let path = hdr_path(dir.path(), 7); // DIR/hdr/007.exr
/// let info = PositionInfo { index: Some(7), angle_deg: Some(12.5), ..PositionInfo::default() };
/// write_hdr_exr(&path, &image, &info, &ExrOptions::default()).unwrap();
///
/// let file = read_exr(&path).unwrap();
/// assert_eq!(file.kind, "radiance");
/// assert_eq!(file.radiance, image.radiance); // f32 channel: exact
/// assert_eq!(file.count.unwrap(), image.count);
/// assert_eq!(file.exposures_s, vec![0.1, 0.2, 0.4]);
/// assert_eq!(file.position.angle_deg, Some(12.5));
/// ```
pub fn write_hdr_exr(
    path: &Path,
    image: &HdrImage,
    info: &PositionInfo,
    opts: &ExrOptions,
) -> HdrResult<()> {
    let (w, h) = (image.width, image.height);
    check_len("radiance", image.radiance.len(), w, h)?;
    for (what, len) in [
        ("std_error", image.std_error.len()),
        ("correlation", image.correlation.len()),
        ("valid", image.valid.len()),
        ("count", image.count.len()),
        ("flags", image.flags.len()),
    ] {
        check_len(what, len, w, h)?;
    }
    let mut channels: Vec<AnyChannel<FlatSamples>> = vec![
        AnyChannel::new("radiance", FlatSamples::F32(image.radiance.clone())),
        AnyChannel::new(
            "valid",
            FlatSamples::F16(image.valid.iter().map(|&v| f16_int(v as u16)).collect()),
        ),
        AnyChannel::new(
            "count",
            FlatSamples::F16(image.count.iter().map(|&c| f16_int(c)).collect()),
        ),
    ];
    if opts.fit_statistics {
        channels.push(AnyChannel::new(
            "std_error",
            FlatSamples::F32(image.std_error.clone()),
        ));
        channels.push(AnyChannel::new(
            "correlation",
            FlatSamples::F32(image.correlation.clone()),
        ));
        channels.push(AnyChannel::new(
            "flags",
            FlatSamples::F16(image.flags.iter().map(|&f| f16_int(f as u16)).collect()),
        ));
    }
    let mut attrs = LayerAttributes::named("hdr");
    attrs.software_name = Some(Text::from(concat!(
        "gantry hdr ",
        env!("CARGO_PKG_VERSION")
    )));
    let o = &mut attrs.other;
    o.insert(Text::from("hdr_kind"), text("radiance"));
    o.insert(Text::from("radiance_units"), text("DN/s"));
    let list: Vec<String> = image.exposures_s.iter().map(|t| format!("{t:e}")).collect();
    o.insert(Text::from("exposures_s"), text(&list.join(" ")));
    o.insert(
        Text::from("exposure_count"),
        AttributeValue::I32(image.exposures_s.len() as i32),
    );
    let m = &image.options;
    o.insert(Text::from("low_dn"), AttributeValue::F64(m.low_dn));
    o.insert(Text::from("high_dn"), AttributeValue::F64(m.high_dn));
    o.insert(
        Text::from("min_correlation"),
        AttributeValue::F64(m.min_correlation),
    );
    o.insert(
        Text::from("min_valid"),
        AttributeValue::I32(m.min_valid.min(i32::MAX as usize) as i32),
    );
    match m.intercept {
        Intercept::Fitted => {
            o.insert(Text::from("intercept"), text("fitted"));
        }
        Intercept::BlackLevel(b) => {
            o.insert(Text::from("intercept"), text("black_level"));
            o.insert(Text::from("black_level_dn"), AttributeValue::F64(b));
        }
    }
    let hot = image
        .flags
        .iter()
        .filter(|&&f| f & crate::flags::HOT != 0)
        .count();
    o.insert(Text::from("hot_pixels"), AttributeValue::I32(hot as i32));
    position_attributes(&mut attrs, info);
    let layer = Layer::new(
        (w, h),
        attrs,
        encoding(opts.compression),
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    write_atomic(path, &Image::from_layer(layer))
}

/// Writes a ground-truth signal-rate image (DN/s, `width × height`, row-major) to `path`
/// atomically, as channel `radiance` with `hdr_kind = truth`.
pub fn write_truth_exr(
    path: &Path,
    width: usize,
    height: usize,
    signal_rate_dn_per_s: &[f32],
    info: &PositionInfo,
) -> HdrResult<()> {
    check_len("truth", signal_rate_dn_per_s.len(), width, height)?;
    let mut attrs = LayerAttributes::named("truth");
    attrs.software_name = Some(Text::from(concat!(
        "gantry hdr ",
        env!("CARGO_PKG_VERSION")
    )));
    attrs.other.insert(Text::from("hdr_kind"), text("truth"));
    attrs
        .other
        .insert(Text::from("radiance_units"), text("DN/s"));
    position_attributes(&mut attrs, info);
    let channels = vec![AnyChannel::new(
        "radiance",
        FlatSamples::F32(signal_rate_dn_per_s.to_vec()),
    )];
    let layer = Layer::new(
        (width, height),
        attrs,
        encoding(ExrCompression::Zip),
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    write_atomic(path, &Image::from_layer(layer))
}

/// Most sample memory an OpenEXR file may make [`read_exr`] take (all parts and channels):
/// 1 GiB, eight times a full-resolution HDR file of the job directory.
pub const MAX_EXR_SAMPLE_BYTES: usize = 1 << 30;

/// The most sample bytes one byte of a file compressed with `c` can hold: 1 uncompressed, 64 for
/// run-length coding (a run of 128 bytes in 2), 1,032 for deflate (its limit; ZIP and PXR24), 11
/// for B44 (a flat 4 × 4 block of halves in 3 bytes), and a generous 4,096 for the wavelet, DCT
/// and JPEG 2000 codecs (PIZ, DWA, HTJ2K).
fn max_expansion(c: exr::compression::Compression) -> u64 {
    use exr::compression::Compression as C;
    match c {
        C::Uncompressed => 1,
        C::RLE => 64,
        C::ZIP1 | C::ZIP16 | C::PXR24 => 1032,
        C::B44 | C::B44A => 11,
        _ => 4096,
    }
}

/// Checks an OpenEXR file's headers before its pixels are read: the samples they announce
/// must fit [`MAX_EXR_SAMPLE_BYTES`] and what the file's length can hold with its compression
/// (see `max_expansion`: a 742-byte file announcing 1 GB of ZIP-compressed samples is refused),
/// and the file must be able to hold the offset table (8 bytes per chunk) they imply. A hostile
/// header (a data window of 2³² lines, say) is refused here instead of making the decoder
/// allocate gigabytes.
pub fn check_exr_size(path: &Path) -> HdrResult<()> {
    let fail = |detail: String| HdrError::Exr {
        path: path.to_path_buf(),
        detail,
    };
    let len = std::fs::metadata(path)
        .map_err(|source| HdrError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| match e {
        exr::error::Error::Io(source) => HdrError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => fail(other.to_string()),
    })?;
    let (mut bytes, mut chunks, mut expansion) = (0usize, 0usize, 1u64);
    for h in &meta.headers {
        expansion = expansion.max(max_expansion(h.compression));
        let px = h.layer_size.width().saturating_mul(h.layer_size.height());
        for c in &h.channels.list {
            bytes = bytes.saturating_add(px.saturating_mul(c.sample_type.bytes_per_sample()));
        }
        chunks = chunks.saturating_add(h.chunk_count);
    }
    if bytes > MAX_EXR_SAMPLE_BYTES {
        return Err(fail(format!(
            "the headers announce {bytes} bytes of samples, more than the {MAX_EXR_SAMPLE_BYTES} accepted"
        )));
    }
    let backed = len.saturating_mul(expansion);
    if bytes as u64 > backed {
        return Err(fail(format!(
            "the headers announce {bytes} bytes of samples, more than the file's {len} bytes can hold \
             (at most {expansion} sample bytes per file byte with its compression)"
        )));
    }
    if (chunks as u64).saturating_mul(8) > len {
        return Err(fail(format!(
            "the headers announce {chunks} chunks: their offset table alone needs more than the file's {len} bytes"
        )));
    }
    Ok(())
}

/// A small whole number as a half float: exact up to 2048 (exposure counts, flag bits, 0/1),
/// half the bytes of `f32`. Larger counts (never written: a series has far fewer exposures)
/// saturate at 65504.
fn f16_int(v: u16) -> f16 {
    f16::from_f32(v as f32)
}

/// Files smaller than this are decoded on the calling thread (see [`read_exr`]).
const PARALLEL_DECODE_BYTES: u64 = 1 << 20;

/// Reads an HDR or truth file written by [`write_hdr_exr`] / [`write_truth_exr`] (or any
/// single-part EXR with a `radiance` channel). Headers are checked first
/// ([`check_exr_size`]).
pub fn read_exr(path: &Path) -> HdrResult<HdrFile> {
    let not_hdr = |d: String| HdrError::NotHdrFile {
        path: path.to_path_buf(),
        detail: d,
    };
    check_exr_size(path)?;
    let mut reader = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes();
    // The exr crate decompresses blocks on a thread pool it starts for every file; for a
    // small file, starting the threads costs more than decoding on this one.
    if std::fs::metadata(path).is_ok_and(|m| m.len() < PARALLEL_DECODE_BYTES) {
        reader = reader.non_parallel();
    }
    let image = reader.from_file(path).map_err(|e| match e {
        exr::error::Error::Io(source) => HdrError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => HdrError::Exr {
            path: path.to_path_buf(),
            detail: other.to_string(),
        },
    })?;
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let channel = |name: &str| -> Option<Vec<f32>> {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .map(|c| c.sample_data.values_as_f32().collect())
    };
    let radiance = channel("radiance").ok_or_else(|| not_hdr("no `radiance` channel".into()))?;
    let attrs = &layer.attributes.other;
    let get = |name: &str| attrs.get(&Text::from(name));
    let f64_attr = |name: &str| -> HdrResult<Option<f64>> {
        match get(name) {
            None => Ok(None),
            Some(AttributeValue::F64(v)) => Ok(Some(*v)),
            Some(AttributeValue::F32(v)) => Ok(Some(*v as f64)),
            Some(other) => Err(not_hdr(format!("attribute {name} has type {other:?}"))),
        }
    };
    let i32_attr = |name: &str| -> HdrResult<Option<i32>> {
        match get(name) {
            None => Ok(None),
            Some(AttributeValue::I32(v)) => Ok(Some(*v)),
            Some(other) => Err(not_hdr(format!("attribute {name} has type {other:?}"))),
        }
    };
    let text_attr = |name: &str| -> HdrResult<Option<String>> {
        match get(name) {
            None => Ok(None),
            Some(AttributeValue::Text(t)) => Ok(Some(t.to_string())),
            Some(other) => Err(not_hdr(format!("attribute {name} has type {other:?}"))),
        }
    };
    let kind = text_attr("hdr_kind")?.unwrap_or_else(|| "radiance".into());
    let exposures_s = match text_attr("exposures_s")? {
        None => Vec::new(),
        Some(s) => s
            .split_whitespace()
            .map(|x| {
                x.parse::<f64>()
                    .map_err(|_| not_hdr(format!("exposure `{x}` is not a number")))
            })
            .collect::<HdrResult<Vec<f64>>>()?,
    };
    let merge_options = match (
        f64_attr("low_dn")?,
        f64_attr("high_dn")?,
        f64_attr("min_correlation")?,
        i32_attr("min_valid")?,
    ) {
        (Some(low_dn), Some(high_dn), Some(min_correlation), Some(min_valid)) => {
            let intercept = match text_attr("intercept")?.as_deref() {
                Some("black_level") => Intercept::BlackLevel(
                    f64_attr("black_level_dn")?
                        .ok_or_else(|| not_hdr("black_level intercept without value".into()))?,
                ),
                _ => Intercept::Fitted,
            };
            Some(MergeOptions {
                low_dn,
                high_dn,
                min_correlation,
                min_valid: min_valid.max(0) as usize,
                intercept,
            })
        }
        _ => None,
    };
    let position = PositionInfo {
        index: i32_attr("position")?.map(|i| i.max(0) as u32),
        angle_deg: f64_attr("angle_deg")?,
        sensor_temperature_c: f64_attr("sensor_temp_c")?,
        timestamp_s: f64_attr("timestamp_s")?,
    };
    Ok(HdrFile {
        width,
        height,
        kind,
        radiance,
        valid: channel("valid").map(|v| v.iter().map(|&x| x > 0.5).collect()),
        count: channel("count").map(|v| v.iter().map(|&x| x.max(0.0) as u16).collect()),
        std_error: channel("std_error"),
        correlation: channel("correlation"),
        flags: channel("flags").map(|v| v.iter().map(|&x| x.max(0.0) as u8).collect()),
        exposures_s,
        merge_options,
        hot_pixels: i32_attr("hot_pixels")?.map(|h| h.max(0) as usize),
        position,
    })
}
