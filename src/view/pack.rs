//! Packing of the transfer into textures: per shell, 7 RGBA textures hold the 25
//! coefficients (channel `k` = coefficient `k`), channel 25 the coverage (alpha) and two
//! spare channels (seed 003 Sec. 2.4: "we pack 4 SH function lighting results into a
//! four-channel texture, giving us 32 x 7 textures").
//!
//! 8 bits per channel with a per-shell, per-coefficient scale and offset (the range over
//! the shell's covered texels). The alternative, half floats, doubles the size; the error
//! of both is measured by [`radiance_error`] (`reports/viewer/packing.md`), and 8-bit is
//! the default because its error is far below the PRT's own.

use super::prt::{Rgb25, Transfer};
use super::sh::N_COEFFS;

/// Textures per shell.
pub const TEXTURES: usize = 7;
/// Channels per shell (`4 * TEXTURES`).
pub const CHANNELS: usize = 4 * TEXTURES;
/// The channel holding the coverage.
pub const ALPHA: usize = N_COEFFS;
/// Texels with less coverage than this do not widen a shell's range (they are nearly
/// invisible, and a far outlier would cost every other texel precision).
const RANGE_ALPHA: f32 = 1e-3;

/// Quantised textures: `bytes[((s * 7 + t) * res * res + texel) * 4 + channel]`,
/// value `offset + scale * byte / 255` with `scale`, `offset` per `[s * 28 + channel]`.
#[derive(Clone, Debug)]
pub struct Packed {
    /// Texels per tile side.
    pub res: usize,
    /// Number of shells.
    pub shells: usize,
    /// The bytes, laid out as the struct doc says.
    pub bytes: Vec<u8>,
    /// Per shell and channel `[s * 28 + channel]`: the byte's scale.
    pub scale: Vec<f32>,
    /// Per shell and channel: the value of byte 0.
    pub offset: Vec<f32>,
}

impl Packed {
    /// Dequantised value of channel `ch` of shell `s` at `texel`.
    #[inline]
    pub fn value(&self, s: usize, ch: usize, texel: usize) -> f32 {
        let n = self.res * self.res;
        let b = self.bytes[((s * TEXTURES + ch / 4) * n + texel) * 4 + ch % 4];
        self.offset[s * CHANNELS + ch] + self.scale[s * CHANNELS + ch] * b as f32 / 255.0
    }
}

/// Channel `ch` of shell `s`, unquantised: a transfer coefficient, the coverage, or 0.
fn channel<'a>(t: &'a Transfer, cov: &'a [Vec<f32>], s: usize, ch: usize) -> Option<&'a [f32]> {
    match ch {
        c if c < N_COEFFS => Some(t.at(s, c)),
        ALPHA => Some(&cov[s]),
        _ => None,
    }
}

/// 8-bit packing with per-shell scale and offset.
pub fn pack_u8(t: &Transfer, cov: &[Vec<f32>]) -> Packed {
    let (res, shells) = (t.res, t.shells);
    let n = res * res;
    let mut p = Packed {
        res,
        shells,
        bytes: vec![0; shells * TEXTURES * n * 4],
        scale: vec![0.0; shells * CHANNELS],
        offset: vec![0.0; shells * CHANNELS],
    };
    for s in 0..shells {
        for ch in 0..CHANNELS {
            let Some(vals) = channel(t, cov, s, ch) else {
                continue;
            };
            let (lo, hi) = if ch == ALPHA {
                (0.0, 1.0)
            } else {
                let mut r = (f32::INFINITY, f32::NEG_INFINITY);
                for (v, a) in vals.iter().zip(&cov[s]) {
                    if *a >= RANGE_ALPHA {
                        r = (r.0.min(*v), r.1.max(*v));
                    }
                }
                if r.0 > r.1 {
                    (0.0, 0.0)
                } else {
                    r
                }
            };
            let scale = hi - lo;
            p.scale[s * CHANNELS + ch] = scale;
            p.offset[s * CHANNELS + ch] = lo;
            for (texel, v) in vals.iter().enumerate() {
                let q = if scale > 0.0 {
                    ((v - lo) / scale * 255.0).round().clamp(0.0, 255.0)
                } else {
                    0.0
                };
                p.bytes[((s * TEXTURES + ch / 4) * n + texel) * 4 + ch % 4] = q as u8;
            }
        }
    }
    p
}

/// `x` rounded to the nearest IEEE half float (round half to even; saturates at 65504).
pub fn to_half_and_back(x: f32) -> f32 {
    let a = x.abs();
    if a >= 65504.0 {
        return 65504.0f32.copysign(x);
    }
    if a < 6.103_515_6e-5 {
        // Subnormal halves: multiples of 2^-24.
        let q = 2f32.powi(-24);
        return ((x / q).round_ties_even()) * q;
    }
    let bits = x.to_bits();
    let lsb = (bits >> 13) & 1;
    f32::from_bits((bits + 0x0fff + lsb) & !0x1fff)
}

/// Relative RMSE of the radiance `sum_k c_k v_k` (per texel, weighted by coverage, RGB)
/// that a packing leaves, against the unpacked transfer, for lighting `c`:
/// `(8-bit, half float)`.
pub fn radiance_error(t: &Transfer, cov: &[Vec<f32>], packed: &Packed, c: &Rgb25) -> (f64, f64) {
    let n = t.res * t.res;
    let (mut e8, mut e16, mut sum, mut wsum) = (0.0, 0.0, 0.0, 0.0);
    for s in 0..t.shells {
        for texel in 0..n {
            let a = cov[s][texel] as f64;
            if a <= 0.0 {
                continue;
            }
            for ch in c.iter() {
                let (mut exact, mut q8, mut q16) = (0.0, 0.0, 0.0);
                for k in 0..N_COEFFS {
                    let v = t.at(s, k)[texel];
                    exact += ch[k] * v as f64;
                    q8 += ch[k] * packed.value(s, k, texel) as f64;
                    q16 += ch[k] * to_half_and_back(v) as f64;
                }
                e8 += a * (q8 - exact).powi(2);
                e16 += a * (q16 - exact).powi(2);
                sum += a * exact;
                wsum += a;
            }
        }
    }
    let mean = (sum / wsum.max(1e-300)).abs().max(1e-300);
    ((e8 / wsum).sqrt() / mean, (e16 / wsum).sqrt() / mean)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Half rounding: exact for representable values, half an ulp (2^-11 relative) at
    /// most otherwise.
    #[test]
    fn half_round_trip() {
        for x in [1.0f32, -2.5, 0.333_333, 1234.567, 3e-5, 7e-8] {
            let h = to_half_and_back(x);
            let tol = if x.abs() >= 6.1e-5 {
                x.abs() * 2f32.powi(-11)
            } else {
                2f32.powi(-25)
            };
            assert!((h - x).abs() <= tol, "{x} -> {h}");
            assert_eq!(to_half_and_back(h), h);
        }
    }

    /// 8-bit values are within half a step of the truth inside each shell's range.
    #[test]
    fn u8_packing_is_within_half_a_step() {
        let res = 8;
        let n = res * res;
        let v: Vec<f32> = (0..2 * N_COEFFS * n)
            .map(|i| ((i * 37 % 101) as f32 / 10.0) - 3.0)
            .collect();
        let t = Transfer {
            res,
            shells: 2,
            k: N_COEFFS,
            v,
        };
        let cov = vec![vec![0.5f32; n]; 2];
        let p = pack_u8(&t, &cov);
        for s in 0..2 {
            for k in 0..N_COEFFS {
                let step = p.scale[s * CHANNELS + k] / 255.0;
                for texel in 0..n {
                    let d = (p.value(s, k, texel) - t.at(s, k)[texel]).abs();
                    assert!(d <= 0.5 * step + 1e-5, "{d} > {step}/2");
                }
            }
            assert!((p.value(s, ALPHA, 3) - 0.5).abs() <= 0.5 / 255.0 + 1e-6);
        }
    }
}
