//! Fitting and refining the segments of the unscattered and scattered lobes.

use super::eval::hidden_mass_bound;
use super::sweep::WINDOW_SLACK;
use super::*;

impl<'a> FarSlice<'a> {
    /// Fit one unscattered segment `[n0, n1]` (midpoint `nm`) of lobe `p`, bisecting as the
    /// tolerance budget in `rf` demands (see the module doc).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn build_unsc(
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
    pub(super) fn phi_bounds(&self, p: usize, n0: &Node, n1: &Node) -> (f64, f64) {
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
    pub(super) fn reaches(&self, p: usize, n0: &Node, n1: &Node, rf: &Refine) -> bool {
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
    pub(super) fn build_narrow(
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
    pub(super) fn gl_piece(
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
    pub(super) fn gl_piece_with(
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
    pub(super) fn gl_nodes(&self, p: usize, u0: f64, u1: f64, count: usize) -> GlNodes {
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
    pub(super) fn cn_rows(&self) -> Option<CnRows<'a>> {
        self.az.model.medulla().map(|m| m.cn_rows())
    }

    /// A scattered segment in tolerance mode: a [`PsiPiece`] where `Phi^s` is monotone
    /// with a bounded slope ratio (bisected until the densities' quadratics are within
    /// budget), else bisected until it spans at most one `psi` bin, where the node
    /// quadrature of [`Self::build_scat`] takes over (near a `Phi^s` caustic of TRTs).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn build_psi(
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
    pub(super) fn misfit_integral(s: [f64; 3], quarter: [(f64, f64); 2]) -> f64 {
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
    pub(super) fn build_scat(
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
}
