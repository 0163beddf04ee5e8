//! Counter-based random numbers: every draw is a pure function of (seed, stream, index), so
//! frames are bit-identical whatever the number of threads that generate them.

/// The SplitMix64 finaliser: a bijective 64-bit mixer with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A random 64-bit word for (`seed`, `stream`, `index`).
#[inline]
pub fn word(seed: u64, stream: u64, index: u64) -> u64 {
    let a = mix64(seed ^ 0x9E37_79B9_7F4A_7C15);
    let b = mix64(a ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
    mix64(b ^ index.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7))
}

/// Key of one frame (or other stream) of a seed: hoisted out of per-pixel loops.
#[inline]
pub fn frame_key(seed: u64, frame: u64) -> u64 {
    word(seed, frame, 0x5049_5845_4C53)
}

/// Uniform in the open interval (0, 1) from a 64-bit word.
#[inline]
pub fn unit_open(w: u64) -> f64 {
    ((w >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
}

/// Quantile function of the standard normal distribution for p in (0, 1): Acklam's rational
/// approximation (relative error below 1.2e-9). The central region needs no transcendental
/// function, which keeps per-pixel noise generation cheap.
#[inline]
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_476_396e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const P_LOW: f64 = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < P_LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - P_LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// Reciprocals 1/k of the Poisson inversion loop (index 0 unused); the loop stops at the last.
const INV_K: [f64; 64] = {
    let mut t = [0.0; 64];
    let mut k = 1;
    while k < 64 {
        t[k] = 1.0 / k as f64;
        k += 1;
    }
    t
};

/// Mean below which Poisson deviates are drawn exactly.
pub const POISSON_EXACT_BELOW: f64 = 12.0;

/// A per-pixel random stream: successive calls give independent draws for one pixel of one
/// frame.
#[derive(Debug, Clone)]
pub struct PixelStream {
    key: u64,
    counter: u64,
}

impl PixelStream {
    /// Stream for (`seed`, `frame`, `pixel`).
    #[inline]
    pub fn new(seed: u64, frame: u64, pixel: u64) -> Self {
        Self::for_pixel(frame_key(seed, frame), pixel)
    }

    /// Stream for `pixel` of the frame whose key is `frame_key` (see [`frame_key`]); the same
    /// as [`PixelStream::new`] with the frame key computed once per frame.
    #[inline]
    pub fn for_pixel(frame_key: u64, pixel: u64) -> Self {
        Self {
            key: mix64(frame_key ^ pixel.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7)),
            counter: 0,
        }
    }

    /// Next uniform in (0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f64 {
        self.counter += 1;
        unit_open(mix64(
            self.key
                .wrapping_add(self.counter.wrapping_mul(0x9E37_79B9_7F4A_7C15)),
        ))
    }

    /// Next standard normal deviate, by inversion of the normal CDF (one uniform per draw).
    #[inline]
    pub fn normal(&mut self) -> f64 {
        normal_quantile(self.uniform())
    }

    /// Poisson deviate of mean `mean`: exact (inversion) below [`POISSON_EXACT_BELOW`],
    /// rounded Gaussian above (the sensor's read noise of ~12 e⁻ hides the difference).
    #[inline]
    pub fn poisson(&mut self, mean: f64) -> f64 {
        if mean <= 0.0 {
            return 0.0;
        }
        if mean < POISSON_EXACT_BELOW {
            let u = self.uniform();
            let mut p = (-mean).exp();
            let mut cdf = p;
            let mut k = 0usize;
            while u > cdf && k < INV_K.len() - 1 {
                k += 1;
                p *= mean * INV_K[k];
                cdf += p;
            }
            k as f64
        } else {
            (mean + mean.sqrt() * self.normal()).round().max(0.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moments(xs: &[f64]) -> (f64, f64) {
        let n = xs.len() as f64;
        let m = xs.iter().sum::<f64>() / n;
        let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
        (m, v)
    }

    #[test]
    fn uniform_and_normal_moments() {
        let u: Vec<f64> = (0..200_000)
            .map(|i| PixelStream::new(7, 3, i).uniform())
            .collect();
        let (m, v) = moments(&u);
        assert!((m - 0.5).abs() < 0.003 && (v - 1.0 / 12.0).abs() < 0.001);
        let g: Vec<f64> = (0..200_000)
            .map(|i| PixelStream::new(7, 4, i).normal())
            .collect();
        let (m, v) = moments(&g);
        assert!(m.abs() < 0.01 && (v - 1.0).abs() < 0.01, "{m} {v}");
    }

    #[test]
    fn normal_quantile_matches_known_values() {
        // Φ⁻¹ at tabulated probabilities.
        for (p, z) in [
            (0.5, 0.0),
            (0.841_344_746_068_542_9, 1.0),
            (0.022_750_131_948_179_2, -2.0),
            (0.998_650_101_968_369_9, 3.0),
            (1e-6, -4.753_424_308_822_899),
        ] {
            assert!(
                (normal_quantile(p) - z).abs() < 1e-7,
                "{p}: {}",
                normal_quantile(p)
            );
        }
    }

    #[test]
    fn poisson_mean_equals_variance_on_both_branches() {
        for mean in [0.3, 5.0, 11.9, 12.1, 40.0, 2500.0] {
            let xs: Vec<f64> = (0..100_000)
                .map(|i| PixelStream::new(11, 0, i).poisson(mean))
                .collect();
            let (m, v) = moments(&xs);
            assert!((m / mean - 1.0).abs() < 0.02, "mean {mean}: {m}");
            assert!((v / mean - 1.0).abs() < 0.04, "var {mean}: {v}");
            assert!(xs.iter().all(|x| x.fract() == 0.0 && *x >= 0.0));
        }
    }

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<f64> = (0..4).map(|_| 0.0).collect();
        let mut s1 = PixelStream::new(1, 2, 3);
        let mut s2 = PixelStream::new(1, 2, 3);
        let mut s3 = PixelStream::new(1, 2, 4);
        let x1: Vec<f64> = a.iter().map(|_| s1.uniform()).collect();
        let x2: Vec<f64> = a.iter().map(|_| s2.uniform()).collect();
        let x3: Vec<f64> = a.iter().map(|_| s3.uniform()).collect();
        assert_eq!(x1, x2);
        assert_ne!(x1, x3);
    }
}
