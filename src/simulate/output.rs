//! Writers for the virtual goniometer: the profile as DATA.md CSV and `metadata.json`.
//!
//! CSV layout: `# key: value` metadata lines (always including `synthetic: true`), then the
//! header `theta_i,theta_r,phi,value,sigma` and one row per grid sample in
//! (theta_i, theta_r, phi) order. Angles are printed as they were given (shortest exact
//! decimal), `value` with 6 significant digits, `sigma` with 3; an invalid sample is written
//! as `value = 0` with an empty `sigma` (DATA.md: `value <= 0` marks no usable signal).

use super::measure::Measured;
use super::SimResult;
use crate::error::{Error, Result};
use std::path::Path;

/// Format with `digits` significant digits in compact scientific notation.
fn sig(x: f64, digits: usize) -> String {
    format!("{:.*e}", digits - 1, x)
}

/// The CSV text of a measured profile with metadata lines `meta`.
pub fn profile_csv(sim: &SimResult, m: &Measured, meta: &[(String, String)]) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(sim.value.len() * 32 + 1024);
    let has_synth = meta.iter().any(|(k, _)| k == "synthetic");
    if !has_synth {
        out.extend_from_slice(b"# synthetic: true\n");
    }
    for (k, v) in meta {
        let v = v.replace(['\n', '\r'], " ");
        out.extend_from_slice(format!("# {k}: {v}\n").as_bytes());
    }
    let mut w = csv::WriterBuilder::new().from_writer(out);
    let err = |e: csv::Error| Error::Invalid(format!("writing CSV: {e}"));
    w.write_record(["theta_i", "theta_r", "phi", "value", "sigma"])
        .map_err(err)?;
    for (i, ti) in sim.theta_i.iter().enumerate() {
        let ti = format!("{ti}");
        for (j, tr) in sim.theta_r.iter().enumerate() {
            let tr = format!("{tr}");
            for (k, ph) in sim.phi.iter().enumerate() {
                let b = sim.index(i, j, k);
                let (v, s) = if m.invalid[b].is_some() {
                    ("0".to_string(), String::new())
                } else {
                    (sig(m.value[b], 6), sig(m.sigma[b], 3))
                };
                w.write_record([ti.as_str(), tr.as_str(), &format!("{ph}"), &v, &s])
                    .map_err(err)?;
            }
        }
    }
    w.into_inner()
        .map_err(|e| Error::Invalid(format!("writing CSV: {e}")))
}

/// Write the profile CSV and `metadata.json` into `dir` (atomically).
pub fn write_all(
    dir: &Path,
    file_name: &str,
    csv_bytes: &[u8],
    metadata: &serde_json::Value,
) -> Result<()> {
    crate::io::write_atomic(&dir.join(file_name), csv_bytes)?;
    let mut js = serde_json::to_vec_pretty(metadata)
        .map_err(|e| Error::Invalid(format!("metadata JSON: {e}")))?;
    js.push(b'\n');
    crate::io::write_atomic(&dir.join("metadata.json"), &js)
}
