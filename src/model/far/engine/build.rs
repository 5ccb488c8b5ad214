//! Building a slice: the constructors, the segmentation, node values and masses.

use super::eval::max_dps;
use super::*;

/// The plan of one part of a slice ([`FarSlice::plan_parts`]): whether it is the direct
/// and/or the mirrored side, its multiplicity (1 or 2), and the initial boundaries in `u`
/// of the unscattered lobes, of TRT and of the scattered lobes.
type PartPlan = (bool, bool, f64, Vec<f64>, Vec<f64>, Vec<f64>);

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

    pub(super) fn range_with(
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
    pub(super) fn build(
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
    pub(super) fn build_taped(
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
        let plans = fs.plan_parts(opts, ranges);
        // Lobe scales for the tolerance budget: sum over parts of mult * integral A dh
        // (adaptive Simpson in u from the initial segments, see [`FarSlice::mass`]).
        let memo = NodeMemo::new();
        let (node_cache, mass) = fs.initial_nodes(&memo, &plans, opts.tol.is_some());
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

    /// The initial boundaries (in `u`) of each of `ranges`' parts, per lobe family: the
    /// unscattered lobes' (`h_i = sqrt(i/n)`, the medulla edge, in tolerance mode the
    /// medulla and Fresnel layers), TRT's (those and the TRT caustic) and the scattered
    /// lobes' (`h_i = h_max sqrt(i/n)` on the offsets that reach the medulla).
    fn plan_parts(&self, opts: &FarOptions, ranges: &[(f64, f64, bool, bool)]) -> Vec<PartPlan> {
        let az = &self.az;
        let lobes = self.lobes;
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
                if let (Some(rows), true) = (self.cn_rows(), opts.tol.is_some()) {
                    hs.extend(rows.x_nodes().iter().map(|&x| x * edge));
                }
                hs.extend(&layer);
                us_s = to_u(&hs, ha, hb.min(hmax));
                sort_dedup(&mut us_s, ha.asin(), hb.min(hmax).asin());
            }
            plans.push((direct, mirror, mult, us, us_trt, us_s));
        }
        plans
    }

    /// The nodes (segment ends and midpoints) of every plan's three families, and in
    /// tolerance mode (`tol_mode`) the lobe scales for the budget: per lobe the sum over
    /// parts of `mult` times its mass ([`FarSlice::mass`]).
    #[allow(clippy::type_complexity)]
    fn initial_nodes(
        &self,
        memo: &NodeMemo,
        plans: &[PartPlan],
        tol_mode: bool,
    ) -> (Vec<(Vec<Node>, Vec<Node>, Vec<Node>)>, [f64; 5]) {
        let fs = self;
        let lobes = self.lobes;
        let mut node_cache: Vec<(Vec<Node>, Vec<Node>, Vec<Node>)> = Vec::new();
        let mut mass = [0.0f64; 5];
        for (_, _, mult, us, us_trt, us_s) in plans {
            // The unscattered families' nodes skip the scattered values (they read only
            // their own lobe's).
            let mk = |v: &Vec<f64>, scattered: bool| -> Vec<Node> {
                let mut out = Vec::with_capacity(2 * v.len());
                for w in v.windows(2) {
                    out.push(fs.node_memo(memo, w[0], scattered));
                    out.push(fs.node_memo(memo, 0.5 * (w[0] + w[1]), scattered));
                }
                if let Some(&last) = v.last() {
                    out.push(fs.node_memo(memo, last, scattered));
                }
                out
            };
            let (a, b, c) = (mk(us, false), mk(us_trt, false), mk(us_s, true));
            if tol_mode {
                let fam = [
                    (&a, lobes.intersect(LobeSet::only(Lobe::R).with(Lobe::TT))),
                    (&b, lobes.intersect(LobeSet::only(Lobe::TRT))),
                    (&c, lobes.intersect(LobeSet::SCATTERED)),
                ];
                for (nodes, set) in fam {
                    let m = fs.mass(memo, nodes, set);
                    for l in set.iter() {
                        mass[l.index()] += mult * m[l.index()];
                    }
                }
            }
            node_cache.push((a, b, c));
        }
        (node_cache, mass)
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
    pub(super) fn peak_rescale(
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
    pub(super) fn node(&self, memo: &NodeMemo, u: f64) -> Node {
        self.node_memo(memo, u, true)
    }

    /// [`Self::node_with`] through the build's memo.
    pub(super) fn node_memo(&self, memo: &NodeMemo, u: f64, scattered: bool) -> Node {
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
    pub(super) fn node_with(&self, u: f64, scattered: bool) -> Node {
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
    pub(super) fn unsc_pre(p: usize, f: f64, cu: f64) -> f64 {
        azimuthal::a_p_cuticle(p, f) * cu
    }

    /// The log of `T_c T_m` of unscattered lobe `p` (seed Eq. 14; 0 for R), clamped at
    /// [`LAM_MIN`].
    pub(super) fn unsc_lam(p: usize, geo: &PathGeometry, ab: &Absorption) -> f64 {
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
    pub(super) fn lam_fit(&self, p: usize, xs: [f64; 3], nodes: [&Node; 3]) -> [f64; 3] {
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
    pub(super) fn gl_node(&self, p: usize, u: f64) -> (f64, f64, f64) {
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
    pub(super) fn g_exact(n: &Node, p: usize) -> f64 {
        n.pre[p] * n.lam[p].exp() / n.dphi[p].abs()
    }

    /// The integrand of a lobe's mass `integral A dh = integral A cos u du` at a node
    /// (scattered lobes: times the scattered fraction).
    pub(super) fn density(n: &Node, l: Lobe) -> f64 {
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
    pub(super) fn mass(&self, memo: &NodeMemo, nodes: &[Node], set: LobeSet) -> [f64; 5] {
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
}

impl Piece {
    /// The `Phi` range the piece covers.
    pub(super) fn range(&self) -> (f64, f64) {
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
pub(super) fn fresnel_layer_u(eta_prime: f64, l: f64) -> Vec<f64> {
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
pub(crate) fn medulla_layer_h(az: &AzimuthalSlice) -> Vec<f64> {
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

pub(super) fn to_u(hs: &[f64], ha: f64, hb: f64) -> Vec<f64> {
    hs.iter()
        .filter(|&&h| h >= ha && h <= hb)
        .map(|&h| h.clamp(0.0, 1.0).asin().min(FRAC_PI_2))
        .collect()
}

pub(super) fn sort_dedup(v: &mut Vec<f64>, lo: f64, hi: f64) {
    v.retain(|&u| u >= lo && u <= hi);
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v.dedup_by(|a, b| (*a - *b).abs() < 1e-15);
}
