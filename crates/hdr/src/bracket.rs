//! Adaptive bracketing: choose a position's exposures from the previous position's radiance.

use crate::error::{HdrError, HdrResult};
use crate::ladder::thesis_ladder;
use crate::merge::{flags, HdrImage, Intercept};

/// Settings of the planner.
#[derive(Debug, Clone, PartialEq)]
pub struct BracketOptions {
    /// Candidate exposures, seconds (sorted ascending by the planner). Default: the thesis's 18.
    pub ladder: Vec<f64>,
    /// Usable samples every rate of interest must get.
    pub min_samples: usize,
    /// Factor by which a pixel's rate may change between neighbouring positions.
    pub margin: f64,
    /// Lower end of the merge's valid window, DN.
    pub low_dn: f64,
    /// Upper end of the merge's valid window, DN.
    pub high_dn: f64,
    /// Black level assumed when the previous image was merged with a fitted intercept, DN.
    pub black_level_dn: f64,
    /// Relative shrink of the signal window for planning (noise headroom), 0..0.5.
    pub guard: f64,
    /// Ladder steps between the chosen exposures before the coverage check (1 = every step).
    pub stride: usize,
    /// Pixels dimmer than this (DN/s) are not planned for.
    pub min_rate_dn_per_s: f64,
}

impl Default for BracketOptions {
    fn default() -> Self {
        Self {
            ladder: thesis_ladder(),
            min_samples: 3,
            margin: 2.0,
            low_dn: 10.0,
            high_dn: 1000.0,
            black_level_dn: 0.0,
            guard: 0.1,
            stride: 2,
            min_rate_dn_per_s: 0.0,
        }
    }
}

impl BracketOptions {
    fn validate(&self) -> HdrResult<Vec<f64>> {
        let bad = |s: String| Err(HdrError::InvalidOption(s));
        let mut ladder = self.ladder.clone();
        if ladder.is_empty() || ladder.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
            return bad("ladder must hold positive finite exposures".into());
        }
        ladder.sort_by(f64::total_cmp);
        ladder.dedup();
        if self.min_samples == 0 || self.stride == 0 {
            return bad("min_samples and stride must be at least 1".into());
        }
        if !(self.margin.is_finite() && self.margin >= 1.0) {
            return bad(format!("margin {}", self.margin));
        }
        if !(self.guard.is_finite() && (0.0..0.5).contains(&self.guard)) {
            return bad(format!("guard {}", self.guard));
        }
        if !(self.black_level_dn.is_finite()
            && self.low_dn.is_finite()
            && self.high_dn.is_finite()
            && self.black_level_dn < self.low_dn
            && self.low_dn < self.high_dn)
        {
            return bad(format!(
                "window {}..{} DN with black level {}",
                self.low_dn, self.high_dn, self.black_level_dn
            ));
        }
        if !(self.min_rate_dn_per_s.is_finite() && self.min_rate_dn_per_s >= 0.0) {
            return bad(format!("min_rate {}", self.min_rate_dn_per_s));
        }
        Ok(ladder)
    }
}

/// The exposures chosen for one position.
#[derive(Debug, Clone, PartialEq)]
pub struct ExposurePlan {
    /// Exposure times, ascending, seconds.
    pub exposures_s: Vec<f64>,
    /// Signal rates planned for (after margin), DN/s; `None` when the full ladder was chosen
    /// for lack of information.
    pub rate_range_dn_per_s: Option<(f64, f64)>,
}

/// Usable-sample window in signal (DN above black) shrunk by the guard.
fn signal_window(opts: &BracketOptions, black: f64) -> (f64, f64) {
    let lo = (opts.low_dn - black) * (1.0 + opts.guard);
    let hi = (opts.high_dn - black) * (1.0 - opts.guard);
    (lo, hi.max(lo))
}

fn usable(ts: &[f64], r: f64, (lo, hi): (f64, f64)) -> usize {
    ts.iter()
        .filter(|&&t| {
            let s = r * t;
            s >= lo && s <= hi
        })
        .count()
}

/// Plans exposures for signal rates `[r_lo, r_hi]` (DN/s, before margin) with black level
/// `black_dn`: steps 2 to 4 of [`plan_exposures`].
///
/// # Examples
///
/// A position whose pixels of interest span 200 to 20 000 DN/s needs far fewer than the
/// thesis's 18 exposures, and every rate still gets at least `min_samples` usable ones:
///
/// ```
/// use hdr::{plan_for_rates, BracketOptions};
///
/// let options = BracketOptions::default();
/// let plan = plan_for_rates(200.0, 20_000.0, 0.0, &options).unwrap();
/// assert!(plan.exposures_s.len() < 18);
/// assert!(plan.exposures_s.windows(2).all(|w| w[0] < w[1]));
/// for rate in [200.0, 2_000.0, 20_000.0] {
///     let usable = plan.exposures_s.iter().filter(|&&t| (10.0..=1000.0).contains(&(rate * t)));
///     assert!(usable.count() >= options.min_samples, "{rate} DN/s");
/// }
/// ```
pub fn plan_for_rates(
    r_lo: f64,
    r_hi: f64,
    black_dn: f64,
    opts: &BracketOptions,
) -> HdrResult<ExposurePlan> {
    let ladder = opts.validate()?;
    if !(r_lo.is_finite() && r_hi.is_finite() && r_lo > 0.0 && r_hi >= r_lo) {
        return Err(HdrError::InvalidOption(format!(
            "rate range {r_lo}..{r_hi} DN/s"
        )));
    }
    let black = if black_dn.is_finite() && black_dn < opts.low_dn {
        black_dn
    } else {
        opts.black_level_dn
    };
    let win = signal_window(opts, black);
    let lo_rate = (r_lo / opts.margin).max(opts.min_rate_dn_per_s).min(r_hi);
    let hi_rate = (r_hi * opts.margin).max(lo_rate);
    let n = ladder.len();
    let mut chosen = vec![false; n];
    // Anchor: the longest exposure whose sample of the dimmest rate stays below the top of the
    // window (or the shortest exposure if even that one overflows).
    let top = ladder
        .iter()
        .rposition(|&t| lo_rate * t <= win.1)
        .unwrap_or(0);
    let mut i = top as isize;
    let mut bright_samples = 0;
    while i >= 0 {
        let t = ladder[i as usize];
        chosen[i as usize] = true;
        let s = hi_rate * t;
        if s <= win.1 && s >= win.0 {
            bright_samples += 1;
        }
        if bright_samples >= opts.min_samples || hi_rate * t < win.0 {
            break;
        }
        i -= opts.stride as isize;
    }
    // Coverage check on a logarithmic grid (32 points per decade, both ends included).
    let decades = (hi_rate / lo_rate).log10();
    let steps = ((decades * 32.0).ceil() as usize).max(1);
    for g in 0..=steps {
        let r = lo_rate * (hi_rate / lo_rate).powf(g as f64 / steps as f64);
        let need = opts.min_samples.min(usable(&ladder, r, win));
        let mut have = ladder
            .iter()
            .zip(&chosen)
            .filter(|(&t, &c)| c && (win.0..=win.1).contains(&(r * t)))
            .count();
        for k in (0..n).rev() {
            if have >= need {
                break;
            }
            if !chosen[k] && (win.0..=win.1).contains(&(r * ladder[k])) {
                chosen[k] = true;
                have += 1;
            }
        }
    }
    let exposures_s: Vec<f64> = ladder
        .iter()
        .zip(&chosen)
        .filter(|(_, &c)| c)
        .map(|(&t, _)| t)
        .collect();
    Ok(ExposurePlan {
        exposures_s,
        rate_range_dn_per_s: Some((lo_rate, hi_rate)),
    })
}

/// Plans the next position's exposures from the previous position's merged image.
///
/// Beyond the thesis, which takes the same 18 exposures at every position. Between neighbouring
/// lamp positions the radiance of a pixel changes little, so the previous position's merged
/// image tells which signal rates the next series must cover. A photosite of rate `r` (DN/s)
/// gives a usable sample at exposure `t` when `low ≤ b + r·t ≤ high` (`b` the black level), i.e.
/// over a fixed factor of ~100 in `t`. The planner
///
/// 1. takes the rates `[r_lo, r_hi]` of the valid pixels of interest (a caller-given region,
///    e.g. the sphere, and at least `min_rate_dn_per_s`), widened when pixels were above the
///    window already in the shortest exposure;
/// 2. widens them by `margin` for the change to the next position;
/// 3. anchors the longest exposure so that the dimmest rate's top sample lands just below the
///    upper end of the window (best signal-to-noise), and steps down the ladder by `stride`
///    steps until the brightest rate has `min_samples` samples;
/// 4. checks every rate of the widened range on a fine logarithmic grid and adds ladder
///    exposures (longest first) wherever a rate has fewer than `min_samples` usable samples
///    (or fewer than the full ladder would give it, near the ends of the ladder).
///
/// The windows used for planning are shrunk by `guard` at both ends so that noise does not
/// push planned samples out of the merge's window.
///
/// `roi` (row-major, same size as the image) restricts the pixels of interest, e.g. to the
/// sample's footprint. Without a previous image, or when it has no valid pixel of interest,
/// the whole ladder is returned.
pub fn plan_exposures(
    previous: Option<&HdrImage>,
    roi: Option<&[bool]>,
    opts: &BracketOptions,
) -> HdrResult<ExposurePlan> {
    let ladder = opts.validate()?;
    let full = ExposurePlan {
        exposures_s: ladder.clone(),
        rate_range_dn_per_s: None,
    };
    let Some(prev) = previous else {
        return Ok(full);
    };
    if let Some(m) = roi {
        if m.len() != prev.len() {
            return Err(HdrError::Dimensions(format!(
                "region of {} pixels for a {}-pixel image",
                m.len(),
                prev.len()
            )));
        }
    }
    let black = match prev.options.intercept {
        Intercept::BlackLevel(b) => b,
        Intercept::Fitted => opts.black_level_dn,
    };
    let shortest_prev = prev.exposures_s.first().copied().unwrap_or(ladder[0]);
    let mut r_lo = f64::INFINITY;
    let mut r_hi = 0.0f64;
    let mut saturated = false;
    for i in 0..prev.len() {
        if roi.is_some_and(|m| !m[i]) {
            continue;
        }
        if prev.flags[i] & flags::HOT != 0 {
            continue;
        }
        if prev.valid[i] {
            let r = prev.radiance[i] as f64;
            if r >= opts.min_rate_dn_per_s && r > 0.0 {
                r_lo = r_lo.min(r);
                r_hi = r_hi.max(r);
            }
        } else if prev.flags[i] & flags::SATURATED != 0 {
            saturated = true;
        }
    }
    if saturated {
        // At least this bright: above the window in the previous shortest exposure.
        let r_sat = (opts.high_dn - black) / shortest_prev;
        r_hi = r_hi.max(r_sat);
        r_lo = r_lo.min(r_sat);
    }
    if !(r_lo.is_finite() && r_hi > 0.0) {
        tracing::debug!("no valid pixel of interest: full ladder");
        return Ok(full);
    }
    plan_for_rates(r_lo, r_hi, black, opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_rate_gets_enough_samples_by_independent_count() {
        let opts = BracketOptions::default();
        let ladder = thesis_ladder();
        for &(lo, hi) in &[
            (1.0, 10.0),
            (3.0, 3.0e4),
            (50.0, 800.0),
            (1e3, 1e7),
            (0.5, 2e7),
        ] {
            let plan = plan_for_rates(lo, hi, 0.0, &opts).unwrap();
            let win = signal_window(&opts, 0.0);
            let (a, b) = plan.rate_range_dn_per_s.unwrap();
            for g in 0..=200 {
                let r = a * (b / a).powf(g as f64 / 200.0);
                let full = usable(&ladder, r, win).min(opts.min_samples);
                let got = usable(&plan.exposures_s, r, win);
                assert!(got >= full, "rate {r}: {got} < {full} for [{lo}, {hi}]");
            }
            assert!(plan.exposures_s.windows(2).all(|w| w[0] < w[1]));
        }
    }

    #[test]
    fn bright_scenes_skip_the_long_exposures() {
        let opts = BracketOptions::default();
        let plan = plan_for_rates(200.0, 2000.0, 0.0, &opts).unwrap();
        let longest = *plan.exposures_s.last().unwrap();
        // The dimmest planned rate (100 DN/s) reaches the window's top below 9 s.
        assert!(longest <= 9.0 * 1.01, "{longest}");
        assert!(plan.exposures_s.len() < 9);
        let t_full: f64 = thesis_ladder().iter().sum();
        let t_plan: f64 = plan.exposures_s.iter().sum();
        assert!(t_plan < t_full / 3.0, "{t_plan} vs {t_full}");
    }

    #[test]
    fn bad_options_are_errors() {
        let mut o = BracketOptions {
            margin: 0.5,
            ..Default::default()
        };
        assert!(plan_for_rates(1.0, 2.0, 0.0, &o).is_err());
        o.margin = 2.0;
        o.ladder = vec![];
        assert!(plan_for_rates(1.0, 2.0, 0.0, &o).is_err());
        let o = BracketOptions::default();
        assert!(plan_for_rates(0.0, 2.0, 0.0, &o).is_err());
        assert!(plan_for_rates(3.0, 2.0, 0.0, &o).is_err());
        assert!(plan_exposures(None, None, &o).unwrap().exposures_s.len() == 18);
    }
}
