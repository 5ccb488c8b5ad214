//! The 5-lobe fur fiber BCSDF (seed paper Sections 3-5).
pub mod cp;
pub mod medulla;
pub mod medulla_mc;
