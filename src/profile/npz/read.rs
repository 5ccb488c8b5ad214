//! A furfit `.npz` or a lone `.npy` read into a [`Profile`]: the arrays found, the axes
//! checked and converted, then the grid's cells turned into samples.

use super::npy::{arr_err, entry, read_axis, read_bytes_array, read_float, read_meta_json};
use crate::error::{Error, Result};
use crate::profile::checks::{
    check_angle, check_channel_name, check_measured, convert_theta_r, read_phi,
};
use crate::profile::merge::{dedupe_notes, wrap_conflict};
use crate::profile::sample::{Layout, LoadOptions, Origin, Profile, Sample};
use crate::text::quoted;
use ndarray::{ArrayD, Dimension, IxDyn};
use std::io::Cursor;
use std::path::Path;

#[derive(serde::Deserialize, Default)]
struct MetaJson {
    #[serde(default)]
    metadata: Vec<(String, String)>,
    #[serde(default)]
    channels: Vec<String>,
}

/// Read a furfit `.npz` (see the module doc) without convention options. Returns the
/// profile and loader notes.
pub fn parse_npz(bytes: &[u8], path: &Path) -> Result<(Profile, Vec<String>)> {
    parse_npz_with(bytes, path, &LoadOptions::default())
}

/// [`parse_npz`] with the convention options of `opts` (`flip_phi`, `phi_offset`,
/// `flip_theta_r`) applied to the axes as they are read.
pub fn parse_npz_with(
    bytes: &[u8],
    path: &Path,
    opts: &LoadOptions,
) -> Result<(Profile, Vec<String>)> {
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).map_err(|e| {
        Error::file(
            path,
            format!("not a readable .npz (zip) archive (truncated or corrupt?): {e}"),
        )
    })?;
    // Two members of one array (`value.npy` twice, or `value.npy` and `value`): which one
    // a reader takes would be the zip library's choice.
    let mut seen = std::collections::HashSet::new();
    for i in 0..zip.len() {
        let name = zip.name_for_index(i).unwrap_or_default();
        let array = name.strip_suffix(".npy").unwrap_or(name).to_string();
        if !seen.insert(array.clone()) {
            return Err(Error::file(
                path,
                format!("the archive holds array {} twice", quoted(&array)),
            ));
        }
    }
    let mut required = |name: &str| -> Result<Vec<u8>> {
        entry(&mut zip, path, name)?
            .ok_or_else(|| arr_err(path, name, "missing from the archive (required)"))
    };
    let ti = required("theta_i")?;
    let tr = required("theta_r")?;
    let ph = required("phi")?;
    let va = required("value")?;
    let theta_axis = |bytes: &[u8], name: &str| -> Result<Vec<f64>> {
        axis(&read_axis(bytes, path, name)?, path, name, |v| {
            check_angle(name, v, 90.0)
        })
    };
    let phi_written = axis(&read_axis(&ph, path, "phi")?, path, "phi", Ok)?;
    let axes = Axes::new(
        theta_axis(&ti, "theta_i")?,
        theta_axis(&tr, "theta_r")?,
        phi_written,
        "phi",
        opts,
        |k, m| arr_err(path, "phi", format!("element {k}: {m}")),
    )?;
    let value = read_float(&va, path, "value")?;
    let present = match entry(&mut zip, path, "present")? {
        Some(b) => {
            let m = read_bytes_array(&b, path, "present")?;
            // A mask holds 1 (a sample) or 0 (none); another value (255, a count) means the
            // array is not one, and reading it as "a sample" would hide that.
            if let Some((ix, v)) = m.indexed_iter().find(|(_, &v)| v > 1) {
                return Err(arr_err(
                    path,
                    "present",
                    format!(
                        "index {:?}: {v} is neither 1 (a sample) nor 0 (none)",
                        ix.slice()
                    ),
                ));
            }
            Some(m)
        }
        None => None,
    };
    let sigma = match entry(&mut zip, path, "sigma")? {
        Some(b) => Some(read_float(&b, path, "sigma")?),
        None => None,
    };
    let phi_i = match entry(&mut zip, path, "phi_i")? {
        Some(b) => Some(read_float(&b, path, "phi_i")?),
        None => None,
    };
    let meta = match entry(&mut zip, path, "meta_json")? {
        Some(b) => {
            let raw = read_meta_json(&b, path)?;
            if raw.ndim() != 1 {
                return Err(arr_err(path, "meta_json", "must be 1-D"));
            }
            let text: Vec<u8> = raw.iter().copied().collect();
            serde_json::from_slice::<MetaJson>(&text).map_err(|e| {
                arr_err(
                    path,
                    "meta_json",
                    format!("not the expected JSON {{\"metadata\": [[k, v], ...], \"channels\": [...]}}: {e}"),
                )
            })?
        }
        None => MetaJson::default(),
    };
    for (k, (key, value)) in meta.metadata.iter().enumerate() {
        crate::profile::label::check_synthetic_label(key, value)
            .map_err(|m| arr_err(path, "meta_json", format!("metadata[{k}]: {m}")))?;
    }
    grid_to_profile(
        path,
        axes,
        opts,
        value,
        Extras {
            present,
            sigma,
            phi_i,
        },
        meta,
    )
}

/// Read a lone `.npy` holding `value`; the axes come from `opts`.
pub fn parse_npy(bytes: &[u8], path: &Path, opts: &LoadOptions) -> Result<(Profile, Vec<String>)> {
    let value = read_float(bytes, path, "value")?;
    let need = |g: &Option<Vec<f64>>, opt: &str| -> Result<Vec<f64>> {
        g.clone().ok_or_else(|| {
            Error::file(
                path,
                format!(
                    "a lone .npy holds only the value array: give its axes as grids ({opt} missing; \
                     --theta-i, --theta-r and --phi are all needed), or use an .npz with axis arrays"
                ),
            )
        })
    };
    let theta = |g: Vec<f64>, opt: &str| -> Result<Vec<f64>> {
        g.into_iter()
            .map(|v| {
                check_angle(opt, v, 90.0)
                    .map_err(|m| Error::Invalid(format!("{}: {m}", path.display())))
            })
            .collect()
    };
    let axes = Axes::new(
        theta(need(&opts.theta_i, "--theta-i")?, "--theta-i")?,
        theta(need(&opts.theta_r, "--theta-r")?, "--theta-r")?,
        need(&opts.phi, "--phi")?,
        "--phi",
        opts,
        |_, m| Error::Invalid(format!("{}: {m}", path.display())),
    )?;
    grid_to_profile(
        path,
        axes,
        opts,
        value,
        Extras {
            present: None,
            sigma: None,
            phi_i: None,
        },
        MetaJson::default(),
    )
}

/// Validate a 1-D axis array, each element with `check` (a message names the element).
pub(super) fn axis(
    a: &ArrayD<f64>,
    path: &Path,
    name: &str,
    check: impl Fn(f64) -> std::result::Result<f64, String>,
) -> Result<Vec<f64>> {
    if a.ndim() != 1 {
        return Err(arr_err(
            path,
            name,
            format!("wrong shape {:?}: an axis must be 1-D", a.shape()),
        ));
    }
    if a.is_empty() {
        return Err(arr_err(path, name, "empty axis"));
    }
    a.iter()
        .enumerate()
        .map(|(k, &v)| check(v).map_err(|m| arr_err(path, name, format!("element {k}: {m}"))))
        .collect()
}

/// The three axes of a grid as the samples take them (the convention options applied, phi
/// wrapped), and phi as written (for a wrap's duplicate message).
struct Axes {
    theta_i: Vec<f64>,
    theta_r: Vec<f64>,
    phi: Vec<f64>,
    phi_written: Vec<f64>,
    /// Where phi came from: the archive's `phi` array, or `--phi` (a lone .npy).
    phi_name: String,
}

impl Axes {
    /// The error of element `k` of the phi axis, placed where that axis came from.
    fn phi_err(&self, path: &Path, k: usize, msg: String) -> Error {
        if self.phi_name == "phi" {
            arr_err(path, "phi", format!("element {k}: {msg}"))
        } else {
            Error::Invalid(format!(
                "{}: {} element {k}: {msg}",
                path.display(),
                self.phi_name
            ))
        }
    }

    /// Axes from checked inclinations and phi as written (checked here by
    /// [`read_phi`] under the name `phi_name`; `err(element, message)` places its error).
    pub(super) fn new(
        theta_i: Vec<f64>,
        theta_r: Vec<f64>,
        phi_written: Vec<f64>,
        phi_name: &str,
        opts: &LoadOptions,
        err: impl Fn(usize, String) -> Error,
    ) -> Result<Axes> {
        let phi = phi_written
            .iter()
            .enumerate()
            .map(|(k, &v)| read_phi(phi_name, v, opts).map_err(|m| err(k, m)))
            .collect::<Result<Vec<f64>>>()?;
        Ok(Axes {
            theta_i,
            theta_r: theta_r
                .into_iter()
                .map(|t| convert_theta_r(opts, t))
                .collect(),
            phi,
            phi_written,
            phi_name: phi_name.to_string(),
        })
    }

    fn lens(&self) -> [usize; 3] {
        [self.theta_i.len(), self.theta_r.len(), self.phi.len()]
    }
}

struct Extras {
    present: Option<ArrayD<u8>>,
    sigma: Option<ArrayD<f64>>,
    phi_i: Option<ArrayD<f64>>,
}

fn grid_to_profile(
    path: &Path,
    axes: Axes,
    opts: &LoadOptions,
    value: ArrayD<f64>,
    extras: Extras,
    meta: MetaJson,
) -> Result<(Profile, Vec<String>)> {
    let shape = value.shape().to_vec();
    let (has_sigma, has_phi_i) = (extras.sigma.is_some(), extras.phi_i.is_some());
    let nc = check_shapes(path, &shape, axes.lens(), &extras)?;
    let channels = channel_names(path, &shape, nc, meta.channels)?;
    let (mut samples, cells) = grid_samples(path, &axes, &shape, nc, &value, &extras)?;
    if samples.is_empty() {
        return Err(arr_err(
            path,
            "value",
            "no samples (every cell is NaN or marked absent)",
        ));
    }
    // As many indices as `value` has axes.
    let cell = |k: usize| format!("{:?}", &cells[k][..shape.len()]);
    let raw_phi: Vec<f64> = cells.iter().map(|c| axes.phi_written[c[2]]).collect();
    let what = "grid cell(s) repeating a direction with identical data";
    let notes = dedupe_notes(&mut samples, &channels, &raw_phi, what, |c| {
        let (pa, pb) = (cells[c.first][2], cells[c.repeat][2]);
        let pair = format!(" in cells {} and {}", cell(c.first), cell(c.repeat));
        let first_at = format!("element {pa}");
        let (wa, wb) = (axes.phi_written[pa], axes.phi_written[pb]);
        match wrap_conflict(wa, wb, &first_at, &c, &pair, opts) {
            Some(m) => axes.phi_err(path, pb, m),
            None => arr_err(
                path,
                c.field.name(),
                format!(
                    "{}: cells {} and {}",
                    c.what(),
                    cell(c.first),
                    cell(c.repeat)
                ),
            ),
        }
    })?;
    Ok((
        Profile {
            samples,
            channels,
            metadata: meta.metadata,
            source: Some(path.to_path_buf()),
            files: vec![path.to_path_buf()],
            layouts: vec![Layout::Grid {
                shape,
                sigma: has_sigma,
                phi_i: has_phi_i,
            }],
        },
        notes,
    ))
}

/// Check `value`'s shape against the axes' lengths (`lens`, optionally with a trailing
/// channel axis) and the extra arrays' shapes against it; returns the channel count.
fn check_shapes(path: &Path, shape: &[usize], lens: [usize; 3], extras: &Extras) -> Result<usize> {
    if !(shape.len() == 3 || shape.len() == 4) || shape[..3] != lens {
        return Err(arr_err(
            path,
            "value",
            format!(
                "wrong shape {shape:?}: expected [theta_i, theta_r, phi] = {lens:?} (optionally with a trailing channel axis)"
            ),
        ));
    }
    let nc = if shape.len() == 4 { shape[3] } else { 1 };
    if nc == 0 {
        return Err(arr_err(path, "value", "channel axis has length 0"));
    }
    for (name, s) in [
        ("present", extras.present.as_ref().map(|a| a.shape())),
        ("sigma", extras.sigma.as_ref().map(|a| a.shape())),
        ("phi_i", extras.phi_i.as_ref().map(|a| a.shape())),
    ] {
        if let Some(s) = s {
            if s != shape {
                return Err(arr_err(
                    path,
                    name,
                    format!("wrong shape {s:?}: must match value's shape {shape:?}"),
                ));
            }
        }
    }
    Ok(nc)
}

/// The profile's channel names from `meta_json`'s `channels` (`names`), checked against
/// `value`'s shape and its channel count `nc`: none for one unnamed channel, numbers for
/// an unnamed channel axis.
fn channel_names(
    path: &Path,
    shape: &[usize],
    nc: usize,
    names: Vec<String>,
) -> Result<Vec<String>> {
    for (k, name) in names.iter().enumerate() {
        check_channel_name(name)
            .map_err(|m| arr_err(path, "meta_json", format!("channels[{k}]: {m}")))?;
        if let Some(j) = names[..k].iter().position(|c| c == name) {
            return Err(arr_err(
                path,
                "meta_json",
                format!("channels[{k}] {} repeats channels[{j}]", quoted(name)),
            ));
        }
    }
    if shape.len() == 4 {
        if names.is_empty() && nc == 1 {
            // A trailing singleton axis is one unnamed channel, as for a 3-D `value`.
            Ok(Vec::new())
        } else if names.is_empty() {
            Ok((0..nc).map(|c| c.to_string()).collect())
        } else if names.len() == nc {
            Ok(names)
        } else {
            Err(arr_err(
                path,
                "meta_json",
                format!(
                    "{} channel names for a channel axis of length {nc}",
                    names.len()
                ),
            ))
        }
    } else if names.len() <= 1 {
        Ok(names)
    } else {
        Err(arr_err(
            path,
            "meta_json",
            format!(
                "{} channel names but value is 3-D (one channel)",
                names.len()
            ),
        ))
    }
}

/// The samples of the grid's present cells (each checked), in row-major order over
/// `value`, and each one's cell `[theta_i, theta_r, phi, channel]`.
fn grid_samples(
    path: &Path,
    axes: &Axes,
    shape: &[usize],
    nc: usize,
    value: &ArrayD<f64>,
    extras: &Extras,
) -> Result<(Vec<Sample>, Vec<[usize; 4]>)> {
    let lens = axes.lens();
    let mut samples = Vec::new();
    let mut cells: Vec<[usize; 4]> = Vec::new();
    let opt = |a: &Option<ArrayD<f64>>, ix: &IxDyn| -> Option<f64> {
        a.as_ref().map(|a| a[ix]).filter(|v| !v.is_nan())
    };
    for (i, &theta_i) in axes.theta_i.iter().enumerate() {
        for (r, &theta_r) in axes.theta_r.iter().enumerate() {
            for (p, &phi) in axes.phi.iter().enumerate() {
                for c in 0..nc {
                    let ix = if shape.len() == 4 {
                        IxDyn(&[i, r, p, c])
                    } else {
                        IxDyn(&[i, r, p])
                    };
                    let v = value[&ix];
                    let here = match &extras.present {
                        Some(m) => m[&ix] != 0,
                        None => !v.is_nan(),
                    };
                    if !here {
                        continue;
                    }
                    let sigma = opt(&extras.sigma, &ix);
                    let phi_i = opt(&extras.phi_i, &ix);
                    check_measured(v, sigma, phi_i).map_err(|(field, msg)| {
                        arr_err(
                            path,
                            field.name(),
                            format!(
                                "index {:?} (theta_i {theta_i}, theta_r {theta_r}, phi {phi}): {msg}",
                                ix.slice()
                            ),
                        )
                    })?;
                    samples.push(Sample {
                        theta_i,
                        theta_r,
                        phi,
                        value: v,
                        sigma,
                        channel: c,
                        phi_i,
                        // Row-major over `value` (a 3-D one has nc = 1, c = 0).
                        origin: Origin::at_cell(((i * lens[1] + r) * lens[2] + p) * nc + c),
                    });
                    cells.push([i, r, p, c]);
                }
            }
        }
    }
    Ok((samples, cells))
}
