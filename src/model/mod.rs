//! The 5-lobe fur BCSDF of the seed paper (Sections 3-5): unscattered lobes R, TT, TRT and
//! medulla-scattered lobes TTs, TRTs, with the conventions of MODEL.md.
//!
//! [`FurModel`] is built once per parameter set and is the one copy of the physics used by
//! the fitter, profile synthesis and the renderer. Per lobe it gives `M_p` (longitudinal,
//! [`longitudinal`]) and `N_p` (azimuthal: near field in [`azimuthal`], far field and
//! multi-scale integrate the same near-field terms over `h`). The value a goniometer sample
//! predicts is `k * sum_p M_p N_p` (MODEL.md).
//!
//! Energy: with `kappa = 0`, no absorption and `l = 1`, the attenuations of all path orders
//! sum to 1 (`F + (1-F)^2 sum_p F^(p-1) = 1`); truncating at p = 2 loses `(1-F) F^2`, which
//! averaged over `h` at `theta_d = 0` is 0.29 % of the incident energy at `eta = 1.2`,
//! 0.76 % at `eta = 1.55` and 1.8 % at `eta = 2.0` (tested in `tests.rs`).
//!
//! Symmetries the model has (tested): `N(h, phi) = N(-h, -phi)` for every lobe, and
//! reciprocity of R, TT, TRT under `theta_i <-> theta_r`. The scattered lobes are not
//! reciprocal: `C^M` is a Monte Carlo table for light entering at `theta_i`.

pub mod azimuthal;
pub mod cp;
pub mod far;
pub mod fresnel;
pub mod geometry;
pub mod grid_plan;
pub mod longitudinal;
pub mod medulla;
pub mod medulla_mc;
pub mod multiscale;
pub mod quadrature;

use crate::params::FurParams;
use azimuthal::Absorption;
use geometry::PathGeometry;
use medulla::{MedullaSlice, MedullaTables};

/// The five lobes, in the order used by [`LobeValues`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Lobe {
    /// Primary reflection at the cuticle (path order p = 0).
    R = 0,
    /// Transmission through the fiber without medulla scattering (p = 1).
    TT = 1,
    /// Transmission, one internal reflection, transmission, unscattered (p = 2).
    TRT = 2,
    /// TT light scattered in the medulla (seed Sec. 4.3).
    TTs = 3,
    /// TRT light scattered in the medulla.
    TRTs = 4,
}

impl Lobe {
    /// All five lobes in [`LobeValues`] order.
    pub const ALL: [Lobe; 5] = [Lobe::R, Lobe::TT, Lobe::TRT, Lobe::TTs, Lobe::TRTs];

    /// Path order p: R 0, TT and TTs 1, TRT and TRTs 2.
    pub fn p(self) -> usize {
        match self {
            Lobe::R => 0,
            Lobe::TT | Lobe::TTs => 1,
            Lobe::TRT | Lobe::TRTs => 2,
        }
    }

    /// Is this a medulla-scattered lobe?
    pub fn is_scattered(self) -> bool {
        matches!(self, Lobe::TTs | Lobe::TRTs)
    }

    /// Position in [`Lobe::ALL`] (the [`LobeValues`] index).
    pub fn index(self) -> usize {
        self as usize
    }

    /// The lobe's name as files and the command line spell it (`R`, `TT`, `TRT`, `TTs`,
    /// `TRTs`).
    pub fn name(self) -> &'static str {
        match self {
            Lobe::R => "R",
            Lobe::TT => "TT",
            Lobe::TRT => "TRT",
            Lobe::TTs => "TTs",
            Lobe::TRTs => "TRTs",
        }
    }

    /// Parse a lobe name (case-insensitive).
    pub fn from_name(s: &str) -> Option<Lobe> {
        Lobe::ALL
            .into_iter()
            .find(|l| l.name().eq_ignore_ascii_case(s.trim()))
    }
}

/// A subset of the five lobes (bit i = [`Lobe::ALL`]\[i\]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LobeSet(pub u8);

impl LobeSet {
    /// All five lobes.
    pub const ALL: LobeSet = LobeSet(0b11111);
    /// The unscattered lobes R, TT, TRT.
    pub const UNSCATTERED: LobeSet = LobeSet(0b00111);
    /// The medulla-scattered lobes TTs, TRTs.
    pub const SCATTERED: LobeSet = LobeSet(0b11000);
    /// No lobe.
    pub const NONE: LobeSet = LobeSet(0);

    /// The set holding `l` alone.
    pub fn only(l: Lobe) -> LobeSet {
        LobeSet(1 << l.index())
    }

    /// Whether `l` is in the set.
    pub fn contains(self, l: Lobe) -> bool {
        self.0 & (1 << l.index()) != 0
    }

    /// The set with `l` added.
    pub fn with(self, l: Lobe) -> LobeSet {
        LobeSet(self.0 | (1 << l.index()))
    }

    /// The lobes in both sets.
    pub fn intersect(self, o: LobeSet) -> LobeSet {
        LobeSet(self.0 & o.0)
    }

    /// Whether the set holds no lobe.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The lobes of the set in [`Lobe::ALL`] order.
    pub fn iter(self) -> impl Iterator<Item = Lobe> {
        Lobe::ALL.into_iter().filter(move |l| self.contains(*l))
    }

    /// Parse `R,TT,TRT,TTs,TRTs` (or `all`), each lobe at most once.
    pub fn parse(s: &str) -> crate::Result<LobeSet> {
        if s.trim().eq_ignore_ascii_case("all") {
            return Ok(LobeSet::ALL);
        }
        let mut set = LobeSet::NONE;
        for part in s.split(',') {
            if part.trim().eq_ignore_ascii_case("all") {
                return Err(crate::Error::Invalid(format!(
                    "lobes '{s}': 'all' stands alone (it already includes every lobe)"
                )));
            }
            let l = Lobe::from_name(part).ok_or_else(|| {
                crate::Error::Invalid(format!(
                    "unknown lobe '{}' (expected R, TT, TRT, TTs, TRTs or all)",
                    part.trim()
                ))
            })?;
            // Refused like a repeated --modes entry: a repeat is most likely a typo for
            // another lobe.
            if set.contains(l) {
                return Err(crate::Error::Invalid(format!(
                    "lobes '{s}': {} given twice",
                    l.name()
                )));
            }
            set = set.with(l);
        }
        Ok(set)
    }
}

/// One value per lobe, indexed by [`Lobe`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LobeValues(pub [f64; 5]);

impl LobeValues {
    /// The value of lobe `l`.
    pub fn get(&self, l: Lobe) -> f64 {
        self.0[l.index()]
    }

    /// Set the value of lobe `l`.
    pub fn set(&mut self, l: Lobe, v: f64) {
        self.0[l.index()] = v;
    }

    /// Sum over the five lobes (the total BCSDF value).
    pub fn sum(&self) -> f64 {
        self.0.iter().sum()
    }

    /// Element-wise product.
    pub fn mul(&self, o: &LobeValues) -> LobeValues {
        let mut r = *self;
        for i in 0..5 {
            r.0[i] *= o.0[i];
        }
        r
    }
}

impl std::ops::Index<Lobe> for LobeValues {
    type Output = f64;
    fn index(&self, l: Lobe) -> &f64 {
        &self.0[l.index()]
    }
}

/// Whether light can scatter in the medulla (`kappa > 0` and `sigma_m_s > 0`): only then
/// do the scattered lobes and their medulla table slice exist.
fn scatters(params: &FurParams) -> bool {
    params.kappa > 0.0 && params.sigma_m_s > 0.0
}

/// The fur BCSDF for one parameter set, with everything that depends only on the
/// parameters precomputed (the `tau`/`g` slice of the medulla tables).
#[derive(Clone, Debug)]
pub struct FurModel {
    /// The parameters the model was built for (internal units).
    pub params: FurParams,
    /// `None` when no scattered lobe can exist (`kappa = 0` or `sigma_m_s = 0`): then the
    /// whole scattered path is skipped and TTs/TRTs are exactly zero.
    medulla: Option<MedullaSlice>,
}

/// Smallest roughness `beta_m`, `beta_n` (radians) the model evaluates, 1e-7 rad
/// (6e-6 deg, far below any goniometer's resolution): inside the hard bounds `(0, ...]`,
/// widths down to 1e-160 deg made `x / beta` and `1 / beta^2` overflow into NaN
/// (black-box audit, 2026-11-28). [`FurModel::with_tables`] floors them;
/// [`FurModel::model_notes`] says so.
pub const MIN_WIDTH: f64 = 1e-7;

impl FurModel {
    /// Build the model with the shipped medulla tables. `params` must already be validated
    /// (see [`FurParams::validate`]).
    pub fn new(params: &FurParams) -> FurModel {
        FurModel::with_tables(params, MedullaTables::builtin())
    }

    /// Build the model with the given medulla tables.
    pub fn with_tables(params: &FurParams, tables: &MedullaTables) -> FurModel {
        let medulla = if scatters(params) {
            Some(tables.slice(params.sigma_m_s * params.kappa, params.g))
        } else {
            None
        };
        let mut params = *params;
        params.beta_m = params.beta_m.max(MIN_WIDTH);
        params.beta_n = params.beta_n.max(MIN_WIDTH);
        FurModel { params, medulla }
    }

    /// Notes on how the model reads these parameters: where they leave the shipped medulla
    /// tables' `(tau, g)` range ([`MedullaTables::domain_notes`]; none when no scattered
    /// lobe exists), and a roughness below [`MIN_WIDTH`].
    pub fn model_notes(params: &FurParams) -> Vec<String> {
        let mut out = if scatters(params) {
            MedullaTables::builtin().domain_notes(params.sigma_m_s * params.kappa, params.g)
        } else {
            Vec::new()
        };
        for (name, v) in [("beta_m", params.beta_m), ("beta_n", params.beta_n)] {
            if v < MIN_WIDTH {
                out.push(format!(
                    "{name} = {} deg is below {} deg: the model evaluates it at that width \
                     (a narrower Gaussian is a spike no grid resolves, and its arithmetic overflows)",
                    crate::error::Num(v.to_degrees()),
                    crate::error::Num(MIN_WIDTH.to_degrees())
                ));
            }
        }
        out
    }

    /// Do the scattered lobes exist for these parameters?
    pub fn has_scattered(&self) -> bool {
        self.medulla.is_some()
    }

    /// The lobes that can be non-zero for these parameters (TTs/TRTs left out when
    /// `kappa = 0` or `sigma_m_s = 0`).
    pub fn active_lobes(&self) -> LobeSet {
        if self.has_scattered() {
            LobeSet::ALL
        } else {
            LobeSet::UNSCATTERED
        }
    }

    /// The lobes whose azimuthal term `N_p` (near or far field) can change when parameter
    /// `id` changes. `alpha` and `beta_m` enter only `M_p` (seed Eq. 5, Table 2), `g`
    /// only the medulla tables of TTs/TRTs (Eqs. 18-19) and `beta_n` only the width of the
    /// unscattered lobes' `D_p` (Eq. 7; the scattered lobes' `D^s_p` is the table's `C^N`,
    /// Eq. 10, and the far field reads `beta_p` only in the R, TT and TRT builders); every
    /// other parameter reaches all five lobes through `eta'`, the path geometry or the
    /// attenuations. The fitter's finite differences use this to reuse the unchanged
    /// terms (bit for bit: test `reused_terms_equal_full_evaluation`).
    pub fn azimuthal_dependence(id: crate::params::ParamId) -> LobeSet {
        use crate::params::ParamId;
        match id {
            ParamId::Alpha | ParamId::BetaM => LobeSet::NONE,
            ParamId::G => LobeSet::SCATTERED,
            ParamId::BetaN => LobeSet::UNSCATTERED,
            _ => LobeSet::ALL,
        }
    }

    /// The medulla table slice for these parameters, if scattered lobes exist.
    pub fn medulla(&self) -> Option<&MedullaSlice> {
        self.medulla.as_ref()
    }

    /// Longitudinal lobes for all five lobes: `M_p(theta_i, theta_r)` for R, TT, TRT (seed
    /// Eq. 5, Table 2) and `M_s(theta_i, theta_r, phi)` for TTs and TRTs (seed Eq. 19).
    pub fn longitudinal(&self, theta_i: f64, theta_r: f64, phi: f64, lobes: LobeSet) -> LobeValues {
        let p = &self.params;
        let mut m = LobeValues::default();
        for l in [Lobe::R, Lobe::TT, Lobe::TRT] {
            if lobes.contains(l) {
                m.set(
                    l,
                    longitudinal::m_p(l.p(), theta_i, theta_r, p.alpha, p.beta_m),
                );
            }
        }
        if let Some(med) = &self.medulla {
            if lobes.contains(Lobe::TTs) || lobes.contains(Lobe::TRTs) {
                let ms = med.cm_lerp(theta_i, theta_r, phi);
                m.set(Lobe::TTs, ms);
                m.set(Lobe::TRTs, ms);
            }
        }
        m
    }

    /// The front and back `C^M` values of seed Eq. 19 at `(theta_i, theta_r)` (`None`
    /// without a medulla): [`medulla::front_back_lerp`] of them at `phi` is the scattered
    /// lobes' `M_s`, so a grid can query the tables once per theta pair.
    pub fn scattered_longitudinal_sides(&self, theta_i: f64, theta_r: f64) -> Option<(f64, f64)> {
        self.medulla.as_ref().map(|m| {
            (
                m.cm(theta_i, theta_r, medulla::Side::Front),
                m.cm(theta_i, theta_r, medulla::Side::Back),
            )
        })
    }

    /// The azimuthal model at one `theta_d` (everything that depends on `theta_d` only).
    pub fn azimuthal(&self, theta_d: f64) -> AzimuthalSlice<'_> {
        let p = &self.params;
        let cos_d = theta_d.cos().max(geometry::MIN_COS_THETA_D);
        AzimuthalSlice {
            model: self,
            cos_theta_d: cos_d,
            eta_prime: geometry::eta_prime(p.eta, cos_d),
            absorption: Absorption {
                sigma_c_a: p.sigma_c_a,
                sigma_m_t: p.sigma_m_a + p.sigma_m_s,
                sigma_m_a: p.sigma_m_a,
                kappa: p.kappa,
                inv_cos_d: 1.0 / cos_d,
            },
        }
    }

    /// Near-field BCSDF per lobe at offset `h`: `M_p(theta_i, theta_r) N_p(h, phi)` for the
    /// lobes in `lobes` (others 0). Summed over lobes this is what a goniometer sample
    /// predicts before the exposure `k` (MODEL.md).
    pub fn eval_near(
        &self,
        theta_i: f64,
        theta_r: f64,
        phi: f64,
        h: f64,
        lobes: LobeSet,
    ) -> LobeValues {
        let lobes = lobes.intersect(self.active_lobes());
        let m = self.longitudinal(theta_i, theta_r, phi, lobes);
        let n = self
            .azimuthal(geometry::theta_d(theta_i, theta_r))
            .near(h, phi, lobes);
        m.mul(&n)
    }
}

/// The azimuthal part of the model at a fixed `theta_d`.
#[derive(Clone, Copy, Debug)]
pub struct AzimuthalSlice<'a> {
    /// The model the slice evaluates.
    pub model: &'a FurModel,
    /// `cos theta_d`, `theta_d = (theta_r - theta_i) / 2` the longitudinal difference
    /// angle.
    pub cos_theta_d: f64,
    /// Bravais index `eta'` (seed Eq. 3).
    pub eta_prime: f64,
    /// Absorption coefficients and the path elongation at this `theta_d`.
    pub absorption: Absorption,
}

impl AzimuthalSlice<'_> {
    /// Path geometry for entry offset `h`.
    pub fn geometry(&self, h: f64) -> PathGeometry {
        PathGeometry::new(h, self.eta_prime, self.model.params.kappa)
    }

    /// [`Self::geometry`] at `gamma_i = u` ([`PathGeometry::at_gamma_i`]).
    pub fn geometry_at_gamma_i(&self, u: f64) -> PathGeometry {
        PathGeometry::at_gamma_i(u, self.eta_prime, self.model.params.kappa)
    }

    /// Layered cuticle reflectance `F(eta', gamma_i, l)` at this path.
    pub fn cuticle(&self, geo: &PathGeometry) -> f64 {
        fresnel::cuticle_reflectance(self.eta_prime, geo.cos_gamma_i, self.model.params.l)
    }

    /// Attenuation `A_p(h)` (R, TT, TRT; seed Eqs. 13-14) and `A^s_p(h)` (TTs, TRTs; Eq. 20)
    /// for the lobes in `lobes`.
    pub fn attenuation(&self, geo: &PathGeometry, lobes: LobeSet) -> LobeValues {
        self.attenuation_with(self.cuticle(geo), geo, lobes)
    }

    /// [`Self::attenuation`] with the cuticle reflectance `f` = [`Self::cuticle`] given
    /// (models that differ only in absorption share it).
    pub fn attenuation_with(&self, f: f64, geo: &PathGeometry, lobes: LobeSet) -> LobeValues {
        let mut a = LobeValues::default();
        for l in lobes.intersect(self.model.active_lobes()).iter() {
            let v = if l.is_scattered() {
                azimuthal::a_s_p(l.p(), f, geo, &self.absorption)
            } else {
                azimuthal::a_p(l.p(), f, geo, &self.absorption)
            };
            a.set(l, v);
        }
        a
    }

    /// Azimuthal distribution of lobe `l` at this path: `D_p` (Eq. 7) or `D^s_p = C^N`
    /// (Eq. 10). Zero for scattered lobes when they do not exist.
    pub fn distribution(&self, l: Lobe, geo: &PathGeometry, phi: f64) -> f64 {
        if l.is_scattered() {
            match &self.model.medulla {
                Some(med) => {
                    let x = azimuthal::medulla_offset(geo, self.model.params.kappa);
                    med.cn(x, azimuthal::psi_s_p(l.p(), geo, phi))
                }
                None => 0.0,
            }
        } else {
            azimuthal::d_p(l.p(), geo, phi, self.model.params.beta_n)
        }
    }

    /// Near-field azimuthal scattering `N_p(h, phi) = A_p(h) D_p(h, phi)` (Eqs. 6, 9) for
    /// the lobes in `lobes`.
    pub fn near(&self, h: f64, phi: f64, lobes: LobeSet) -> LobeValues {
        self.near_at(&self.geometry(h), phi, lobes)
    }

    /// [`Self::near`] on a path given by its geometry (e.g. [`Self::geometry_at_gamma_i`]).
    pub fn near_at(&self, geo: &PathGeometry, phi: f64, lobes: LobeSet) -> LobeValues {
        let mut n = self.attenuation(geo, lobes);
        for l in Lobe::ALL {
            if n.get(l) != 0.0 {
                n.set(l, n.get(l) * self.distribution(l, geo, phi));
            }
        }
        n
    }
}

#[cfg(test)]
mod tests;
