//! Decoding a model's coordinates to BRDF values fast enough for interaction: the basis
//! re-stored component-major in half precision, so that a decode from `k` coordinates reads
//! only the first `k` components, two bytes each.

use half::f16;
use rayon::prelude::*;

use crate::error::{ReduceError, Result};
use crate::model::Model;

/// Entries per block: one block's running sums (16 KiB of `f32`) stay in the L1 cache while
/// the block's rows of the components stream past.
const BLOCK: usize = 4096;

/// A model's decoder for interactive use ([`Model::decoder`]): the same map as
/// [`Model::synthesize`] (mean plus the components weighted by the coordinates, then the
/// mapping's inverse, clamped at 0), with the components stored block by block and
/// component-major in half precision.
///
/// A decode from `k` coordinates reads `2 k D` bytes of the basis instead of `4 K D` (`D`
/// entries, `K` stored components): a quarter at `k = K / 2`. Half precision keeps 11
/// significant bits, so in the model's space (`ln f` for the log mapping) a decoded value
/// differs from [`Model::synthesize`]'s by at most `Σ_j |x_j| |δu_j|` with
/// `|δu_j| ≤ 2⁻¹¹ |u_j|` (tested). On the model of the 96 shared MERL materials that is at most
/// 3·10⁻³ in `ln f` over the corpus's coordinates at `k = 45` (0.3 %; the `model_cost`
/// benchmark reports it), far under any model's own error (several per cent).
/// The mean stays in single precision.
///
/// # Examples
///
/// ```
/// use reduce::{build_model, Corpus};
///
/// let mut corpus = Corpus::new(50);
/// for i in 0..6 {
///     let values: Vec<f64> = (0..50).map(|d| 0.1 + 0.05 * (i as f64) * (d as f64 / 10.0).sin().abs()).collect();
///     corpus.push_values(format!("m{i}"), &values).unwrap();
/// }
/// let model = build_model(&corpus, 4, None, None).unwrap();
/// let decoder = model.decoder(model.components()).unwrap();
/// let x = [0.3, -0.2];
/// let fast = decoder.decode(&x).unwrap();
/// let exact = model.synthesize(&x).unwrap();
/// assert!(fast.iter().zip(&exact).all(|(a, b)| (a - b).abs() <= 1e-3 * b));
/// ```
#[derive(Debug, Clone)]
pub struct Decoder {
    /// The model's mean (its space), `D` entries.
    mean: Vec<f32>,
    /// Components kept, `k`.
    components: usize,
    /// Block `b`, component `j`, entry `i` of the block at
    /// `(b · k + j) · BLOCK + i` (the last block padded with zeros).
    basis: Vec<f16>,
    /// The mapping's inverse: floor and per-bin weights ([`crate::Mapping::inverse_form`]).
    floor: f64,
    weights: Option<&'static [f32]>,
}

impl Model {
    /// A [`Decoder`] of this model's first `k` components (at most [`Model::components`]).
    /// Building it reads the whole basis once (about a second for a MERL model of 60
    /// components on two cores) and holds `2 k D` bytes.
    pub fn decoder(&self, k: usize) -> Result<Decoder> {
        let kk = self.pca.components;
        if k == 0 || k > kk {
            return Err(ReduceError::Dimension {
                what: "components of a decoder (1 to K)",
                expected: kk,
                got: k,
            });
        }
        let dim = self.pca.dim;
        let blocks = dim.div_ceil(BLOCK);
        let mut basis = vec![f16::ZERO; blocks * k * BLOCK];
        basis
            .par_chunks_mut(k * BLOCK)
            .enumerate()
            .for_each(|(b, out)| {
                let d0 = b * BLOCK;
                let n = BLOCK.min(dim - d0);
                for i in 0..n {
                    let row = &self.pca.basis[(d0 + i) * kk..(d0 + i) * kk + k];
                    for (j, &u) in row.iter().enumerate() {
                        out[j * BLOCK + i] = f16::from_f32(u);
                    }
                }
            });
        let (floor, weights) = self.mapping.inverse_form();
        Ok(Decoder {
            mean: self.pca.mean.clone(),
            components: k,
            basis,
            floor,
            weights,
        })
    }
}

impl Decoder {
    /// Number of components the decoder holds.
    pub fn components(&self) -> usize {
        self.components
    }

    /// Length of a decoded vector (`D`).
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// BRDF values (clamped to ≥ 0) of the point with coordinates `x` (its length selects
    /// how many components are used, at most [`Decoder::components`]), as
    /// [`Model::synthesize`] gives them up to half-precision rounding of the basis.
    pub fn decode(&self, x: &[f64]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.dim()];
        self.decode_into(x, &mut out)?;
        Ok(out)
    }

    /// [`Decoder::decode`] into `out` (length [`Decoder::dim`]), which an interactive caller
    /// keeps between decodes.
    pub fn decode_into(&self, x: &[f64], out: &mut [f64]) -> Result<()> {
        if x.len() > self.components {
            return Err(ReduceError::Dimension {
                what: "number of coordinates (at most the decoder's components)",
                expected: self.components,
                got: x.len(),
            });
        }
        if out.len() != self.dim() {
            return Err(ReduceError::Dimension {
                what: "length of the decoded vector",
                expected: self.dim(),
                got: out.len(),
            });
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(ReduceError::NonFinite("coordinates"));
        }
        let xf: Vec<f32> = x.iter().map(|&v| v as f32).collect();
        let k = self.components;
        out.par_chunks_mut(BLOCK)
            .zip(self.basis.par_chunks(k * BLOCK))
            .enumerate()
            .for_each(|(b, (o, block))| {
                let d0 = b * BLOCK;
                let n = o.len();
                let mut acc = [0.0f32; BLOCK];
                acc[..n].copy_from_slice(&self.mean[d0..d0 + n]);
                accumulate(&mut acc[..n], block, &xf);
                match self.weights {
                    None => {
                        for (v, &z) in o.iter_mut().zip(&acc[..n]) {
                            *v = (z.exp() as f64 - self.floor).max(0.0);
                        }
                    }
                    Some(w) => {
                        let bins = w.len();
                        for (i, (v, &z)) in o.iter_mut().zip(&acc[..n]).enumerate() {
                            let c = w[(d0 + i) % bins] as f64;
                            *v = ((z.exp() as f64 - self.floor) / c).max(0.0);
                        }
                    }
                }
            });
        Ok(())
    }
}

/// `acc[i] += Σ_j x[j] u_j[i]` over one block: `rows` holds the block's component rows,
/// `BLOCK` apart. With AVX2, FMA and F16C (detected at run time) the half-precision values are
/// widened eight at a time in registers; elsewhere one at a time.
fn accumulate(acc: &mut [f32], rows: &[f16], x: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("f16c")
        {
            // SAFETY: the features were detected just above.
            unsafe { accumulate_f16c(acc, rows, x) };
            return;
        }
    }
    accumulate_scalar(acc, rows, x);
}

/// [`accumulate`] one entry at a time (processors without the vector instructions).
fn accumulate_scalar(acc: &mut [f32], rows: &[f16], x: &[f32]) {
    for (j, &xj) in x.iter().enumerate() {
        let row = &rows[j * BLOCK..j * BLOCK + acc.len()];
        for (a, u) in acc.iter_mut().zip(row) {
            *a += xj * u.to_f32();
        }
    }
}

/// [`accumulate`] with AVX2, FMA and F16C: four component rows per pass over the block's sums,
/// eight entries per instruction; the block's tail (fewer than eight entries) one at a time.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c")]
fn accumulate_f16c(acc: &mut [f32], rows: &[f16], x: &[f32]) {
    use std::arch::x86_64::*;
    let n = acc.len();
    let whole = n - n % 8;
    let row = |j: usize| &rows[j * BLOCK..j * BLOCK + n];
    let mut j = 0;
    while j < x.len() {
        let m = (x.len() - j).min(4);
        let r: [&[f16]; 4] = std::array::from_fn(|t| row(j + t.min(m - 1)));
        let xs: [f32; 4] = std::array::from_fn(|t| if t < m { x[j + t] } else { 0.0 });
        let xv = xs.map(|v| _mm256_set1_ps(v));
        let mut i = 0;
        while i < whole {
            // SAFETY: i + 8 ≤ n, the length of `acc` and of every row; unaligned loads.
            unsafe {
                let mut a = _mm256_loadu_ps(acc.as_ptr().add(i));
                for t in 0..4 {
                    let h = _mm_loadu_si128(r[t].as_ptr().add(i) as *const __m128i);
                    a = _mm256_fmadd_ps(xv[t], _mm256_cvtph_ps(h), a);
                }
                _mm256_storeu_ps(acc.as_mut_ptr().add(i), a);
            }
            i += 8;
        }
        for i in whole..n {
            for t in 0..m {
                acc[i] += xs[t] * r[t][i].to_f32();
            }
        }
        j += m;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::ggx_corpus;
    use crate::{build_mapped_model, Corpus, Mapping};

    /// Model-space value of a decoded entry (`z = ln(f w + floor)`), `None` where clamped.
    fn mapped(f: f64, i: usize, floor: f64, w: Option<&[f32]>) -> Option<f64> {
        let w = w.map_or(1.0, |w| w[i % w.len()] as f64);
        (f > 0.0).then(|| (f * w + floor).ln())
    }

    /// Every decoded entry is within the half-precision rounding of its terms of the exact
    /// decode: `|Δz| ≤ Σ_j |x_j| (2⁻¹¹ |u_j| + 2⁻²⁵)` (relative rounding of normal halves,
    /// absolute of subnormal ones), plus single-precision summation slack.
    fn check_against_exact(model: &Model, x: &[f64]) {
        let decoder = model.decoder(model.components()).unwrap();
        let fast = decoder.decode(x).unwrap();
        let exact = model.synthesize(x).unwrap();
        let (floor, w) = model.mapping.inverse_form();
        let kk = model.pca.components;
        let mut compared = 0;
        for (i, (a, b)) in fast.iter().zip(&exact).enumerate() {
            let (Some(za), Some(zb)) = (mapped(*a, i, floor, w), mapped(*b, i, floor, w)) else {
                continue;
            };
            let u = &model.pca.basis[i * kk..i * kk + x.len()];
            let bound: f64 = x
                .iter()
                .zip(u)
                .map(|(xj, uj)| xj.abs() * (uj.abs() as f64 / 2048.0 + 2f64.powi(-25)))
                .sum::<f64>()
                + 1e-5 * (1.0 + zb.abs());
            assert!(
                (za - zb).abs() <= bound,
                "entry {i}: {za} against {zb}, bound {bound}"
            );
            compared += 1;
        }
        assert!(
            compared > fast.len() / 2,
            "only {compared} entries unclamped"
        );
    }

    #[test]
    fn the_decoder_agrees_with_the_exact_decode_in_both_mappings() {
        let c = ggx_corpus();
        for mapping in [Mapping::Log, Mapping::COSINE] {
            let m = build_mapped_model(&c, mapping, 3, None, None).unwrap();
            for row in 0..4 {
                let x: Vec<f64> = (0..3).map(|j| m.pca.coords[(row, j)]).collect();
                check_against_exact(&m, &x);
                // fewer coordinates than components, and a point off the corpus
                check_against_exact(&m, &x[..1]);
                check_against_exact(&m, &[x[0] * 1.5, -x[1], 0.5 * x[2]]);
            }
        }
    }

    /// A length that is not a whole number of blocks (nor of eight): the tail entries decode
    /// like the rest.
    #[test]
    fn the_last_partial_block_decodes_too() {
        let dim = 2 * BLOCK + 13;
        let mut c = Corpus::new(dim);
        for i in 0..6 {
            let v: Vec<f64> = (0..dim)
                .map(|d| {
                    0.05 + 0.1
                        * (i as f64 + 1.0)
                        * ((d as f64) * 0.01 * (i as f64 + 1.0)).sin().abs()
                })
                .collect();
            c.push_values(format!("m{i}"), &v).unwrap();
        }
        let m = build_mapped_model(&c, Mapping::Log, 5, None, None).unwrap();
        assert_eq!(m.decoder(5).unwrap().dim(), dim);
        for row in 0..6 {
            let x: Vec<f64> = (0..5).map(|j| m.pca.coords[(row, j)]).collect();
            check_against_exact(&m, &x);
        }
    }

    /// The vector kernel (where this processor has it) and the scalar one give the same sums
    /// for every number of rows (whole groups of four and the rest) and a ragged length.
    #[test]
    fn both_kernels_give_the_same_sums() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let rows: Vec<f16> = (0..7 * BLOCK)
            .map(|_| f16::from_f32(rng.gen_range(-1.0..1.0)))
            .collect();
        for k in 0..=7 {
            let x: Vec<f32> = (0..k).map(|_| rng.gen_range(-3.0..3.0)).collect();
            for n in [BLOCK, BLOCK - 5, 3] {
                let start: Vec<f32> = (0..n).map(|i| i as f32 * 1e-3).collect();
                let (mut a, mut b) = (start.clone(), start.clone());
                accumulate(&mut a, &rows, &x);
                accumulate_scalar(&mut b, &rows, &x);
                for (i, (p, q)) in a.iter().zip(&b).enumerate() {
                    let scale: f32 = 1.0 + x.iter().map(|v| v.abs()).sum::<f32>();
                    assert!(
                        (p - q).abs() <= 1e-5 * scale,
                        "k {k} n {n} entry {i}: {p} {q}"
                    );
                }
            }
        }
    }

    #[test]
    fn bad_requests_are_typed_errors() {
        let c = ggx_corpus();
        let m = build_mapped_model(&c, Mapping::Log, 3, None, None).unwrap();
        assert!(m.decoder(0).is_err());
        assert!(m.decoder(4).is_err());
        let d = m.decoder(2).unwrap();
        assert_eq!(d.components(), 2);
        assert!(d.decode(&[0.0; 3]).is_err());
        assert!(d.decode(&[f64::NAN]).is_err());
        let mut short = vec![0.0; d.dim() - 1];
        assert!(d.decode_into(&[1.0], &mut short).is_err());
        // no coordinates: the mean
        let mean = d.decode(&[]).unwrap();
        let exact = m.synthesize(&[]).unwrap();
        assert!(mean
            .iter()
            .zip(&exact)
            .all(|(a, b)| (a - b).abs() <= 1e-6 * (1.0 + b.abs())));
    }
}
