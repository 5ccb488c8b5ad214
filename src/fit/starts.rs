//! Automatic starting points: a scrambled Halton design over the model's plausible box of
//! the free parameters ([`crate::models::FiberModel::plausible_box`]), plus the model's
//! presets (the fur model: seed Table 4) and a user `--init`, scored on a subsample.

use super::problem::ParamLayout;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// One Halton base per parameter (a model has at most this many).
const PRIMES: [u64; 16] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53];

fn radical_inverse(mut i: u64, base: u64) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    let b = base as f64;
    while i > 0 {
        f /= b;
        r += f * (i % base) as f64;
        i /= base;
    }
    r
}

/// `n` points of the Halton sequence in the free dimensions of `layout`, each coordinate
/// shifted by a seeded random offset modulo 1 (Cranley-Patterson rotation), mapped into
/// the plausible box. Fixed parameters keep their value. File units.
pub fn halton_starts(layout: &ParamLayout, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let n_params = layout.fixed.len();
    assert!(
        n_params <= PRIMES.len(),
        "a model has at most 16 parameters"
    );
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5eed_0fa1_7000u64);
    let shift: Vec<f64> = (0..n_params).map(|_| rng.random::<f64>()).collect();
    (0..n)
        .map(|i| {
            let mut v = vec![0.0; n_params];
            for k in 0..n_params {
                v[k] = match layout.fixed[k] {
                    Some(x) => x,
                    None => {
                        let t = (radical_inverse(i as u64 + 1, PRIMES[k]) + shift[k]).fract();
                        let (lo, hi, log) = layout.model.plausible_box(k);
                        if log {
                            (lo.ln() + t * (hi.ln() - lo.ln())).exp()
                        } else {
                            lo + t * (hi - lo)
                        }
                    }
                };
            }
            v
        })
        .collect()
}

/// The model's presets as starts (fixed parameters overridden).
pub fn preset_starts(layout: &ParamLayout) -> Vec<Vec<f64>> {
    layout
        .model
        .presets()
        .iter()
        .map(|p| {
            let mut v = p.values.to_vec();
            for (k, f) in layout.fixed.iter().enumerate() {
                if let Some(x) = f {
                    v[k] = *x;
                }
            }
            v
        })
        .collect()
}

/// A seeded subsample of `n` indices out of `0..total` (sorted; all of them if
/// `total <= n`).
pub fn subsample(total: usize, n: usize, seed: u64) -> Vec<usize> {
    if total <= n {
        return (0..total).collect();
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5ab5_a3b1e0u64);
    let mut idx: Vec<usize> = (0..total).collect();
    // Partial Fisher-Yates.
    for i in 0..n {
        let j = rng.random_range(i..total);
        idx.swap(i, j);
    }
    let mut out = idx[..n].to_vec();
    out.sort_unstable();
    out
}

/// Samples per `theta_d` the grouped subsample aims for: the far field's per-`theta_d`
/// set-up (segmentation and fits) is shared by all samples of that `theta_d`, so a
/// subsample spread thinly over every `theta_d` costs nearly as much as the full profile.
const PER_THETA_D: usize = 24;

/// A seeded subsample of about `n` of the `points` (sorted indices; all of them if
/// `points.len() <= n`) that keeps the evaluation cheap: every k-th distinct `theta_d`
/// (in order, random offset, so the whole `theta_d` range stays covered) with k chosen for
/// about [`PER_THETA_D`] samples each, then `n` samples drawn uniformly from those groups.
pub fn subsample_grouped(
    points: &[(f64, f64, f64)],
    n: usize,
    seed: u64,
    slice_of: impl Fn(f64, f64) -> f64,
) -> Vec<usize> {
    let total = points.len();
    if total <= n {
        return (0..total).collect();
    }
    let td: Vec<f64> = points.iter().map(|&(ti, tr, _)| slice_of(ti, tr)).collect();
    let mut distinct: Vec<f64> = td.clone();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    let want_groups = n.div_ceil(PER_THETA_D).max(1);
    let k = (distinct.len() / want_groups).max(1);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x7d_9e37_79b9);
    let offset = rng.random_range(0..k);
    let keep: std::collections::HashSet<u64> = distinct
        .iter()
        .skip(offset)
        .step_by(k)
        .map(|t| t.to_bits())
        .collect();
    let pool: Vec<usize> = (0..total)
        .filter(|&i| keep.contains(&td[i].to_bits()))
        .collect();
    if pool.len() <= n {
        return pool;
    }
    subsample(pool.len(), n, seed)
        .into_iter()
        .map(|j| pool[j])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grouped subsample has the requested size, is seeded, uses about
    /// `n / PER_THETA_D` distinct theta_d spread over the whole range, and keeps all
    /// points when there are few.
    #[test]
    fn grouped_subsample_thins_theta_d() {
        let mut pts = Vec::new();
        for ti in [0.0f64, 15.0, 30.0, 45.0] {
            for k in 0..81 {
                for j in 0..90 {
                    let tr = -80.0 + 2.0 * k as f64;
                    let phi = -176.0 + 4.0 * j as f64;
                    pts.push((ti.to_radians(), tr.to_radians(), phi.to_radians()));
                }
            }
        }
        let td = crate::model::geometry::theta_d;
        let a = subsample_grouped(&pts, 1500, 3, td);
        assert_eq!(a.len(), 1500);
        assert_eq!(a, subsample_grouped(&pts, 1500, 3, td));
        assert_ne!(a, subsample_grouped(&pts, 1500, 4, td));
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        let mut tds: Vec<f64> = a
            .iter()
            .map(|&i| crate::model::geometry::theta_d(pts[i].0, pts[i].1))
            .collect();
        tds.sort_by(f64::total_cmp);
        tds.dedup();
        // 192 distinct theta_d on this grid; 1500 / 24 -> 63 wanted -> every 3rd -> 64.
        assert!((55..=70).contains(&tds.len()), "{} theta_d", tds.len());
        assert!(tds[0] < (-55f64).to_radians() && tds[tds.len() - 1] > 30f64.to_radians());
        assert_eq!(
            subsample_grouped(&pts[..100], 1500, 3, td),
            (0..100).collect::<Vec<_>>()
        );
    }

    #[test]
    fn halton_is_in_box_and_seeded() {
        for model in crate::models::MODELS {
            let layout = ParamLayout::all_free(model);
            let a = halton_starts(&layout, 64, 7);
            let b = halton_starts(&layout, 64, 7);
            let c = halton_starts(&layout, 64, 8);
            assert_eq!(a, b);
            assert_ne!(a, c);
            for v in &a {
                for id in layout.all() {
                    let (lo, hi, _) = model.plausible_box(id.index());
                    let x = v[id.index()];
                    // exp(ln) round trip can overshoot the box edge by an ulp or so.
                    assert!(x >= lo * (1.0 - 1e-12) - 1e-12 && x <= hi * (1.0 + 1e-12) + 1e-12);
                    assert!(id.spec().contains(x));
                }
            }
        }
    }

    #[test]
    fn subsample_is_distinct_and_sorted() {
        let s = subsample(1000, 100, 1);
        assert_eq!(s.len(), 100);
        assert!(s.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(subsample(10, 100, 1), (0..10).collect::<Vec<_>>());
    }
}
