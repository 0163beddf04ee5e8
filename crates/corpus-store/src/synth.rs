//! Synthetic corpora: plausible, physically valid materials made from measured ones.

use brdf::analytic::Ggx;
use brdf::LogTransform;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Gamma};
use rayon::prelude::*;
use sampling::{GridTable, SampleGrid};

use crate::error::{Result, StoreError};
use crate::pack::MaterialSource;

/// Largest directional albedo a synthetic material keeps (larger ones are scaled to it).
pub const MAX_ALBEDO: f64 = 0.98;

/// Options of a synthetic corpus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthOptions {
    /// Number of materials.
    pub n: usize,
    /// Seed.
    pub seed: u64,
    /// Base materials per combination (at least 1, at most the base corpus size).
    pub mix: usize,
    /// Probability of an added analytic lobe.
    pub lobe_probability: f64,
}

impl Default for SynthOptions {
    /// 1,000 materials, seed 0, 3 per combination, lobes on half of them.
    fn default() -> Self {
        SynthOptions {
            n: 1000,
            seed: 0,
            mix: 3,
            lobe_probability: 0.5,
        }
    }
}

/// Generator of a synthetic corpus from base materials (log-space vectors on one grid).
///
/// Synthetic corpora are plausible, physically valid materials made from measured ones.
/// Material `i` of a synthetic corpus (seed `S`) is drawn with its own generator (seeded by
/// `S` and `i`, so any material can be regenerated alone and a pack resumes exactly):
///
/// 1. a random convex combination, in log space, of `mix` distinct base materials with flat
///    Dirichlet weights — `y = Σ wⱼ yⱼ`. Since every `yⱼ ≥ ln ε`, so is `y`: the material is
///    non-negative. In log space this is a weighted geometric mean of the BRDF values, which
///    keeps the shape of peaks (a linear mix would superimpose two peaks);
/// 2. with probability `lobe_probability`, plus an analytic GGX specular lobe (roughness
///    log-uniform in [0.03, 0.5], grey specular scale in [0.005, 0.1] with a ±20 % tint,
///    index of refraction in [1.3, 1.8]) added to the BRDF values;
/// 3. a check of physical validity on the material's own grid: every value finite and
///    non-negative, reciprocal (the tabulated material evaluated both ways), and directional
///    albedo at most 1 at incidence 0°, 30°, 60° and 80°. A material whose albedo exceeds
///    [`MAX_ALBEDO`] is scaled down to it (in linear values); any other failure is an error.
///
/// # Examples
///
/// ```
/// use corpus_store::{MaterialSource, SynthOptions, Synthesizer};
/// use sampling::SampleGrid;
///
/// let grid = SampleGrid::new(15, 15, 30).unwrap();
/// let sources = brdf::sources(&["lambert:kd=0.5", "ggx:alpha=0.1", "ggx:alpha=0.4"]).unwrap();
/// let opts = SynthOptions { n: 4, seed: 7, ..SynthOptions::default() };
/// let synth = Synthesizer::from_sources(&sources, grid, opts).unwrap();
/// assert_eq!(synth.len(), 4);
/// // every material is regenerated alone, identically
/// assert_eq!(synth.log_values(2).unwrap(), synth.log_values(2).unwrap());
/// assert_eq!(synth.log_values(2).unwrap().len(), 3 * grid.len());
/// ```
#[derive(Debug, Clone)]
pub struct Synthesizer {
    base: Vec<f32>,
    base_names: Vec<String>,
    grid: SampleGrid,
    options: SynthOptions,
}

/// The physical checks of one material (see [`Synthesizer`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Validity {
    /// Smallest BRDF value (1/sr).
    pub min_value: f64,
    /// Largest directional albedo over the checked incidences and channels.
    pub max_albedo: f64,
    /// Relative RMS of f(ωi, ωo) − f(ωo, ωi) on random pairs.
    pub reciprocity: f64,
}

impl Validity {
    /// Whether all checks pass (non-negative, albedo ≤ 1, reciprocity residual ≤ 10⁻⁹).
    pub fn is_valid(&self) -> bool {
        self.min_value >= 0.0 && self.max_albedo <= 1.0 && self.reciprocity <= 1e-9
    }
}

/// Checks a material given as channel-major BRDF values on `grid`.
pub fn validity(values: &[f64], grid: SampleGrid) -> Result<Validity> {
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(StoreError::InvalidParameter(format!(
            "value {i} is not finite"
        )));
    }
    let min_value = values.iter().copied().fold(f64::INFINITY, f64::min);
    let table = GridTable::new(grid, values.to_vec())?;
    let max_albedo = [0.0f64, 30.0, 60.0, 80.0]
        .iter()
        .flat_map(|deg| brdf::directional_albedo(&table, deg.to_radians(), 32, 64))
        .fold(0.0, f64::max);
    let reciprocity = brdf::reciprocity_residual(&table, 256, 7);
    Ok(Validity {
        min_value,
        max_albedo,
        reciprocity,
    })
}

impl Synthesizer {
    /// A generator over `base_names.len()` base materials, row-major log-space vectors of
    /// length `3 × grid.len()` in `base`.
    pub fn new(
        base: Vec<f32>,
        base_names: Vec<String>,
        grid: SampleGrid,
        options: SynthOptions,
    ) -> Result<Synthesizer> {
        let dim = 3 * grid.len();
        if base_names.is_empty() || base.len() != base_names.len() * dim {
            return Err(StoreError::InvalidParameter(format!(
                "{} base values for {} materials of {dim}",
                base.len(),
                base_names.len()
            )));
        }
        if options.mix == 0 || options.mix > base_names.len() {
            return Err(StoreError::InvalidParameter(format!(
                "mix of {} materials out of {}",
                options.mix,
                base_names.len()
            )));
        }
        if !(0.0..=1.0).contains(&options.lobe_probability) {
            return Err(StoreError::InvalidParameter(
                "lobe probability must be in [0, 1]".into(),
            ));
        }
        Ok(Synthesizer {
            base,
            base_names,
            grid,
            options,
        })
    }

    /// Decodes base materials (`brdf::corpus` sources) on `grid`.
    pub fn from_sources(
        sources: &[brdf::Source],
        grid: SampleGrid,
        options: SynthOptions,
    ) -> Result<Synthesizer> {
        let set = sampling::TrainingSet::from_sources(sources, grid)?;
        let names = sources.iter().map(|s| s.name()).collect();
        let mut base = Vec::with_capacity(set.len() * set.dim());
        for m in 0..set.len() {
            base.extend(
                set.material(m)
                    .iter()
                    .map(|&v| brdf::to_log(v as f64) as f32),
            );
        }
        Synthesizer::new(base, names, grid, options)
    }

    /// The grid of the generated materials.
    pub fn grid(&self) -> SampleGrid {
        self.grid
    }

    /// Names of the base materials.
    pub fn base_names(&self) -> &[String] {
        &self.base_names
    }

    /// A short description of how material `i` is made (base materials and weights, lobe).
    pub fn recipe(&self, i: usize) -> String {
        let r = self.draw(i);
        let mut s: Vec<String> = r
            .parts
            .iter()
            .map(|&(j, w)| format!("{:.3}·{}", w, self.base_names[j]))
            .collect();
        if let Some(g) = r.lobe {
            s.push(format!(
                "+ggx(alpha={:.3}, ks={:.4}, ior={:.2})",
                g.alpha, g.ks[1], g.ior
            ));
        }
        s.join(" ")
    }

    fn draw(&self, i: usize) -> Recipe {
        let seed = self.options.seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let n0 = self.base_names.len();
        let picks = rand::seq::index::sample(&mut rng, n0, self.options.mix).into_vec();
        let gamma = Gamma::new(1.0, 1.0).expect("shape and scale 1 are valid");
        let g: Vec<f64> = picks
            .iter()
            .map(|_| gamma.sample(&mut rng) + 1e-12)
            .collect();
        let total: f64 = g.iter().sum();
        let parts = picks.into_iter().zip(g.iter().map(|x| x / total)).collect();
        let lobe = (rng.gen::<f64>() < self.options.lobe_probability).then(|| {
            let alpha = (rng.gen_range(0.03f64.ln()..0.5f64.ln())).exp();
            let ks = rng.gen_range(0.005..0.1);
            let tint: [f64; 3] = std::array::from_fn(|_| ks * rng.gen_range(0.8..1.2));
            Ggx {
                kd: [0.0; 3],
                ks: tint,
                alpha,
                ior: rng.gen_range(1.3..1.8),
            }
        });
        Recipe { parts, lobe }
    }

    /// Material `i` as BRDF values (channel-major, 1/sr) before the validity check.
    fn raw_values(&self, i: usize) -> Vec<f64> {
        let dim = 3 * self.grid.len();
        let r = self.draw(i);
        let mut y = vec![0.0f64; dim];
        for &(j, w) in &r.parts {
            let row = &self.base[j * dim..(j + 1) * dim];
            y.par_iter_mut()
                .zip(row)
                .for_each(|(a, &b)| *a += w * b as f64);
        }
        let t = LogTransform::DEFAULT;
        let mut f: Vec<f64> = y.par_iter().map(|&v| t.inverse_clamped(v)).collect();
        if let Some(g) = r.lobe {
            let lobe = GridTable::tabulate(&g, self.grid);
            f.par_iter_mut()
                .zip(&lobe.values)
                .for_each(|(a, b)| *a += b.max(0.0));
        }
        f
    }

    /// Material `i` as a log-space vector, checked (and scaled to [`MAX_ALBEDO`] if needed).
    pub fn material(&self, i: usize) -> Result<Vec<f32>> {
        let mut f = self.raw_values(i);
        let v = validity(&f, self.grid)?;
        if v.max_albedo > MAX_ALBEDO {
            let s = MAX_ALBEDO / v.max_albedo;
            f.par_iter_mut().for_each(|x| *x *= s);
        }
        let v = validity(&f, self.grid)?;
        if !v.is_valid() {
            return Err(StoreError::Invalid {
                index: i,
                reason: format!("{v:?}"),
            });
        }
        Ok(f.iter().map(|&x| brdf::to_log(x) as f32).collect())
    }
}

struct Recipe {
    parts: Vec<(usize, f64)>,
    lobe: Option<Ggx>,
}

impl MaterialSource for Synthesizer {
    fn len(&self) -> usize {
        self.options.n
    }
    fn name(&self, i: usize) -> String {
        format!("synth-{}-{i:06}", self.options.seed)
    }
    fn grid(&self) -> SampleGrid {
        self.grid
    }
    fn log_values(&self, i: usize) -> Result<Vec<f32>> {
        self.material(i)
    }
}
