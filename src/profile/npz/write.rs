//! A [`Profile`] written as a furfit `.npz` ([`to_bytes`]).

use crate::error::{Error, Result};
use crate::profile::sample::{Profile, Sample};
use ndarray::{ArrayD, IxDyn};
use ndarray_npy::NpzWriter;
use std::io::Cursor;

/// Largest grid (cells) the writer produces; a sparser profile should be saved as CSV.
const MAX_WRITE_CELLS: usize = 50_000_000;

/// Sorted distinct values of one angle over the samples.
fn axis_of(profile: &Profile, get: impl Fn(&Sample) -> f64) -> Result<Vec<f64>> {
    let mut v: Vec<f64> = Vec::with_capacity(profile.samples.len());
    for s in &profile.samples {
        let a = get(s);
        if !a.is_finite() {
            return Err(Error::Invalid(format!(
                "cannot write npz: a sample has a non-finite angle ({a})"
            )));
        }
        v.push(a + 0.0);
    }
    v.sort_by(f64::total_cmp);
    v.dedup_by(|a, b| a.to_bits() == b.to_bits());
    Ok(v)
}

/// Encode a profile as a furfit `.npz` (see the module doc); uncompressed, with fixed zip
/// timestamps, so the same profile always gives the same bytes.
pub fn to_bytes(profile: &Profile) -> Result<Vec<u8>> {
    let ax = [
        axis_of(profile, |s| s.theta_i)?,
        axis_of(profile, |s| s.theta_r)?,
        axis_of(profile, |s| s.phi)?,
    ];
    let nc = profile.n_channels();
    let four = !profile.channels.is_empty();
    let mut shape = vec![ax[0].len(), ax[1].len(), ax[2].len()];
    if four {
        shape.push(nc);
    }
    let cells = shape
        .iter()
        .try_fold(1usize, |a, &n| a.checked_mul(n))
        .filter(|n| *n <= MAX_WRITE_CELLS)
        .ok_or_else(|| {
            Error::Invalid(format!(
                "grid {shape:?} too large for npz (limit {MAX_WRITE_CELLS} cells); save as .csv"
            ))
        })?;
    let _ = cells;
    let mut value = ArrayD::<f64>::from_elem(IxDyn(&shape), f64::NAN);
    let mut present = ArrayD::<u8>::zeros(IxDyn(&shape));
    let mut sigma = ArrayD::<f64>::from_elem(IxDyn(&shape), f64::NAN);
    let mut phi_i = ArrayD::<f64>::from_elem(IxDyn(&shape), f64::NAN);
    let find = |a: &[f64], v: f64| a.binary_search_by(|x| x.total_cmp(&(v + 0.0))).unwrap_or(0);
    for s in &profile.samples {
        if s.channel >= nc {
            return Err(Error::Invalid(format!(
                "cannot write npz: sample channel {} out of range ({nc} channels)",
                s.channel
            )));
        }
        let mut ix = vec![
            find(&ax[0], s.theta_i),
            find(&ax[1], s.theta_r),
            find(&ax[2], s.phi),
        ];
        if four {
            ix.push(s.channel);
        }
        let ix = IxDyn(&ix);
        if present[&ix] != 0 {
            return Err(Error::Invalid(format!(
                "cannot write npz: two samples share the grid cell theta_i {}, theta_r {}, phi {}{}",
                s.theta_i,
                s.theta_r,
                s.phi,
                // By name, as a loader's duplicate error names it.
                profile
                    .channels
                    .get(s.channel)
                    .map(|n| format!(", channel {n}"))
                    .unwrap_or_default()
            )));
        }
        present[&ix] = 1;
        value[&ix] = s.value;
        if let Some(x) = s.sigma {
            sigma[&ix] = x;
        }
        if let Some(x) = s.phi_i {
            phi_i[&ix] = x;
        }
    }
    let meta = serde_json::json!({
        "metadata": profile.metadata,
        "channels": profile.channels,
    });
    let meta = serde_json::to_vec(&meta)
        .map_err(|e| Error::Invalid(format!("cannot encode npz metadata: {e}")))?;
    let werr = |e: ndarray_npy::WriteNpzError| Error::Invalid(format!("writing npz: {e}"));
    let mut w = NpzWriter::new(Cursor::new(Vec::new()));
    for (name, a) in [("theta_i", &ax[0]), ("theta_r", &ax[1]), ("phi", &ax[2])] {
        w.add_array(name, &ndarray::Array1::from(a.clone()))
            .map_err(werr)?;
    }
    w.add_array("value", &value).map_err(werr)?;
    w.add_array("present", &present).map_err(werr)?;
    if profile.samples.iter().any(|s| s.sigma.is_some()) {
        w.add_array("sigma", &sigma).map_err(werr)?;
    }
    if profile.samples.iter().any(|s| s.phi_i.is_some()) {
        w.add_array("phi_i", &phi_i).map_err(werr)?;
    }
    w.add_array("meta_json", &ndarray::Array1::from(meta))
        .map_err(werr)?;
    Ok(w.finish().map_err(werr)?.into_inner())
}
