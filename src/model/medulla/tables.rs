//! The CP-compressed tables (`CpTable`, `MedullaTables`) and their file format.

use super::grid::hermite_stencil;
use crate::error::{Error, Num, Result};
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// File magic of the tables file.
pub const MAGIC: &[u8; 8] = b"FURMEDUL";
/// File format version.
pub const VERSION: u32 = 1;

/// Which half of the exit directions a `C^M` slice describes (seed Eq. 19).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// Exit `|psi| < pi/2`: back toward the light (`C^M_{phi=0}`).
    Front,
    /// Exit `|psi| >= pi/2`: onward (`C^M_{phi=pi}`).
    Back,
}

/// Kind of a stored tensor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableKind {
    /// The azimuthal table `C^N(tau, g, x, psi)` (seed Sec. 3).
    Cn = 0,
    /// The longitudinal table `C^M` of the front side (seed Eq. 19).
    CmFront = 1,
    /// The longitudinal table `C^M` of the back side (seed Eq. 19).
    CmBack = 2,
}

/// One CP-compressed 4-D table: `value = sum_r prod_m f[m](axis_m; r)` with linear
/// interpolation of each factor along its axis.
#[derive(Clone, Debug, PartialEq)]
pub struct CpTable {
    /// CP rank `R`: the number of rank-one terms summed.
    pub rank: usize,
    /// Node coordinates of each of the four axes, ascending.
    pub axes: [Vec<f64>; 4],
    /// `factors[m][i * rank + r]`, lambda folded into mode 0.
    pub factors: [Vec<f64>; 4],
}

impl CpTable {
    /// Per-rank weights after collapsing modes 0 and 1 (`tau`, `g`) at `(a, b)`, each
    /// factor interpolated by [`hermite_stencil`]: the scattered lobes are then
    /// continuously differentiable in `kappa`, `sigma_m_s` and `g`, which the fitter
    /// differentiates (with linear interpolation the cost had a kink at every node, and
    /// LM stopped on it with one-sided derivatives).
    pub(super) fn collapse01(&self, a: f64, b: f64) -> Vec<f64> {
        let r = self.rank;
        let (ia, wa) = hermite_stencil(&self.axes[0], a);
        let (ib, wb) = hermite_stencil(&self.axes[1], b);
        let f0 = &self.factors[0];
        let f1 = &self.factors[1];
        (0..r)
            .map(|k| {
                let a0: f64 = (0..4).map(|q| wa[q] * f0[ia[q] * r + k]).sum();
                let b0: f64 = (0..4).map(|q| wb[q] * f1[ib[q] * r + k]).sum();
                a0 * b0
            })
            .collect()
    }

    /// Step and first centre of the uniform last axis.
    pub(super) fn last_axis(&self) -> (f64, f64, usize) {
        let a = &self.axes[3];
        (a[0], a[1] - a[0], a.len())
    }

    /// Evaluate `sum_r w_r f2(i2, f2) f3(k0, k1, f3)` (unclamped).
    #[inline]
    #[allow(clippy::needless_range_loop)]
    pub(super) fn eval23(
        &self,
        w: &[f64],
        i: usize,
        fi: f64,
        k0: usize,
        k1: usize,
        fk: f64,
    ) -> f64 {
        let r = self.rank;
        let x0 = &self.factors[2][i * r..(i + 1) * r];
        let x1 = &self.factors[2][(i + 1) * r..(i + 2) * r];
        let p0 = &self.factors[3][k0 * r..(k0 + 1) * r];
        let p1 = &self.factors[3][k1 * r..(k1 + 1) * r];
        // Four independent accumulators (fixed order) let the compiler vectorise.
        let mut acc = [0.0f64; 4];
        let chunks = w
            .chunks_exact(4)
            .zip(x0.chunks_exact(4))
            .zip(x1.chunks_exact(4))
            .zip(p0.chunks_exact(4))
            .zip(p1.chunks_exact(4));
        for ((((w4, a0), a1), b0), b1) in chunks {
            for j in 0..4 {
                let a = a0[j] + fi * (a1[j] - a0[j]);
                let b = b0[j] + fk * (b1[j] - b0[j]);
                acc[j] += w4[j] * a * b;
            }
        }
        let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
        for k in r / 4 * 4..r {
            let a = x0[k] + fi * (x1[k] - x0[k]);
            let b = p0[k] + fk * (p1[k] - p0[k]);
            s += w[k] * a * b;
        }
        s
    }

    /// Value at mode-2 node `i` and mode-3 node `k` (unclamped).
    pub(super) fn node23(&self, w: &[f64], i: usize, k: usize) -> f64 {
        let r = self.rank;
        (0..r)
            .map(|q| w[q] * self.factors[2][i * r + q] * self.factors[3][k * r + q])
            .sum()
    }
}

/// The medulla tables: three CP-compressed tensors and their build metadata.
#[derive(Clone, Debug, PartialEq)]
pub struct MedullaTables {
    /// The azimuthal table `C^N(tau, g, x, psi)` (seed Sec. 3).
    pub cn: Arc<CpTable>,
    /// The longitudinal tables `C^M`, front and back (seed Eq. 19).
    pub cm: [Arc<CpTable>; 2],
    /// Seed and nominal paths per cell of the build.
    pub seed: u64,
    /// Nominal Monte Carlo paths per cell of the build.
    pub paths: u64,
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or_else(|| bad("truncated file"))?;
        let s = &self.b[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
    fn f32(&mut self) -> Result<f32> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
}

fn bad(msg: &str) -> Error {
    Error::Invalid(format!("medulla tables: {msg}"))
}

impl MedullaTables {
    /// The tables shipped in `assets/medulla_tables.bin`, parsed once.
    pub fn builtin() -> &'static MedullaTables {
        static T: OnceLock<MedullaTables> = OnceLock::new();
        T.get_or_init(|| {
            MedullaTables::from_bytes(include_bytes!("../../../assets/medulla_tables.bin"))
                .expect("the shipped medulla tables are valid (checked by tests)")
        })
    }

    /// Load a tables file.
    pub fn load(path: &Path) -> Result<MedullaTables> {
        let b = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        MedullaTables::from_bytes(&b).map_err(|e| Error::file(path, e.to_string()))
    }

    /// Parse the binary format (see the module doc). Errors, never panics.
    pub fn from_bytes(b: &[u8]) -> Result<MedullaTables> {
        use sha2::{Digest, Sha256};
        if b.len() < 8 + 4 + 32 || &b[..8] != MAGIC {
            return Err(bad("not a furfit medulla tables file (bad magic)"));
        }
        let (body, sum) = b.split_at(b.len() - 32);
        if Sha256::digest(body).as_slice() != sum {
            return Err(bad("checksum mismatch (corrupt or truncated file)"));
        }
        let mut r = Reader { b: body, pos: 8 };
        let version = r.u32()?;
        if version != VERSION {
            return Err(bad(&format!("unsupported version {version}")));
        }
        let seed = r.u64()?;
        let paths = r.u64()?;
        let n = r.u32()?;
        if n != 3 {
            return Err(bad(&format!("expected 3 tensors, found {n}")));
        }
        let mut tabs = Vec::new();
        for want in 0..3u32 {
            let kind = r.u32()?;
            if kind != want {
                return Err(bad(&format!("tensor {want} has kind {kind}")));
            }
            let rank = r.u32()? as usize;
            if rank == 0 || rank > 1024 {
                return Err(bad(&format!("tensor {want}: bad rank {rank}")));
            }
            let modes = r.u32()?;
            if modes != 4 {
                return Err(bad(&format!("tensor {want}: {modes} modes, expected 4")));
            }
            let mut axes: [Vec<f64>; 4] = Default::default();
            for (m, ax) in axes.iter_mut().enumerate() {
                let len = r.u32()? as usize;
                if !(2..=100_000).contains(&len) {
                    return Err(bad(&format!("tensor {want} mode {m}: bad length {len}")));
                }
                for _ in 0..len {
                    ax.push(r.f64()?);
                }
                if ax.iter().any(|v| !v.is_finite()) || ax.windows(2).any(|w| w[1] <= w[0]) {
                    return Err(bad(&format!(
                        "tensor {want} mode {m}: axis not finite and increasing"
                    )));
                }
            }
            let mut factors: [Vec<f64>; 4] = Default::default();
            for (m, f) in factors.iter_mut().enumerate() {
                let len = axes[m].len() * rank;
                f.reserve(len);
                for _ in 0..len {
                    let v = r.f32()?;
                    if !v.is_finite() {
                        return Err(bad(&format!("tensor {want} mode {m}: non-finite factor")));
                    }
                    f.push(v as f64);
                }
            }
            tabs.push(CpTable {
                rank,
                axes,
                factors,
            });
        }
        if r.pos != body.len() {
            return Err(bad("trailing bytes after the last tensor"));
        }
        let mut it = tabs.into_iter().map(Arc::new);
        let cn = it.next().unwrap();
        let front = it.next().unwrap();
        let back = it.next().unwrap();
        Ok(MedullaTables {
            cn,
            cm: [front, back],
            seed,
            paths,
        })
    }

    /// Serialise to the binary format (factors rounded to f32).
    pub fn to_bytes(&self) -> Vec<u8> {
        use sha2::{Digest, Sha256};
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&VERSION.to_le_bytes());
        b.extend_from_slice(&self.seed.to_le_bytes());
        b.extend_from_slice(&self.paths.to_le_bytes());
        b.extend_from_slice(&3u32.to_le_bytes());
        for (kind, t) in [&self.cn, &self.cm[0], &self.cm[1]].iter().enumerate() {
            b.extend_from_slice(&(kind as u32).to_le_bytes());
            b.extend_from_slice(&(t.rank as u32).to_le_bytes());
            b.extend_from_slice(&4u32.to_le_bytes());
            for ax in &t.axes {
                b.extend_from_slice(&(ax.len() as u32).to_le_bytes());
                for v in ax {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
            for f in &t.factors {
                for v in f {
                    b.extend_from_slice(&(*v as f32).to_le_bytes());
                }
            }
        }
        let sum = Sha256::digest(&b);
        b.extend_from_slice(&sum);
        b
    }

    /// Round the factors to f32 exactly as a write/read round trip does.
    pub fn rounded(mut self) -> Self {
        let round = |t: &Arc<CpTable>| {
            let mut c = (**t).clone();
            for f in c.factors.iter_mut() {
                for v in f.iter_mut() {
                    *v = *v as f32 as f64;
                }
            }
            Arc::new(c)
        };
        self.cn = round(&self.cn);
        self.cm = [round(&self.cm[0]), round(&self.cm[1])];
        self
    }

    /// The `(tau, g)` range the tables cover: `[tau_min, tau_max]`, `[g_min, g_max]`.
    pub fn domain(&self) -> ([f64; 2], [f64; 2]) {
        let ends = |a: &[f64]| [a[0], a[a.len() - 1]];
        (ends(&self.cn.axes[0]), ends(&self.cn.axes[1]))
    }

    /// Messages for a `(tau, g)` outside [`Self::domain`], where [`Self::slice`] uses the
    /// nearest table edge for the shape of the scattered lobes: the value is inside the
    /// parameter's hard bounds, so it is no error, but the user must not take the
    /// scattered lobes there for the model's (MODEL.md: never a silent clamp).
    pub fn domain_notes(&self, tau: f64, g: f64) -> Vec<String> {
        let ([t0, t1], [g0, g1]) = self.domain();
        let mut notes = Vec::new();
        if g < g0 || g > g1 {
            notes.push(format!(
                "g = {} is outside the medulla tables' g range [{g0}, {g1}]: the scattered \
                 lobes (TTs, TRTs) use the shape at g = {}",
                Num(g),
                g.clamp(g0, g1)
            ));
        }
        if tau > t1 {
            notes.push(format!(
                "tau = sigma_m_s * kappa = {} is above the medulla tables' range [{t0}, {t1}]: \
                 the scattered lobes' shape is the one at tau = {t1} (their strength still \
                 follows tau)",
                Num(tau)
            ));
        }
        notes
    }
}
