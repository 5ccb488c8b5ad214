//! Goniometric fiber profiles: the in-memory [`Profile`] and its loaders and writers
//! (CSV per DATA.md, `.npy`/`.npz` dense grids, the Yan-2015 text format).
//!
//! Angles are stored in **degrees**, exactly as read, so that a profile round-trips through
//! every format bit for bit; use [`Sample::angles_rad`] to get the radians the model needs.

use std::path::PathBuf;

/// One goniometer sample: light from `theta_i`, camera at `(theta_r, phi)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Incident inclination, degrees.
    pub theta_i: f64,
    /// Outgoing inclination, degrees.
    pub theta_r: f64,
    /// Relative azimuth `phi_r - phi_i`, degrees in (-180, 180].
    pub phi: f64,
    /// Measured linear intensity; `<= 0` or NaN marks an invalid sample (DATA.md).
    pub value: f64,
    /// Standard error of `value`, if known.
    pub sigma: Option<f64>,
    /// Index into [`Profile::channels`] (0 when the profile has a single channel).
    pub channel: usize,
    /// Optional absolute incident azimuth, degrees (kept for round trips, unused by the model).
    pub phi_i: Option<f64>,
}

impl Sample {
    /// A sample with usable signal: finite and strictly positive.
    pub fn is_valid(&self) -> bool {
        self.value.is_finite() && self.value > 0.0
    }

    /// `(theta_i, theta_r, phi)` in radians.
    pub fn angles_rad(&self) -> (f64, f64, f64) {
        (
            self.theta_i.to_radians(),
            self.theta_r.to_radians(),
            self.phi.to_radians(),
        )
    }
}

/// A goniometric profile: samples plus the file's metadata.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Profile {
    pub samples: Vec<Sample>,
    /// Channel names (`r`, `g`, `b`, `650nm` ...). Empty means one unnamed channel.
    pub channels: Vec<String>,
    /// `# key: value` metadata, in file order.
    pub metadata: Vec<(String, String)>,
    /// Where the profile was read from, if anywhere.
    pub source: Option<PathBuf>,
}

impl Profile {
    /// Number of valid samples.
    pub fn n_valid(&self) -> usize {
        self.samples.iter().filter(|s| s.is_valid()).count()
    }

    /// Number of invalid samples (kept, never used in a logarithm).
    pub fn n_invalid(&self) -> usize {
        self.samples.len() - self.n_valid()
    }

    /// Number of channels (at least 1).
    pub fn n_channels(&self) -> usize {
        self.channels.len().max(1)
    }

    /// First metadata value for `key`.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Set (replace or append) a metadata entry.
    pub fn set_meta(&mut self, key: &str, value: impl Into<String>) {
        let value = value.into();
        match self.metadata.iter_mut().find(|(k, _)| k == key) {
            Some(e) => e.1 = value,
            None => self.metadata.push((key.to_string(), value)),
        }
    }

    /// Does the profile say it is synthetic (metadata `synthetic: true` or
    /// `source: synthetic...`)?
    pub fn is_synthetic(&self) -> bool {
        self.meta("synthetic")
            .map(|v| v.eq_ignore_ascii_case("true") || v.eq_ignore_ascii_case("yes"))
            .unwrap_or(false)
            || self
                .meta("source")
                .map(|v| v.to_ascii_lowercase().contains("synthetic"))
                .unwrap_or(false)
    }
}
