//! Writers for the virtual goniometer: the profile (DATA.md CSV or furfit `.npz`, chosen
//! by the file name's extension and written by the shared [`crate::profile`] writers) and
//! `metadata.json`, written as a group: both files or neither, so a profile is never left
//! without the metadata saying how it was made.
//!
//! The profile holds one sample per grid cell in (theta_i, theta_r, phi) order, with
//! metadata (always including `synthetic: true`) and columns/arrays
//! `theta_i, theta_r, phi, value, sigma`. `value` is rounded to 6 significant digits and
//! `sigma` to 3 (more would be Monte Carlo noise), the same numbers in either format; an
//! invalid sample has `value = 0` and no `sigma` (DATA.md: `value <= 0` marks no usable
//! signal).

use super::measure::Measured;
use super::SimResult;
use crate::error::{Error, Result};
use crate::profile::{self, Profile, Sample};
use std::path::{Component, Path};

/// `x` rounded to `digits` significant digits.
fn round_sig(x: f64, digits: usize) -> f64 {
    format!("{:.*e}", digits - 1, x).parse().unwrap_or(x)
}

/// The measured profile as a [`Profile`] with metadata `meta` (line breaks in values become
/// spaces: a CSV metadata line holds one line).
pub fn to_profile(sim: &SimResult, m: &Measured, meta: &[(String, String)]) -> Profile {
    let mut prof = Profile::default();
    if !meta.iter().any(|(k, _)| k == "synthetic") {
        prof.set_meta("synthetic", "true");
    }
    for (k, v) in meta {
        prof.metadata
            .push((k.clone(), v.replace(['\n', '\r'], " ")));
    }
    prof.samples.reserve(sim.value.len());
    for (i, &theta_i) in sim.theta_i.iter().enumerate() {
        for (j, &theta_r) in sim.theta_r.iter().enumerate() {
            for (k, &phi) in sim.phi.iter().enumerate() {
                let b = sim.index(i, j, k);
                let (value, sigma) = if m.invalid[b].is_some() {
                    (0.0, None)
                } else {
                    (round_sig(m.value[b], 6), Some(round_sig(m.sigma[b], 3)))
                };
                prof.samples.push(Sample {
                    theta_i,
                    theta_r,
                    phi,
                    value,
                    sigma,
                    channel: 0,
                    phi_i: None,
                    origin: Default::default(),
                });
            }
        }
    }
    prof
}

/// Check `--file` before any work is done: a plain file name (it is placed inside
/// `--out`, so no directory part, `..` or root) ending in `.csv` or `.npz`.
pub fn check_file_name(name: &str) -> Result<()> {
    let p = Path::new(name);
    let plain = !name.contains(['/', '\\'])
        && matches!(p.components().collect::<Vec<_>>()[..], [Component::Normal(n)] if n == name);
    if !plain {
        return Err(Error::Invalid(format!(
            "--file '{name}': must be a plain file name (it is written inside --out; give \
             directories with --out)"
        )));
    }
    if name.eq_ignore_ascii_case("metadata.json") {
        return Err(Error::Invalid(format!(
            "--file '{name}': that name is taken by the metadata file"
        )));
    }
    profile::save_format(p).map_err(|e| Error::Invalid(format!("--file {e}")))?;
    Ok(())
}

/// Check before any work that writing `dir/file_name` and `dir/metadata.json` loses
/// nothing: where either exists, `force` must be given, `dir/metadata.json` must record an
/// earlier `furfit simulate` run (its `command`), and that run's profile (its `file`;
/// `profile.csv` in records from before the field) must be `file_name`. So a lab profile
/// or a hand-written metadata file is never replaced, not even with `--force`, and a
/// profile is never left beside a `metadata.json` that describes another run.
pub fn check_replace(dir: &Path, file_name: &str, force: bool) -> Result<()> {
    crate::io::check_out_dir(dir)?;
    let meta = dir.join("metadata.json");
    let target = dir.join(file_name);
    for p in [&target, &meta] {
        crate::io::check_out_file(p)?;
    }
    let Some(first) = [&target, &meta].into_iter().find(|p| p.exists()) else {
        return Ok(());
    };
    if !force {
        return Err(Error::file(
            first,
            "exists; simulate would replace it (give --force to replace an earlier furfit \
             simulation, or choose another --out)",
        ));
    }
    let record = crate::io::read_json(&meta).ok().filter(|v| {
        v["command"]
            .as_str()
            .is_some_and(|c| c.starts_with("furfit simulate"))
    });
    let Some(record) = record else {
        return Err(Error::file(
            first,
            format!(
                "exists and {} does not record a furfit simulate run: not replaced, even with \
                 --force (move it away first)",
                meta.display()
            ),
        ));
    };
    let recorded = record["file"].as_str().unwrap_or("profile.csv");
    if recorded != file_name && (target.exists() || dir.join(recorded).exists()) {
        return Err(Error::file(
            first,
            format!(
                "{} describes the simulated profile {recorded}, not {file_name}: not replaced, \
                 even with --force (use --file {recorded}, or another --out)",
                meta.display()
            ),
        ));
    }
    // A profile edited or replaced since (a user's own data in its place): not ours to
    // replace (metadata from before the digest was recorded is taken on trust).
    if let (Some(want), true) = (record["file_sha256"].as_str(), target.is_file()) {
        let bytes = std::fs::read(&target).map_err(|e| Error::io(&target, e))?;
        if crate::io::sha256_hex(&bytes) != want {
            return Err(Error::file(
                &target,
                format!(
                    "was changed since furfit simulate wrote it (its SHA-256 is not the one \
                     {} records): not replaced, even with --force (move it away first)",
                    meta.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Write the profile `dir/file_name` (format by extension) and `dir/metadata.json` as one
/// group ([`crate::io::write_atomic_all`]): a failure leaves both as they were.
pub fn write_all(
    dir: &Path,
    file_name: &str,
    prof: &Profile,
    metadata: &serde_json::Value,
) -> Result<()> {
    check_file_name(file_name)?;
    let path = dir.join(file_name);
    let bytes = profile::encode(&path, prof)?;
    // The profile's digest, so a later `--force` replaces only this file as written.
    let mut metadata = metadata.clone();
    if let serde_json::Value::Object(m) = &mut metadata {
        m.insert("file_sha256".into(), crate::io::sha256_hex(&bytes).into());
    }
    let mut js = serde_json::to_vec_pretty(&metadata)
        .map_err(|e| Error::Invalid(format!("metadata JSON: {e}")))?;
    js.push(b'\n');
    crate::io::write_atomic_all(&[(path, bytes), (dir.join("metadata.json"), js)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_name_must_be_plain_csv_or_npz() {
        for ok in ["profile.csv", "p.npz", "P.CSV", "a b.csv", "..csv.csv"] {
            assert!(check_file_name(ok).is_ok(), "{ok}");
        }
        for (bad, why) in [
            ("../escape.csv", "plain file name"),
            ("sub/p.csv", "plain file name"),
            ("/tmp/p.csv", "plain file name"),
            ("a\\p.csv", "plain file name"),
            ("..", "plain file name"),
            (".", "plain file name"),
            ("", "plain file name"),
            ("p.csv/", "plain file name"),
            ("p.txt", ".csv or .npz"),
            ("p.npy", ".csv or .npz"),
            ("profile", ".csv or .npz"),
            ("metadata.json", "metadata"),
        ] {
            let e = check_file_name(bad).unwrap_err().to_string();
            assert!(e.contains(why) && e.contains("--file"), "{bad}: {e}");
        }
    }
}
