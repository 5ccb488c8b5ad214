//! Evaluating a built slice at one `phi`, a list or an even grid.

use super::sweep::{
    FourierGrid, FourierTable, SweepWindow, UniformGrid, PSI_SWEEP_SLACK, SWEEP_MAX_STEP,
    TABULATE_MIN_PHI, WINDOW_SLACK,
};
use super::*;

impl<'a> FarSlice<'a> {
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
    pub(super) fn eval_list(&self, list: &PhiList) -> Vec<LobeValues> {
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
                        self.add_piece_side(
                            pc,
                            sign,
                            sorted,
                            grid.as_ref(),
                            (beta, w),
                            (phi_swept, &phi_nodes),
                            &mut s,
                        );
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

    /// Add one unscattered piece `pc` at `mu = sign phi` to the sums `s` of the sorted
    /// `phi`: every image `k` whose window (`beta`, half-width `w`) can reach them, by
    /// node sweeps along an even `grid` (for a Phi piece when `phi_swept`, through its
    /// node form `phi_nodes`) or one `phi` at a time ([`Self::add_piece`]).
    #[allow(clippy::too_many_arguments)]
    fn add_piece_side(
        &self,
        pc: &Piece,
        sign: f64,
        sorted: &[f64],
        grid: Option<&UniformGrid>,
        (beta, w): (f64, f64),
        (phi_swept, phi_nodes): (bool, &[(f64, f64)]),
        s: &mut [f64],
    ) {
        let (lo, hi) = pc.range();
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
            (Piece::Gl { nodes, .. }, Some(g)) if g.step <= SWEEP_MAX_STEP * beta => {
                Some((nodes.as_slice(), g))
            }
            (Piece::Phi { .. }, Some(g)) if phi_swept => Some((phi_nodes, g)),
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
                    images(TAU * k as f64, 0, sorted.len(), s);
                }
            } else {
                visit(0, sorted.len(), s);
            }
            return;
        }

        let k0 = ((lo - w - PI) / TAU).floor() as i64 - 1;
        let k1 = ((hi + w + PI) / TAU).ceil() as i64 + 1;
        for k in k0..=k1 {
            let shift = TAU * k as f64;
            let (a, b) = (lo - w - shift - WINDOW_SLACK, hi + w - shift + WINDOW_SLACK);
            let (a, b) = if sign > 0.0 { (a, b) } else { (-b, -a) };
            if b < -PI || a > PI {
                continue;
            }
            let qa = sorted.partition_point(|&x| x < a);
            let qb = sorted.partition_point(|&x| x <= b);
            images(shift, qa, qb, s);
        }
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
    pub(super) fn image_window(&self, p: usize) -> (f64, f64) {
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
    pub(super) fn add_piece(&self, pc: &Piece, mu: f64, beta: f64, w: f64, s: &mut f64) {
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
    pub(super) fn add_scattered(&self, part: &Part, phi: f64, out: &mut LobeValues) {
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
    pub(super) fn add_psi_pieces(&self, part: &Part, phi: f64, out: &mut LobeValues) {
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
    pub(super) fn row_steps(&self, g: &UniformGrid) -> Option<i64> {
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
    pub(super) fn add_rows_sweep(
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
    pub(super) fn scattered_tabulated(&self, part: &Part) -> bool {
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
    pub(super) fn add_scattered_sweep(
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
    pub(super) fn keep_lobes(&self, mut v: LobeValues) -> LobeValues {
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
pub(super) fn max_dps(opts: &FarOptions) -> f64 {
    let ratio = opts.tol.unwrap_or(1e-4) / 1e-4;
    opts.scattered_step * ratio.cbrt().clamp(0.01f64.cbrt(), 4.0)
}

/// A bound on a segment's fit error that its quarter-point checks cannot see: when the
/// log-attenuation departs from its fit by more than [`LAM_DEV_MAX`] there (`dev`), the
/// mass can hide between the check points (TT at kappa -> 1 and grazing theta_d:
/// `exp(-c sqrt(u_edge - u))` with c in the hundreds puts nearly all of it within 1e-5 of
/// the medulla edge, while the quarter points see ~e^-100 in both fit and integrand), and
/// the largest `value` over the five nodes bounds the error instead; else 0.
pub(super) fn hidden_mass_bound(dev: f64, nodes: [&Node; 5], value: impl Fn(&Node) -> f64) -> f64 {
    if dev > LAM_DEV_MAX {
        nodes.iter().fold(0.0f64, |a, n| a.max(value(n)))
    } else {
        0.0
    }
}

/// A list of `phi` prepared for [`FarSlice::eval_many`]: wrapped to `[-pi, pi]`, the order
/// that sorts them (ties by index), the sorted values and their even spacing, if any.
pub(super) struct PhiList {
    wrapped: Vec<f64>,
    order: Vec<usize>,
    sorted: Vec<f64>,
    grid: Option<UniformGrid>,
}

impl PhiList {
    pub(super) fn new(phis: &[f64]) -> PhiList {
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
pub(super) fn clamp_dips(mut v: LobeValues) -> LobeValues {
    for x in v.0.iter_mut() {
        if *x < 0.0 {
            *x = 0.0;
        }
    }
    v
}
