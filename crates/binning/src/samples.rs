//! BRDF samples and their per-position files.

use crate::error::{BinningError, Result};
use brdf::BINS;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 8] = b"GBSAMPL1";
const HEADER: usize = 8 + 4 + 8 + 8;

/// One BRDF sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// `channel · BINS + bin`.
    pub key: u32,
    /// BRDF value, 1/sr.
    pub value: f32,
}

impl Sample {
    /// A sample of `channel` in flat MERL bin `bin`.
    pub fn new(channel: usize, bin: usize, value: f32) -> Self {
        Self {
            key: (channel * BINS + bin) as u32,
            value,
        }
    }
}

/// Largest valid key plus one.
pub const KEYS: usize = 3 * BINS;

/// The samples of one lamp position.
///
/// A sample is one BRDF value of one colour channel in one MERL bin: a `u32` key
/// (`channel · BINS + bin`) and an `f32` value in 1/sr, 8 bytes. One lamp position of a full-size
/// capture gives a few hundred thousand samples; a whole capture 20–80 million.
///
/// Each finished position is stored as its own file (written atomically), which is both the
/// capture's checkpoint and the input of the final binning pass. Format (little-endian):
///
/// ```text
/// magic  "GBSAMPL1"            8 bytes
/// position index               u32
/// turntable angle (degrees)    f64
/// sample count n               u64
/// n × (key u32, value f32)
/// FNV-1a 64 of the records     u64
/// ```
///
/// # Examples
///
/// ```
/// use binning::{PositionSamples, Sample};
///
/// let position = PositionSamples {
///     position: 4,
///     angle_deg: 12.5,
///     samples: vec![Sample::new(0, 17, 0.25), Sample::new(2, 99, 1.5)],
/// };
/// let bytes = position.to_bytes();
/// assert_eq!(bytes.len(), 28 + 2 * 8 + 8); // header, records, checksum
/// let path = std::path::Path::new("004.samples");
/// assert_eq!(PositionSamples::parse(&bytes, path).unwrap(), position);
/// // a flipped bit in a value fails the checksum
/// let mut damaged = bytes.clone();
/// damaged[33] ^= 1;
/// assert!(PositionSamples::parse(&damaged, path).is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct PositionSamples {
    /// Index of the lamp position in the capture.
    pub position: u32,
    /// Turntable angle, degrees.
    pub angle_deg: f64,
    /// The samples.
    pub samples: Vec<Sample>,
}

fn fnv1a(hash: u64, bytes: &[u8]) -> u64 {
    let mut h = hash;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

impl PositionSamples {
    /// The file bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER + 8 * self.samples.len() + 8);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&self.position.to_le_bytes());
        out.extend_from_slice(&self.angle_deg.to_le_bytes());
        out.extend_from_slice(&(self.samples.len() as u64).to_le_bytes());
        for s in &self.samples {
            out.extend_from_slice(&s.key.to_le_bytes());
            out.extend_from_slice(&s.value.to_le_bytes());
        }
        let h = fnv1a(FNV_OFFSET, &out[HEADER..]);
        out.extend_from_slice(&h.to_le_bytes());
        out
    }

    /// Writes the file atomically (temporary sibling, fsync, rename).
    pub fn write(&self, path: &Path) -> Result<()> {
        brdf::write_atomic(path, &self.to_bytes()).map_err(|e| match e {
            brdf::BrdfError::Io { path, io } => BinningError::Io { path, io },
            other => BinningError::Brdf(other),
        })
    }

    /// Reads and checks a sample file.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| BinningError::io(path, e))?;
        Self::parse(&bytes, path)
    }

    /// Parses and checks file bytes; `path` only names the source in errors.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Self> {
        let header = parse_header(bytes, path)?;
        let need = HEADER as u64 + 8 * header.count + 8;
        if bytes.len() as u64 != need {
            return Err(malformed(
                path,
                format!("{} bytes, header announces {need}", bytes.len()),
            ));
        }
        let body = &bytes[HEADER..bytes.len() - 8];
        let stored = u64::from_le_bytes(bytes[bytes.len() - 8..].try_into().unwrap_or([0; 8]));
        if fnv1a(FNV_OFFSET, body) != stored {
            return Err(malformed(path, "checksum mismatch".into()));
        }
        let mut samples = Vec::with_capacity(header.count as usize);
        for rec in body.chunks_exact(8) {
            samples.push(decode(rec, path)?);
        }
        Ok(Self {
            position: header.position,
            angle_deg: header.angle_deg,
            samples,
        })
    }
}

fn malformed(path: &Path, reason: String) -> BinningError {
    BinningError::Malformed {
        path: path.into(),
        reason,
    }
}

struct Header {
    position: u32,
    angle_deg: f64,
    count: u64,
}

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header> {
    if bytes.len() < HEADER {
        return Err(malformed(path, "shorter than the header".into()));
    }
    if &bytes[..8] != MAGIC {
        return Err(malformed(path, "bad magic".into()));
    }
    let position = u32::from_le_bytes(bytes[8..12].try_into().unwrap_or([0; 4]));
    let angle_deg = f64::from_le_bytes(bytes[12..20].try_into().unwrap_or([0; 8]));
    let count = u64::from_le_bytes(bytes[20..28].try_into().unwrap_or([0; 8]));
    if !angle_deg.is_finite() {
        return Err(malformed(path, "non-finite angle".into()));
    }
    if count > (1 << 40) {
        return Err(malformed(path, format!("absurd sample count {count}")));
    }
    Ok(Header {
        position,
        angle_deg,
        count,
    })
}

#[inline]
fn decode(rec: &[u8], path: &Path) -> Result<Sample> {
    let key = u32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]);
    let value = f32::from_le_bytes([rec[4], rec[5], rec[6], rec[7]]);
    if key as usize >= KEYS {
        return Err(malformed(path, format!("key {key} out of range")));
    }
    if !value.is_finite() {
        return Err(malformed(path, "non-finite value".into()));
    }
    Ok(Sample { key, value })
}

/// Anything that can hand out its samples, possibly several times (one per binning pass).
pub trait SampleSource: Sync {
    /// Total number of samples.
    fn sample_count(&self) -> Result<u64>;
    /// Calls `f` on successive chunks of samples, covering every sample once.
    fn visit(&self, f: &mut dyn FnMut(&[Sample])) -> Result<()>;
}

impl SampleSource for [PositionSamples] {
    fn sample_count(&self) -> Result<u64> {
        Ok(self.iter().map(|p| p.samples.len() as u64).sum())
    }
    fn visit(&self, f: &mut dyn FnMut(&[Sample])) -> Result<()> {
        for p in self {
            f(&p.samples);
        }
        Ok(())
    }
}

/// Sample files on disk, streamed in chunks so that memory does not grow with their size.
#[derive(Debug, Clone)]
pub struct SampleFiles {
    paths: Vec<PathBuf>,
}

impl SampleFiles {
    /// The given files, in the given order.
    pub fn new(paths: Vec<PathBuf>) -> Self {
        Self { paths }
    }

    /// The files.
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }
}

const CHUNK: usize = 1 << 16;

impl SampleSource for SampleFiles {
    fn sample_count(&self) -> Result<u64> {
        let mut total = 0;
        for p in &self.paths {
            let mut f = std::fs::File::open(p).map_err(|e| BinningError::io(p, e))?;
            let mut head = [0u8; HEADER];
            f.read_exact(&mut head)
                .map_err(|e| BinningError::io(p, e))?;
            total += parse_header(&head, p)?.count;
        }
        Ok(total)
    }

    fn visit(&self, f: &mut dyn FnMut(&[Sample])) -> Result<()> {
        let mut buf = vec![0u8; CHUNK * 8];
        let mut chunk = Vec::with_capacity(CHUNK);
        for p in &self.paths {
            let file = std::fs::File::open(p).map_err(|e| BinningError::io(p, e))?;
            let len = file.metadata().map_err(|e| BinningError::io(p, e))?.len();
            let mut r = BufReader::with_capacity(1 << 20, file);
            let mut head = [0u8; HEADER];
            r.read_exact(&mut head)
                .map_err(|e| BinningError::io(p, e))?;
            let header = parse_header(&head, p)?;
            if len != HEADER as u64 + 8 * header.count + 8 {
                return Err(malformed(p, format!("{len} bytes do not match the header")));
            }
            let mut hash = FNV_OFFSET;
            let mut left = header.count as usize;
            while left > 0 {
                let n = left.min(CHUNK);
                let bytes = &mut buf[..8 * n];
                r.read_exact(bytes).map_err(|e| BinningError::io(p, e))?;
                hash = fnv1a(hash, bytes);
                chunk.clear();
                for rec in bytes.chunks_exact(8) {
                    chunk.push(decode(rec, p)?);
                }
                f(&chunk);
                left -= n;
            }
            let mut tail = [0u8; 8];
            r.read_exact(&mut tail)
                .map_err(|e| BinningError::io(p, e))?;
            if u64::from_le_bytes(tail) != hash {
                return Err(malformed(p, "checksum mismatch".into()));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn example() -> PositionSamples {
        PositionSamples {
            position: 7,
            angle_deg: 12.5,
            samples: (0..1000)
                .map(|i| Sample::new(i % 3, i * 997 % BINS, i as f32 * 0.25))
                .collect(),
        }
    }

    #[test]
    fn file_round_trip_and_streaming_agree() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("007.samples");
        let s = example();
        s.write(&p).unwrap();
        assert_eq!(PositionSamples::read(&p).unwrap(), s);
        let files = SampleFiles::new(vec![p.clone(), p]);
        assert_eq!(files.sample_count().unwrap(), 2000);
        let mut seen = Vec::new();
        files.visit(&mut |c| seen.extend_from_slice(c)).unwrap();
        assert_eq!(seen.len(), 2000);
        assert_eq!(&seen[..1000], &s.samples[..]);
    }

    #[test]
    fn corrupted_files_are_detected() {
        let dir = tempfile::tempdir().unwrap();
        let good = example().to_bytes();
        let p = Path::new("x");
        let mut flipped = good.clone();
        flipped[HEADER + 5] ^= 0x40;
        assert!(matches!(
            PositionSamples::parse(&flipped, p),
            Err(BinningError::Malformed { .. })
        ));
        assert!(PositionSamples::parse(&good[..good.len() - 1], p).is_err());
        let mut bad_key = example();
        bad_key.samples[3].key = KEYS as u32;
        assert!(PositionSamples::parse(&bad_key.to_bytes(), p).is_err());
        // Streaming notices a truncated file too.
        let path = dir.path().join("t.samples");
        std::fs::write(&path, &good[..good.len() - 9]).unwrap();
        let err = SampleFiles::new(vec![path]).visit(&mut |_| {});
        assert!(err.is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
            ..ProptestConfig::default()
        })]
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
            let _ = PositionSamples::parse(&bytes, Path::new("fuzz"));
        }
    }
}
