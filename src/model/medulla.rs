//! PLACEHOLDER until the `tables` branch lands (the Monte Carlo + CP-ALS medulla tables).
//! It has the final API; its values are a crude smooth stand-in (NOT the physics): do not
//! write tests against these numbers.
#[derive(Clone, Debug)]
pub struct MedullaTables;
#[derive(Clone, Debug)]
pub struct MedullaSlice {
    tau: f64,
}
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Front,
    Back,
}
impl MedullaTables {
    pub fn builtin() -> &'static MedullaTables {
        static T: MedullaTables = MedullaTables;
        &T
    }
    pub fn slice(&self, tau: f64, _g: f64) -> MedullaSlice {
        MedullaSlice { tau }
    }
}
impl MedullaSlice {
    pub fn scattered_fraction(&self, x: f64) -> f64 {
        1.0 - (-2.0 * self.tau * (1.0 - x * x).max(0.0).sqrt()).exp()
    }
    pub fn cn(&self, x: f64, psi: f64) -> f64 {
        self.scattered_fraction(x) * (1.0 - psi.cos()) / (2.0 * std::f64::consts::PI)
    }
    pub fn cm(&self, _theta_i: f64, theta_r: f64, _side: Side) -> f64 {
        theta_r.cos() / 2.0
    }
    pub fn cm_lerp(&self, theta_i: f64, theta_r: f64, _phi: f64) -> f64 {
        self.cm(theta_i, theta_r, Side::Front)
    }
}
