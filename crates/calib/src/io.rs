//! File formats of a calibration session: raw target frames as 16-bit grey PNG and
//! `digitizer.csv`, and the atomic writer they go through. The whole run is written by
//! [`crate::pipeline::write_run`].

use crate::error::{CalibError, CalibResult};
use crate::extrinsics::TipCorrespondence;
use crate::lamp::LampReading;
use crate::schema::Point3;
use gantry_hal::{BayerFrame, BayerPattern};
use std::io::Write;
use std::path::Path;

pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> CalibError + '_ {
    move |source| CalibError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `bytes` to `path` atomically ([`brdf::write_atomic_with`]: a temporary file in the
/// same directory, then a rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> CalibResult<()> {
    brdf::write_atomic_with(path, |w| w.write_all(bytes)).map_err(io_err(path))
}

/// PNG bytes of a raw frame as 16-bit grey: each sample shifted left by 16 − bit depth bits.
pub fn frame_png16(frame: &BayerFrame) -> CalibResult<Vec<u8>> {
    frame
        .validate()
        .map_err(|e| CalibError::Invalid(format!("frame: {e}")))?;
    let shift = 16 - frame.bit_depth as u32;
    let data: Vec<u16> = frame.data.iter().map(|&v| v << shift).collect();
    let buf = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(
        frame.width as u32,
        frame.height as u32,
        data,
    )
    .ok_or_else(|| CalibError::Invalid("frame size".into()))?;
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageLuma16(buf).write_to(&mut out, image::ImageFormat::Png)?;
    Ok(out.into_inner())
}

/// Reads a 16-bit grey PNG written by [`frame_png16`] back into a frame of `bit_depth` bits
/// with the Bayer `pattern` (exposure and timestamps are not stored: 1 s, 0 s). The samples
/// are taken as left-aligned: a `bit_depth` of 16 keeps every bit, a smaller one drops the low
/// bits.
pub fn read_frame_png16(
    path: &Path,
    bit_depth: u8,
    pattern: BayerPattern,
) -> CalibResult<BayerFrame> {
    if bit_depth == 0 || bit_depth > 16 {
        return Err(CalibError::Invalid(format!("bit depth {bit_depth}")));
    }
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)?;
    let img = match img {
        image::DynamicImage::ImageLuma16(b) => b,
        other => {
            return Err(CalibError::Parse {
                path: path.to_path_buf(),
                detail: format!("expected 16-bit grey PNG, found {:?}", other.color()),
            })
        }
    };
    let (w, h) = (img.width() as usize, img.height() as usize);
    let shift = 16 - bit_depth as u32;
    let data: Vec<u16> = img.into_raw().into_iter().map(|v| v >> shift).collect();
    BayerFrame::new(w, h, bit_depth, pattern, data, 1.0, 0.0, 20.0, 0).map_err(|e| {
        CalibError::Parse {
            path: path.to_path_buf(),
            detail: e.to_string(),
        }
    })
}

/// Digitizer and caliper measurements as stored in `digitizer.csv`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DigitizerLog {
    /// Tip positions with their pixels.
    pub tips: Vec<TipCorrespondence>,
    /// Lamp positions at turntable angles.
    pub lamp: Vec<LampReading>,
    /// Sphere surface points.
    pub sphere_points: Vec<Point3>,
    /// Caliper diameter of the sphere, metres.
    pub sphere_diameter_m: f64,
}

/// Header line of `digitizer.csv`.
pub const DIGITIZER_CSV_HEADER: &str = "kind,index,angle_deg,x_m,y_m,z_m,u_px,v_px";

/// CSV text of a digitizer log: one row per reading, `kind` ∈ {tip, lamp, sphere, caliper};
/// the caliper row holds the diameter in `x_m`; unused columns are empty.
pub fn digitizer_csv(log: &DigitizerLog) -> String {
    let mut s = String::from(DIGITIZER_CSV_HEADER);
    s.push('\n');
    for (i, t) in log.tips.iter().enumerate() {
        let [x, y, z] = t.world;
        s += &format!("tip,{i},,{x},{y},{z},{},{}\n", t.pixel[0], t.pixel[1]);
    }
    for (i, l) in log.lamp.iter().enumerate() {
        let [x, y, z] = l.position;
        s += &format!("lamp,{i},{},{x},{y},{z},,\n", l.angle_deg);
    }
    for (i, p) in log.sphere_points.iter().enumerate() {
        s += &format!("sphere,{i},,{},{},{},,\n", p[0], p[1], p[2]);
    }
    s += &format!("caliper,0,,{},,,,\n", log.sphere_diameter_m);
    s
}

/// Parses `digitizer.csv` text; `path` is only used in error messages.
pub fn parse_digitizer_csv(text: &str, path: &Path) -> CalibResult<DigitizerLog> {
    let bad = |line: usize, detail: String| CalibError::Parse {
        path: path.to_path_buf(),
        detail: format!("line {line}: {detail}"),
    };
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == DIGITIZER_CSV_HEADER => {}
        _ => return Err(bad(1, format!("header must be `{DIGITIZER_CSV_HEADER}`"))),
    }
    let mut log = DigitizerLog::default();
    let mut diameter = None;
    for (n, line) in lines {
        let n = n + 1;
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 8 {
            return Err(bad(n, format!("{} fields, 8 expected", f.len())));
        }
        let num = |k: usize| -> CalibResult<f64> {
            let v: f64 = f[k]
                .parse()
                .map_err(|_| bad(n, format!("`{}` is not a number", f[k])))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(n, format!("non-finite value `{}`", f[k])))
            }
        };
        match f[0] {
            "tip" => log.tips.push(TipCorrespondence {
                world: [num(3)?, num(4)?, num(5)?],
                pixel: [num(6)?, num(7)?],
            }),
            "lamp" => log.lamp.push(LampReading {
                angle_deg: num(2)?,
                position: [num(3)?, num(4)?, num(5)?],
            }),
            "sphere" => log.sphere_points.push([num(3)?, num(4)?, num(5)?]),
            "caliper" => diameter = Some(num(3)?),
            other => return Err(bad(n, format!("unknown kind `{other}`"))),
        }
    }
    log.sphere_diameter_m = diameter.ok_or_else(|| bad(0, "no caliper row".into()))?;
    Ok(log)
}

/// Reads `digitizer.csv`.
pub fn read_digitizer_csv(path: &Path) -> CalibResult<DigitizerLog> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    parse_digitizer_csv(&text, path)
}
