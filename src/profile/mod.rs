//! Goniometric fiber profiles: the in-memory [`Profile`] and its loaders and writers
//! (CSV per DATA.md, `.npy`/`.npz` dense grids, the Yan-2015 text format).
//!
//! Angles are stored in **degrees**, exactly as read (unless [`LoadOptions`] asks for a
//! convention conversion, or a phi written outside (-180, 180] is wrapped into it), so that a
//! profile round-trips through every format bit for bit; use [`Sample::angles_rad`] to get
//! the radians the model needs.
//!
//! Entry points: [`load`] / [`load_full`] pick the reader by extension ([`csv`], [`npz`]
//! for `.npz` and lone `.npy`, [`yan`] for `.txt`/`.dat`), [`save`] writes `.csv` or `.npz`
//! atomically, [`load_dir`] reads and [`merge`]s a species folder (skipping, with a note,
//! a `.txt`/`.dat` that is not a Yan-2015 profile, e.g. `notes.txt`: [`looks_like_yan`]).
//! [`summary`] computes what `furfit inspect` prints.
//!
//! Choices shared by every reader (each documented again in its module):
//! - angles are normalised once: `-0` -> `0`, and any finite phi in [-360, 360] (files
//!   written in [0, 360) are common) is converted by the [`LoadOptions`] conventions and
//!   wrapped to MODEL.md's (-180, 180] (`-180` -> `180`, `270` -> `-90`) by one function,
//!   [`read_phi`], so one direction has one spelling whatever the format;
//! - a repeated direction (same `theta_i, theta_r, phi, channel`) whose other fields are
//!   identical is collapsed into its first occurrence with a note in [`Loaded::notes`]; a
//!   repeat that differs is an error naming both places (and, when the two were written
//!   with different phi that wrap alike, e.g. a sweep's 0 and 360, saying so:
//!   [`wrap_conflict`]);
//! - invalid values (NaN, `<= 0`) are kept as samples, never dropped; two of them for one
//!   direction (NaN and -1 at a sweep's two ends) are one invalid sample, collapsed;
//! - a file whose every angle lies within +-3.2 (not all 0), or whose thetas lie within
//!   +-pi/2 and phi within +-2 pi, gets a warning note: the values look like radians, but
//!   files hold degrees ([`radians_warning`]);
//! - text echoed from a file in a message is [`crate::text::escaped`] (a BOM, a NUL), and
//!   a number below the f64 range (`1e-400`) is an error like one above it
//!   ([`crate::text::parse_number`]).
//!
//! Rooms: [`sample`] holds the types, [`checks`] the per-value rules and angle
//! conventions, [`label`] the synthetic/measured label ([`crate::text`] reads numbers and quotes text),
//! [`merge`] merging and duplicates, [`load`] the by-extension entry points; one module per
//! format ([`csv`], [`npz`], [`yan`]); [`provenance`] a folder's `metadata.json`;
//! [`summary`] what `furfit inspect` prints. Everything is re-exported here, so callers
//! name `profile::Profile`, `profile::load` and so on.

mod checks;
mod label;
mod load;
mod merge;
mod sample;

pub mod csv;
pub mod npz;
pub mod provenance;
pub mod summary;
pub mod yan;

pub use checks::*;
pub use label::*;
pub use load::*;
pub use merge::*;
pub use sample::*;

#[cfg(test)]
mod tests;
