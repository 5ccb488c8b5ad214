//! What `furfit inspect` prints about a profile: counts, and per angle the distinct values,
//! range and most common step.

use super::sample::{Profile, Sample};

/// Resolution of [`AxisStats::step`], steps per degree: differences are grouped after
/// rounding to 1e-9 deg.
pub const STEPS_PER_DEG: f64 = 1e9;

/// The distinct values one angle takes over a profile's samples.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisStats {
    /// Number of distinct values.
    pub distinct: usize,
    /// Smallest value, degrees.
    pub min: f64,
    /// Largest value, degrees.
    pub max: f64,
    /// The most common difference between consecutive distinct values (the smallest one on
    /// a tie); `None` unless two values differ by 5e-10 deg or more. Differences are grouped
    /// after rounding to 1e-9 deg ([`STEPS_PER_DEG`]), so `0.1`-step grids with float noise
    /// count as one step; a difference that rounds to 0 is a near-duplicate, not a step (a
    /// "step 0" says nothing).
    pub step: Option<f64>,
    /// Whether every difference but near-duplicates is `step` (so it is the axis's step, not
    /// only the most common one); true with fewer than three distinct values.
    pub even: bool,
    /// The smallest and largest difference (as `step`, near-duplicates aside), and whether
    /// `step` occurs more than once: when no step repeats (0, 10, 25, 45), "most common"
    /// means nothing and the range says more.
    pub step_range: Option<(f64, f64)>,
    /// Whether the most common step occurs more than once.
    pub step_repeats: bool,
    /// Pairs of consecutive distinct values closer than 5e-10 deg (e.g. 20 and
    /// 20.000000000000004, float noise of a computed grid), and the first such pair.
    pub near_duplicates: usize,
    /// The first near-duplicate pair, if any.
    pub near_pair: Option<(f64, f64)>,
}

impl AxisStats {
    /// Stats of `get` over the samples; `None` for an empty profile.
    pub fn of(samples: &[Sample], get: impl Fn(&Sample) -> f64) -> Option<AxisStats> {
        Self::of_axis(samples, get, None)
    }

    /// [`AxisStats::of`] for an angle of period `360` (phi): the first and last values
    /// are neighbours across the seam too, so -179.99999999999994 and 180 are one
    /// near-duplicate direction, not two values a "step" of 360 apart.
    pub fn of_periodic(samples: &[Sample], get: impl Fn(&Sample) -> f64) -> Option<AxisStats> {
        Self::of_axis(samples, get, Some(360.0))
    }

    fn of_axis(
        samples: &[Sample],
        get: impl Fn(&Sample) -> f64,
        period: Option<f64>,
    ) -> Option<AxisStats> {
        let mut v: Vec<f64> = samples.iter().map(get).filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        v.dedup();
        let mut steps = Vec::with_capacity(v.len());
        let (mut near_duplicates, mut near_pair) = (0, None);
        if let (Some(p), [first, .., last]) = (period, v.as_slice()) {
            if ((first + p - last) * STEPS_PER_DEG).round() as i64 == 0 {
                near_duplicates += 1;
                near_pair = Some((*last, *first));
                v.remove(0);
            }
        }
        for w in v.windows(2) {
            match ((w[1] - w[0]) * STEPS_PER_DEG).round() as i64 {
                0 => {
                    near_duplicates += 1;
                    near_pair.get_or_insert((w[0], w[1]));
                }
                d => steps.push(d),
            }
        }
        steps.sort_unstable();
        let mut best: Option<(i64, usize)> = None;
        let mut k = 0;
        while k < steps.len() {
            let run = steps[k..].iter().take_while(|s| **s == steps[k]).count();
            if best.is_none_or(|(_, n)| run > n) {
                best = Some((steps[k], run));
            }
            k += run;
        }
        Some(AxisStats {
            distinct: v.len(),
            min: v[0],
            max: v[v.len() - 1],
            step: best.map(|(s, _)| s as f64 / STEPS_PER_DEG),
            // Sorted: all equal when the first equals the last.
            even: steps.first() == steps.last(),
            step_range: steps
                .first()
                .zip(steps.last())
                .map(|(a, b)| (*a as f64 / STEPS_PER_DEG, *b as f64 / STEPS_PER_DEG)),
            step_repeats: best.is_some_and(|(_, n)| n > 1),
            near_duplicates,
            near_pair,
        })
    }
}

/// A profile's summary.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Samples in the profile.
    pub n_samples: usize,
    /// Valid samples (finite value > 0).
    pub n_valid: usize,
    /// Invalid samples (NaN, `<= 0`), kept but not fitted.
    pub n_invalid: usize,
    /// The `theta_i` axis (degrees); `None` for an empty profile.
    pub theta_i: Option<AxisStats>,
    /// The `theta_r` axis (degrees); `None` for an empty profile.
    pub theta_r: Option<AxisStats>,
    /// The `phi` axis (degrees); `None` for an empty profile.
    pub phi: Option<AxisStats>,
    /// Samples with a sigma.
    pub n_sigma: usize,
    /// Valid samples per channel (index as in `Profile::channels`).
    pub valid_per_channel: Vec<usize>,
}

impl Summary {
    /// The summary of profile `p`.
    pub fn of(p: &Profile) -> Summary {
        let mut per = vec![0; p.n_channels()];
        for s in p.samples.iter().filter(|s| s.is_valid()) {
            if let Some(c) = per.get_mut(s.channel) {
                *c += 1;
            }
        }
        Summary {
            n_samples: p.samples.len(),
            n_valid: p.n_valid(),
            n_invalid: p.n_invalid(),
            theta_i: AxisStats::of(&p.samples, |s| s.theta_i),
            theta_r: AxisStats::of(&p.samples, |s| s.theta_r),
            phi: AxisStats::of_periodic(&p.samples, |s| s.phi),
            n_sigma: p.samples.iter().filter(|s| s.sigma.is_some()).count(),
            valid_per_channel: per,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(phi: f64) -> Sample {
        Sample::new(0.0, 0.0, phi, 1.0)
    }

    #[test]
    fn most_common_step() {
        let v: Vec<Sample> = [0.0, 0.1, 0.2, 0.30000000000000004, 0.4, 1.0, 1.0]
            .into_iter()
            .map(s)
            .collect();
        let a = AxisStats::of(&v, |x| x.phi).unwrap();
        assert_eq!(a.distinct, 6);
        assert_eq!((a.min, a.max), (0.0, 1.0));
        // Four steps of 0.1 (up to float noise, hence the 1e-12 tolerance) and one of 0.6.
        assert!((a.step.unwrap() - 0.1).abs() < 1e-12, "{:?}", a.step);
        assert!(!a.even);
        let even = AxisStats::of(&v[..5], |x| x.phi).unwrap();
        assert!(even.even, "float noise is not unevenness");
        assert!(a.step_repeats);
        let one = AxisStats::of(&v[..1], |x| x.phi).unwrap();
        assert_eq!(one.step, None);
        assert!(one.even);
        assert!(AxisStats::of(&[], |x| x.phi).is_none());
    }

    /// When no step repeats (0, 10, 25, 45) the stats say so and give the range of steps
    /// (inspect printed "most common step 10 deg" for steps of 10, 15 and 20, once each).
    #[test]
    fn steps_that_never_repeat_give_their_range() {
        let v: Vec<Sample> = [0.0, 10.0, 25.0, 45.0].into_iter().map(s).collect();
        let a = AxisStats::of(&v, |x| x.phi).unwrap();
        assert!(!a.even && !a.step_repeats, "{a:?}");
        let (lo, hi) = a.step_range.unwrap();
        assert!(
            (lo - 10.0).abs() < 1e-12 && (hi - 20.0).abs() < 1e-12,
            "{a:?}"
        );
        // Two values: one step, which is the axis's step.
        let a = AxisStats::of(&v[..2], |x| x.phi).unwrap();
        assert!(a.even && !a.step_repeats, "{a:?}");
    }

    /// Values closer than the step resolution are near-duplicates, not a step (20 and
    /// 20.000000000000004 gave "step 0 deg").
    #[test]
    fn near_duplicates_are_not_a_step() {
        // Across the phi seam: one direction, no step of 360.
        let seam = -179.99999999999994;
        let a = AxisStats::of_periodic(&[s(180.0), s(seam)], |x| x.phi).unwrap();
        assert_eq!((a.distinct, a.step), (1, None), "{a:?}");
        assert_eq!((a.near_duplicates, a.near_pair), (1, Some((180.0, seam))));
        let near = 20.000000000000004;
        let a = AxisStats::of(&[s(20.0), s(near)], |x| x.phi).unwrap();
        assert_eq!((a.distinct, a.step), (2, None));
        assert_eq!((a.near_duplicates, a.near_pair), (1, Some((20.0, near))));
        // Beside a real grid the step stays the grid's, and the grid even.
        let v: Vec<Sample> = [0.0, 10.0, 20.0, near, 30.0].into_iter().map(s).collect();
        let a = AxisStats::of(&v, |x| x.phi).unwrap();
        // 10 up to the 1e-9 rounding of the step.
        assert!((a.step.unwrap() - 10.0).abs() < 1e-12, "{:?}", a.step);
        assert!(a.even && a.near_duplicates == 1, "{a:?}");
    }
}
