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
use super::options::FarOptions;
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
    /// Closed-form segments of the unscattered lobes (`Phi` pieces of R, TT, TRT).
    pub unscattered_segments: usize,
    /// Gauss-Legendre segments of the unscattered lobes (where no closed form holds).
    pub gl_segments: usize,
    /// Gauss-Legendre nodes over those segments (each a Gaussian every `phi` pays for).
    pub gl_nodes: usize,
    /// Segments of the scattered lobes TTs, TRTs.
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
    /// Closed-form pieces: `Phi` pieces (R, TT, TRT) or segments (TTs, TRTs).
    pub closed_form: usize,
    /// Gauss-Legendre pieces (unscattered lobes only).
    pub gl_segments: usize,
    /// Gauss-Legendre nodes over those pieces.
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

pub(super) mod build;
mod eval;
mod segments;
mod sweep;
#[cfg(test)]
mod tests;
