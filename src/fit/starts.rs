//! Automatic starting points: a scrambled Halton design over a plausible box of the free
//! parameters, plus the seed Table 4 presets (and a user `--init`), scored on a subsample.

use super::problem::ParamLayout;
use crate::params::{ParamId, N_PARAMS, PRESETS};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// The box the global stage samples, file units, per parameter: `(lo, hi, log_scale)`.
/// It spans seed Table 4's fitted values with margin (the hard bounds are wider; the local
/// solver may leave the box, never the hard bounds).
pub fn plausible_box(id: ParamId) -> (f64, f64, bool) {
    match id {
        ParamId::Eta => (1.1, 1.9, false),
        ParamId::Kappa => (0.02, 0.95, false),
        ParamId::Alpha => (-4.0, 8.0, false),
        ParamId::BetaM => (1.5, 20.0, true),
        ParamId::BetaN => (1.0, 30.0, true),
        ParamId::SigmaCA => (0.005, 2.0, true),
        ParamId::SigmaMS => (0.2, 5.0, true),
        ParamId::SigmaMA => (0.005, 1.0, true),
        ParamId::G => (-0.3, 0.9, false),
        ParamId::L => (0.3, 3.0, true),
    }
}

const PRIMES: [u64; N_PARAMS] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29];

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
pub fn halton_starts(layout: &ParamLayout, n: usize, seed: u64) -> Vec<[f64; N_PARAMS]> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5eed_0fa1_7000u64);
    let shift: Vec<f64> = (0..N_PARAMS).map(|_| rng.random::<f64>()).collect();
    (0..n)
        .map(|i| {
            let mut v = [0.0; N_PARAMS];
            for id in ParamId::ALL {
                let k = id.index();
                v[k] = match layout.fixed[k] {
                    Some(x) => x,
                    None => {
                        let t = (radical_inverse(i as u64 + 1, PRIMES[k]) + shift[k]).fract();
                        let (lo, hi, log) = plausible_box(id);
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

/// The seed Table 4 presets as starts (fixed parameters overridden).
pub fn preset_starts(layout: &ParamLayout) -> Vec<[f64; N_PARAMS]> {
    PRESETS
        .iter()
        .map(|p| {
            let mut v = p.values;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halton_is_in_box_and_seeded() {
        let layout = ParamLayout::all_free();
        let a = halton_starts(&layout, 64, 7);
        let b = halton_starts(&layout, 64, 7);
        let c = halton_starts(&layout, 64, 8);
        assert_eq!(a, b);
        assert_ne!(a, c);
        for v in &a {
            for id in ParamId::ALL {
                let (lo, hi, _) = plausible_box(id);
                let x = v[id.index()];
                // exp(ln) round trip can overshoot the box edge by an ulp or so.
                assert!(x >= lo * (1.0 - 1e-12) - 1e-12 && x <= hi * (1.0 + 1e-12) + 1e-12);
                assert!(id.spec().contains(x));
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
