//! Parallel reductions whose result does not depend on thread scheduling.
//!
//! Rayon's `fold` and `reduce` split work where threads steal it, so a floating-point sum
//! can differ in its last bits between two runs on the same data. The reductions of this
//! crate fold fixed groups of consecutive items instead (`fold_chunks`) and combine the
//! group results sequentially, in order: the same data and seed give the same bits.

use rayon::prelude::*;

/// Most groups a reduction is cut into: enough to balance many cores.
const MAX_GROUPS: usize = 64;

/// Memory all groups' accumulators may hold at once before fewer groups are used.
const BUDGET_BYTES: usize = 256 << 20;

/// Items per group when `items` items are reduced into accumulators of `acc_bytes` bytes
/// each. The group count depends only on the sizes, never on the thread count, so results
/// are the same on every machine; it shrinks (to two at least) when many accumulators would
/// not fit the memory budget.
pub(crate) fn group_size(items: usize, acc_bytes: usize) -> usize {
    let by_memory = (BUDGET_BYTES / acc_bytes.max(1)).max(2);
    let groups = MAX_GROUPS.min(by_memory).min(items.max(1));
    items.div_ceil(groups).max(1)
}

/// Combines the per-group results of `parts` in index order, starting from `identity()`.
pub(crate) fn reduce_in_order<A, P>(
    parts: P,
    identity: impl Fn() -> A,
    combine: impl Fn(A, A) -> A,
) -> A
where
    A: Send,
    P: IndexedParallelIterator<Item = A>,
{
    let parts: Vec<A> = parts.collect();
    parts.into_iter().fold(identity(), combine)
}

/// Element-wise sum of two equal-length vectors, into the first.
pub(crate) fn add_into(mut a: Vec<f64>, b: Vec<f64>) -> Vec<f64> {
    for (x, y) in a.iter_mut().zip(&b) {
        *x += y;
    }
    a
}

/// `Σ f(v)` over a slice, in `f64`, summed in fixed chunks and then in order.
pub(crate) fn sum_in_order(values: &[f32], f: impl Fn(f32) -> f64 + Sync) -> f64 {
    let parts = values
        .par_chunks(group_size(values.len(), 8).max(1 << 12))
        .map(|c| c.iter().map(|&v| f(v)).sum::<f64>());
    reduce_in_order(parts, || 0.0, |a, b| a + b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_are_bitwise_reproducible_across_pool_sizes() {
        // Values spanning many magnitudes make the sum order-sensitive.
        let v: Vec<f32> = (0..300_000u32)
            .map(|i| {
                (i.wrapping_mul(2_654_435_761) % 1_000_003) as f32 * 10f32.powi((i % 13) as i32 - 6)
            })
            .collect();
        let sums: Vec<u64> = [1, 2, 3, 7]
            .iter()
            .map(|&t| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(t)
                    .build()
                    .unwrap();
                pool.install(|| sum_in_order(&v, |x| x as f64)).to_bits()
            })
            .collect();
        assert!(sums.windows(2).all(|w| w[0] == w[1]), "{sums:?}");
        let direct: f64 = v.iter().map(|&x| x as f64).sum();
        let got = f64::from_bits(sums[0]);
        assert!(
            (got - direct).abs() <= 1e-12 * direct.abs(),
            "{got} vs {direct}"
        );
    }
}
