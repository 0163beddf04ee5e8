//! Haar versus smooth wavelets at an equal number of kept coefficients.

use crate::basis::{keep_largest, relative_l2_error, zero_all_but};
use crate::cwb::Layout;
use crate::error::Result;
use crate::transform::Wavelet;

/// Error of one filter at one coefficient count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CountError {
    /// The filter.
    pub wavelet: Wavelet,
    /// Number of coefficients kept.
    pub count: usize,
    /// Relative L2 error over the table region.
    pub relative_error: f64,
}

/// Relative error of the best-`count` approximation of `values` for every filter and count:
/// Haar versus smooth wavelets at an equal number of kept coefficients.
///
/// For each filter the tabulated function is transformed, only its `count` largest-magnitude
/// coefficients are kept, and the inverse transform is compared with the original over the
/// table region (the zero padding is not scored). All filters are scaled to DC gain √2 per
/// level, so magnitudes are comparable; for the biorthogonal CDF 5/3 the magnitude rule is the
/// usual approximation of the L2-optimal choice.
///
/// `layout.wavelet` is ignored; `layout.side` and `layout.extent` place the table.
pub fn error_at_equal_counts(
    layout: Layout,
    values: &[f32],
    wavelets: &[Wavelet],
    counts: &[usize],
) -> Result<Vec<CountError>> {
    let mut out = Vec::with_capacity(wavelets.len() * counts.len());
    for &wavelet in wavelets {
        let l = Layout { wavelet, ..layout };
        let coefficients = l.analyse(values)?;
        for &count in counts {
            let keep = keep_largest(coefficients.data(), count);
            let mut c = coefficients.clone();
            zero_all_but(c.data_mut(), &keep);
            let approx = l.synthesise(c)?;
            out.push(CountError {
                wavelet,
                count,
                relative_error: relative_l2_error(values, &approx),
            });
        }
    }
    Ok(out)
}
