//! Robust binning of BRDF samples into a MERL table in bounded memory.

use crate::error::{BinningError, Result};
use crate::samples::{SampleSource, KEYS};
use brdf::{MerlTable, BINS};
use rayon::prelude::*;

/// Default memory budget for the values of one pass.
pub const DEFAULT_BUDGET_BYTES: usize = 512 << 20;

/// Bytes [`bin_samples`] holds besides the values of a pass, whatever the budget: the sample
/// counts (`u32` per key), the raw table (`f64` per key), one pass's offsets and fill cursors
/// (two `usize` per key at most) and the finished table (`f64` per key). A caller with a budget
/// for its whole process gives the values what is left after these.
pub const FIXED_BYTES: usize = KEYS * (4 + 8 + 2 * 8 + 8);

/// Options of [`bin_samples`].
#[derive(Debug, Clone)]
pub struct BinningOptions {
    /// Largest memory used for values in one pass, bytes.
    pub budget_bytes: usize,
    /// Fraction discarded at each end of every bin's sorted values (the thesis: 0.25).
    pub trim_fraction: f64,
}

impl Default for BinningOptions {
    fn default() -> Self {
        Self {
            budget_bytes: DEFAULT_BUDGET_BYTES,
            trim_fraction: 0.25,
        }
    }
}

/// A binned table with the number of samples behind every value.
#[derive(Debug, Clone)]
pub struct BinnedTable {
    /// The table; bins without samples are missing (negative).
    pub table: MerlTable,
    /// Samples per key (`channel · BINS + bin`).
    pub counts: Vec<u32>,
    /// Number of passes over the samples that binning needed (after the counting pass).
    pub passes: usize,
}

impl BinnedTable {
    /// Fraction of (channel, bin) values that received at least one sample.
    pub fn coverage(&self) -> f64 {
        self.counts.iter().filter(|c| **c > 0).count() as f64 / self.counts.len() as f64
    }

    /// Total number of samples.
    pub fn total_samples(&self) -> u64 {
        self.counts.iter().map(|c| *c as u64).sum()
    }
}

/// Mean of the values left after discarding `trim` of them at each end. Sorts `values`.
pub fn trimmed_mean(values: &mut [f32], trim: f64) -> f64 {
    values.sort_unstable_by(|a, b| a.total_cmp(b));
    let n = values.len();
    let cut = ((n as f64) * trim).floor() as usize;
    let kept = &values[cut..n - cut];
    if kept.is_empty() {
        return f64::NAN;
    }
    kept.iter().map(|v| *v as f64).sum::<f64>() / kept.len() as f64
}

/// Bins every sample of `source` into a MERL table, robustly and in bounded memory (thesis §3.6).
///
/// Per bin and channel the thesis discards the lowest and the highest 25% of the values and
/// averages the rest (§3.6). That needs every value of a bin at once, and a capture has 20–80
/// million of them, so binning is a counting sort done in passes:
///
/// 1. one streaming pass counts the samples of every key (3 × 1,458,000 `u32` counters, 17.5 MB);
/// 2. the key range is cut into contiguous slices whose samples fit the memory budget
///    (4 bytes per sample: the key is implied by the position in the sorted array);
/// 3. per slice, one more streaming pass scatters the values to their place, then each bin is
///    sorted and its interquartile mean taken, in parallel.
///
/// Memory is therefore the counters plus `min(budget, all values)`, whatever the number of
/// samples, at the cost of re-reading the sample files once per slice. With the default budget of
/// 512 MiB a full 80-million-sample capture is binned in one pass. The result does not depend on
/// the order in which samples arrive (values are sorted before trimming and summed in sorted
/// order), so a resumed capture bins to the same bytes.
///
/// # Examples
///
/// In each bin the lowest and highest quarter are dropped and the rest averaged, so an outlier
/// (a hot pixel, a specular glint of dust) does not move the value:
///
/// ```
/// use binning::{bin_samples, BinningOptions, PositionSamples, Sample};
/// let bin = brdf::bin_index(10, 20, 30);
/// // Eight samples of the red channel in one bin, one of them an outlier.
/// let values = [0.50f32, 0.51, 0.49, 0.50, 0.52, 0.48, 0.50, 9.0];
/// let position = PositionSamples {
///     position: 0,
///     angle_deg: 0.0,
///     samples: values.iter().map(|&v| Sample::new(0, bin, v)).collect(),
/// };
/// let binned = bin_samples(&[position][..], &BinningOptions::default())?;
/// assert_eq!(binned.counts[bin], 8);
/// assert!((binned.table.get(0, bin) - 0.5).abs() < 0.01);
/// assert!(!binned.table.is_valid(1, bin), "no green sample, no green value");
/// # Ok::<(), binning::BinningError>(())
/// ```
pub fn bin_samples<S: SampleSource + ?Sized>(
    source: &S,
    opts: &BinningOptions,
) -> Result<BinnedTable> {
    if !(0.0..0.5).contains(&opts.trim_fraction) {
        return Err(BinningError::Parameter(format!(
            "trim fraction {} outside [0, 0.5)",
            opts.trim_fraction
        )));
    }
    let budget_values = (opts.budget_bytes / 4).max(1 << 16);
    let mut counts = vec![0u32; KEYS];
    source.visit(&mut |chunk| {
        for s in chunk {
            counts[s.key as usize] = counts[s.key as usize].saturating_add(1);
        }
    })?;
    // Cut the key range into slices of at most `budget_values` samples (a single key with more
    // samples than the budget gets a slice of its own).
    let mut slices = Vec::new();
    let mut start = 0usize;
    let mut acc = 0usize;
    for (k, &c) in counts.iter().enumerate() {
        if acc > 0 && acc + c as usize > budget_values {
            slices.push((start, k));
            start = k;
            acc = 0;
        }
        acc += c as usize;
    }
    slices.push((start, KEYS));
    let mut raw = vec![-1.0f64; KEYS];
    for &(lo, hi) in &slices {
        bin_slice(
            source,
            &counts,
            lo,
            hi,
            opts.trim_fraction,
            &mut raw[lo..hi],
        )?;
    }
    for (c, chunk) in raw.chunks_mut(BINS).enumerate() {
        let s = brdf::MERL_SCALE[c];
        for v in chunk {
            if *v >= 0.0 {
                *v /= s;
            }
        }
    }
    tracing::debug!(passes = slices.len(), "binned samples");
    Ok(BinnedTable {
        table: MerlTable::from_raw(raw)?,
        counts,
        passes: slices.len(),
    })
}

fn bin_slice<S: SampleSource + ?Sized>(
    source: &S,
    counts: &[u32],
    lo: usize,
    hi: usize,
    trim: f64,
    out: &mut [f64],
) -> Result<()> {
    let mut offsets = Vec::with_capacity(hi - lo + 1);
    let mut total = 0usize;
    for &c in &counts[lo..hi] {
        offsets.push(total);
        total += c as usize;
    }
    offsets.push(total);
    if total == 0 {
        return Ok(());
    }
    let mut values = vec![0.0f32; total];
    let mut fill = offsets[..hi - lo].to_vec();
    source.visit(&mut |chunk| {
        for s in chunk {
            let k = s.key as usize;
            if (lo..hi).contains(&k) {
                let slot = &mut fill[k - lo];
                values[*slot] = s.value;
                *slot += 1;
            }
        }
    })?;
    if fill.iter().zip(&offsets[1..]).any(|(f, e)| f != e) {
        return Err(BinningError::Dimensions(
            "sample source changed between passes".into(),
        ));
    }
    // Process groups of consecutive keys in parallel; each group owns a contiguous value range.
    const GROUP: usize = 4096;
    let mut groups: Vec<(usize, &mut [f32], &mut [f64])> = Vec::new();
    let mut rest_values: &mut [f32] = &mut values;
    let mut rest_out: &mut [f64] = out;
    let mut k = 0;
    while k < hi - lo {
        let end = (k + GROUP).min(hi - lo);
        let n = offsets[end] - offsets[k];
        let (gv, rv) = rest_values.split_at_mut(n);
        let (go, ro) = rest_out.split_at_mut(end - k);
        groups.push((k, gv, go));
        rest_values = rv;
        rest_out = ro;
        k = end;
    }
    groups.into_par_iter().for_each(|(k0, vals, outs)| {
        let base = offsets[k0];
        for (i, o) in outs.iter_mut().enumerate() {
            let a = offsets[k0 + i] - base;
            let b = offsets[k0 + i + 1] - base;
            if b > a {
                let m = trimmed_mean(&mut vals[a..b], trim);
                // BRDF values are non-negative; a negative mean can only come from noise
                // around zero and must not read as "missing".
                *o = if m.is_finite() { m.max(0.0) } else { -1.0 };
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::{PositionSamples, Sample};
    use rand::{Rng, SeedableRng};

    #[test]
    fn trimmed_mean_discards_quartiles() {
        let mut v = vec![100.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, -50.0];
        // Sorted: -50 1 2 3 4 5 6 100; drop 2 at each end: 2 3 4 5.
        assert_eq!(trimmed_mean(&mut v, 0.25), 3.5);
        assert_eq!(trimmed_mean(&mut [7.0], 0.25), 7.0);
        assert_eq!(trimmed_mean(&mut [1.0, 3.0, 100.0], 0.25), 104.0 / 3.0);
    }

    fn random_positions(seed: u64, n_pos: usize, per: usize) -> Vec<PositionSamples> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n_pos)
            .map(|p| PositionSamples {
                position: p as u32,
                angle_deg: p as f64,
                samples: (0..per)
                    .map(|_| {
                        let bin = rng.gen_range(0..2000) * 700;
                        Sample::new(rng.gen_range(0..3), bin, rng.gen_range(0.0..10.0))
                    })
                    .collect(),
            })
            .collect()
    }

    #[test]
    fn multi_pass_binning_equals_single_pass_and_a_direct_computation() {
        let positions = random_positions(5, 20, 5000);
        let one = bin_samples(positions.as_slice(), &BinningOptions::default()).unwrap();
        let tiny = BinningOptions {
            budget_bytes: 1,
            ..Default::default()
        };
        let many = bin_samples(positions.as_slice(), &tiny).unwrap();
        assert_eq!(one.passes, 1);
        assert!(many.passes > 1, "{}", many.passes);
        assert_eq!(one.table.raw(), many.table.raw());
        assert_eq!(one.counts, many.counts);
        assert_eq!(one.total_samples(), 100_000);
        // Direct computation for a few keys.
        let mut by_key: std::collections::BTreeMap<u32, Vec<f32>> = Default::default();
        for p in &positions {
            for s in &p.samples {
                by_key.entry(s.key).or_default().push(s.value);
            }
        }
        for (&key, vals) in by_key.iter().take(50) {
            let mut v = vals.clone();
            v.sort_by(|a, b| a.total_cmp(b));
            let cut = v.len() / 4;
            let kept = &v[cut..v.len() - cut];
            let mean = kept.iter().map(|x| *x as f64).sum::<f64>() / kept.len() as f64;
            let (c, bin) = (key as usize / BINS, key as usize % BINS);
            assert!((one.table.get(c, bin) - mean).abs() < 1e-9 * mean.max(1.0));
        }
        // Bins without samples are missing.
        assert!(!one.table.is_valid(0, 1));
        assert!(one.coverage() > 0.0 && one.coverage() < 0.01);
    }

    #[test]
    fn order_of_samples_does_not_change_the_result() {
        let positions = random_positions(9, 10, 3000);
        let mut reversed = positions.clone();
        reversed.reverse();
        for p in &mut reversed {
            p.samples.reverse();
        }
        let a = bin_samples(positions.as_slice(), &BinningOptions::default()).unwrap();
        let b = bin_samples(reversed.as_slice(), &BinningOptions::default()).unwrap();
        assert_eq!(a.table.raw(), b.table.raw());
    }

    #[test]
    fn outliers_are_rejected() {
        // 12 samples of 1.0 and 3 wild outliers on each side in one bin: the trimmed mean is 1.
        let mut samples: Vec<Sample> = (0..12).map(|_| Sample::new(1, 42, 1.0)).collect();
        samples.extend((0..3).map(|_| Sample::new(1, 42, 1e6)));
        samples.extend((0..3).map(|_| Sample::new(1, 42, 0.0)));
        let p = [PositionSamples {
            position: 0,
            angle_deg: 0.0,
            samples,
        }];
        let b = bin_samples(&p[..], &BinningOptions::default()).unwrap();
        assert!((b.table.get(1, 42) - 1.0).abs() < 1e-12);
        assert_eq!(b.counts[BINS + 42], 18);
    }
}
