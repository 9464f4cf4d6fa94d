//! Shared robust statistics: medians, the MAD scale, and the two-sided CUSUM with its ARL
//! design. Every detector uses these, so a statistic means the same thing everywhere.
//! (Hand-written: a few lines each, and their exact arithmetic is part of byte-identical replay.)

/// SplitMix64: a small deterministic generator. The core's Monte Carlo designs (and the test
/// fixtures) draw from it so that the same seed gives the same numbers on every machine and
/// with every crate version (a generator crate may change its streams between releases).
// `pub` for the dev-only fixtures (`fixtures::Rng`); a release build does not export it
#[cfg_attr(not(feature = "fixtures"), allow(unreachable_pub))]
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

#[cfg_attr(not(feature = "fixtures"), allow(unreachable_pub))]
impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    /// Standard normal (Box–Muller).
    pub(crate) fn gauss(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The factor that makes the median absolute deviation a consistent estimate of a normal σ.
pub(crate) const MAD_TO_SIGMA: f64 = 1.4826;

/// The quantile of the captures' luminances taken as the white when the config gives no scale:
/// high enough that a sample's brightest geometries (a diffuser's normal incidence, a glossy
/// sample's peak) set it, low enough that a few clipped or stray captures do not.
pub(crate) const WHITE_QUANTILE: f64 = 0.99;

/// Fewest usable luminances the white is taken from.
pub(crate) const WHITE_MIN_CAPTURES: usize = 8;

/// The white level of a set of capture luminances (`WHITE_QUANTILE` of the positive, finite
/// ones, by the nearest rank), or `None` when fewer than `WHITE_MIN_CAPTURES` are usable.
/// Scaling every luminance by a factor scales the result by the same factor.
pub(crate) fn white_level(ys: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = ys
        .iter()
        .copied()
        .filter(|y| y.is_finite() && *y > 0.0)
        .collect();
    if v.len() < WHITE_MIN_CAPTURES {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((WHITE_QUANTILE * v.len() as f64).ceil() as usize).clamp(1, v.len());
    Some(v[rank - 1])
}

/// Median of a sorted slice (the mean of the middle two for an even length); 0 when empty.
pub(crate) fn median_sorted(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The upper median of a sorted, non-empty slice (`v[n / 2]`): what `robust_scale_upper`
/// selects. NaN when empty.
#[cfg(test)]
fn upper_median_sorted(v: &[f64]) -> f64 {
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Robust scale about zero: `MAD_TO_SIGMA` · median |x| (the median as in `median_sorted`).
/// NaN when empty.
pub(crate) fn robust_scale_about_zero(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    a.sort_by(f64::total_cmp);
    MAD_TO_SIGMA * median_sorted(&a)
}

/// Robust scale about zero with the upper median: `MAD_TO_SIGMA` · |x|₍ₙ/₂₎. NaN when empty.
/// The order statistic is selected, not sorted for: O(n), and the same value.
pub(crate) fn robust_scale_upper(v: &[f64]) -> f64 {
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    if a.is_empty() {
        return f64::NAN;
    }
    let k = a.len() / 2;
    let (_, m, _) = a.select_nth_unstable_by(k, f64::total_cmp);
    MAD_TO_SIGMA * *m
}

/// Siegmund's approximation of the in-control average run length of a one-sided CUSUM with
/// reference k and threshold h (both in standard deviations).
pub(crate) fn cusum_arl0(k: f64, h: f64) -> f64 {
    let a = 2.0 * k * (h + 1.166);
    if k.abs() < 1e-12 {
        return (h + 1.166).powi(2);
    }
    ((a).exp() - a - 1.0) / (2.0 * k * k)
}

/// The smallest threshold h (to 0.01) whose two-sided ARL₀ reaches `target` observations.
pub(crate) fn cusum_threshold(k: f64, target: f64) -> f64 {
    let mut h = 0.5;
    while cusum_arl0(k, h) / 2.0 < target && h < 50.0 {
        h += 0.01;
    }
    h
}

/// What a CUSUM side has accumulated since it last left zero: the raw estimates behind it, for
/// the alarm's size and its standard error.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct CusumRun {
    /// Sum of the raw estimates.
    pub sum: f64,
    /// Sum of their squared standard errors.
    pub var: f64,
    /// How many observations.
    pub n: usize,
    /// The label of the observation that started the run (a capture index).
    pub start: u64,
}

impl CusumRun {
    /// The run's mean estimate and its standard error (NaN when empty).
    pub(crate) fn mean_and_se(&self) -> (f64, f64) {
        let n = self.n as f64;
        (self.sum / n, self.var.sqrt() / n)
    }
}

/// A two-sided CUSUM of standardised statistics with reference value k, which also keeps the
/// run of raw estimates behind each side.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Cusum {
    pub up: f64,
    pub down: f64,
    pub up_run: CusumRun,
    pub down_run: CusumRun,
}

impl Cusum {
    /// Feed a standardised statistic `z` with the raw estimate and its standard error behind
    /// it; `start` labels the observation (kept as the run's start when a side leaves zero).
    pub(crate) fn add(&mut self, z: f64, k: f64, estimate: f64, se: f64, start: u64) {
        let up = (self.up + z - k).max(0.0);
        let down = (self.down - z - k).max(0.0);
        let grow = |prev: f64, now: f64, run: &mut CusumRun| {
            if now == 0.0 {
                *run = CusumRun::default();
            } else {
                if prev == 0.0 {
                    *run = CusumRun {
                        start,
                        ..CusumRun::default()
                    };
                }
                run.sum += estimate;
                run.var += se * se;
                run.n += 1;
            }
        };
        grow(self.up, up, &mut self.up_run);
        grow(self.down, down, &mut self.down_run);
        self.up = up;
        self.down = down;
    }

    /// The larger side.
    pub(crate) fn max(&self) -> f64 {
        self.up.max(self.down)
    }

    pub(crate) fn reset(&mut self) {
        *self = Cusum::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_and_scales() {
        assert_eq!(median_sorted(&[]), 0.0);
        assert_eq!(median_sorted(&[1.0, 2.0, 4.0]), 2.0);
        assert_eq!(median_sorted(&[1.0, 2.0, 4.0, 8.0]), 3.0);
        assert_eq!(upper_median_sorted(&[1.0, 2.0, 4.0, 8.0]), 4.0);
        assert!(upper_median_sorted(&[]).is_nan());
        assert!((robust_scale_about_zero(&[1.0, -2.0, 3.0]) - MAD_TO_SIGMA * 2.0).abs() < 1e-12);
        assert!((robust_scale_about_zero(&[1.0, -2.0]) - MAD_TO_SIGMA * 1.5).abs() < 1e-12);
        assert!((robust_scale_upper(&[1.0, -2.0]) - MAD_TO_SIGMA * 2.0).abs() < 1e-12);
        // selecting the order statistic gives exactly what sorting gives
        let mut g = SplitMix64(7);
        for n in [1usize, 2, 3, 10, 101, 1000] {
            let v: Vec<f64> = (0..n).map(|_| g.gauss()).collect();
            let mut sorted: Vec<f64> = v.iter().map(|x| x.abs()).collect();
            sorted.sort_by(f64::total_cmp);
            assert_eq!(
                robust_scale_upper(&v),
                MAD_TO_SIGMA * upper_median_sorted(&sorted)
            );
        }
        assert!(robust_scale_upper(&[]).is_nan());
        assert!(robust_scale_about_zero(&[]).is_nan());
    }

    #[test]
    fn cusum_tracks_the_run_behind_each_side() {
        let mut c = Cusum::default();
        c.add(3.0, 1.0, 0.5, 0.1, 7);
        c.add(3.0, 1.0, 0.7, 0.1, 8);
        assert!((c.up - 4.0).abs() < 1e-12);
        assert_eq!(c.up_run.n, 2);
        assert_eq!(c.up_run.start, 7);
        assert!((c.up_run.sum - 1.2).abs() < 1e-12);
        c.add(-4.0, 1.0, -0.1, 0.1, 9);
        assert_eq!(c.up, 0.0);
        assert_eq!(c.up_run.n, 0);
        assert!((c.down - 3.0).abs() < 1e-12);
    }

    #[test]
    fn the_arl_threshold_grows_with_the_target() {
        let h20 = cusum_threshold(1.0, 20.0 * 81.0);
        assert!((h20 - 3.23).abs() < 0.011, "{h20}");
        assert!(cusum_threshold(1.0, 20.0 * 81.0 * 2.0) > h20);
    }

    #[test]
    fn the_white_level_is_a_high_quantile_that_ignores_the_unusable_and_follows_the_scale() {
        let ys: Vec<f64> = (1..=200).map(f64::from).collect();
        assert_eq!(white_level(&ys), Some(198.0));
        let mut with_bad = ys.clone();
        with_bad.extend([f64::NAN, f64::INFINITY, -1.0, 0.0]);
        assert_eq!(white_level(&with_bad), Some(198.0));
        for k in [1e-3, 1.0, 1e3] {
            let scaled: Vec<f64> = ys.iter().map(|y| y * k).collect();
            let w = white_level(&scaled).unwrap();
            assert!((w / (198.0 * k) - 1.0).abs() < 1e-12, "{k}: {w}");
        }
        assert_eq!(white_level(&[1.0; 7]), None);
        assert_eq!(white_level(&[f64::NAN; 100]), None);
        assert_eq!(white_level(&[2.0; 8]), Some(2.0));
    }
}
