//! Dense-grid profiles: `.npz` archives and lone `.npy` arrays (NumPy formats, read and
//! written with `ndarray-npy`).
//!
//! # Arrays in a furfit `.npz`
//! | name | dtype | shape | meaning |
//! |---|---|---|---|
//! | `theta_i` | float64 or integer | `[I]` | incident inclinations, degrees, in [-90, 90] (required) |
//! | `theta_r` | float64 or integer | `[R]` | outgoing inclinations, degrees, in [-90, 90] (required) |
//! | `phi` | float64 or integer | `[P]` | relative azimuths, degrees, in [-360, 360] (required) |
//! | `value` | float64 | `[I, R, P]` or `[I, R, P, C]` | intensity; NaN = missing (required) |
//! | `present` | uint8 (or bool) | same as `value` | 1 = a sample exists at this cell, 0 = none (optional) |
//! | `sigma` | float64 | same as `value` | standard error; NaN = none (optional) |
//! | `phi_i` | float64 | same as `value` | absolute incident azimuth, degrees in [-360, 360]; NaN = none (optional) |
//! | `meta_json` | uint8 | `[n]` | UTF-8 JSON `{"metadata": [[key, value], ...], "channels": [name, ...]}` (optional; the text's bytes, `np.frombuffer(s.encode(), np.uint8)`) |
//!
//! float32 arrays are accepted too and widened to float64; a float32 axis is read as the
//! shortest decimal that names each element (`np.float32(0.1)` as 0.1, not
//! 0.10000000149011612), the grid the file was written for, so it matches a CSV of the same
//! angles instead of doubling every direction. The three axes may also be any integer dtype
//! (NumPy's `np.array([0, 15, 30])` is int64), converted to float64.
//!
//! A cell is a sample when `present` is 1 (any value but 0 and 1 is an error naming the
//! first such cell's index); without `present`, when `value` is not NaN. A sample's value, sigma and phi_i (NaN decoded as "none" for the latter two) obey
//! the CSV reader's rules ([`super::check_measured`]): an infinite `value`, a negative or
//! infinite `sigma` or a `phi_i` outside [-360, 360] is an error naming the array and the cell's
//! index; only cells that are samples are checked. The `present` mask is what lets a sparse CSV profile, including its invalid NaN
//! samples, round trip exactly: the writer always writes it, and stores invalid values as
//! they are (a negative value stays negative, NaN stays NaN). Channel names come from
//! `meta_json` (`channels` must then have `C` entries for a 4-D `value`, at most one for a
//! 3-D one; none may be empty, as in CSV); a 4-D `value` without names gets the names `"0"`,
//! `"1"`, ..., except a single channel (`[I, R, P, 1]`, NumPy's trailing singleton axis),
//! which stays unnamed like the same data shaped `[I, R, P]`, so the two merge. The writer
//! writes a 3-D `value` for a profile without channel names, 4-D otherwise.
//!
//! Axis values are normalised as in the CSV reader (`-0` -> `0`; phi, any finite value in
//! [-360, 360], converted by the [`super::LoadOptions`] conventions and wrapped to
//! (-180, 180] by [`super::read_phi`], so `np.arange(0, 360, 5.)` reads). Two cells that
//! land on the same direction (a phi axis holding both 0 and 360 or -180 and 180, or a
//! repeated axis value) are duplicates: identical ones are collapsed (with a note),
//! different ones are an error naming both cells (with as many indices as `value` has axes;
//! a wrap's pair on the `phi` array, saying so). Samples come out in grid order (`theta_i`,
//! `theta_r`, `phi`, channel, in array order); the writer sorts each axis ascending, so a
//! written-and-reloaded profile is in [`super::Profile::sort_grid_order`] order.
//!
//! Before an array is decoded its header is checked against the bytes actually present, so
//! a truncated or corrupt array is an error naming it (never a huge allocation or a panic);
//! an array larger than 512 MiB uncompressed, or of more than 20 M cells (a profile's
//! memory: ~190 bytes a sample), is refused from its header. Archives from `numpy.savez` and
//! `numpy.savez_compressed` (deflate) are both read; the writer stores arrays uncompressed
//! (NumPy reads them with `numpy.load`). Checked by hand with NumPy 2.4:
//! `np.savez(f, theta_i=ti, theta_r=tr, phi=ph, value=v)` loads, and `np.load` reads what
//! [`to_bytes`] writes, `meta_json` decoding with `json.loads(bytes(z["meta_json"]))`.
//!
//! # A lone `.npy`
//! A `.npy` file holds only `value` (3-D or 4-D, float64/float32, NaN = missing); its three
//! axes must be given as grids in [`super::LoadOptions`] (`--theta-i`, `--theta-r`,
//! `--phi` on the command line) and their lengths must match the array's shape.
//!
//! Files: [`npy`] reads and checks single arrays, [`read`] turns an archive or a lone
//! `.npy` into a profile, [`write`] encodes one.

mod npy;
mod read;
mod write;

pub use read::*;
pub use write::*;

#[cfg(test)]
mod tests;
