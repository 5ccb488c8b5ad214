//! The piecewise-analytic far-field / multi-scale evaluator (seed Eqs. 23-26, Appendix).
//!
//! Everything that does not depend on `phi` is done once per `theta_d` in
//! [`FarSlice::far`]: the segmentation, the node values and the fits. [`FarSlice::eval`]
//! then costs a handful of closed-form integrals per lobe and `phi`.
//!
//! # Method
//! * Symmetry (Eq. 23): `A(-h) = A(h)` and `D(-h, phi) = D(h, -phi)` for the unscattered
//!   lobes, so only `h in [0, 1]` is segmented and each segment is evaluated for `phi` and
//!   `-phi`. For the scattered lobes the mirrored table query `C^N(-x, wrap(phi + Phi^s))`
//!   is evaluated directly, so no symmetry of the tables is assumed.
//! * Segments `h_i = sqrt(i/n)` (Sec. 5.1 "Segmentation"), plus breakpoints where the
//!   integrand is not smooth: the medulla edge `h = kappa eta'` and the TRT caustic.
//! * Fits are made in `u = gamma_i = asin h` (`dh = cos u du`), not in `h`: `gamma_i` is
//!   then exactly linear and `Phi_p(u)` smooth up to `h = 1`, which removes the square-root
//!   endpoint behaviour that a fit in `h` has in the last segment.
//! * Unscattered lobes: on a segment where `Phi_p` is monotone the integral is written in
//!   the variable `Phi` itself, `integral A D dh = integral g(Phi) G(Phi - phi; beta_p) dPhi`
//!   with `g = A cos u / |dPhi/du|`. The Gaussian is then exact for every `beta_n` (a fit
//!   of `Phi_p` in `h` would need thousands of segments at `beta_n = 0.1 deg`), and
//!   `g = Q1(Phi) exp(L(Phi))` — a quadratic prefactor times the exponential of the
//!   log-attenuation, linear as in the paper or (tolerance mode) quadratic — makes the
//!   integrand the Appendix's `Q1 exp(Q2)` form, solved in erf form
//!   ([`closed_form::poly_gauss`](super::closed_form::poly_gauss)). The wrapped
//!   Gaussian's `2 pi` images are summed over those whose window reaches the segment.
//!   Near the caustic (`dPhi/du -> 0`, where `g` is singular and the quadratic coefficient
//!   of the paper's form vanishes) segments are bisected until either `Phi` is monotone
//!   with a bounded slope ratio or the segment spans at most `2 beta_p` in `Phi`; such
//!   short segments are integrated by a 16-point Gauss-Legendre rule of the exact integrand
//!   (the Gaussian is resolved there), bisected further in tolerance mode until either the
//!   attenuation's quadratic fit or the rule's agreement with an 8-point rule (the lobe's
//!   Gaussian at probes out to 4 beta) is within budget.
//! * Scattered lobes, paper mode: prefactor `(1 - F) F^(p-1) cos u` times the queried
//!   `C^N` is interpolated by a quadratic per segment and the log-attenuation `ln(T_a T_b)`
//!   by a line: the Appendix's `C exp(L)` form
//!   ([`closed_form::poly_exp`](super::closed_form::poly_exp)), i.e. a three-node quadrature
//!   per segment whose `C^N` values are read per `phi`.
//! * Scattered lobes, tolerance mode: `C^N` is piecewise bilinear in the table's offset
//!   `x` and azimuth `psi` (2 degree bins), and a quadratic through three node values
//!   cannot follow its kinks (that limited the node quadrature to ~1e-3 of the peak).
//!   Segments are cut at the table's `x` nodes, where `C^N` is linear in `x` between two
//!   rows, and integrated in the variable `Phi^s` itself where it is monotone: the density
//!   `A^s P_s / |dPhi^s/du|` and its share of the upper row are quadratics in `Phi^s`, and
//!   their integral against the rows' piecewise-linear interpolant is exact
//!   ([`CnRows::integrate`]). Near a `Phi^s` caustic (TRTs) segments are bisected down to
//!   one `psi` bin and left to the node quadrature.
//! * Culling (Sec. 5.1 "Acceleration"): a segment covering `Phi` in `[lo, hi]` is skipped
//!   for every image `phi + 2 pi k` outside `[lo - 8.5 beta_p, hi + 8.5 beta_p]` (the
//!   paper's 3 beta would lose up to 0.3 % of the mass; 8.5 sigma loses < 1e-16).
//!   A slice built for one `phi` only ([`FarSlice::far_at`], [`FarSlice::range_at`]: a
//!   single call) applies the same test before refining: an unscattered segment whose
//!   `Phi_p` range (bounded through the monotone `dPhi_p/du`) cannot reach the window is
//!   not built at all, which leaves the value unchanged bit for bit.
//! * Tolerance mode: each fitted segment is checked at its quarter points against the exact
//!   integrand and bisected while its error exceeds `tol` of the lobe's mean
//!   over `phi` (a lower bound of its peak).
//! * Evaluation on an even `phi` grid: node Gaussians are swept along the grid by
//!   recurrence, or, for a lobe wide enough that the wrapped Gaussian's Fourier series
//!   (Poisson summation) has fewer terms than a node's window has grid points, summed in
//!   Fourier space ([`FourierGrid`]): every image at once, a few dozen rotations per node.
#![allow(clippy::needless_range_loop)] // fixed-size per-lobe arrays read clearer indexed

use super::closed_form::{
    lam_curve_cap, poly, poly_exp, poly_gauss, poly_gauss_nodes, quadratic_through,
};
use super::FarOptions;
use crate::model::azimuthal::{self, beta_p, wrap_angle, wrapped_gaussian, Absorption};
use crate::model::fresnel;
use crate::model::geometry::PathGeometry;
use crate::model::medulla::{CnProfile, CnRows};
use crate::model::quadrature::GaussLegendre;
use crate::model::{AzimuthalSlice, Lobe, LobeSet, LobeValues};
use std::cell::RefCell;
use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::Arc;
use wide::f64x4;

/// Floor of a node's log-attenuation: `exp` of it is 0 in f64 as `exp(-inf)` is, but a
/// finite value keeps the linear fits of `ln A` (differences of node values) from
/// `inf - inf` = NaN when an absorption near the f64 limit (1e300) overflows the exponent.
const LAM_MIN: f64 = -1e4;

/// Culling window half-width in lobe standard deviations (see module doc).
pub const CULL_SIGMAS: f64 = 8.5;
/// Maximum bisection depth of a segment.
const MAX_DEPTH: u32 = 30;
/// Most bisections the tolerance mode may spend on one lobe of one part. Legitimate stiff
/// cases need a few hundred (beta_n = 0.1 deg: ~330 per lobe); the cap only stops a
/// runaway (a fit error at the rounding floor of its inputs), and a slice that hit it
/// says so in [`SliceStats::capped`].
const MAX_SPLITS: usize = 4096;
/// Cuticle layers `l` below which [`fresnel_layer_u`] also resolves the grazing layer of
/// the pile-of-plates reflectance: the layer is then within about `l w` of grazing in `u`
/// (`w` the Fresnel layer's own width), finer than the initial segments' nodes sample
/// (every preset has `l >= 0.44`, every shipped fit `l > 0.1`).
const L_LAYER_MAX: f64 = 4e-3;
/// Least extinction across the medulla radius, `c kappa` in [`medulla_layer_h`], that
/// grades the initial segments toward the medulla edge.
const MEDULLA_LAYER_MIN: f64 = 16.0;
/// Relative accuracy of the lobe masses that scale the tolerance budget.
const MASS_REL: f64 = 1e-2;
const MASS_MAX_DEPTH: u32 = 30;
/// See [`Refine::small`].
const SMALL_SEGMENTS: f64 = 1024.0;
/// A segment is integrated in the `Phi` variable when `min |Phi'| >= RATIO_MIN max |Phi'|`.
const RATIO_MIN: f64 = 0.5;
/// A segment spanning at most this many `beta_p` in `Phi` may be integrated by GL.
const GL_SPAN_SIGMAS: f64 = 2.0;
const GL_NODES: usize = 16;
/// Largest deviation (nats) of a piece's log-attenuation from its fit (the chord, or the
/// quadratic of [`FarSlice::lam_fit`]) at the quarter points before the fit check stops
/// trusting those points (see
/// [`hidden_mass_bound`]): a factor e, far beyond the curvature of an ordinary
/// absorption profile across a piece that passes the fit check.
const LAM_DEV_MAX: f64 = 1.0;
/// In tolerance mode a GL piece spanning at most [`GL_FEW_SPAN_SIGMAS`] `beta_p` in `Phi`
/// keeps [`GL_NODES_LEAST`] or [`GL_NODES_FEW`] nodes instead of [`GL_NODES`] when the
/// smaller rule's sum of the lobe's Gaussian agrees with the next larger one's to
/// [`GL_FEW_REL`] `* tol` of the piece's peak at the [`GL_FEW_PROBES`] (in `beta_p` from
/// the piece's middle; [`FarSlice::gl_piece_with`]): every `phi` then pays for 4 or 8
/// Gaussians instead of 16 per piece. For the Gaussian alone this holds by far (at
/// `4.3 beta`, where the lobe is 1e-4 of its peak, its exponent changes by ~4.8 across a
/// span of `beta`: an `exp(2.4 x)` on the rule's `[-1, 1]`, integrated by 8 nodes to
/// ~1e-10 of itself); the probes catch a prefactor `A cos u` that is not smooth across
/// the piece (TT at `eta -> 1` and grazing `theta_d`, inside the Fresnel layer, lost a
/// factor 4 in the stability sweep without them).
const GL_NODES_FEW: usize = 8;
/// The smallest rule of the cascade in [`FarSlice::gl_piece_with`].
const GL_NODES_LEAST: usize = 4;
const GL_FEW_SPAN_SIGMAS: f64 = 1.0;
const GL_FEW_REL: f64 = 1e-3;
/// Probe offsets in `beta_p`: out to 4 (at 4.3 the lobe is 1e-4 of its peak); the
/// powers in [`FarSlice::gl_piece`] follow this order.
const GL_FEW_PROBES: [f64; 7] = [-4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0];
/// At most this many pieces per initial scattered segment from the psi step (the step's
/// whole range of `Phi^s`, under 2 pi, needs at most ~6300 at the strict step).
const MAX_PSI_PIECES: f64 = 16384.0;
/// Up to this many psi-step pieces an initial scattered segment is bisected instead (the
/// default step needs at most ~21).
const BISECT_PSI_PIECES: usize = 64;

/// A scattered segment over which `Phi^s` moves less than this (radians) is left to node
/// quadrature instead of a [`PsiPiece`]: `Phi^s = gamma_t - gamma_i + ...` carries an
/// absolute rounding error of ~1e-15, which would dominate a fit in `Phi^s` over a tiny
/// span (TTs at `eta -> 1`, where `gamma_t -> gamma_i`, or a medulla of radius 1e-6); over
/// such a span `C^N` meets at most one kink, a 3e-5 part of a bin.
const PSI_MIN_SPAN: f64 = 1e-6;

/// An unscattered segment over which `Phi_p` moves at most this (radians) is never fitted
/// in `Phi`: at `eta = 1 + 1e-15` TT's `Phi_1 = pi + 2 (gamma_t - gamma_i)` spans a few
/// ulps, and the quadratic through three such points had infinite and NaN coefficients
/// (TT came out NaN at `phi = pi`, its peak; black-box accuracy search, 2026-11-28). Such
/// a segment is narrow for any width at or above [`crate::model::MIN_WIDTH`], so it goes
/// to Gauss-Legendre in `u`.
const PHI_MIN_SPAN: f64 = 1e-9;

/// Most pieces (psi pieces and quadrature nodes) of a scattered lobe that
/// [`FarSlice::peak_rescale`] checks.
const RESCALE_MAX_PIECES: usize = 16;
/// Azimuths at which [`FarSlice::peak_rescale`] reads the built lobe.
const RESCALE_PHIS: usize = 24;
/// Rebuilds [`FarSlice::peak_rescale`] may ask for, each at a smaller budget.
const RESCALE_ROUNDS: usize = 3;

/// The nodes one slice build has evaluated, by the bits of `u` and whether the scattered
/// values were asked for. The lobes of a family share their initial segments and bisect
/// them alike, and the mass estimate evaluates the quarter points that the builders then
/// check: without it two in five node evaluations of a grid synthesis slice were repeats
/// (red fox, human). A node is a pure function of its key, so a memo hit returns the same
/// bits as a fresh evaluation.
struct NodeMemo(RefCell<MemoEntries>);

/// The nodes of a [`NodeMemo`] and their index by key.
struct MemoEntries {
    index: BitsMap<(u64, bool), u32>,
    nodes: Vec<Node>,
}

impl NodeMemo {
    fn new() -> Self {
        // A grid synthesis slice's 250-400 nodes (cat, human presets) without regrowing
        // (a regrowth copied its 232-byte nodes).
        NodeMemo(RefCell::new(MemoEntries {
            index: BitsMap::with_capacity_and_hasher(512, Default::default()),
            nodes: Vec::with_capacity(512),
        }))
    }
}

/// A hasher for `f64` bit patterns: a multiply per word (Fibonacci hashing), its high half
/// folded into the low one that picks the bucket (midpoints of dyadic offsets end in zero
/// bits), enough for keys that are distinct doubles. The default SipHash costs several
/// times more per key and guards against adversarial keys, which angles are not.
#[derive(Default)]
pub struct BitsHasher(u64);

/// A map keyed by `f64` bit patterns (and small tags) with [`BitsHasher`].
pub type BitsMap<K, V> = HashMap<K, V, BuildHasherDefault<BitsHasher>>;

impl Hasher for BitsHasher {
    fn finish(&self) -> u64 {
        self.0 ^ (self.0 >> 32)
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }

    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0 ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// The nodes of one Gauss-Legendre rule of at most [`GL_NODES`] points
/// ([`FarSlice::gl_nodes`]), read as a slice.
struct GlNodes {
    nodes: [(f64, f64); GL_NODES],
    len: usize,
}

impl std::ops::Deref for GlNodes {
    type Target = [(f64, f64)];
    fn deref(&self) -> &[(f64, f64)] {
        &self.nodes[..self.len]
    }
}

/// Values at one offset `u = asin h`, for all lobes at once.
#[derive(Clone, Copy, Debug)]
struct Node {
    u: f64,
    /// Unwrapped `Phi_p` and `dPhi_p/du`, p = 0, 1, 2.
    phi: [f64; 3],
    dphi: [f64; 3],
    /// Prefactor per lobe (Fresnel part times `cos u`), indexed by [`Lobe`].
    pre: [f64; 5],
    /// Log-attenuation per lobe (absorption exponent), indexed by [`Lobe`].
    lam: [f64; 5],
    /// Medulla-table offset `x = sin gamma_t / kappa` and segment directions `Phi^s_p`.
    x_med: f64,
    phis: [f64; 2],
    /// `dPhi^s_p/du`.
    dphis: [f64; 2],
    /// Scattered fraction at `x_med` (for the scattered-lobe error check).
    frac: f64,
    /// Probability `P_s(tau, x_med)` of scattering in the medulla at all (kept so the
    /// scattered builders do not recompute its `expm1` at every shared node).
    prob: f64,
}

/// A fitted unscattered segment.
#[derive(Clone, Debug)]
enum Piece {
    /// `g(Phi) = (c0 + c1 x + c2 x^2) exp(l0 + l1 x + l2 x^2)`, `x = Phi - lo` in
    /// `[0, len]`, `lam = [l0, l1, l2]` (`l2 = 0` in paper mode).
    Phi {
        lo: f64,
        len: f64,
        c: [f64; 3],
        lam: [f64; 3],
    },
    /// Gauss-Legendre nodes `(Phi_k, w_k A_k cos u_k)` covering `Phi` in `[lo, hi]`.
    Gl {
        lo: f64,
        hi: f64,
        nodes: Vec<(f64, f64)>,
    },
}

/// One node of the fitted scattered segments (over `u`, nodes at 0, len/2, len of each
/// segment; neighbouring segments share their end node, whose weights are summed).
#[derive(Clone, Debug)]
struct ScatNode {
    x_med: f64,
    /// Weight `w` with `integral = sum_nodes w C^N_shape(x, psi)`: the Appendix's
    /// `C exp(L)` integral of the quadratic through the node values is linear in those
    /// values, so the prefactor, the scattered fraction `P_s(tau, x)` and the exponential
    /// part are folded in once per node instead of once per `phi`.
    w: f64,
    phi: f64,
    /// `C^N` at this node tabulated over `psi` ([`FarSlice::tabulate_scattered`]).
    prof: Option<Arc<CnProfile>>,
}

/// A scattered segment integrated against the medulla table's `psi` structure exactly
/// (tolerance mode): `Phi^s` is monotone across it, covering `[phi_hi - len, phi_hi]`, and
/// in `s = phi_hi - Phi^s` the density `w = A^s P_s / |dPhi^s/du|` (`A^s` the prefactor
/// times the attenuation) and `w t` (`t` the offset's weight of row `row + 1`) are
/// quadratics `g`. At `phi` the piece adds
/// `integral_0^len [g_0 R_row + g_1 (R_row+1 - R_row)](phi - phi_hi + s) ds`
/// ([`CnRows::integrate`]); fitting `w` and `w t` rather than the two rows' weights keeps
/// their misfits from adding where neighbouring rows nearly agree.
#[derive(Clone, Debug)]
struct PsiPiece {
    phi_hi: f64,
    len: f64,
    row: usize,
    g: [[f64; 3]; 2],
}

/// The scattered segments of one lobe of one part: node-quadrature segments as their merged
/// nodes, and exact `psi` pieces.
#[derive(Clone, Debug, Default)]
struct ScatNodes {
    nodes: Vec<ScatNode>,
    segments: usize,
    psi: Vec<PsiPiece>,
}

impl ScatNodes {
    /// Add a segment's three nodes `(x_med, phi, w)`, merging its first node into the last
    /// one when they are the same node (same `x_med` and `phi` bit for bit).
    fn push_segment(&mut self, nodes: [(f64, f64, f64); 3]) {
        self.segments += 1;
        for (j, (x_med, phi, w)) in nodes.into_iter().enumerate() {
            if j == 0 {
                if let Some(last) = self.nodes.last_mut() {
                    if last.x_med.to_bits() == x_med.to_bits()
                        && last.phi.to_bits() == phi.to_bits()
                    {
                        last.w += w;
                        continue;
                    }
                }
            }
            self.nodes.push(ScatNode {
                x_med,
                w,
                phi,
                prof: None,
            });
        }
    }
}

/// One contiguous range of `h >= 0` with which mirror images it contributes.
#[derive(Clone, Debug, Default)]
struct Part {
    /// Contributes `D(h, phi)` (the `h >= 0` side).
    direct: bool,
    /// Contributes `D(-h, phi)` (the mirrored `h <= 0` side).
    mirror: bool,
    unsc: [Vec<Piece>; 3],
    scat: [ScatNodes; 2],
}

impl Part {
    /// The sides that contribute, as the sign of `phi` each reads: `1` for the direct side,
    /// `-1` for the mirrored one (`D(-h, phi) = D(h, -phi)`; `C^N(-x, psi) = C^N(x, -psi)`).
    fn signs(&self) -> impl Iterator<Item = f64> {
        [(self.direct, 1.0), (self.mirror, -1.0)]
            .into_iter()
            .filter_map(|(on, sign)| on.then_some(sign))
    }
}

/// The far field (or a multi-scale range) at one `theta_d`, ready to evaluate at any `phi`.
#[derive(Clone, Debug)]
pub struct FarSlice<'a> {
    az: AzimuthalSlice<'a>,
    lobes: LobeSet,
    cull: bool,
    tol: Option<f64>,
    /// The largest change of `Phi^s_p` across a scattered segment in tolerance mode
    /// ([`max_dps`]).
    max_dps: f64,
    /// Normalisation: 1/2 for the far field, 1/(h2 - h1) for multi-scale.
    weight: f64,
    parts: Vec<Part>,
    betas: [f64; 3],
    /// Lobes whose refinement hit a limit (see [`SliceStats::capped`]).
    capped: LobeSet,
}

/// Work counters (for reports).
#[derive(Clone, Copy, Debug, Default)]
pub struct SliceStats {
    pub unscattered_segments: usize,
    pub gl_segments: usize,
    /// Gauss-Legendre nodes over those segments (each a Gaussian every `phi` pays for).
    pub gl_nodes: usize,
    pub scattered_segments: usize,
    /// The counts above per lobe, indexed by [`Lobe::index`]: closed-form pieces (`Phi`
    /// pieces of R, TT, TRT; segments of TTs, TRTs), Gauss-Legendre pieces and their nodes
    /// (unscattered lobes only).
    pub per_lobe: [LobeWork; 5],
    /// Lobes whose refinement stopped at [`MAX_SPLITS`] or the maximum depth while its
    /// error check still asked for more (their accuracy is not guaranteed by `tol`).
    pub capped: LobeSet,
}

/// One lobe's share of [`SliceStats`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LobeWork {
    pub closed_form: usize,
    pub gl_segments: usize,
    pub gl_nodes: usize,
}

/// The refinement decisions of one slice build, per part and lobe, in the order taken
/// ([`FarSlice::far_taped`]). Replayed by the build of a nearby parameter set, they give
/// it the same segments and rules, so the far field is a smooth function of the
/// parameters around the recording one: a tolerance-mode build decides splits and rules
/// by comparing error estimates with budgets, and a finite-difference step that tips one
/// comparison would change the value by up to `tol` of the lobe's peak, far more than the
/// step's own effect.
#[derive(Clone, Debug, Default)]
pub struct Decisions {
    parts: Vec<[Vec<u32>; 5]>,
    /// The build's [`SliceStats::capped`] lobes.
    capped: LobeSet,
}

impl Decisions {
    /// Lobes whose refinement hit a limit in the build that returned these decisions
    /// (their accuracy is not guaranteed by `tol`; [`SliceStats::capped`]).
    pub fn capped(&self) -> LobeSet {
        self.capped
    }
}

/// Records or replays one lobe's decisions ([`Decisions`]).
enum Tape<'d> {
    Off,
    Record(Vec<u32>),
    /// The recorded decisions and the next one to read.
    Replay(&'d [u32], usize),
}

/// Marks a structural fact on a tape (see [`Tape::fact`]).
const FACT: u32 = 1 << 31;

impl Tape<'_> {
    /// An accuracy decision (split or accept, which rule): `computed` when recording or
    /// off, the recorded one when replaying.
    fn choose(&mut self, computed: u32) -> u32 {
        match self {
            Tape::Off => computed,
            Tape::Record(v) => {
                v.push(computed);
                computed
            }
            Tape::Replay(log, at) => match log.get(*at) {
                Some(&x) if x & FACT == 0 => {
                    *at += 1;
                    x
                }
                _ => {
                    *self = Tape::Off;
                    computed
                }
            },
        }
    }

    fn choose_bool(&mut self, computed: bool) -> bool {
        self.choose(computed as u32) != 0
    }

    /// A structural fact the build cannot override (is `Phi` monotone across the
    /// segment?): always `computed`. A replay that meets a different fact than recorded
    /// is out of step with the recording and goes on computing its own decisions.
    fn fact(&mut self, computed: bool) -> bool {
        self.fact_u32(computed as u32);
        computed
    }

    /// [`Self::fact`] for a count below `FACT` (larger ones are recorded as `FACT - 1`).
    fn fact_u32(&mut self, computed: u32) {
        let code = FACT | computed.min(FACT - 1);
        match self {
            Tape::Off => {}
            Tape::Record(v) => v.push(code),
            Tape::Replay(log, at) => {
                if log.get(*at) == Some(&code) {
                    *at += 1;
                } else {
                    *self = Tape::Off;
                }
            }
        }
    }
}

/// What a build does with decisions.
#[derive(Clone, Copy)]
enum TapeMode<'d> {
    Off,
    Record,
    Replay(&'d Decisions),
}

/// Refinement state of one lobe of one part.
struct Refine<'d> {
    tape: Tape<'d>,
    /// Error budget (`None`: the paper's fixed segmentation).
    budget: Option<f64>,
    /// Scattered lobes: a segment whose integrated error `e len` is below this (a
    /// [`SMALL_SEGMENTS`]-th of the lobe's whole budget) is accepted even if its pointwise
    /// error is not. This ends the bisection at the medulla edge, where the chord
    /// `s_m ~ sqrt(kappa^2 - sin^2 gamma_t)` makes the prefactor and the log-attenuation
    /// non-analytic: the pointwise fit error there shrinks only like `sqrt(len)` while its
    /// integral shrinks like `len^1.5`.
    small: f64,
    splits_left: usize,
    /// A wanted split was refused ([`MAX_SPLITS`] or [`MAX_DEPTH`]).
    capped: bool,
    /// Scattered lobes: the summed error bounds of the [`PsiPiece`]s accepted (each bounds
    /// the piece's error at every `phi`), for [`FarSlice::peak_rescale`].
    err_sum: f64,
    /// The azimuths `mu` (`phi`, `-phi` for the mirrored side) at which the part will be
    /// evaluated, when the slice serves one `phi` ([`FarSlice::far_at`]); empty: all.
    reach: Vec<f64>,
    /// The build's node memo.
    memo: &'d NodeMemo,
}

impl Refine<'_> {
    /// Take one bisection: the children's depth, or `None` (and mark the lobe capped)
    /// when the depth or split limit is reached.
    fn split(&mut self, depth: u32) -> Option<u32> {
        let allowed = depth < MAX_DEPTH && self.splits_left > 0;
        // The tape is read either way; the limits hold even for a replay out of step.
        if self.tape.choose_bool(allowed) && allowed {
            self.splits_left -= 1;
            Some(depth + 1)
        } else {
            self.capped = true;
            None
        }
    }
}

impl<'a> FarSlice<'a> {
    /// The far field `1/2 integral_{-1}^{1}` (Eq. 22).
    pub fn far(az: &AzimuthalSlice<'a>, lobes: LobeSet, opts: &FarOptions) -> Self {
        Self::build(az, lobes, opts, &[(0.0, 1.0, true, true)], 0.5, None)
    }

    /// [`FarSlice::far`] that records its refinement decisions, or with `replay` takes
    /// those of an earlier build instead of deciding afresh ([`Decisions`]; a replay that
    /// falls out of step with its recording decides the rest itself). Without `replay` it
    /// equals [`FarSlice::far`] bit for bit, and returns what it decided; with `replay` the
    /// returned decisions are empty.
    pub fn far_taped(
        az: &AzimuthalSlice<'a>,
        lobes: LobeSet,
        opts: &FarOptions,
        replay: Option<&Decisions>,
    ) -> (Self, Decisions) {
        let mode = replay.map_or(TapeMode::Record, TapeMode::Replay);
        Self::build_taped(az, lobes, opts, &[(0.0, 1.0, true, true)], 0.5, None, mode)
    }

    /// [`FarSlice::far`] evaluated at one `phi` only (a single call). With culling on,
    /// unscattered segments whose `Phi_p` cannot come within the culling window of `phi`
    /// are not built at all: every piece refined from them would be culled at `phi`, so
    /// the value is the same as `FarSlice::far(..).eval(phi)` bit for bit (unless the
    /// full build hit [`MAX_SPLITS`], which the saved splits can then avoid).
    pub fn far_at(
        az: &AzimuthalSlice<'a>,
        lobes: LobeSet,
        opts: &FarOptions,
        phi: f64,
    ) -> LobeValues {
        Self::build(az, lobes, opts, &[(0.0, 1.0, true, true)], 0.5, Some(phi)).eval(phi)
    }

    /// The multi-scale range `1/(h2 - h1) integral_{h1}^{h2}` (Eq. 26), `h1 < h2` in [-1, 1].
    pub fn range(
        az: &AzimuthalSlice<'a>,
        h1: f64,
        h2: f64,
        lobes: LobeSet,
        opts: &FarOptions,
    ) -> Self {
        Self::range_with(az, h1, h2, lobes, opts, None)
    }

    /// [`FarSlice::range`] evaluated at one `phi` only, building only what can reach it
    /// (as [`FarSlice::far_at`]).
    pub fn range_at(
        az: &AzimuthalSlice<'a>,
        (h1, h2): (f64, f64),
        lobes: LobeSet,
        opts: &FarOptions,
        phi: f64,
    ) -> LobeValues {
        Self::range_with(az, h1, h2, lobes, opts, Some(phi)).eval(phi)
    }

    fn range_with(
        az: &AzimuthalSlice<'a>,
        h1: f64,
        h2: f64,
        lobes: LobeSet,
        opts: &FarOptions,
        target: Option<f64>,
    ) -> Self {
        let mut ranges = Vec::new();
        if h2 > 0.0 {
            ranges.push((h1.max(0.0), h2, true, false));
        }
        if h1 < 0.0 {
            ranges.push(((-h2).max(0.0), -h1, false, true));
        }
        // Merge when the two sides cover the same |h| range (the far field case).
        if ranges.len() == 2 && ranges[0].0 == ranges[1].0 && ranges[0].1 == ranges[1].1 {
            ranges = vec![(ranges[0].0, ranges[0].1, true, true)];
        }
        Self::build(az, lobes, opts, &ranges, 1.0 / (h2 - h1), target)
    }

    /// `target`: the one `phi` the slice will be evaluated at, if known (see
    /// [`FarSlice::far_at`]).
    fn build(
        az: &AzimuthalSlice<'a>,
        lobes: LobeSet,
        opts: &FarOptions,
        ranges: &[(f64, f64, bool, bool)],
        weight: f64,
        target: Option<f64>,
    ) -> Self {
        Self::build_taped(az, lobes, opts, ranges, weight, target, TapeMode::Off).0
    }

    #[allow(clippy::too_many_arguments)]
    fn build_taped(
        az: &AzimuthalSlice<'a>,
        lobes: LobeSet,
        opts: &FarOptions,
        ranges: &[(f64, f64, bool, bool)],
        weight: f64,
        target: Option<f64>,
        mode: TapeMode,
    ) -> (Self, Decisions) {
        let mut decisions = Decisions::default();
        let lobes = lobes.intersect(az.model.active_lobes());
        let bn = az.model.params.beta_n;
        let mut fs = FarSlice {
            az: *az,
            lobes,
            cull: opts.cull,
            tol: opts.tol,
            max_dps: max_dps(opts),
            weight,
            parts: Vec::new(),
            betas: [beta_p(0, bn), beta_p(1, bn), beta_p(2, bn)],
            capped: LobeSet::NONE,
        };
        // The far field (all of [-1, 1], Eq. 22) rather than a multi-scale range.
        let full_width = ranges == [(0.0, 1.0, true, true)];
        // Initial boundaries per part and lobe family.
        let nu = opts.n_unscattered.max(1);
        let ns = opts.n_scattered.max(1);
        let kappa = az.model.params.kappa;
        let edge = kappa * az.eta_prime;
        let caustic = az.trt_caustic_u();
        let mut plans = Vec::new();
        for &(ha, hb, direct, mirror) in ranges {
            let (ha, hb) = (ha.clamp(0.0, 1.0), hb.clamp(0.0, 1.0));
            if hb <= ha {
                continue;
            }
            let mult = direct as u8 as f64 + mirror as u8 as f64;
            // Unscattered: h_i = sqrt(i/n) clipped, + medulla edge.
            let mut hs: Vec<f64> = (0..=nu).map(|i| (i as f64 / nu as f64).sqrt()).collect();
            hs.push(ha);
            hs.push(hb);
            if edge > 0.0 && edge < 1.0 {
                hs.push(edge);
            }
            let layer = if opts.tol.is_some() {
                medulla_layer_h(az)
            } else {
                Vec::new()
            };
            hs.extend(&layer);
            let mut us = to_u(&hs, ha, hb);
            if opts.tol.is_some() {
                us.extend(fresnel_layer_u(az.eta_prime, az.model.params.l));
            }
            sort_dedup(&mut us, ha.asin(), hb.asin());
            let mut us_trt = us.clone();
            if let Some(uc) = caustic {
                us_trt.push(uc);
                sort_dedup(&mut us_trt, ha.asin(), hb.asin());
            }
            // Scattered: h_i = h_max sqrt(i/n) on the medulla-reaching offsets.
            let hmax = edge.min(1.0);
            let mut us_s = Vec::new();
            if lobes.intersect(LobeSet::SCATTERED) != LobeSet::NONE && ha < hmax {
                let mut hs: Vec<f64> = (0..=ns)
                    .map(|i| hmax * (i as f64 / ns as f64).sqrt())
                    .collect();
                hs.push(ha);
                hs.push(hb.min(hmax));
                // Tolerance mode integrates along psi between the table's offset nodes
                // (`x = h / (kappa eta')`), where `C^N` is linear in `x`.
                if let (Some(rows), true) = (fs.cn_rows(), opts.tol.is_some()) {
                    hs.extend(rows.x_nodes().iter().map(|&x| x * edge));
                }
                hs.extend(&layer);
                us_s = to_u(&hs, ha, hb.min(hmax));
                sort_dedup(&mut us_s, ha.asin(), hb.min(hmax).asin());
            }
            plans.push((direct, mirror, mult, us, us_trt, us_s));
        }
        // Lobe scales for the tolerance budget: sum over parts of mult * integral A dh
        // (adaptive Simpson in u from the initial segments, see [`FarSlice::mass`]).
        let memo = NodeMemo::new();
        let mut node_cache: Vec<(Vec<Node>, Vec<Node>, Vec<Node>)> = Vec::new();
        let mut mass = [0.0f64; 5];
        for (_, _, mult, us, us_trt, us_s) in &plans {
            // The unscattered families' nodes skip the scattered values (they read only
            // their own lobe's).
            let mk = |v: &Vec<f64>, scattered: bool| -> Vec<Node> {
                let mut out = Vec::with_capacity(2 * v.len());
                for w in v.windows(2) {
                    out.push(fs.node_memo(&memo, w[0], scattered));
                    out.push(fs.node_memo(&memo, 0.5 * (w[0] + w[1]), scattered));
                }
                if let Some(&last) = v.last() {
                    out.push(fs.node_memo(&memo, last, scattered));
                }
                out
            };
            let (a, b, c) = (mk(us, false), mk(us_trt, false), mk(us_s, true));
            if opts.tol.is_some() {
                let fam = [
                    (&a, lobes.intersect(LobeSet::only(Lobe::R).with(Lobe::TT))),
                    (&b, lobes.intersect(LobeSet::only(Lobe::TRT))),
                    (&c, lobes.intersect(LobeSet::SCATTERED)),
                ];
                for (nodes, set) in fam {
                    let m = fs.mass(&memo, nodes, set);
                    for l in set.iter() {
                        mass[l.index()] += mult * m[l.index()];
                    }
                }
            }
            node_cache.push((a, b, c));
        }
        let budget = opts.tol.map(|t| {
            let mut b = [0.0; 5];
            for i in 0..5 {
                b[i] = t * mass[i];
            }
            b
        });
        for (k, (direct, mirror, mult, _, _, _)) in plans.iter().enumerate() {
            let mut part = Part {
                direct: *direct,
                mirror: *mirror,
                ..Default::default()
            };
            let (a, b, c) = &node_cache[k];
            for l in lobes.iter() {
                let nodes = if l == Lobe::TRT {
                    b
                } else if l.is_scattered() {
                    c
                } else {
                    a
                };
                // Error budgets (see module doc): an unscattered segment's fitted density
                // g(Phi) may be off by `tol / 4` of the lobe's mean over phi (each phi sees
                // the Gaussian-weighted error of at most a few branches); a scattered
                // segment's prefactor by `tol / 4` of the mean spread over the whole range
                // (every segment contributes at every phi).
                let bud = budget.map(|b| {
                    if l.is_scattered() {
                        let span = c.last().map_or(0.0, |n| n.u) - c.first().map_or(0.0, |n| n.u);
                        b[l.index()] / (mult * span.max(1e-300))
                    } else {
                        b[l.index()] / (mult * TAU)
                    }
                });
                let small = budget.map_or(0.0, |b| b[l.index()] / (mult * SMALL_SEGMENTS));
                let reach: Vec<f64> = match target {
                    Some(phi) if opts.cull => {
                        part.signs().map(|sign| sign * wrap_angle(phi)).collect()
                    }
                    _ => Vec::new(),
                };
                let refine = |scale: f64| Refine {
                    tape: match mode {
                        TapeMode::Off => Tape::Off,
                        TapeMode::Record => Tape::Record(Vec::new()),
                        TapeMode::Replay(d) => d
                            .parts
                            .get(k)
                            .map_or(Tape::Off, |lobes| Tape::Replay(&lobes[l.index()], 0)),
                    },
                    budget: bud.map(|b| b * scale),
                    small: small * scale,
                    splits_left: MAX_SPLITS,
                    capped: false,
                    err_sum: 0.0,
                    reach: reach.clone(),
                    memo: &memo,
                };
                let run = |fs: &FarSlice<'a>, rf: &mut Refine, part: &mut Part| {
                    // The initial segmentation's size is a fact: a step that adds or
                    // removes an initial breakpoint (the TRT caustic, the medulla edge)
                    // leaves the recording's decisions for other segments.
                    rf.tape.fact_u32(nodes.len() as u32);
                    for seg in (0..nodes.len().saturating_sub(2)).step_by(2) {
                        let (n0, nm, n1) = (&nodes[seg], &nodes[seg + 1], &nodes[seg + 2]);
                        if l.is_scattered() && rf.budget.is_some() {
                            fs.build_psi(l, n0, nm, n1, 0, rf, &mut part.scat[l.p() - 1]);
                        } else if l.is_scattered() {
                            fs.build_scat(l, n0, nm, n1, 0, rf, &mut part.scat[l.p() - 1]);
                        } else {
                            fs.build_unsc(l.p(), n0, nm, n1, 0, rf, &mut part.unsc[l.p()]);
                        }
                    }
                };
                let mut rf = refine(1.0);
                run(&fs, &mut rf, &mut part);
                // A scattered lobe of few pieces, whose error bounds may add up at its
                // peak: rebuilt with a smaller budget until they fit `tol` of the peak
                // (a replay takes the recorded segmentation as it is). Multi-scale ranges
                // only: in the far field the pieces' errors are measured well inside `tol`
                // (`tol_mode_meets_1e_4_on_random_parameters`), and a rebuild that a
                // parameter step switches on or off made the fitter stall on the step
                // (red fox: 235 LM iterations, 13.6 s, against 170 and 7 s).
                if l.is_scattered() && !full_width && !matches!(mode, TapeMode::Replay(_)) {
                    let mut scale = 1.0;
                    let lobe_mass = mass[l.index()];
                    for _ in 0..RESCALE_ROUNDS {
                        let Some(s) = fs.peak_rescale(&part, l, *mult, rf.err_sum, lobe_mass)
                        else {
                            break;
                        };
                        scale *= s;
                        part.scat[l.p() - 1] = ScatNodes::default();
                        rf = refine(scale);
                        run(&fs, &mut rf, &mut part);
                    }
                }
                if rf.capped {
                    fs.capped = fs.capped.with(l);
                }
                if let Tape::Record(v) = rf.tape {
                    if decisions.parts.len() <= k {
                        decisions.parts.resize_with(k + 1, Default::default);
                    }
                    decisions.parts[k][l.index()] = v;
                }
            }
            fs.parts.push(part);
        }
        decisions.capped = fs.capped;
        (fs, decisions)
    }

    /// When a scattered lobe of at most [`RESCALE_MAX_PIECES`] pieces has error bounds
    /// that, added up, exceed `tol` of a lower bound of its peak (its built value at
    /// [`RESCALE_PHIS`] azimuths less those bounds), the factor to scale its budget by
    /// (half the ratio, at least 1/64); `None` when they fit or cannot be checked.
    ///
    /// The budget holds the bounds' sum to `tol` of the lobe's *mass*, i.e. `2 pi tol` of
    /// its mean over `phi`: spread over many pieces the errors do not add up at one `phi`,
    /// but a multi-scale range near `h = 1` has two or three pieces whose errors add at
    /// the peak (1.7e-4 of it at `tol` 1e-4; accuracy search, 2026-11-28). Checking costs
    /// an evaluation per azimuth per piece, so lobes of many pieces are not checked; the
    /// far field is not checked at all (see the caller).
    fn peak_rescale(
        &self,
        part: &Part,
        l: Lobe,
        mult: f64,
        err_sum: f64,
        mass: f64,
    ) -> Option<f64> {
        let tol = self.tol?;
        let sn = &part.scat[l.p() - 1];
        let pieces = sn.psi.len() + sn.nodes.len();
        let bound = self.weight * mult * err_sum;
        // The peak is at least the mean over phi, `weight mass / 2 pi` (the mass is
        // estimated to 1 %, `MASS_REL`): bounds below that fit without evaluating.
        let mean = self.weight * mass / TAU * (1.0 - 2.0 * MASS_REL);
        if err_sum <= 0.0 || bound <= tol * mean || pieces == 0 || pieces > RESCALE_MAX_PIECES {
            return None;
        }
        let built = (0..RESCALE_PHIS)
            .map(|j| {
                let phi = -PI + TAU * (j as f64 + 0.5) / RESCALE_PHIS as f64;
                let mut v = LobeValues::default();
                self.add_scattered(part, phi, &mut v);
                v.get(l)
            })
            .fold(0.0f64, f64::max);
        let peak = built - bound;
        if bound <= tol * peak.max(0.0) {
            return None;
        }
        Some((0.5 * tol * peak.max(0.0) / bound).clamp(1.0 / 64.0, 0.5))
    }

    /// Node values at `u`, from the build's memo when evaluated before.
    fn node(&self, memo: &NodeMemo, u: f64) -> Node {
        self.node_memo(memo, u, true)
    }

    /// [`Self::node_with`] through the build's memo.
    fn node_memo(&self, memo: &NodeMemo, u: f64, scattered: bool) -> Node {
        let key = (u.to_bits(), scattered);
        let mut m = memo.0.borrow_mut();
        if let Some(&i) = m.index.get(&key) {
            return m.nodes[i as usize];
        }
        let n = self.node_with(u, scattered);
        let i = m.nodes.len() as u32;
        m.index.insert(key, i);
        m.nodes.push(n);
        n
    }

    /// [`Self::node`], leaving the scattered lobes' values at 0 unless `scattered` (the
    /// quadrature nodes of an unscattered piece read only their own lobe).
    fn node_with(&self, u: f64, scattered: bool) -> Node {
        let az = &self.az;
        let geo = az.geometry_at_gamma_i(u);
        let f = az.cuticle(&geo);
        let cu = geo.cos_gamma_i;
        let ab = &az.absorption;
        let ct = geo.cos_gamma_t.max(1e-300);
        let mut n = Node {
            u,
            phi: [0.0; 3],
            dphi: [0.0; 3],
            pre: [0.0; 5],
            lam: [0.0; 5],
            x_med: 0.0,
            phis: [0.0; 2],
            dphis: [0.0; 2],
            frac: 0.0,
            prob: 0.0,
        };
        for p in 0..3 {
            n.phi[p] = azimuthal::phi_p(p, &geo);
            n.dphi[p] = 2.0 * p as f64 * cu / (az.eta_prime * ct) - 2.0;
            n.pre[p] = Self::unsc_pre(p, f, cu);
            n.lam[p] = Self::unsc_lam(p, &geo, ab);
        }
        if scattered && self.lobes.intersect(LobeSet::SCATTERED) != LobeSet::NONE {
            let meets = geo.meets_medulla();
            for p in 1..3 {
                let pf = p as f64;
                let l = 2 + p;
                n.pre[l] = if meets {
                    azimuthal::a_s_p_cuticle(p, f) * cu
                } else {
                    0.0
                };
                n.lam[l] = azimuthal::a_s_p_exponent(p, &geo, ab).max(LAM_MIN);
                n.phis[p - 1] = azimuthal::phi_s_p(p, &geo);
                // Phi^s_p = (gamma_t - u) + (p - 1)(pi + 2 gamma_t), dgamma_t/du as above.
                n.dphis[p - 1] = (2.0 * pf - 1.0) * cu / (az.eta_prime * ct) - 1.0;
            }
            n.x_med = azimuthal::medulla_offset(&geo, self.az.model.params.kappa);
            if let Some(m) = self.az.model.medulla() {
                n.prob = m.scattered_probability(n.x_med);
                n.frac = m.cn_mass(n.x_med) * n.prob;
            }
        }
        n
    }

    /// The factor of unscattered lobe `p`'s `A_p cos u` outside its exponential
    /// (seed Eqs. 13-14): `F cos u`, `(1 - F)^2 cos u`, `(1 - F)^2 F cos u`.
    fn unsc_pre(p: usize, f: f64, cu: f64) -> f64 {
        azimuthal::a_p_cuticle(p, f) * cu
    }

    /// The log of `T_c T_m` of unscattered lobe `p` (seed Eq. 14; 0 for R), clamped at
    /// [`LAM_MIN`].
    fn unsc_lam(p: usize, geo: &PathGeometry, ab: &Absorption) -> f64 {
        azimuthal::a_p_exponent(p, geo, ab).max(LAM_MIN)
    }

    /// The log-attenuation `ln(T_c T_m)` of unscattered lobe `p` over a `Phi` piece whose
    /// nodes (in increasing `Phi`) sit at `xs` (`xs[0] = 0`), as `[l0, l1, l2]` in
    /// `x = Phi - lo`: the line through the end nodes in paper mode (the Appendix's
    /// linear log-attenuation), the quadratic through all three in tolerance mode. Its
    /// curvature is capped at [`lam_curve_cap`] (the closed form needs a
    /// concave exponent) and the capped quadratic still passes through the end nodes, so
    /// the fit is continuous in the parameters; the quarter-point check then judges it.
    /// Where the attenuation curves (the medulla's chord, steep absorption) the line
    /// missed by 10-2000x the budget on pieces the quadratic fits (TT, cat preset), which
    /// sent those pieces to 16-point Gauss-Legendre rules.
    fn lam_fit(&self, p: usize, xs: [f64; 3], nodes: [&Node; 3]) -> [f64; 3] {
        let (l0, l2, len) = (nodes[0].lam[p], nodes[2].lam[p], xs[2]);
        let curve = match self.tol {
            Some(_) => {
                let fit = quadratic_through(xs, nodes.map(|n| n.lam[p]))[2];
                fit.min(lam_curve_cap(self.betas[p]))
            }
            None => 0.0,
        };
        [l0, (l2 - l0) / len - curve * len, curve]
    }

    /// A Gauss-Legendre node of unscattered lobe `p` at `u`: `(Phi_p, pre, lam)` as
    /// [`Self::node_with`] gives them, bit for bit. R (`Phi_0 = -2 gamma_i`, `A_0 = F`)
    /// needs no refraction, so it skips the `asin` of `gamma_t`; the other lobes skip the
    /// values of the lobes they do not need. A sixth of a slice's node evaluations are R's
    /// quadrature nodes (human preset).
    fn gl_node(&self, p: usize, u: f64) -> (f64, f64, f64) {
        let az = &self.az;
        if p == 0 {
            let cu = u.sin_cos().1.max(0.0);
            let f = fresnel::cuticle_reflectance(az.eta_prime, cu, az.model.params.l);
            return (-2.0 * u, Self::unsc_pre(0, f, cu), 0.0);
        }
        let geo = az.geometry_at_gamma_i(u);
        let f = az.cuticle(&geo);
        (
            azimuthal::phi_p(p, &geo),
            Self::unsc_pre(p, f, geo.cos_gamma_i),
            Self::unsc_lam(p, &geo, &az.absorption),
        )
    }

    /// The exact unscattered integrand's `g = A cos u / |Phi'|` parts at a node.
    fn g_exact(n: &Node, p: usize) -> f64 {
        n.pre[p] * n.lam[p].exp() / n.dphi[p].abs()
    }

    /// The integrand of a lobe's mass `integral A dh = integral A cos u du` at a node
    /// (scattered lobes: times the scattered fraction).
    fn density(n: &Node, l: Lobe) -> f64 {
        let base = n.pre[l.index()] * n.lam[l.index()].exp();
        if l.is_scattered() {
            base * n.frac
        } else {
            base
        }
    }

    /// `integral A cos u du` per lobe of `set` over the node list (triples
    /// `u_k, mid, u_k+1`): adaptive Simpson, bisecting a triple while its two-half estimate
    /// differs from the whole by more than [`MASS_REL`] of the coarse total or of itself.
    /// A plain Simpson sum on the initial segments can miss by orders of magnitude when
    /// the mass sits in a thin layer (Fresnel at `h -> 1` for `eta -> 1`, steep absorption
    /// at grazing `theta_d`); the tolerance budget built from it then becomes absurdly
    /// tight and the refinement runs away. This only sets the budget's scale: 1 % is ample.
    fn mass(&self, memo: &NodeMemo, nodes: &[Node], set: LobeSet) -> [f64; 5] {
        // The bisection stack holds each node's `u` and densities, not the whole node
        // (a fifth of its size): copying nodes in and out of it was most of the build's
        // memmove time (human preset, tolerance mode).
        let dens = |n: &Node| {
            let mut d = [0.0f64; 5];
            for l in set.iter() {
                d[l.index()] = Self::density(n, l);
            }
            (n.u, d)
        };
        let simpson = |a: &(f64, [f64; 5]), m: &(f64, [f64; 5]), b: &(f64, [f64; 5]), i: usize| {
            (b.0 - a.0) / 6.0 * (a.1[i] + 4.0 * m.1[i] + b.1[i])
        };
        let slim: Vec<(f64, [f64; 5])> = nodes.iter().map(dens).collect();
        let mut coarse = [0.0f64; 5];
        for k in (0..slim.len().saturating_sub(2)).step_by(2) {
            for l in set.iter() {
                let i = l.index();
                coarse[i] += simpson(&slim[k], &slim[k + 1], &slim[k + 2], i);
            }
        }
        let mut out = [0.0f64; 5];
        let mut stack: Vec<_> = (0..slim.len().saturating_sub(2))
            .step_by(2)
            .map(|k| (slim[k], slim[k + 1], slim[k + 2], 0u32))
            .collect();
        let scattered = set.intersect(LobeSet::SCATTERED) != LobeSet::NONE;
        while let Some((a, m, b, depth)) = stack.pop() {
            let (q1, q3) = (
                dens(&self.node_memo(memo, 0.5 * (a.0 + m.0), scattered)),
                dens(&self.node_memo(memo, 0.5 * (m.0 + b.0), scattered)),
            );
            let mut done = true;
            for l in set.iter() {
                let i = l.index();
                let whole = simpson(&a, &m, &b, i);
                let halves = simpson(&a, &q1, &m, i) + simpson(&m, &q3, &b, i);
                // Relative to the larger of the coarse total and this triple's own estimate,
                // so a coarse total that missed the mass (even 0) cannot demand more than
                // 1 % of the triple itself.
                let scale = coarse[i].abs().max(halves.abs());
                if (halves - whole).abs() > MASS_REL * scale {
                    done = false;
                }
            }
            if done || depth >= MASS_MAX_DEPTH {
                for l in set.iter() {
                    let i = l.index();
                    out[i] += simpson(&a, &q1, &m, i) + simpson(&m, &q3, &b, i);
                }
            } else {
                stack.push((a, q1, m, depth + 1));
                stack.push((m, q3, b, depth + 1));
            }
        }
        out
    }

    /// Fit one unscattered segment `[n0, n1]` (midpoint `nm`) of lobe `p`, bisecting as the
    /// tolerance budget in `rf` demands (see the module doc).
    #[allow(clippy::too_many_arguments)]
    fn build_unsc(
        &self,
        p: usize,
        n0: &Node,
        nm: &Node,
        n1: &Node,
        depth: u32,
        rf: &mut Refine,
        out: &mut Vec<Piece>,
    ) {
        if !self.reaches(p, n0, n1, rf) {
            return;
        }
        let beta = self.betas[p];
        let d = [n0.dphi[p], nm.dphi[p], n1.dphi[p]];
        let (dmin, dmax) = (
            d.iter().fold(f64::INFINITY, |a, &b| a.min(b.abs())),
            d.iter().fold(0.0f64, |a, &b| a.max(b.abs())),
        );
        let same_sign =
            (d[0] > 0.0 && d[1] > 0.0 && d[2] > 0.0) || (d[0] < 0.0 && d[1] < 0.0 && d[2] < 0.0);
        let ph = [n0.phi[p], nm.phi[p], n1.phi[p]];
        let lo = ph.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = ph.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        // Taped decisions ([`Decisions`]): the facts first, then the thresholds.
        let monotone = rf.tape.fact(same_sign && hi - lo > PHI_MIN_SPAN);
        let narrow = rf.tape.choose_bool(hi - lo <= GL_SPAN_SIGMAS * beta);
        let phi_fit = monotone && rf.tape.choose_bool(dmin >= RATIO_MIN * dmax);
        let memo = rf.memo;
        let quarter = |s: &Self| {
            (
                s.node_memo(memo, 0.5 * (n0.u + nm.u), false),
                s.node_memo(memo, 0.5 * (nm.u + n1.u), false),
            )
        };
        if phi_fit {
            // Phi-space fit, oriented so that x = Phi - lo increases.
            let mut nodes = [n0, nm, n1];
            if d[0] < 0.0 {
                nodes.reverse();
            }
            let xs = [
                nodes[0].phi[p] - lo,
                nodes[1].phi[p] - lo,
                nodes[2].phi[p] - lo,
            ];
            let len = xs[2];
            let gs = [
                nodes[0].pre[p] / nodes[0].dphi[p].abs(),
                nodes[1].pre[p] / nodes[1].dphi[p].abs(),
                nodes[2].pre[p] / nodes[2].dphi[p].abs(),
            ];
            let lam = self.lam_fit(p, xs, [nodes[0], nodes[1], nodes[2]]);
            let c = quadratic_through(xs, gs);
            let piece = Piece::Phi { lo, len, c, lam };
            let Some(b) = rf.budget else {
                out.push(piece);
                return;
            };
            let (q1, q3) = quarter(self);
            let mut e = 0.0f64;
            let mut dev = 0.0f64;
            for q in [q1, q3] {
                let x = q.phi[p] - lo;
                let lx = poly(&lam, x);
                let fit = poly(&c, x) * lx.exp();
                e = e.max((fit - Self::g_exact(&q, p)).abs());
                dev = dev.max((lx - q.lam[p]).abs());
            }
            e = e.max(hidden_mass_bound(dev, [n0, nm, n1, &q1, &q3], |n| {
                Self::g_exact(n, p)
            }));
            if rf.tape.choose_bool(e <= b) {
                out.push(piece);
            } else if narrow {
                // The Gaussian is resolved across the whole segment: refine in u for GL
                // instead (the fit in Phi is limited by the rounding of Phi differences
                // when Phi' -> 0, e.g. TT at eta -> 1, and would never converge).
                self.build_narrow(p, n0, nm, n1, &q1, &q3, depth, rf, out);
            } else if let Some(depth) = rf.split(depth) {
                self.build_unsc(p, n0, &q1, nm, depth, rf, out);
                self.build_unsc(p, nm, &q3, n1, depth, rf, out);
            } else {
                out.push(piece);
            }
            return;
        }
        if narrow {
            if rf.budget.is_some() {
                let (q1, q3) = quarter(self);
                self.build_narrow(p, n0, nm, n1, &q1, &q3, depth, rf, out);
            } else {
                out.push(self.gl_piece(p, n0, n1, lo, hi, false, &mut rf.tape));
            }
            return;
        }
        match rf.split(depth) {
            Some(depth) => {
                let (q1, q3) = quarter(self);
                self.build_unsc(p, n0, &q1, nm, depth, rf, out);
                self.build_unsc(p, nm, &q3, n1, depth, rf, out);
            }
            None => out.push(self.gl_piece(p, n0, n1, lo, hi, false, &mut rf.tape)),
        }
    }

    /// Bounds of `Phi_p` over `[n0.u, n1.u]`. `dPhi_p/du = 2p cos u / (eta' cos gamma_t) - 2`
    /// is monotone in `u` on `[0, pi/2]` (`cos u / cos gamma_t` falls from 1 to 0 for
    /// `eta' >= 1`) and lies in `[-2, 2p/eta' - 2]`, so inside the segment it lies between
    /// its end values clamped to that range (the computed ones leave it only by rounding,
    /// or at `h = 1`, where `cos u / cos gamma_t` is 0/0).
    fn phi_bounds(&self, p: usize, n0: &Node, n1: &Node) -> (f64, f64) {
        let top = (2.0 * p as f64 / self.az.eta_prime - 2.0).max(-2.0);
        let (d0, d1) = (n0.dphi[p].clamp(-2.0, top), n1.dphi[p].clamp(-2.0, top));
        let (dlo, dhi) = (d0.min(d1).min(0.0), d0.max(d1).max(0.0));
        let len = n1.u - n0.u;
        let (f0, f1) = (n0.phi[p], n1.phi[p]);
        (
            (f0 + dlo * len).max(f1 - dhi * len),
            (f0 + dhi * len).min(f1 - dlo * len),
        )
    }

    /// Can a piece of lobe `p` refined from `[n0, n1]` reach an azimuth of `rf.reach`?
    /// The same image test as [`FarSlice::add_piece`] on a range holding every such
    /// piece's range, widened by [`WINDOW_SLACK`] against rounding.
    fn reaches(&self, p: usize, n0: &Node, n1: &Node, rf: &Refine) -> bool {
        if rf.reach.is_empty() {
            return true;
        }
        let (lo, hi) = self.phi_bounds(p, n0, n1);
        let w = self.image_window(p).1 + WINDOW_SLACK;
        rf.reach
            .iter()
            .any(|&mu| ((lo - w - mu) / TAU).ceil() <= ((hi + w - mu) / TAU).floor())
    }

    /// A segment narrow in `Phi` (at most [`GL_SPAN_SIGMAS`] `beta_p`): Gauss-Legendre in
    /// `u` of the exact integrand, once the attenuation `A cos u` itself is resolved — its
    /// quadratic-times-exp-linear fit in `u` is within budget when weighted by the
    /// Gaussian's height `1 / (beta sqrt(2 pi))` and the segment's length (a bound on the
    /// change of `integral A G du`); the 16-point rule is then far more accurate than that.
    /// Or, in tolerance mode, once the 16- and 8-point rules' Gaussians agree to within the
    /// budget at every probe of [`GL_FEW_PROBES`]: that takes 2-6x fewer pieces for the
    /// presets (a quadratic in `u` resolves the Fresnel and absorption factors far more
    /// slowly than the rules integrate them).
    #[allow(clippy::too_many_arguments)]
    fn build_narrow(
        &self,
        p: usize,
        n0: &Node,
        nm: &Node,
        n1: &Node,
        q1: &Node,
        q3: &Node,
        depth: u32,
        rf: &mut Refine,
        out: &mut Vec<Piece>,
    ) {
        if !self.reaches(p, n0, n1, rf) {
            return;
        }
        let len = n1.u - n0.u;
        let b = rf.budget.unwrap_or(f64::INFINITY);
        let norm = 1.0 / (self.betas[p] * TAU.sqrt());
        let (l0, l1) = (n0.lam[p], n1.lam[p]);
        let lin = (l1 - l0) / len.max(1e-300);
        let c = quadratic_through([0.0, 0.5 * len, len], [n0.pre[p], nm.pre[p], n1.pre[p]]);
        let mut e = 0.0f64;
        let mut dev = 0.0f64;
        for q in [q1, q3] {
            let x = q.u - n0.u;
            let fit = poly(&c, x) * (l0 + lin * x).exp();
            e = e.max((fit - q.pre[p] * q.lam[p].exp()).abs());
            dev = dev.max((l0 + lin * x - q.lam[p]).abs());
        }
        e = e.max(hidden_mass_bound(dev, [n0, nm, n1, q1, q3], |n| {
            (n.pre[p] * n.lam[p].exp()).abs()
        }));
        let ph = [n0.phi[p], nm.phi[p], n1.phi[p]];
        let lo = ph.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = ph.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        // The piece built for the agreement check, kept in case no split is allowed.
        let mut checked = None;
        if rf.tape.choose_bool(e * len * norm > b) {
            // The prefactor's quadratic is a sufficient test, not a necessary one: the
            // 16-point rule also stands when it agrees with the 8-point rule to within the
            // budget at every probe (the 8-point rule's error bounds its own, far smaller
            // one). Not where the log-attenuation bends sharply (`hidden_mass_bound`):
            // there both rules may miss the same spike.
            if rf.tape.choose_bool(dev <= LAM_DEV_MAX) {
                let (piece, err) = self.gl_piece_with(p, n0, n1, lo, hi, true, true, &mut rf.tape);
                if rf.tape.choose_bool(err <= b) {
                    out.push(piece);
                    return;
                }
                checked = Some(piece);
            }
            if let Some(depth) = rf.split(depth) {
                let (a1, a3) = (
                    self.node_memo(rf.memo, 0.5 * (n0.u + q1.u), false),
                    self.node_memo(rf.memo, 0.5 * (q1.u + nm.u), false),
                );
                self.build_narrow(p, n0, q1, nm, &a1, &a3, depth, rf, out);
                let (b1, b3) = (
                    self.node_memo(rf.memo, 0.5 * (nm.u + q3.u), false),
                    self.node_memo(rf.memo, 0.5 * (q3.u + n1.u), false),
                );
                self.build_narrow(p, nm, q3, n1, &b1, &b3, depth, rf, out);
                return;
            }
        }
        let piece = match checked {
            Some(piece) => piece,
            None => self.gl_piece(p, n0, n1, lo, hi, true, &mut rf.tape),
        };
        out.push(piece);
    }

    /// Gauss-Legendre piece of lobe `p` over `[n0.u, n1.u]` whose nodes' `Phi` span
    /// `[lo, hi]`, with [`GL_NODES`] nodes, or in tolerance mode with `few_ok` with
    /// [`GL_NODES_FEW`] where those give the same lobe (see there).
    #[allow(clippy::too_many_arguments)]
    fn gl_piece(
        &self,
        p: usize,
        n0: &Node,
        n1: &Node,
        lo: f64,
        hi: f64,
        few_ok: bool,
        tape: &mut Tape,
    ) -> Piece {
        self.gl_piece_with(p, n0, n1, lo, hi, few_ok, false, tape).0
    }

    /// [`Self::gl_piece`] and, in tolerance mode with `estimate`, an estimate of its error:
    /// the largest difference of the lobe's Gaussian at the probes between the rule kept
    /// and the next larger one (infinite otherwise).
    ///
    /// In tolerance mode with `few_ok`, a piece spanning at most [`GL_FEW_SPAN_SIGMAS`]
    /// `beta_p` tries the rules bottom up, as embedded rules are used: the
    /// [`GL_NODES_LEAST`]-point rule stands when it agrees with the [`GL_NODES_FEW`]-point
    /// one at every probe, else that one when it agrees with the [`GL_NODES`]-point rule,
    /// else the latter. Two rules agreeing at all seven probes by accident, while both are
    /// off, would take a prefactor that the smaller rule's nodes happen to sample right
    /// and the larger one's wrong by the same amount at every probe. The 16-point nodes
    /// are evaluated only when a smaller rule fails (node evaluations are most of a
    /// slice's build).
    #[allow(clippy::too_many_arguments)]
    fn gl_piece_with(
        &self,
        p: usize,
        n0: &Node,
        n1: &Node,
        lo: f64,
        hi: f64,
        few_ok: bool,
        estimate: bool,
        tape: &mut Tape,
    ) -> (Piece, f64) {
        let beta = self.betas[p];
        let range = |nodes: &[(f64, f64)]| {
            nodes
                .iter()
                .fold((lo, hi), |(a, b), &(ph, _)| (a.min(ph), b.max(ph)))
        };
        let piece = |nodes: &[(f64, f64)]| {
            let (plo, phi_hi) = range(nodes);
            Piece::Gl {
                lo: plo,
                hi: phi_hi,
                nodes: nodes.to_vec(),
            }
        };
        let Some(tol) = self.tol.filter(|_| estimate || few_ok) else {
            return (
                piece(&self.gl_nodes(p, n0.u, n1.u, GL_NODES)),
                f64::INFINITY,
            );
        };
        let few = self.gl_nodes(p, n0.u, n1.u, GL_NODES_FEW);
        let (flo, fhi) = range(&few);
        let few_fits = few_ok && tape.choose_bool(fhi - flo <= GL_FEW_SPAN_SIGMAS * beta);
        // Two rules' Gaussian sums at the probes `mid + k beta`:
        // exp(-(y - k)^2 / 2) = exp(-y^2 / 2) exp(y)^k exp(-k^2 / 2) with
        // y = (ph - mid) / beta (|y| about 1 at most here), two exponentials per node; the
        // largest difference and the larger rule's peak over the probes.
        let mid = 0.5 * (flo + fhi);
        let sums = |nodes: &[(f64, f64)]| -> [f64; GL_FEW_PROBES.len()] {
            let mut out = [0.0; GL_FEW_PROBES.len()];
            for &(ph, w) in nodes {
                let y = (ph - mid) / beta;
                let base = w * (-0.5 * y * y).exp();
                let e1 = y.exp();
                let (e2, i1) = (e1 * e1, 1.0 / e1);
                let (e4, i2) = (e2 * e2, i1 * i1);
                let pow = [i2 * i2, i2, i1, 1.0, e1, e2, e4];
                for (o, ek) in out.iter_mut().zip(pow) {
                    *o += base * ek;
                }
            }
            out
        };
        let compare = |small: &[f64; GL_FEW_PROBES.len()], large: &[f64; GL_FEW_PROBES.len()]| {
            let (mut diff, mut peak) = (0.0f64, 0.0f64);
            for ((x, y), k) in large.iter().zip(small).zip(GL_FEW_PROBES) {
                let c = (-0.5 * k * k).exp();
                diff = diff.max(c * (x - y).abs());
                peak = peak.max(c * x.abs());
            }
            (diff, peak)
        };
        let norm = 1.0 / (beta * TAU.sqrt());
        let few_sums = sums(&few);
        if few_fits {
            let least = self.gl_nodes(p, n0.u, n1.u, GL_NODES_LEAST);
            let (diff, peak) = compare(&sums(&least), &few_sums);
            if tape.choose_bool(diff <= GL_FEW_REL * tol * peak) {
                return (piece(&least), diff * norm);
            }
        }
        let full = self.gl_nodes(p, n0.u, n1.u, GL_NODES);
        let (diff, peak) = compare(&few_sums, &sums(&full));
        let nodes = if few_fits && tape.choose_bool(diff <= GL_FEW_REL * tol * peak) {
            &few
        } else {
            &full
        };
        (piece(nodes), diff * norm)
    }

    /// `count`-point (at most [`GL_NODES`]) Gauss-Legendre nodes `(Phi_p, weight * A cos u)`
    /// of lobe `p` on `[u0, u1]`, on the stack: a piece tries up to three rules and keeps
    /// one, so only the kept rule's nodes are copied to the heap.
    fn gl_nodes(&self, p: usize, u0: f64, u1: f64, count: usize) -> GlNodes {
        debug_assert!(count <= GL_NODES);
        let gl = GaussLegendre::cached(count);
        let (c, r) = (0.5 * (u0 + u1), 0.5 * (u1 - u0));
        let mut out = GlNodes {
            nodes: [(0.0, 0.0); GL_NODES],
            len: count,
        };
        for ((o, x), w) in out.nodes.iter_mut().zip(&gl.nodes).zip(&gl.weights) {
            let (phi, pre, lam) = self.gl_node(p, c + r * x);
            // R's exponent is 0: skip the exponential (a factor 1, exact).
            let a = w * r * pre;
            *o = (phi, if p == 0 { a } else { a * lam.exp() });
        }
        out
    }

    /// The slice's medulla table rows, if the fiber has a medulla.
    fn cn_rows(&self) -> Option<CnRows<'a>> {
        self.az.model.medulla().map(|m| m.cn_rows())
    }

    /// A scattered segment in tolerance mode: a [`PsiPiece`] where `Phi^s` is monotone
    /// with a bounded slope ratio (bisected until the densities' quadratics are within
    /// budget), else bisected until it spans at most one `psi` bin, where the node
    /// quadrature of [`Self::build_scat`] takes over (near a `Phi^s` caustic of TRTs).
    #[allow(clippy::too_many_arguments)]
    fn build_psi(
        &self,
        l: Lobe,
        n0: &Node,
        nm: &Node,
        n1: &Node,
        depth: u32,
        rf: &mut Refine,
        out: &mut ScatNodes,
    ) {
        let Some(rows) = self.cn_rows() else {
            return;
        };
        let (i, k) = (l.index(), l.p() - 1);
        let len_u = n1.u - n0.u;
        if len_u <= 0.0 {
            return;
        }
        let q1 = self.node(rf.memo, 0.5 * (n0.u + nm.u));
        let q3 = self.node(rf.memo, 0.5 * (nm.u + n1.u));
        let all = [n0, &q1, nm, &q3, n1];
        let d = all.map(|n| n.dphis[k]);
        let monotone = d.iter().all(|&v| v > 0.0) || d.iter().all(|&v| v < 0.0);
        let (dmin, dmax) = d.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &v| {
            (a.min(v.abs()), b.max(v.abs()))
        });
        let span = (n1.phis[k] - n0.phis[k]).abs();
        let monotone = rf.tape.fact(monotone && span > 0.0);
        if !(monotone && rf.tape.choose_bool(dmin >= RATIO_MIN * dmax)) {
            if rf.tape.choose_bool(span <= rows.bin_width()) {
                self.build_scat(l, n0, nm, n1, depth, rf, out);
            } else if let Some(depth) = rf.split(depth) {
                self.build_psi(l, n0, &q1, nm, depth, rf, out);
                self.build_psi(l, nm, &q3, n1, depth, rf, out);
            } else {
                self.build_scat(l, n0, nm, n1, depth, rf, out);
            }
            return;
        }
        let row = rows.row_at(nm.x_med);
        let phi_hi = n0.phis[k].max(n1.phis[k]);
        let dens = |n: &Node| -> (f64, [f64; 2]) {
            let w = n.pre[i] * n.prob * n.lam[i].exp() / n.dphis[k].abs();
            let t = rows.weight(row, n.x_med);
            (phi_hi - n.phis[k], [w, w * t])
        };
        let [a, b, c] = [dens(n0), dens(nm), dens(n1)];
        let folds = rf.tape.fact((b.0 - a.0) * (c.0 - b.0) <= 0.0);
        if rf.tape.choose_bool(span < PSI_MIN_SPAN) || folds {
            // Phi^s constant to rounding across the segment: no quadratic in Phi^s through
            // the nodes (see PSI_MIN_SPAN).
            self.build_scat(l, n0, nm, n1, depth, rf, out);
            return;
        }
        let g = [0, 1].map(|j| quadratic_through([a.0, b.0, c.0], [a.1[j], b.1[j], c.1[j]]));
        if let Some(bud) = rf.budget {
            // Error of the piece at any phi: each density's misfit times the mass of what
            // it multiplies over `len`: row i (at most `len * peak`, and 1.1, a row's mass
            // plus its floor) and the gap to row i + 1 (at most `len * gap`).
            let mut e = [0.0f64; 2];
            let mut quarter = [(0.0, 0.0); 2];
            for (k, q) in [q1, q3].into_iter().enumerate() {
                let (s, v) = dens(&q);
                quarter[k] = (s, v[0] - poly(&g[0], s));
                for j in 0..2 {
                    e[j] = e[j].max((poly(&g[j], s) - v[j]).abs());
                }
            }
            // Row i's part, sharper: with `R = Rbar + (R - Rbar)` over the piece's window,
            // the misfit `E` integrates against the mean `Rbar <= peak` (`integral E` is
            // a quadrature error, estimated from the quartic through all five nodes) and
            // against the row's variation across the window, at most `len * slope` (and
            // `peak`). Rows vary over tens of degrees, pieces span a few: the variation
            // term is a small part of `e len peak`.
            let mean_part = Self::misfit_integral([a.0, b.0, c.0], quarter).abs() * rows.peak;
            let var_part = e[0] * span * (span * rows.slope(row)).min(rows.peak);
            let row_part = (e[0] * (span * rows.peak).min(1.1)).min(mean_part + var_part);
            let err = row_part + e[1] * span * rows.gap(row);
            if rf.tape.choose_bool(err > bud * len_u && err > rf.small) {
                if let Some(depth) = rf.split(depth) {
                    self.build_psi(l, n0, &q1, nm, depth, rf, out);
                    self.build_psi(l, nm, &q3, n1, depth, rf, out);
                    return;
                }
            }
            // Accepted (or no split left): its bound counts toward the lobe's.
            rf.err_sum += err;
        }
        out.segments += 1;
        out.psi.push(PsiPiece {
            phi_hi,
            len: span,
            row,
            g,
        });
    }

    /// `integral E ds` over the nodes' range of the misfit `E = q - f` of the quadratic `f`
    /// through the nodes at `s` (any order) against the quartic `q` through them and the two
    /// `quarter` points `(s, q(s) - f(s))`: `E = P (alpha + beta s)` with
    /// `P = (s - s0)(s - s1)(s - s2)`, a quartic that 3-point Gauss-Legendre integrates
    /// exactly.
    fn misfit_integral(s: [f64; 3], quarter: [(f64, f64); 2]) -> f64 {
        let p = |x: f64| (x - s[0]) * (x - s[1]) * (x - s[2]);
        let [(x1, r1), (x2, r2)] = quarter;
        let (y1, y2) = (r1 / p(x1), r2 / p(x2));
        if !(y1.is_finite() && y2.is_finite()) || x1 == x2 {
            return f64::INFINITY;
        }
        let beta = (y2 - y1) / (x2 - x1);
        let alpha = y1 - beta * x1;
        let lo = s[0].min(s[1]).min(s[2]);
        let hi = s[0].max(s[1]).max(s[2]);
        let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
        let node = (0.6f64).sqrt() * half;
        [(mid - node, 5.0), (mid, 8.0), (mid + node, 5.0)]
            .iter()
            .map(|&(x, w)| w / 9.0 * p(x) * (alpha + beta * x))
            .sum::<f64>()
            * half
    }

    /// A scattered segment by three-node quadrature of the queried `C^N` (paper mode, and
    /// the tolerance mode's one-bin segments at a `Phi^s` caustic).
    #[allow(clippy::too_many_arguments)]
    fn build_scat(
        &self,
        l: Lobe,
        n0: &Node,
        nm: &Node,
        n1: &Node,
        depth: u32,
        rf: &mut Refine,
        out: &mut ScatNodes,
    ) {
        let i = l.index();
        let k = l.p() - 1;
        let len = n1.u - n0.u;
        if len <= 0.0 {
            return;
        }
        // C^N is interpolated along psi = phi -+ Phi^s: keep its change per segment small
        // enough for a quadratic to follow a table's structure (FarOptions::scattered_step).
        let dps = (n1.phis[k] - n0.phis[k]).abs();
        if depth == 0 && rf.budget.is_some() {
            // When the psi step asks for many pieces (the strict step), cut the initial
            // segment into them at once: bisection would spend the split budget
            // depth-first and, once it ran out, leave the rest of the range coarse. The
            // pieces may still be bisected for their fit. Few pieces (the default step)
            // are left to bisection, which adapts to a non-uniform `Phi^s`.
            let pieces = (dps / self.max_dps).ceil().clamp(1.0, MAX_PSI_PIECES) as u32;
            let pieces = rf.tape.choose(pieces).max(1) as usize;
            if pieces > BISECT_PSI_PIECES {
                let at = |j: usize| n0.u + len * j as f64 / pieces as f64;
                let mut a = *n0;
                for j in 0..pieces {
                    let b = if j + 1 == pieces {
                        *n1
                    } else {
                        self.node(rf.memo, at(j + 1))
                    };
                    let m = self.node(rf.memo, 0.5 * (a.u + b.u));
                    self.build_scat(l, &a, &m, &b, 1, rf, out);
                    a = b;
                }
                return;
            }
        }
        let (l0, l1) = (n0.lam[i], n1.lam[i]);
        let lin = (l1 - l0) / len;
        if let Some(b) = rf.budget {
            {
                let q1 = self.node(rf.memo, 0.5 * (n0.u + nm.u));
                let q3 = self.node(rf.memo, 0.5 * (nm.u + n1.u));
                let ys = [
                    n0.pre[i] * n0.frac,
                    nm.pre[i] * nm.frac,
                    n1.pre[i] * n1.frac,
                ];
                let c = quadratic_through([0.0, 0.5 * len, len], ys);
                let mut e = 0.0f64;
                for q in [q1, q3] {
                    let x = q.u - n0.u;
                    let fit = poly(&c, x) * (l0 + lin * x).exp();
                    e = e.max((fit - q.pre[i] * q.frac * q.lam[i].exp()).abs());
                }
                let fit_poor = e > b && e * len > rf.small;
                if rf.tape.choose_bool(fit_poor || dps > self.max_dps) {
                    if let Some(depth) = rf.split(depth) {
                        self.build_scat(l, n0, &q1, nm, depth, rf, out);
                        self.build_scat(l, nm, &q3, n1, depth, rf, out);
                        return;
                    }
                }
            }
        }
        let pre_p = [
            n0.pre[i] * n0.prob,
            nm.pre[i] * nm.prob,
            n1.pre[i] * n1.prob,
        ];
        let mut w = [0.0; 3];
        for j in 0..3 {
            let mut e = [0.0; 3];
            e[j] = 1.0;
            let c = quadratic_through([0.0, 0.5 * len, len], e);
            w[j] = pre_p[j] * poly_exp(&c, l0, lin, len);
        }
        out.push_segment([
            (n0.x_med, n0.phis[k], w[0]),
            (nm.x_med, nm.phis[k], w[1]),
            (n1.x_med, n1.phis[k], w[2]),
        ]);
    }

    /// Tabulate `C^N` over `psi` at every scattered node (shared between the two scattered
    /// lobes and between neighbouring segments), so each later [`Self::eval`] costs a lerp
    /// per node instead of a sum over the table's ranks. Worth it when the slice is
    /// evaluated at more than a handful of `phi`; values change only by rounding.
    pub fn tabulate_scattered(&mut self) {
        let Some(med) = self.az.model.medulla() else {
            return;
        };
        let mut cache: HashMap<u64, Arc<CnProfile>> = HashMap::new();
        for part in &mut self.parts {
            for node in part.scat.iter_mut().flat_map(|s| s.nodes.iter_mut()) {
                let prof = cache
                    .entry(node.x_med.to_bits())
                    .or_insert_with(|| Arc::new(med.cn_profile(node.x_med)))
                    .clone();
                node.prof = Some(prof);
            }
        }
    }

    /// Work counters.
    pub fn stats(&self) -> SliceStats {
        let mut s = SliceStats {
            capped: self.capped,
            ..Default::default()
        };
        for part in &self.parts {
            for (p, v) in part.unsc.iter().enumerate() {
                let w = &mut s.per_lobe[p];
                for pc in v {
                    match pc {
                        Piece::Phi { .. } => w.closed_form += 1,
                        Piece::Gl { nodes, .. } => {
                            w.gl_segments += 1;
                            w.gl_nodes += nodes.len();
                        }
                    }
                }
            }
            for (l, sn) in [Lobe::TTs, Lobe::TRTs].into_iter().zip(&part.scat) {
                s.per_lobe[l.index()].closed_form += sn.segments;
            }
        }
        for (l, w) in Lobe::ALL.into_iter().zip(&s.per_lobe) {
            if l.is_scattered() {
                s.scattered_segments += w.closed_form;
            } else {
                s.unscattered_segments += w.closed_form;
                s.gl_segments += w.gl_segments;
                s.gl_nodes += w.gl_nodes;
            }
        }
        s
    }

    /// `N_p(phi)` for the lobes of this slice.
    ///
    /// A quadratic through non-negative node values can dip a rounding-level amount below
    /// zero where the true integrand vanishes (e.g. `1 - F -> 0` at grazing); such values
    /// are returned as 0. [`FarSlice::eval_raw`] gives the unclamped sum (the stability
    /// report counts and sizes those dips).
    pub fn eval(&self, phi: f64) -> LobeValues {
        clamp_dips(self.eval_raw(phi))
    }

    /// [`FarSlice::eval`] without clamping negative rounding dips to 0.
    pub fn eval_raw(&self, phi: f64) -> LobeValues {
        let phi = wrap_angle(phi);
        let mut out = LobeValues::default();
        for part in &self.parts {
            for p in 0..3 {
                let (beta, w) = self.image_window(p);
                let mut s = 0.0;
                for pc in &part.unsc[p] {
                    for sign in part.signs() {
                        self.add_piece(pc, sign * phi, beta, w, &mut s);
                    }
                }
                if s != 0.0 {
                    out.0[p] += self.weight * s;
                }
            }
            self.add_scattered(part, phi, &mut out);
        }
        self.keep_lobes(out)
    }

    /// [`FarSlice::eval`] at many `phi` at once. Faster for a whole grid: each unscattered
    /// piece finds by binary search the `phi` its culling window can reach, instead of
    /// every `phi` testing every piece. On an uneven grid it equals evaluating the `phi` one
    /// by one bit for bit (same terms in the same order per `phi`); on an evenly spaced grid
    /// it sweeps node Gaussians by recurrence (quadrature pieces, and Phi pieces in their
    /// node form), or sums them in Fourier space for a wide lobe (`FourierGrid`), and
    /// reads the scattered tables along the grid, within 1e-11 of each
    /// lobe's peak of the one-by-one values (tests `eval_many_equals_eval_exactly`,
    /// `eval_many_on_even_grids_matches_eval`).
    pub fn eval_many(&self, phis: &[f64]) -> Vec<LobeValues> {
        if !self.cull {
            return phis.iter().map(|&phi| self.eval(phi)).collect();
        }
        self.eval_list(&PhiList::new(phis))
    }

    /// [`Self::eval_many`] (with culling) on a prepared list.
    fn eval_list(&self, list: &PhiList) -> Vec<LobeValues> {
        let PhiList {
            wrapped,
            order,
            sorted,
            grid,
        } = list;
        // The grid step in table bins, if the scattered lobes can be read along the rows.
        let row_step = grid.as_ref().and_then(|g| self.row_steps(g));
        let mut out = vec![LobeValues::default(); wrapped.len()];
        // Per-lobe sums in sorted order (contiguous for the sweeps), added to `out` through
        // `order`; each phi's terms are added in the same order as by `eval`.
        let mut s = vec![0.0; wrapped.len()];
        // Node form of the current Phi piece (poly_gauss_nodes), reused across pieces.
        let mut phi_nodes: Vec<(f64, f64)> = Vec::new();
        // Nodes of a lobe summed in Fourier space (`FourierGrid`), reused across lobes,
        // and the grid's trigonometric table.
        let mut spectral: Vec<(f64, f64)> = Vec::new();
        let mut table = FourierTable::default();
        for part in &self.parts {
            let sides = part.signs().count();
            for p in 0..3 {
                let (beta, w) = self.image_window(p);
                s.iter_mut().for_each(|x| *x = 0.0);
                let fourier = grid
                    .as_ref()
                    .filter(|g| g.step <= SWEEP_MAX_STEP * beta)
                    .and_then(|g| FourierGrid::new(g, sorted.len(), beta, w, sides));
                spectral.clear();
                for pc in &part.unsc[p] {
                    let (lo, hi) = pc.range();
                    // The node form of a Phi piece, built once for both sides.
                    let phi_swept = match (pc, grid) {
                        (Piece::Phi { lo, len, c, lam }, Some(g))
                            if g.step <= SWEEP_MAX_STEP * beta =>
                        {
                            phi_nodes.clear();
                            poly_gauss_nodes(c, lam, *lo, *len, beta, &mut phi_nodes)
                        }
                        _ => false,
                    };
                    if fourier.is_some() {
                        match pc {
                            Piece::Gl { nodes, .. } => {
                                spectral.extend_from_slice(nodes);
                                continue;
                            }
                            Piece::Phi { .. } if phi_swept => {
                                spectral.extend_from_slice(&phi_nodes);
                                continue;
                            }
                            _ => {}
                        }
                    }
                    for sign in part.signs() {
                        // Candidates: mu = sign phi within the window of some image k,
                        // widened by WINDOW_SLACK so rounding cannot drop a phi that
                        // add_piece's own test keeps. If the windows of neighbouring images
                        // could overlap, every phi is a candidate (visited once).
                        let width = hi - lo + 2.0 * w + 2.0 * WINDOW_SLACK;
                        let visit = |a: usize, b: usize, s: &mut [f64]| {
                            for q in a..b {
                                self.add_piece(pc, sign * sorted[q], beta, w, &mut s[q]);
                            }
                        };
                        // Quadrature-node pieces on an evenly spaced grid: the Gaussian of
                        // each node follows a two-multiply recurrence along the grid. A Phi
                        // piece of a few beta is swept through its node form too: per phi
                        // its closed form costs an erf pair or (short pieces, distant phi)
                        // a Gauss-Legendre rule of exponentials; a third of grid synthesis
                        // went there (red fox).
                        let sweep = match (pc, grid) {
                            (Piece::Gl { nodes, .. }, Some(g))
                                if g.step <= SWEEP_MAX_STEP * beta =>
                            {
                                Some((nodes.as_slice(), g))
                            }
                            (Piece::Phi { .. }, Some(g)) if phi_swept => {
                                Some((phi_nodes.as_slice(), g))
                            }
                            _ => None,
                        };
                        // The images `sign * phi + shift` of sorted `qa..qb`, by sweep or
                        // one `phi` at a time.
                        let images = |shift: f64, qa: usize, qb: usize, s: &mut [f64]| match sweep {
                            Some((nodes, g)) => {
                                let at = SweepWindow {
                                    sign,
                                    shift,
                                    qa,
                                    qb,
                                    beta,
                                    w,
                                };
                                g.gaussian_sweep(nodes, &at, s);
                            }
                            None => visit(qa, qb, s),
                        };
                        if width >= TAU {
                            if sweep.is_some() {
                                // Every image whose window can reach the grid; the sweep
                                // cuts each node to its own window.
                                let k0 = ((lo - w - PI) / TAU).floor() as i64;
                                let k1 = ((hi + w + PI) / TAU).ceil() as i64;
                                for k in k0..=k1 {
                                    images(TAU * k as f64, 0, sorted.len(), &mut s);
                                }
                            } else {
                                visit(0, sorted.len(), &mut s);
                            }
                            continue;
                        }

                        let k0 = ((lo - w - PI) / TAU).floor() as i64 - 1;
                        let k1 = ((hi + w + PI) / TAU).ceil() as i64 + 1;
                        for k in k0..=k1 {
                            let shift = TAU * k as f64;
                            let (a, b) =
                                (lo - w - shift - WINDOW_SLACK, hi + w - shift + WINDOW_SLACK);
                            let (a, b) = if sign > 0.0 { (a, b) } else { (-b, -a) };
                            if b < -PI || a > PI {
                                continue;
                            }
                            let qa = sorted.partition_point(|&x| x < a);
                            let qb = sorted.partition_point(|&x| x <= b);
                            images(shift, qa, qb, &mut s);
                        }
                    }
                }
                if let (Some(f), Some(g)) = (&fourier, grid) {
                    table.reserve(g, sorted.len(), f.rho.len());
                    f.add(&spectral, (part.direct, part.mirror), &table, &mut s);
                }
                for (&i, &si) in order.iter().zip(&s) {
                    if si != 0.0 {
                        out[i].0[p] += self.weight * si;
                    }
                }
            }
            match (grid, row_step) {
                (Some(g), Some(m)) => self.add_rows_sweep(part, g, m, order, &mut s, &mut out),
                (Some(g), None) if self.scattered_tabulated(part) => {
                    self.add_scattered_sweep(part, g, order, &mut s, &mut out);
                    for (o, &phi) in out.iter_mut().zip(wrapped) {
                        self.add_psi_pieces(part, phi, o);
                    }
                }
                _ => {
                    for (o, &phi) in out.iter_mut().zip(wrapped) {
                        self.add_scattered(part, phi, o);
                    }
                }
            }
        }
        out.into_iter()
            .map(|v| clamp_dips(self.keep_lobes(v)))
            .collect()
    }

    /// [`Self::eval_many`] for a slice built to serve one grid of `phi` (grid synthesis,
    /// the renderer's tables): tabulates the scattered nodes' `C^N` first when there are
    /// [`TABULATE_MIN_PHI`] or more `phi` and the grid does not let the slice read the
    /// table's rows along it ([`Self::add_rows_sweep`], which needs no tabulation).
    pub fn eval_grid(mut self, phis: &[f64]) -> Vec<LobeValues> {
        let list = self.cull.then(|| PhiList::new(phis));
        let reads_rows = list
            .as_ref()
            .and_then(|l| l.grid.as_ref())
            .is_some_and(|g| self.row_steps(g).is_some());
        if phis.len() >= TABULATE_MIN_PHI && !reads_rows {
            self.tabulate_scattered();
        }
        match list {
            Some(l) => self.eval_list(&l),
            None => phis.iter().map(|&phi| self.eval(phi)).collect(),
        }
    }

    /// The width `beta_p` of unscattered lobe `p` and the half-width of the window of
    /// `Phi` around `phi` whose images are summed (the +-8.5 beta culling, or with culling
    /// off 40 beta + pi).
    fn image_window(&self, p: usize) -> (f64, f64) {
        let beta = self.betas[p];
        let w = if self.cull {
            CULL_SIGMAS * beta
        } else {
            // No culling: every segment, and images up to 40 sigma away.
            40.0 * beta + PI
        };
        (beta, w)
    }

    /// Add piece `pc`'s wrapped-Gaussian integral at azimuth `mu` (`phi` or `-phi` for the
    /// mirrored side) to `s`: every `2 pi` image of `mu` within `w` of the piece.
    fn add_piece(&self, pc: &Piece, mu: f64, beta: f64, w: f64, s: &mut f64) {
        let (lo, hi) = pc.range();
        let kmin = ((lo - w - mu) / TAU).ceil() as i64;
        let kmax = ((hi + w - mu) / TAU).floor() as i64;
        if kmax < kmin {
            return;
        }
        match pc {
            Piece::Phi { lo, len, c, lam } => {
                for k in kmin..=kmax {
                    let m = mu + TAU * k as f64 - lo;
                    *s += poly_gauss(c, lam, m, beta, *len);
                }
            }
            Piece::Gl { nodes, .. } => {
                if self.cull {
                    // Only the images inside the window (as for Phi pieces).
                    let norm = 1.0 / (beta * TAU.sqrt());
                    let inv2b2 = 0.5 / (beta * beta);
                    for k in kmin..=kmax {
                        let m = mu + TAU * k as f64;
                        for &(ph, wt) in nodes {
                            let y = ph - m;
                            *s += wt * norm * (-y * y * inv2b2).exp();
                        }
                    }
                } else {
                    for &(ph, wt) in nodes {
                        *s += wt * wrapped_gaussian(ph - mu, beta);
                    }
                }
            }
        }
    }

    /// Add the scattered lobes (TTs, TRTs) of `part` at wrapped `phi` to `out`.
    fn add_scattered(&self, part: &Part, phi: f64, out: &mut LobeValues) {
        let Some(med) = self.az.model.medulla() else {
            return;
        };
        for k in 0..2 {
            let mut s = 0.0;
            for node in &part.scat[k].nodes {
                let (d, m) = (wrap_angle(phi - node.phi), wrap_angle(phi + node.phi));
                // P_s is even in x and folded into `w`.
                let mut sh = 0.0;
                match &node.prof {
                    Some(pr) => {
                        if part.direct {
                            sh += pr.shape_clamped(d);
                        }
                        if part.mirror {
                            sh += pr.shape_clamped_mirror(m);
                        }
                    }
                    None => {
                        if part.direct {
                            sh += med.cn_shape_clamped(node.x_med, d);
                        }
                        if part.mirror {
                            sh += med.cn_shape_clamped(-node.x_med, m);
                        }
                    }
                }
                s += node.w * sh;
            }
            out.0[3 + k] += self.weight * s;
        }
        self.add_psi_pieces(part, phi, out);
    }

    /// Add the [`PsiPiece`]s of `part`'s scattered lobes at wrapped `phi` to `out`: the
    /// direct side reads the rows at `phi - Phi^s`, the mirrored side `C^N(-x, phi + Phi^s)`
    /// = `C^N(x, -phi - Phi^s)`.
    fn add_psi_pieces(&self, part: &Part, phi: f64, out: &mut LobeValues) {
        let Some(rows) = self.cn_rows() else {
            return;
        };
        for k in 0..2 {
            let pieces = &part.scat[k].psi;
            if pieces.is_empty() {
                continue;
            }
            let mut s = 0.0;
            for pc in pieces {
                for sign in part.signs() {
                    s += rows.integrate(pc.row, sign * phi - pc.phi_hi, pc.len, &pc.g);
                }
            }
            out.0[3 + k] += self.weight * s;
        }
    }

    /// The grid step in whole `psi` bins of the medulla table, when it is one (within
    /// [`PSI_SWEEP_SLACK`]): the scattered lobes are then read along the grid by
    /// [`Self::add_rows_sweep`].
    fn row_steps(&self, g: &UniformGrid) -> Option<i64> {
        let rows = self.cn_rows()?;
        let m = g.step / rows.bin_width();
        (m.round() >= 1.0 && (m - m.round()).abs() <= PSI_SWEEP_SLACK).then(|| m.round() as i64)
    }

    /// The scattered lobes of `part` ([`Self::add_scattered`]) along an evenly spaced
    /// sorted grid whose step is `m` whole `psi` bins ([`Self::row_steps`]; `out` indexed
    /// through `order`, `s` scratch of the grid's length). Moving along the grid moves
    /// every table query by `m` bins, so each [`PsiPiece`] is one weighting of the row
    /// nodes ([`CnRows::accumulate_piece`]) and each quadrature node one bilinear weighting
    /// ([`CnRows::accumulate_point`]); they are summed per row and read along the grid in
    /// one pass per direction ([`CnRows::correlate`]). The direct side reads
    /// `C^N(x, phi - Phi^s)`, the mirrored `C^N(-x, phi + Phi^s)`, and a query at a
    /// negative offset reads the row of `|x|` at `-psi`
    /// ([`crate::model::medulla::MedullaSlice::cn`]), which reverses its direction along
    /// the grid.
    fn add_rows_sweep(
        &self,
        part: &Part,
        g: &UniformGrid,
        m: i64,
        order: &[usize],
        s: &mut [f64],
        out: &mut [LobeValues],
    ) {
        let Some(rows) = self.cn_rows() else {
            return;
        };
        // Row weights read with steps +m and -m.
        let mut acc = [rows.row_weights(), rows.row_weights()];
        for k in 0..2 {
            let sn = &part.scat[k];
            if sn.psi.is_empty() && sn.nodes.is_empty() {
                continue;
            }
            acc.iter_mut().for_each(|a| a.clear());
            for sign in part.signs() {
                // psi at the first grid point: phi - phi_hi (direct), -phi - phi_hi (mirror).
                let a = &mut acc[(sign < 0.0) as usize];
                for pc in &sn.psi {
                    rows.accumulate_piece(a, pc.row, sign * g.first - pc.phi_hi, pc.len, &pc.g);
                }
                for node in &sn.nodes {
                    // The query's offset (the mirror's is -x, as in add_scattered) and
                    // its psi = phi - sign Phi^s, read flipped at a negative offset.
                    let x = sign * node.x_med;
                    let dir = if x.is_sign_negative() { -1.0 } else { 1.0 };
                    let psi0 = dir * (g.first - sign * node.phi);
                    rows.accumulate_point(&mut acc[(dir < 0.0) as usize], x, psi0, node.w);
                }
            }
            s.iter_mut().for_each(|x| *x = 0.0);
            for (a, step) in acc.iter().zip([m, -m]) {
                rows.correlate(a, step, s);
            }
            for (q, &i) in order.iter().enumerate() {
                out[i].0[3 + k] += self.weight * s[q];
            }
        }
    }

    /// Whether every scattered node of `part` has its `C^N` profile tabulated.
    fn scattered_tabulated(&self, part: &Part) -> bool {
        self.az.model.medulla().is_some()
            && part
                .scat
                .iter()
                .flat_map(|sn| &sn.nodes)
                .all(|n| n.prof.is_some())
    }

    /// [`Self::add_scattered`] for every `phi` of an evenly spaced sorted grid (`out`
    /// indexed through `order`, `s` scratch of the grid's length): each node's tabulated
    /// profile is read along the grid ([`CnProfile::shape_on_grid`]). Per `phi` the nodes
    /// are summed in the same order as `add_scattered`.
    fn add_scattered_sweep(
        &self,
        part: &Part,
        g: &UniformGrid,
        order: &[usize],
        s: &mut [f64],
        out: &mut [LobeValues],
    ) {
        let n = order.len();
        // Stays 0 when the part has no direct side.
        let mut direct = vec![0.0; n];
        for k in 0..2 {
            s.iter_mut().for_each(|x| *x = 0.0);
            for node in &part.scat[k].nodes {
                let pr = node.prof.as_ref().expect("tabulated (scattered_tabulated)");
                // P_s is even in x and folded into `w`; direct at phi - node.phi, mirror
                // at phi + node.phi (periodic: no wrap needed). A side that is off adds 0,
                // as in add_scattered.
                if part.direct {
                    pr.shape_on_grid(false, g.first - node.phi, g.step, n, |q, v| direct[q] = v);
                }
                if part.mirror {
                    pr.shape_on_grid(true, g.first + node.phi, g.step, n, |q, v| {
                        s[q] += node.w * (direct[q] + v)
                    });
                } else {
                    for (x, &d) in s.iter_mut().zip(&direct) {
                        *x += node.w * d;
                    }
                }
            }
            for (q, &i) in order.iter().enumerate() {
                out[i].0[3 + k] += self.weight * s[q];
            }
        }
    }

    /// `v` with the lobes outside this slice's set zeroed.
    fn keep_lobes(&self, mut v: LobeValues) -> LobeValues {
        for l in Lobe::ALL {
            if !self.lobes.contains(l) {
                v.set(l, 0.0);
            }
        }
        v
    }
}

/// Largest change of `Phi^s_p` across a scattered segment in tolerance mode
/// ([`FarOptions::scattered_step`] at `tol = 1e-4`, scaled by the cube root of the
/// tolerance ratio, clamped to [1/4.6, 4], i.e. to `tol` in [1e-6, 6.4e-3]: the lower
/// clamp bounds the piece count at tolerances below those the tests and reports use).
fn max_dps(opts: &FarOptions) -> f64 {
    let ratio = opts.tol.unwrap_or(1e-4) / 1e-4;
    opts.scattered_step * ratio.cbrt().clamp(0.01f64.cbrt(), 4.0)
}

/// A bound on a segment's fit error that its quarter-point checks cannot see: when the
/// log-attenuation departs from its fit by more than [`LAM_DEV_MAX`] there (`dev`), the
/// mass can hide between the check points (TT at kappa -> 1 and grazing theta_d:
/// `exp(-c sqrt(u_edge - u))` with c in the hundreds puts nearly all of it within 1e-5 of
/// the medulla edge, while the quarter points see ~e^-100 in both fit and integrand), and
/// the largest `value` over the five nodes bounds the error instead; else 0.
fn hidden_mass_bound(dev: f64, nodes: [&Node; 5], value: impl Fn(&Node) -> f64) -> f64 {
    if dev > LAM_DEV_MAX {
        nodes.iter().fold(0.0f64, |a, n| a.max(value(n)))
    } else {
        0.0
    }
}

/// A list of `phi` prepared for [`FarSlice::eval_many`]: wrapped to `[-pi, pi]`, the order
/// that sorts them (ties by index), the sorted values and their even spacing, if any.
struct PhiList {
    wrapped: Vec<f64>,
    order: Vec<usize>,
    sorted: Vec<f64>,
    grid: Option<UniformGrid>,
}

impl PhiList {
    fn new(phis: &[f64]) -> PhiList {
        let wrapped: Vec<f64> = phis.iter().map(|&phi| wrap_angle(phi)).collect();
        let mut order: Vec<usize> = (0..phis.len()).collect();
        order.sort_by(|&a, &b| wrapped[a].total_cmp(&wrapped[b]).then(a.cmp(&b)));
        let sorted: Vec<f64> = order.iter().map(|&i| wrapped[i]).collect();
        let grid = UniformGrid::detect(&sorted);
        PhiList {
            wrapped,
            order,
            sorted,
            grid,
        }
    }
}

/// `v` with negative rounding dips set to 0 (see [`FarSlice::eval`]).
fn clamp_dips(mut v: LobeValues) -> LobeValues {
    for x in v.0.iter_mut() {
        if *x < 0.0 {
            *x = 0.0;
        }
    }
    v
}

/// [`FarSlice::eval_many`] sweeps a quadrature-node piece along an even `phi` grid only
/// when the step is at most this many `beta`: the recurrence's ratio then stays below
/// `e^(SWEEP_MAX_STEP * CULL_SIGMAS + SWEEP_MAX_STEP^2 / 2)` = `e^42` (no overflow), and a
/// coarser grid puts at most a couple of `phi` in a node's window anyway.
const SWEEP_MAX_STEP: f64 = 4.0;

/// [`FourierGrid`] sums the series to the first `n` with `n beta >= FOURIER_REACH`: the
/// terms left out are below `exp(-FOURIER_REACH^2 / 2)` = 1e-17 of the mean.
const FOURIER_REACH: f64 = 8.85;
/// Most terms of a [`FourierGrid`] (beyond, the node sweep is cheaper for any grid).
const FOURIER_MAX_TERMS: usize = 256;
/// Nodes per block of [`FourierGrid::add`] (independent rotations, one vector lane each).
const FOURIER_LANES: usize = 4;

/// The wrapped-Gaussian sum of a lobe's nodes on an evenly spaced grid, in Fourier space:
/// `sum_k W_k sum_j G(Phi_k - phi + 2 pi j; beta)` is
/// `1/(2 pi) sum_k W_k (1 + 2 sum_{n>=1} rho_n cos n(Phi_k - phi))` with
/// `rho_n = exp(-n^2 beta^2 / 2)` (the Fourier series of the wrapped normal, Poisson
/// summation; [`wrapped_gaussian`] sums the same series at one point for `beta > 1.5`,
/// to the same 1e-17 term), so the nodes enter only through `A_n = sum_k W_k cos n Phi_k` and
/// `B_n = sum_k W_k sin n Phi_k`. For a wide lobe (fur: `beta_n` ~ 10-20 deg) the series
/// needs a few dozen terms while a node's Gaussian window covers the whole grid: per node
/// that is `n` complex rotations instead of two sides times the grid. It sums every image
/// (the culled sweep leaves out those beyond `CULL_SIGMAS`, below `e^-36` of a node's
/// peak), so the two agree far within 1e-12 of the lobe's peak.
struct FourierGrid {
    /// `rho_n`, `n = 0..terms`.
    rho: Vec<f64>,
}

/// `cos n phi_q` and `sin n phi_q` on a grid (`[n][q]`), shared by the lobes of a slice.
#[derive(Default)]
struct FourierTable {
    terms: usize,
    cos: Vec<f64>,
    sin: Vec<f64>,
}

impl FourierTable {
    /// Make the table hold at least `terms` rows for the `points` of `g`.
    fn reserve(&mut self, g: &UniformGrid, points: usize, terms: usize) {
        if self.terms >= terms {
            return;
        }
        self.cos = vec![0.0; terms * points];
        self.sin = vec![0.0; terms * points];
        for q in 0..points {
            let (si, co) = (g.first + q as f64 * g.step).sin_cos();
            let (mut re, mut im) = (1.0, 0.0);
            for n in 0..terms {
                self.cos[n * points + q] = re;
                self.sin[n * points + q] = im;
                (re, im) = (re * co - im * si, re * si + im * co);
            }
        }
        self.terms = terms;
    }
}

impl FourierGrid {
    /// `Some` when the series costs less than sweeping each node over its window on
    /// `points` grid points (`sides` 1 or 2; a complex rotation counted as two sweep steps).
    fn new(g: &UniformGrid, points: usize, beta: f64, w: f64, sides: usize) -> Option<Self> {
        let terms = (FOURIER_REACH / beta).ceil();
        let window = ((2.0 * w / g.step).floor() + 1.0).min(points as f64);
        if !(terms <= FOURIER_MAX_TERMS as f64 && 2.0 * terms < sides as f64 * window) {
            return None;
        }
        let rho = (0..=terms as usize)
            .map(|n| (-0.5 * (n as f64 * beta).powi(2)).exp())
            .collect();
        Some(FourierGrid { rho })
    }

    /// Add the sum over `nodes` `(Phi_k, W_k)` for the direct side (`G(Phi_k - phi)`) and
    /// the mirrored one (`G(Phi_k + phi)`) at every grid point of `table` to `s` (sorted
    /// order; `table` holds at least `self.rho.len()` rows).
    fn add(
        &self,
        nodes: &[(f64, f64)],
        (direct, mirror): (bool, bool),
        table: &FourierTable,
        s: &mut [f64],
    ) {
        if nodes.is_empty() || !(direct || mirror) {
            return;
        }
        let terms = self.rho.len();
        // A_n, B_n by rotation, z^n with z = exp(i Phi_k) (error ~n eps), in blocks of
        // FOURIER_LANES nodes with one partial sum per lane.
        const L: usize = FOURIER_LANES;
        let (mut a, mut b) = (vec![[0.0; L]; terms], vec![[0.0; L]; terms]);
        for block in nodes.chunks(L) {
            let (mut re, mut im, mut co, mut si) = ([0.0; L], [0.0; L], [1.0; L], [0.0; L]);
            for (j, &(ph, wt)) in block.iter().enumerate() {
                (si[j], co[j]) = ph.sin_cos();
                re[j] = wt;
            }
            for n in 0..terms {
                for j in 0..L {
                    a[n][j] += re[j];
                    b[n][j] += im[j];
                    (re[j], im[j]) = (re[j] * co[j] - im[j] * si[j], re[j] * si[j] + im[j] * co[j]);
                }
            }
        }
        // Direct + mirror: cos n(Phi - phi) + cos n(Phi + phi) = 2 cos n Phi cos n phi;
        // the sine parts carry the difference of the sides.
        let ca = (direct as u8 + mirror as u8) as f64;
        let cb = direct as u8 as f64 - mirror as u8 as f64;
        let points = s.len();
        for n in 0..terms {
            let f = if n == 0 { 1.0 } else { 2.0 * self.rho[n] } / TAU;
            let an = ca * f * a[n].iter().sum::<f64>();
            let bn = cb * f * b[n].iter().sum::<f64>();
            let row = n * points..(n + 1) * points;
            for (x, c) in s.iter_mut().zip(&table.cos[row.clone()]) {
                *x += an * c;
            }
            if bn != 0.0 {
                for (x, c) in s.iter_mut().zip(&table.sin[row]) {
                    *x += bn * c;
                }
            }
        }
    }
}

/// Points per run of the Gaussian recurrence before it restarts from exponentials: each
/// of its [`SWEEP_CHAINS`] chains takes `SWEEP_RUN / SWEEP_CHAINS` = 32 steps, whose drift
/// is ~`32^2 eps / 2` = 6e-14 relative, and the restart costs two exponentials per 128
/// points instead of 128.
const SWEEP_RUN: usize = 128;
/// Interleaved recurrence chains of a sweep run (see [`UniformGrid::gaussian_sweep`]).
const SWEEP_CHAINS: usize = 4;
/// Sweep runs whose starting exponentials [`UniformGrid::gaussian_sweep`] takes together
/// (a multiple of the 4 lanes of `f64x4`).
const SWEEP_BATCH: usize = 32;

/// Sorted `phi` that are evenly spaced: `first + q * step` within [`UNIFORM_SLACK`].
struct UniformGrid {
    first: f64,
    step: f64,
}

/// Largest deviation (radians) of a sorted grid from its arithmetic progression that still
/// counts as even: a grid of `to_radians` of even degree steps deviates by a few ulp
/// (~1e-15). A node's Gaussian then moves by `|y| dev / beta^2 <= 8.5 dev / beta` of itself
/// (1e-11 at `beta` = 0.1 deg), below the engine's 1e-4 tolerance by far.
const UNIFORM_SLACK: f64 = 1e-13;

/// Where a piece's node Gaussians are swept: images `mu = sign * phi + shift` for the
/// sorted `phi` in `qa..qb`, lobe width `beta`, window half-width `w`.
struct SweepWindow {
    sign: f64,
    shift: f64,
    qa: usize,
    qb: usize,
    beta: f64,
    w: f64,
}

impl UniformGrid {
    /// `Some` when `sorted` has at least three distinct, evenly spaced values.
    fn detect(sorted: &[f64]) -> Option<UniformGrid> {
        let n = sorted.len();
        if n < 3 {
            return None;
        }
        let (first, last) = (sorted[0], sorted[n - 1]);
        let step = (last - first) / (n - 1) as f64;
        if step <= 0.0 {
            return None;
        }
        sorted
            .iter()
            .enumerate()
            .all(|(q, &x)| (x - (first + q as f64 * step)).abs() <= UNIFORM_SLACK)
            .then_some(UniformGrid { first, step })
    }

    /// Add `sum_nodes wt G(ph - mu_q; beta)` to `s[q]` (sorted order) for every `q` of the window
    /// whose image `mu_q` lies within `w` of the node (beyond, a node's Gaussian is below
    /// `e^-36` of its peak, as [`FarSlice::add_piece`] would add). Along the grid
    /// `y_q = ph - mu_q` moves by `-sign * step`, so `G_{q+1} = G_q r_q` with
    /// `r_{q+1} = r_q exp(-step^2 / beta^2)`: two exponentials per run of [`SWEEP_RUN`]
    /// points instead of one per `phi`.
    fn gaussian_sweep(&self, nodes: &[(f64, f64)], at: &SweepWindow, s: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { self.gaussian_sweep_avx2(nodes, at, s) };
        }
        self.gaussian_sweep_body(nodes, at, s)
    }

    /// [`Self::gaussian_sweep`] compiled for AVX2 (wider vectors for the chains; the same
    /// operations in the same order, so the same values bit for bit).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn gaussian_sweep_avx2(&self, nodes: &[(f64, f64)], at: &SweepWindow, s: &mut [f64]) {
        self.gaussian_sweep_body(nodes, at, s)
    }

    #[inline(always)]
    fn gaussian_sweep_body(&self, nodes: &[(f64, f64)], at: &SweepWindow, s: &mut [f64]) {
        let c = 0.5 / (at.beta * at.beta);
        let norm = 1.0 / (at.beta * TAU.sqrt());
        let d = at.sign * self.step;
        let damp = (-2.0 * self.step * self.step * c).exp();
        let damp_s2 = damp.powi((SWEEP_CHAINS * SWEEP_CHAINS) as i32);
        let inv_step = 1.0 / self.step;
        // The runs (start, end, weight) and the exponents of their first value and ratio,
        // batched so that the exponentials are taken four at a time: a narrow lobe's
        // window holds ~10 points, so these two per run were most of a sweep.
        let mut runs = [(0usize, 0usize, 0.0f64); SWEEP_BATCH];
        let mut args = [[0.0f64; SWEEP_BATCH]; 2];
        let mut n = 0;
        for &(ph, wt) in nodes {
            // mu_q within w of ph: sign * x_q in [ph - shift - w, ph - shift + w].
            let (lo, hi) = (ph - at.shift - at.w, ph - at.shift + at.w);
            let (xlo, xhi) = if at.sign > 0.0 { (lo, hi) } else { (-hi, -lo) };
            let q0 = (((xlo - self.first) * inv_step).ceil().max(at.qa as f64)) as usize;
            let q1 = (((xhi - self.first) * inv_step).floor() + 1.0).min(at.qb as f64);
            if q1 <= q0 as f64 {
                continue;
            }
            let q1 = q1 as usize;
            // Restarted from the exact grid position every SWEEP_RUN points: `damp`'s
            // rounding compounds quadratically along a chain (n^2 eps / 2).
            for start in (q0..q1).step_by(SWEEP_RUN) {
                let mu = at.sign * (self.first + start as f64 * self.step) + at.shift;
                let y = ph - mu;
                // A ratio's exponent is at most c w^2 = 36 in magnitude where a run has
                // a second point (both within w = 8.5 beta of the node: sweeps run with
                // culling on); f64x4::exp's 0 above 708 (not inf) can only reach a ratio
                // that is never used.
                runs[n] = (start, (start + SWEEP_RUN).min(q1), wt);
                args[0][n] = -y * y * c;
                args[1][n] = (2.0 * y * d - self.step * self.step) * c;
                n += 1;
                if n == SWEEP_BATCH {
                    sweep_runs(&runs, &args, norm, [damp, damp_s2], s);
                    n = 0;
                }
            }
        }
        sweep_runs(&runs[..n], &args, norm, [damp, damp_s2], s);
    }
}

/// The recurrences of [`UniformGrid::gaussian_sweep`]'s batched `runs`: run `i` adds
/// `wt G_q` to `s[q]` for `q` in `start..end`, from `G_start = wt norm exp(args[0][i])`
/// with first ratio `exp(args[1][i])`, each ratio moving by `damp[0]` (`damp[1]` =
/// `damp[0]^(S^2)` along a chain). A function, not a closure, so that it is inlined into
/// the AVX2 build (a closure was compiled for the baseline target).
#[inline(always)]
fn sweep_runs(
    runs: &[(usize, usize, f64)],
    args: &[[f64; SWEEP_BATCH]; 2],
    norm: f64,
    [damp, damp_s2]: [f64; 2],
    s: &mut [f64],
) {
    let n = runs.len();
    let mut e = [[0.0f64; SWEEP_BATCH]; 2];
    for (ek, ak) in e.iter_mut().zip(args) {
        for (o, a) in ek[..n.next_multiple_of(4)]
            .chunks_exact_mut(4)
            .zip(ak.chunks_exact(4))
        {
            o.copy_from_slice(&f64x4::from([a[0], a[1], a[2], a[3]]).exp().to_array());
        }
    }
    for (i, &(start, end, wt)) in runs.iter().enumerate() {
        let mut g = wt * norm * e[0][i];
        let mut r = e[1][i];
        // SWEEP_CHAINS interleaved chains, chain k on points start + k + j S
        // (S = SWEEP_CHAINS): its multiplier is the product of S consecutive ratios, and
        // moves by damp^(S^2) per step. Independent chains keep the multiplier latency off
        // the critical path.
        let mut gs = [0.0; SWEEP_CHAINS];
        let mut ratios = [0.0; 2 * SWEEP_CHAINS - 1];
        for (k, rk) in ratios.iter_mut().enumerate() {
            if k < SWEEP_CHAINS {
                gs[k] = g;
                g *= r;
            }
            *rk = r;
            r *= damp;
        }
        // ratios[k] = r_{start + k}; chain k's multiplier is r_{start + k} ...
        // r_{start + k + S - 1}.
        let mut ps: [f64; SWEEP_CHAINS] =
            std::array::from_fn(|k| ratios[k..k + SWEEP_CHAINS].iter().product());
        let run = &mut s[start..end];
        let mut chunks = run.chunks_exact_mut(SWEEP_CHAINS);
        for chunk in &mut chunks {
            for k in 0..SWEEP_CHAINS {
                chunk[k] += gs[k];
                gs[k] *= ps[k];
                ps[k] *= damp_s2;
            }
        }
        for (x, gk) in chunks.into_remainder().iter_mut().zip(gs) {
            *x += gk;
        }
    }
}

/// How far (in bins) a grid step may be from a whole number of `psi` bins for
/// [`FarSlice::add_rows_sweep`]: over 360 points the positions then drift by under 4e-7 of
/// a bin, which moves a piece's integral (or a node's query) by that fraction of its value
/// at most.
const PSI_SWEEP_SLACK: f64 = 1e-9;

/// [`FarSlice::eval_grid`] tabulates the medulla table per scattered node from this many
/// `phi` on: a node's profile (one rank dot product per psi bin) costs about as much as
/// 60 rank-sum queries, and each `phi` makes about five queries per node.
const TABULATE_MIN_PHI: usize = 12;

/// Slack (radians) of [`FarSlice::eval_many`]'s candidate windows: far above the rounding
/// of `lo - w - mu` (~1e-15) and far below any window width, so it only adds candidates
/// whose own image test then rejects them.
const WINDOW_SLACK: f64 = 1e-9;

impl Piece {
    /// The `Phi` range the piece covers.
    fn range(&self) -> (f64, f64) {
        match self {
            Piece::Phi { lo, len, .. } => (*lo, lo + len),
            Piece::Gl { lo, hi, .. } => (*lo, *hi),
        }
    }
}

/// Breakpoints resolving the grazing Fresnel layer (tolerance mode only). For `eta' -> 1`
/// the cuticle reflectance `F` stays near 0 except where `cos u` is within a few
/// `w = sqrt(1 - 1/eta'^2)` (`cos gamma_t` at `h = 1`) of zero, where it climbs to 1: at
/// `eta = 1 + 1e-9` that layer is `4.5e-5` wide in `u` and holds all of R's mass, and the
/// initial segments' nodes (and so the mass estimate and the fit checks) never see it.
/// A geometric mesh `u = pi/2 - w 2^k / 4` up to `pi/2 - 0.05` resolves it; for ordinary
/// `eta'` (`w > 0.2`) it adds nothing.
///
/// Few cuticle layers make a second such layer: the pile-of-plates `F = l f / (1 + (l -
/// 1) f)` passes 1/2 where `1 - f ~ l`, i.e. within about `l w` of grazing in `u`, and
/// below that `F ~ l f / (1 - f)` is small, so at `l = 5e-6` most of R sits in a layer
/// 1e-6 wide (R was 1.4e-4 of its peak off at `phi = pi`; accuracy search, 2026-11-28).
/// Below [`L_LAYER_MAX`] the mesh starts at `l w / 4` instead.
fn fresnel_layer_u(eta_prime: f64, l: f64) -> Vec<f64> {
    let w = (1.0 - 1.0 / (eta_prime * eta_prime)).max(0.0).sqrt();
    let mut out = Vec::new();
    // Few cuticle layers narrow the layer in proportion (see the doc above).
    let narrow = if l < L_LAYER_MAX { l } else { 1.0 };
    let mut d = (0.25 * w * narrow).max(1e-9);
    while d < 0.05 {
        out.push(FRAC_PI_2 - d);
        d *= 2.0;
    }
    out
}

/// Breakpoints (in `h`) resolving the layer inside the medulla edge where its extinction
/// is steep (tolerance mode only). Paths through the medulla lose `exp(-c s_m)` with
/// `c` up to `4 sigma_m_t / cos theta_d` (TRT), and scattered ones gain
/// `1 - exp(-2 sigma_m_s s_m)`; the medulla chord `s_m = sqrt(kappa^2 - sin^2 gamma_t)`
/// falls to 0 at the edge as a square root, so for `c kappa` in the hundreds all of TRTs'
/// mass sits within ~`1 / c^2` of the edge in `h` (2e-6 at `tau = 200`). No initial node
/// saw it, the mass estimate and the fit checks read zeros, and TRTs came out 10 orders
/// low (black-box audit, 2026-11-28). A geometric mesh `s_m = kappa 2^-k` down to
/// `c s_m = 1/2` resolves it; below [`MEDULLA_LAYER_MIN`] (every preset and shipped fit
/// short of grazing `theta_d`) it adds nothing.
pub(super) fn medulla_layer_h(az: &AzimuthalSlice) -> Vec<f64> {
    let ab = &az.absorption;
    let kappa = ab.kappa;
    let c = (4.0 * ab.sigma_m_t * ab.inv_cos_d).max(2.0 * (ab.sigma_m_t - ab.sigma_m_a));
    let mut out = Vec::new();
    // NaN (an infinite sigma times a zero chord) adds nothing either.
    if c * kappa <= MEDULLA_LAYER_MIN || c.is_nan() || kappa <= 0.0 {
        return out;
    }
    let mut s_m = 0.5 * kappa;
    while c * s_m > 0.5 && out.len() < 200 {
        let sin_t = (kappa * kappa - s_m * s_m).max(0.0).sqrt();
        out.push(az.eta_prime * sin_t);
        s_m *= 0.5;
    }
    out
}

fn to_u(hs: &[f64], ha: f64, hb: f64) -> Vec<f64> {
    hs.iter()
        .filter(|&&h| h >= ha && h <= hb)
        .map(|&h| h.clamp(0.0, 1.0).asin().min(FRAC_PI_2))
        .collect()
}

fn sort_dedup(v: &mut Vec<f64>, lo: f64, hi: f64) {
    v.retain(|&u| u >= lo && u <= hi);
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v.dedup_by(|a, b| (*a - *b).abs() < 1e-15);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::quadrature::adaptive_gk;
    use crate::model::FurModel;
    use crate::params::FurParams;

    /// `lam_fit`: paper mode keeps the Appendix's chord; tolerance mode's quadratic passes
    /// through all three nodes, and where its curvature is capped, still through the end
    /// nodes. Interpolation is exact up to rounding of the node values' size (1e-12
    /// absolute on exponents of order 1-10).
    #[test]
    fn lam_fit_is_the_chord_or_the_capped_quadratic() {
        let m = FurModel::new(&FurParams::preset("cat").expect("preset"));
        let az = m.azimuthal(0.2);
        let tol = FarSlice::far(&az, LobeSet::ALL, &FarOptions::default());
        let paper = FarSlice::far(&az, LobeSet::ALL, &FarOptions::paper());
        let p = 1;
        let nodes = [0.1, 0.3, 0.5].map(|u| tol.node_with(u, false));
        let mut ns = [&nodes[0], &nodes[1], &nodes[2]];
        if nodes[0].dphi[p] < 0.0 {
            ns.reverse();
        }
        let lo = ns[0].phi[p];
        let xs = ns.map(|n| n.phi[p] - lo);
        let at = |lam: &[f64; 3], k: usize| poly(lam, xs[k]) - ns[k].lam[p];
        let chord = paper.lam_fit(p, xs, ns);
        assert_eq!(chord[2], 0.0);
        let quad = tol.lam_fit(p, xs, ns);
        // The medulla's chord bends cat's TT attenuation: the line misses the middle node.
        assert!(at(&chord, 1).abs() > 1e-4, "{}", at(&chord, 1));
        for k in 0..3 {
            assert!(at(&chord, k).abs() <= 1e-12 || k == 1);
            assert!(at(&quad, k).abs() <= 1e-12, "node {k}: {}", at(&quad, k));
        }
        // A Gaussian so wide that the cap binds: the end nodes still fit exactly.
        // (Here the attenuation is convex, curvature 3.8 per rad^2.)
        assert!(quad[2] > 1.0, "{quad:?}");
        let mut wide = FarSlice::far(&az, LobeSet::ALL, &FarOptions::default());
        let cap = 0.5 * quad[2];
        wide.betas[p] = (super::super::closed_form::LAM_CURVE_MAX * 0.5 / cap).sqrt();
        let capped = wide.lam_fit(p, xs, ns);
        assert!((capped[2] - cap).abs() <= 1e-12 * cap, "{capped:?}");
        for k in [0, 2] {
            assert!(
                at(&capped, k).abs() <= 1e-12,
                "node {k}: {}",
                at(&capped, k)
            );
        }
    }

    /// [`FarSlice::gl_piece_with`]'s estimate (the 16- and 8-point rules' difference at the
    /// probes) must bound the 16-point rule's actual error at the probes, measured against
    /// adaptive Gauss-Kronrod to 1e-12, on pieces up to the [`GL_SPAN_SIGMAS`] span that
    /// narrow pieces have (2.5 beta, a margin for the end nodes), and must not claim 1e-4
    /// on a piece far too wide for the rules. Human TT and TRT at theta_d = 0.3 from u = 0.3:
    /// pieces up to du = 0.1 are smooth (errors at rounding level); wider ones straddle
    /// the medulla edge (u = 0.453), whose kink in the attenuation the rules cannot
    /// integrate exactly, and there the estimate must still hold.
    #[test]
    fn gl_estimate_bounds_the_rule_error() {
        let m = FurModel::new(&FurParams::preset("human").expect("preset"));
        let az = m.azimuthal(0.3);
        let fs = FarSlice::far(&az, LobeSet::ALL, &FarOptions::default());
        let mut kinked = 0;
        for p in [1, 2] {
            let beta = fs.betas[p];
            let gauss = |x: f64| (-0.5 * (x / beta).powi(2)).exp() / (beta * TAU.sqrt());
            for du in [0.005, 0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.2] {
                let (u0, u1) = (0.3, 0.3 + du);
                let (n0, n1) = (fs.node_with(u0, true), fs.node_with(u1, true));
                let (lo, hi) = (n0.phi[p].min(n1.phi[p]), n0.phi[p].max(n1.phi[p]));
                let (piece, err) =
                    fs.gl_piece_with(p, &n0, &n1, lo, hi, false, true, &mut Tape::Off);
                let Piece::Gl { nodes, .. } = &piece else {
                    panic!("not a GL piece")
                };
                let (plo, phi) = piece.range();
                let mid = 0.5 * (plo + phi);
                let (mut actual, mut peak) = (0.0f64, 0.0f64);
                for k in GL_FEW_PROBES {
                    let at = mid + k * beta;
                    let rule: f64 = nodes.iter().map(|&(ph, w)| w * gauss(ph - at)).sum();
                    let exact = adaptive_gk(
                        |u| {
                            let n = fs.node_with(u, false);
                            n.pre[p] * n.lam[p].exp() * gauss(n.phi[p] - at)
                        },
                        &[u0, u1],
                        1e-12,
                        0.0,
                        100_000,
                    )
                    .value;
                    actual = actual.max((rule - exact).abs());
                    peak = peak.max(exact.abs());
                }
                let span = (phi - plo) / beta;
                if span <= 1.25 * GL_SPAN_SIGMAS {
                    if actual > 1e-6 * peak {
                        kinked += 1;
                    }
                    assert!(
                        actual <= err + 1e-12 * peak,
                        "p {p} span {span:.2} beta: error {actual:.2e} above estimate {err:.2e}"
                    );
                }
                if span > 4.0 {
                    assert!(
                        err > 1e-4 * peak,
                        "p {p} span {span:.2} beta: estimate {err:.2e}"
                    );
                }
            }
        }
        // The kink makes errors the estimate has to catch (TT at du 0.2, 0.4; TRT at 0.2).
        assert!(
            kinked >= 3,
            "only {kinked} pieces with errors above rounding"
        );
    }

    /// The AVX2 build of the sweep must give the portable build's values bit for bit (the
    /// dispatch picks one by CPU; results may not depend on the machine), on long runs
    /// (restarts), short windows, both signs and a shifted image.
    #[test]
    fn gaussian_sweep_avx2_equals_portable_build() {
        let sorted: Vec<f64> = (0..361).map(|q| -PI + q as f64 * TAU / 360.0).collect();
        let g = UniformGrid::detect(&sorted).expect("even grid");
        let nodes: Vec<(f64, f64)> = (0..37)
            .map(|k| (-3.0 + 0.17 * k as f64, 1.0 + 0.01 * k as f64))
            .collect();
        for (beta, sign, shift) in [(0.3, 1.0, 0.0), (0.05, -1.0, 0.0), (0.5, 1.0, TAU)] {
            let at = SweepWindow {
                sign,
                shift,
                qa: 0,
                qb: sorted.len(),
                beta,
                w: CULL_SIGMAS * beta,
            };
            let mut portable = vec![0.0; sorted.len()];
            g.gaussian_sweep_body(&nodes, &at, &mut portable);
            let mut chosen = vec![0.0; sorted.len()];
            g.gaussian_sweep(&nodes, &at, &mut chosen);
            assert!(portable.iter().any(|&v| v > 0.0));
            for (a, b) in portable.iter().zip(&chosen) {
                assert_eq!(a.to_bits(), b.to_bits(), "beta {beta} sign {sign}");
            }
        }
    }

    /// The Fourier sum of node Gaussians equals the wrapped Gaussians summed directly, for
    /// either side alone and both, at widths where it is chosen; it is not chosen for a
    /// narrow lobe, whose window covers a few grid points.
    #[test]
    fn fourier_grid_equals_wrapped_gaussian_sums() {
        let sorted: Vec<f64> = (0..91).map(|q| q as f64 * PI / 90.0).collect();
        let g = UniformGrid::detect(&sorted).expect("even grid");
        let nodes: Vec<(f64, f64)> = (0..23)
            .map(|k| (-2.9 + 0.41 * k as f64, 0.2 + 0.05 * (k % 7) as f64))
            .collect();
        let mut table = FourierTable::default();
        for beta in [0.2, 0.5, 1.3, 2.5] {
            let f = FourierGrid::new(&g, sorted.len(), beta, CULL_SIGMAS * beta, 2)
                .expect("a wide lobe takes the series");
            table.reserve(&g, sorted.len(), f.rho.len());
            for sides in [(true, false), (false, true), (true, true)] {
                let mut s = vec![0.0; sorted.len()];
                f.add(&nodes, sides, &table, &mut s);
                let scale: f64 = nodes.iter().map(|n| n.1).sum::<f64>() / (beta * TAU.sqrt());
                for (q, &phi) in sorted.iter().enumerate() {
                    let direct: f64 = nodes
                        .iter()
                        .map(|&(ph, w)| {
                            let d = if sides.0 {
                                wrapped_gaussian(ph - phi, beta)
                            } else {
                                0.0
                            };
                            let m = if sides.1 {
                                wrapped_gaussian(ph + phi, beta)
                            } else {
                                0.0
                            };
                            w * (d + m)
                        })
                        .sum();
                    // Truncation is 1e-17 of the mean; rounding grows with the terms
                    // (up to 45 here) times eps of the nodes' summed peak.
                    assert!(
                        (s[q] - direct).abs() <= 1e-13 * scale,
                        "beta {beta} sides {sides:?} phi {phi}: {} vs {direct}",
                        s[q]
                    );
                }
            }
        }
        // Human hair's R lobe (beta_n 3.75 deg): 136 terms against a 33-point window.
        let beta = 3.75f64.to_radians();
        assert!(FourierGrid::new(&g, sorted.len(), beta, CULL_SIGMAS * beta, 2).is_none());
    }

    /// The misfit integral of a quartic is exact (the quartic through five points is
    /// itself), whatever the nodes' order and spacing.
    #[test]
    fn misfit_integral_is_exact_for_quartics() {
        let f = |x: f64| 0.3 - 1.1 * x + 0.7 * x * x + 2.0 * x.powi(3) - 1.5 * x.powi(4);
        for s in [[0.0, 0.5, 1.0], [0.9, 0.35, 0.1], [2.0, 2.3, 3.1]] {
            let c = quadratic_through(s, s.map(f));
            let quarter = [0.25, 0.75].map(|t| {
                let x = s[0] + t * (s[2] - s[0]);
                (x, f(x) - poly(&c, x))
            });
            let est = FarSlice::misfit_integral(s, quarter);
            // Reference: 40-point Gauss-Legendre of f - quadratic over the nodes' range.
            let (lo, hi) = (s[0].min(s[2]), s[0].max(s[2]));
            let gl = crate::model::quadrature::GaussLegendre::cached(40);
            let exact: f64 = gl
                .nodes
                .iter()
                .zip(&gl.weights)
                .map(|(x, w)| {
                    let u = 0.5 * (lo + hi) + 0.5 * (hi - lo) * x;
                    0.5 * (hi - lo) * w * (f(u) - poly(&c, u))
                })
                .sum();
            // Both exact up to rounding of terms of order 1.
            assert!((est - exact).abs() < 1e-12, "{s:?}: {est} vs {exact}");
            assert!(exact.abs() > 1e-4, "the case must have a misfit to measure");
        }
    }
}
