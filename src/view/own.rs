//! The fiber-aware self-shadowing of the transfer ([`super::prt::Shadowing::Others`]): a
//! texel's own fibers do not shadow themselves.
//!
//! Why: a texel of shell `s` shows the fibers crossing it. Toward a direction near a
//! fiber's own tangent, the ray march of seed 003 Eq. 4 runs along that very fiber's
//! pieces in the shells above (below) and counts them as occluders, darkening the fiber
//! by itself, the more so the sharper the texels. A real fiber is a convex tube: a ray
//! leaving its surface never meets it again, and the path tracer skips the hit fiber for
//! its shadow rays. So the transmittance a fiber `f` in texel `x` sees toward `d` is that
//! of the OTHER fibers, `exp(-(tau(x, d) - tau_f(x, d)))`, and the texel's transmittance
//! is its fibers' mean, weighted by their optical depth in the texel (their share of its
//! coverage): `T(x, d) = sum_f od_f(x) exp(-(tau - tau_f)) / sum_f od_f(x)`.
//!
//! `tau` is the sweep's ([`super::prt`]): optical depths summed shell by shell, the
//! running sum resampled bilinearly at every shell. The shells' optical depth is exactly
//! the sum of the pieces' ([`super::shells::Pieces`]), so `tau_f` is the same operator
//! applied to fiber `f`'s pieces alone, and `tau - tau_f` is exactly the other fibers'
//! share. The operator is linear: `k` bilinear resamplings by the fractional shift
//! `(fx, fz)` compose into a separable binomial kernel (`k` steps of the 2-tap filter
//! `(1 - f, f)`), so shell `s + k`'s depth reaches texel `x` from texels
//! `x + k (ox, oz) + (mx, mz)` with weight `B(k, fx; mx) B(k, fz; mz)`. [`Kernel`]
//! tabulates it; a fiber's pieces are a few texels each, so `tau_f` costs a few lookups
//! per shell. The march along `f` stops once the kernel has found (almost) none of `f`'s
//! depth in [`MISSES`] shells running (the fiber has left the ray; curl brings it back
//! by less than a texel), and the kernel's weights below [`TAIL`] are left out.

use super::shells::{Patch, Pieces, TexelFibers};

/// Shells in a row without any of the fiber's depth on the kernel that end its march.
pub const MISSES: usize = 2;

/// The binomial kernels `B(k, f; m) = C(k, m) f^m (1 - f)^(k - m)` of one sweep
/// direction's fractional shifts, `k = 0..=shells`, triangular (`k (k + 1) / 2 + m`).
pub struct Kernel {
    px: Vec<f32>,
    pz: Vec<f32>,
    /// Per `k`: the `m` ranges in `x` and `z` where the weights reach [`TAIL`].
    bands: Vec<[i64; 4]>,
}

/// Kernel weights below this are left out (a fraction of the fiber's optical depth of
/// that order: `exp(1e-5)` changes no transmittance visibly).
pub const TAIL: f32 = 1e-5;

/// The first and last `m` of row `k` of a binomial table with a weight `>= TAIL`.
fn band(table: &[f32], k: usize) -> (i64, i64) {
    let row = &table[k * (k + 1) / 2..(k + 1) * (k + 2) / 2];
    let lo = row.iter().position(|&b| b >= TAIL).unwrap_or(0);
    let hi = row.iter().rposition(|&b| b >= TAIL).unwrap_or(0);
    (lo as i64, hi as i64)
}

fn binomial_table(f: f64, kmax: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity((kmax + 1) * (kmax + 2) / 2);
    let mut row = vec![1.0f64];
    out.push(1.0);
    for _ in 1..=kmax {
        // One more 2-tap step: B(k, m) = (1 - f) B(k - 1, m) + f B(k - 1, m - 1).
        let mut next = vec![0.0; row.len() + 1];
        for (m, b) in row.iter().enumerate() {
            next[m] += (1.0 - f) * b;
            next[m + 1] += f * b;
        }
        out.extend(next.iter().map(|&v| v as f32));
        row = next;
    }
    out
}

impl Kernel {
    /// The kernel of a sweep whose per-shell step is `(fx, fz)` texels, fractional parts
    /// spread as binomial weights over `shells` steps.
    pub fn new(fx: f32, fz: f32, shells: usize) -> Kernel {
        let (px, pz) = (
            binomial_table(fx as f64, shells),
            binomial_table(fz as f64, shells),
        );
        let bands = (0..=shells)
            .map(|k| {
                let ((a, b), (c, d)) = (band(&px, k), band(&pz, k));
                [a, b, c, d]
            })
            .collect();
        Kernel { px, pz, bands }
    }

    /// `sum_y od(y) B(k, fx; y_i - bx) B(k, fz; y_j - bz)` over the patch `q`.
    fn apply(&self, k: usize, bx: i64, bz: i64, q: &Patch, vals: &[f32]) -> f32 {
        let [lx, hx, lz, hz] = self.bands[k];
        let (mx0, mx1) = (lx.max(q.i0 - bx), hx.min(q.i0 + q.w as i64 - 1 - bx));
        let (mz0, mz1) = (lz.max(q.j0 - bz), hz.min(q.j0 + q.h as i64 - 1 - bz));
        if mx0 > mx1 || mz0 > mz1 {
            return 0.0;
        }
        let tri = k * (k + 1) / 2;
        let mut sum = 0.0;
        for mz in mz0..=mz1 {
            let wz = self.pz[tri + mz as usize];
            let b = (bz + mz - q.j0) as usize;
            let row = &vals[q.at + b * q.w..q.at + (b + 1) * q.w];
            let mut sx = 0.0;
            for mx in mx0..=mx1 {
                sx += self.px[tri + mx as usize] * row[(bx + mx - q.i0) as usize];
            }
            sum += wz * sx;
        }
        sum
    }
}

/// What the march along a fiber needs of one sweep direction
/// ([`super::prt`]'s `Step`): its kernel and its whole-texel shift per shell.
pub struct Sweep {
    /// The fractional-step kernel.
    pub kernel: Kernel,
    /// Whole texels moved per shell, `(x, z)`.
    pub shift: (i64, i64),
}

/// The fibers of every texel, for [`Shadowing::Others`](super::prt::Shadowing::Others).
pub struct Own<'a> {
    pieces: &'a Pieces,
    /// Per shell: `(start, entries)`, [`Pieces::by_texel`].
    by_texel: Vec<TexelFibers>,
}

impl<'a> Own<'a> {
    /// Index every texel's fibers of `pieces`.
    pub fn new(pieces: &'a Pieces) -> Own<'a> {
        Own {
            pieces,
            by_texel: pieces.by_texel(),
        }
    }

    /// Replace `e` (row `j` of shell `s`, `exp(-tau)` per texel) by the texel's fibers'
    /// mean transmittance through the other fibers (module doc), for sweep direction
    /// `st` (`up`: toward `+y`; each piece's depth along it is its vertical one times
    /// its entry of `factors`, [`Pieces::factors`]), `tau` holding `half` of the texel's
    /// own shell's depth. Texels no fiber covers keep `exp(-tau)`.
    pub fn transmittance(
        &self,
        e: &mut [f32],
        tau: &[f32],
        (st, factors, half): (&Sweep, &[f32], f32),
        s: usize,
        j: usize,
        up: bool,
    ) {
        let res = self.pieces.res;
        let (start, entries) = &self.by_texel[s];
        for i in 0..res {
            let t = j * res + i;
            let ents = &entries[start[t] as usize..start[t + 1] as usize];
            if ents.is_empty() {
                continue;
            }
            let (mut acc, mut wsum) = (0.0f32, 0.0f32);
            for &(f, w) in ents {
                let f = f as usize;
                let shells = self.pieces.shells;
                let here = half * w * factors[f * shells + s];
                let tf = self.tau_own(f, s, (i, j), (st, factors), up) + here;
                acc += w * (-(tau[i] - tf).max(0.0)).exp();
                wsum += w;
            }
            e[i] = acc / wsum;
        }
    }

    /// `tau_f`: fiber `f`'s own optical depth on the sweep's ray from texel `x` of shell
    /// `s` (module doc).
    pub fn tau_own(
        &self,
        f: usize,
        s: usize,
        x: (usize, usize),
        (st, factors): (&Sweep, &[f32]),
        up: bool,
    ) -> f32 {
        let p = self.pieces;
        let kern = &st.kernel;
        let res = p.res as i64;
        // The texel in the fiber's own (unwrapped) coordinates.
        let home = p.patch(f, s);
        let xi = home.i0 + (x.0 as i64 - home.i0).rem_euclid(res);
        let xj = home.j0 + (x.1 as i64 - home.j0).rem_euclid(res);
        let (ox, oz) = st.shift;
        let (mut tau, mut misses) = (0.0f32, 0);
        for k in 1..p.shells {
            let s2 = if up {
                s + k
            } else if k <= s {
                s - k
            } else {
                break;
            };
            if s2 >= p.shells {
                break;
            }
            let q = p.patch(f, s2);
            let v = if q.w == 0 {
                0.0
            } else {
                let ki = k as i64;
                kern.apply(k, xi + ki * ox, xj + ki * oz, q, &p.vals)
            };
            tau += v * factors[f * p.shells + s2];
            if v > TAIL {
                misses = 0;
            } else {
                misses += 1;
                if misses >= MISSES {
                    break;
                }
            }
        }
        tau
    }
}

#[cfg(test)]
mod tests {
    use super::super::prt::{sh_weights, transfer_pieces, Shadowing};
    use super::super::sh::{Rule, N_COEFFS};
    use super::super::shells::{pieces, FurSpec};
    use crate::render::math::V3;
    use std::f64::consts::PI;

    fn spec() -> FurSpec {
        FurSpec {
            res: 32,
            shells: 8,
            radius: 0.02,
            ..FurSpec::default()
        }
    }

    /// `v_0` (the SH constant: the texel's mean transmittance times sqrt(4 pi)) of every
    /// texel fiber 0 covers in shells `0..upto`, per shadowing.
    fn v0_of_fiber0(fibers: &[Vec<V3>], sv: Shadowing, upto: usize) -> Vec<f32> {
        let spec = spec();
        let p = pieces(&spec, fibers);
        let rule = Rule::product(8, 16);
        let t = transfer_pieces(&spec, &p, &rule, sv, &sh_weights(&rule), N_COEFFS);
        let mut out = Vec::new();
        for s in 0..upto {
            let q = p.patch(0, s);
            for b in 0..q.h {
                for a in 0..q.w {
                    // Texels fiber 0 covers well and no other fiber does.
                    let od = p.vals[q.at + b * q.w + a];
                    let (i, j) = (
                        (q.i0 + a as i64).rem_euclid(32) as usize,
                        (q.j0 + b as i64).rem_euclid(32) as usize,
                    );
                    let others: f32 = (1..fibers.len())
                        .map(|f| {
                            let r = p.patch(f, s);
                            let (da, db) = (
                                (i as i64 - r.i0).rem_euclid(32) as usize,
                                (j as i64 - r.j0).rem_euclid(32) as usize,
                            );
                            if da < r.w && db < r.h {
                                p.vals[r.at + db * r.w + da]
                            } else {
                                0.0
                            }
                        })
                        .sum();
                    if od > 0.1 && others == 0.0 {
                        out.push(t.at(s, 0)[j * 32 + i]);
                    }
                }
            }
        }
        out
    }

    /// A single straight fiber, tilted as the comb, is not shadowed by itself with
    /// `Others`: every texel it covers transmits everything (`v_0 = sqrt(4 pi)`; the
    /// kernel's tail cut and f32 rounding: 1e-3 relative). With `All` the same texels
    /// are darkened by the fiber's own pieces above and below (by more than 1 %: the
    /// effect this mode is there to remove).
    #[test]
    fn a_lone_straight_fiber_does_not_shadow_itself() {
        let spec = spec();
        let root = V3::new(0.3, 0.0, 0.5);
        let t = spec.comb();
        let fiber: Vec<V3> = (0..=8)
            .map(|i| root + t * (spec.height() / t.y * i as f64 / 8.0 * 0.999))
            .collect();
        let full = (4.0 * PI).sqrt() as f32;
        let others = v0_of_fiber0(std::slice::from_ref(&fiber), Shadowing::Others, 8);
        let all = v0_of_fiber0(&[fiber], Shadowing::All, 8);
        assert!(!others.is_empty() && others.len() == all.len());
        for v in &others {
            assert!((v / full - 1.0).abs() < 1e-3, "{v} vs {full}");
        }
        let darkest = all.iter().copied().fold(f32::INFINITY, f32::min);
        assert!(darkest < 0.99 * full, "All mode: {darkest} vs {full}");
    }

    /// The other fibers still shadow: a vertical fiber under a roof of horizontal ones
    /// (nine bars across the tile at 80 % of the height) loses light with `Others` (more than 1 %),
    /// and less than with `All` (which adds the fiber's own pieces).
    #[test]
    fn other_fibers_still_shadow() {
        let spec = spec();
        let h = spec.height();
        let stem = vec![V3::new(0.5, 0.0, 0.5), V3::new(0.5, 0.5 * h, 0.5)];
        let y = 0.8 * h;
        let mut fibers = vec![stem];
        for k in 0..9 {
            let z = 0.42 + 0.02 * k as f64;
            fibers.push(
                (0..=8)
                    .map(|i| V3::new(i as f64 / 8.0 - 0.001, y, z))
                    .collect(),
            );
        }
        let full = (4.0 * PI).sqrt() as f32;
        let others = v0_of_fiber0(&fibers, Shadowing::Others, 3);
        let all = v0_of_fiber0(&fibers, Shadowing::All, 3);
        assert!(!others.is_empty() && others.len() == all.len());
        for (o, a) in others.iter().zip(&all) {
            assert!(*o < 0.99 * full, "others: {o} vs {full}");
            assert!(*a < *o - 1e-3 * full, "all {a} >= others {o}");
        }
    }
}
