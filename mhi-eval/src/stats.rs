//! Uncertainty of the report's means: percentile bootstrap intervals over triplets, and paired
//! bootstrap intervals of the difference between two methods scored on the same triplets; and
//! of a median of a few timings (the bench's ratios): a distribution-free interval from order
//! statistics.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// How intervals are drawn: `resamples` bootstrap resamples from a generator seeded with `seed`,
/// so a report is reproducible; the interval is the central `level` of the resampled means.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bootstrap {
    /// Seed of the resampling.
    pub seed: u64,
    /// Number of resamples.
    pub resamples: usize,
    /// Coverage of the interval (0.95).
    pub level: f64,
}

impl Default for Bootstrap {
    fn default() -> Self {
        Self {
            seed: 0,
            resamples: 2000,
            level: 0.95,
        }
    }
}

impl Bootstrap {
    /// The same settings with another seed.
    pub fn with_seed(self, seed: u64) -> Self {
        Self { seed, ..self }
    }

    /// The mean of `values` and its percentile bootstrap interval `[lo, hi]`. With one value
    /// the interval is that value (nothing is known about the spread); `None` for no value or a
    /// non-finite one.
    pub fn mean_ci(&self, values: &[f64]) -> Option<(f64, [f64; 2])> {
        if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let n = values.len();
        let mean = values.iter().sum::<f64>() / n as f64;
        if n == 1 {
            return Some((mean, [mean, mean]));
        }
        let ci = self.interval(n, |idx| {
            Some(idx.map(|i| values[i]).sum::<f64>() / n as f64)
        })?;
        Some((mean, ci))
    }

    /// The ratio of sums `Σ num / Σ den` (a ratio of means, e.g. total exact time over total
    /// pruned time) and its percentile bootstrap interval, the pairs `(num[i], den[i])`
    /// resampled together. `None` for no pair, a non-finite value, a sum of `den` that is not
    /// positive in the data, or slices of different lengths.
    pub fn ratio_ci(&self, num: &[f64], den: &[f64]) -> Option<(f64, [f64; 2])> {
        let n = num.len();
        if n == 0 || den.len() != n || num.iter().chain(den).any(|v| !v.is_finite()) {
            return None;
        }
        let ratio = |idx: &mut dyn Iterator<Item = usize>| {
            let (a, b) = idx.fold((0.0, 0.0), |(a, b), i| (a + num[i], b + den[i]));
            (b > 0.0).then(|| a / b)
        };
        let r = ratio(&mut (0..n))?;
        // A resample whose denominators sum to zero has no ratio; it is left out.
        Some((r, self.interval(n, ratio).unwrap_or([r, r])))
    }

    /// The central `level` of `stat` over `resamples` bootstrap resamples of `n` items (each
    /// given as the iterator of its drawn indices); resamples whose `stat` is `None` are left
    /// out, and `None` when all are. The stream depends on the seed and `n` only, so two
    /// methods scored on the same triplets resample the same triplets.
    fn interval(
        &self,
        n: usize,
        stat: impl Fn(&mut dyn Iterator<Item = usize>) -> Option<f64>,
    ) -> Option<[f64; 2]> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ (n as u64).wrapping_mul(0x9E37_79B9));
        let mut v: Vec<f64> = (0..self.resamples.max(1))
            .filter_map(|_| stat(&mut (0..n).map(|_| rng.random_range(0..n))))
            .collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let tail = (1.0 - self.level.clamp(0.0, 1.0)) / 2.0;
        let at = |q: f64| v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
        Some([at(tail), at(1.0 - tail)])
    }

    /// The mean of the paired differences `a[i] − b[i]` and its bootstrap interval (triplets
    /// resampled together, so what the two methods share cancels).
    ///
    /// # Panics
    /// Debug builds panic when the two slices differ in length (the caller pairs them).
    pub fn paired(&self, a: &[f64], b: &[f64]) -> Option<(f64, [f64; 2])> {
        debug_assert_eq!(a.len(), b.len());
        let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
        self.mean_ci(&d)
    }
}

/// Whether an interval contains 0: the difference it bounds is within noise.
pub fn within_noise(ci: [f64; 2]) -> bool {
    ci[0] <= 0.0 && ci[1] >= 0.0
}

/// A distribution-free interval for the median of whatever `values` were drawn from
/// (independently), and its coverage: the order statistics `x₍ₖ₎` and `x₍ₙ₊₁₋ₖ₎` of the sorted
/// values, which hold the median between them with probability `1 − 2·P(Bin(n, ½) < k)` for
/// any continuous distribution. `k` is the largest with a coverage of at least `level`; when
/// even the whole range covers less (n ≤ 5 at 95 %), the range is returned with the coverage it
/// has (75 % for 3 values, 94 % for 5). `None` for no value or a non-finite one.
///
/// Made for a handful of timings whose spread is the machine's, not a bell curve: five rounds
/// of a ratio give `[min, max]` at 94 %, nine give the second smallest and second largest at
/// 96 %.
pub fn median_interval(values: &[f64], level: f64) -> Option<([f64; 2], f64)> {
    if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    // P(Bin(n, ½) ≤ j) for j = 0, 1, …, accumulated from the binomial coefficients in f64
    // (exact enough for any n a bench runs; the terms are scaled by 2⁻ⁿ as they are built).
    let coverage = |k: usize| {
        let mut term = 0.5_f64.powi(n as i32); // C(n, 0) / 2ⁿ
        let mut below = 0.0;
        for j in 0..k {
            below += term;
            term *= (n - j) as f64 / (j + 1) as f64;
        }
        1.0 - 2.0 * below
    };
    let mut k = 1;
    while 2 * (k + 1) <= n + 1 && coverage(k + 1) >= level {
        k += 1;
    }
    Some(([v[k - 1], v[n - k]], coverage(k)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_brackets_the_mean_shrinks_with_n_and_is_reproducible() {
        let b = Bootstrap::default();
        let small: Vec<f64> = (0..10).map(|i| f64::from(i % 5)).collect();
        let large: Vec<f64> = (0..1000).map(|i| f64::from(i % 5)).collect();
        let (m, ci) = b.mean_ci(&small).unwrap();
        assert!((m - 2.0).abs() < 1e-12 && ci[0] < m && m < ci[1], "{ci:?}");
        let (_, ci_l) = b.mean_ci(&large).unwrap();
        assert!(
            ci_l[1] - ci_l[0] < 0.3 * (ci[1] - ci[0]),
            "{ci_l:?} vs {ci:?}"
        );
        assert_eq!(b.mean_ci(&small), b.mean_ci(&small));
        assert_ne!(b.with_seed(1).mean_ci(&small), b.mean_ci(&small));
        assert_eq!(b.mean_ci(&[3.0]), Some((3.0, [3.0, 3.0])));
        assert_eq!(b.mean_ci(&[]), None);
        assert_eq!(b.mean_ci(&[1.0, f64::NAN]), None);
        // Standard error of a mean of 1000 values of variance 2: 0.0447; a 95 % interval spans
        // about ±1.96 of it.
        let half = (ci_l[1] - ci_l[0]) / 2.0;
        assert!(
            (half - 1.96 * (2.0_f64 / 1000.0).sqrt()).abs() < 0.02,
            "{half}"
        );
    }

    #[test]
    fn ratio_interval_brackets_the_ratio_of_sums_and_narrows_with_more_pairs() {
        let b = Bootstrap::default();
        // Times that vary from view to view, the second always about half the first.
        let exact: Vec<f64> = (0..40).map(|i| 20.0 + f64::from(i % 7) * 3.0).collect();
        let pruned: Vec<f64> = exact
            .iter()
            .enumerate()
            .map(|(i, e)| e / 2.0 + if i % 2 == 0 { 0.8 } else { -0.6 })
            .collect();
        let (r, ci) = b.ratio_ci(&exact, &pruned).unwrap();
        let want = exact.iter().sum::<f64>() / pruned.iter().sum::<f64>();
        assert!(
            (r - want).abs() < 1e-12 && ci[0] < r && r < ci[1],
            "{r} {ci:?}"
        );
        assert!(ci[0] > 1.9 && ci[1] < 2.1, "{ci:?}");
        let (_, few) = b.ratio_ci(&exact[..8], &pruned[..8]).unwrap();
        assert!(few[1] - few[0] > ci[1] - ci[0], "{few:?} against {ci:?}");
        assert_eq!(b.ratio_ci(&[], &[]), None);
        assert_eq!(b.ratio_ci(&[1.0], &[0.0]), None);
        assert_eq!(b.ratio_ci(&[1.0, 2.0], &[1.0]), None);
        assert_eq!(b.ratio_ci(&[1.0], &[f64::NAN]), None);
        assert_eq!(b.ratio_ci(&[3.0], &[2.0]), Some((1.5, [1.5, 1.5])));
    }

    #[test]
    fn median_interval_picks_order_statistics_with_the_stated_coverage() {
        let (ci, c) = median_interval(&[5.0, 1.0, 3.0], 0.95).unwrap();
        assert_eq!(ci, [1.0, 5.0]);
        assert!((c - 0.75).abs() < 1e-12, "{c}");
        let (ci, c) = median_interval(&[4.0, 2.0, 9.0, 1.0, 3.0], 0.95).unwrap();
        assert_eq!(ci, [1.0, 9.0]);
        assert!((c - 0.9375).abs() < 1e-12, "{c}");
        // Nine values: the second smallest and second largest, 1 − 2·10/512.
        let nine: Vec<f64> = (1..=9).map(f64::from).collect();
        let (ci, c) = median_interval(&nine, 0.95).unwrap();
        assert_eq!(ci, [2.0, 8.0]);
        assert!((c - (1.0 - 20.0 / 512.0)).abs() < 1e-12, "{c}");
        // Fourteen: k = 4 would cover 94.3 %, under the level, so k = 3 (98.7 %).
        let fourteen: Vec<f64> = (1..=14).map(f64::from).collect();
        let (ci, c) = median_interval(&fourteen, 0.95).unwrap();
        assert_eq!(ci, [3.0, 12.0]);
        assert!((c - (1.0 - 2.0 * 106.0 / 16384.0)).abs() < 1e-12, "{c}");
        assert_eq!(median_interval(&[2.5], 0.95), Some(([2.5, 2.5], 0.0)));
        assert_eq!(median_interval(&[], 0.95), None);
        assert_eq!(median_interval(&[1.0, f64::INFINITY], 0.95), None);
    }

    #[test]
    fn median_interval_covers_the_median_as_often_as_it_says() {
        // Skewed draws (exponential, median ln 2): the share of intervals holding the median
        // matches the stated coverage, for 5 and 11 values.
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for n in [5, 11] {
            let trials = 4000;
            let (mut hits, mut stated) = (0, 0.0);
            for _ in 0..trials {
                let v: Vec<f64> = (0..n).map(|_| -(1.0 - rng.random::<f64>()).ln()).collect();
                let (ci, c) = median_interval(&v, 0.95).unwrap();
                stated = c;
                hits +=
                    usize::from(ci[0] <= std::f64::consts::LN_2 && std::f64::consts::LN_2 <= ci[1]);
            }
            let seen = hits as f64 / trials as f64;
            assert!(
                (seen - stated).abs() < 0.015,
                "n = {n}: {seen} against {stated}"
            );
        }
    }

    #[test]
    fn paired_differences_see_a_small_consistent_gain_that_unpaired_noise_hides() {
        let b = Bootstrap::default();
        // Scores vary a lot between triplets; method a is always 0.1 better.
        let base: Vec<f64> = (0..30)
            .map(|i| 20.0 + 5.0 * ((i * 7 % 11) as f64))
            .collect();
        let a: Vec<f64> = base.iter().map(|v| v + 0.1).collect();
        let (d, ci) = b.paired(&a, &base).unwrap();
        assert!((d - 0.1).abs() < 1e-9 && !within_noise(ci), "{ci:?}");
        // Pure noise around zero: within noise.
        let c: Vec<f64> = base
            .iter()
            .enumerate()
            .map(|(i, v)| v + if i % 2 == 0 { 0.5 } else { -0.5 })
            .collect();
        let (_, ci) = b.paired(&c, &base).unwrap();
        assert!(within_noise(ci), "{ci:?}");
    }
}
