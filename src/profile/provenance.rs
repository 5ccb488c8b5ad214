//! The species folder's `metadata.json` as a source of the synthetic/measured label.
//!
//! DATA.md puts "what the data is and where it came from" in a small metadata file beside
//! a species' profiles, and synthetic data must always be labelled as such. A profile
//! converted from synthetic data (Yan text keeps no header, numpy writes no `meta_json`)
//! may carry no label itself, so the folder's file counts too: either saying "synthetic"
//! makes the data synthetic (the label can only be added, never removed).

use super::sample::Profile;
use crate::error::{Error, Result};
use std::path::Path;

/// The metadata file of a species folder.
pub const FOLDER_METADATA: &str = "metadata.json";

/// What a folder's `metadata.json` says of the data ([`super::says_synthetic`] of its
/// top-level entries; a JSON `true`/`1` counts like "true"): `Some(true)` when any entry
/// says synthetic, `Some(false)` for an explicit "not synthetic" and nothing saying
/// synthetic, `None` when it says neither or does not exist.
fn folder_says_synthetic(dir: &Path) -> Result<Option<bool>> {
    let path = dir.join(FOLDER_METADATA);
    if !path.is_file() {
        return Ok(None);
    }
    let v = crate::io::read_json(&path)?;
    let Some(obj) = v.as_object() else {
        return Err(Error::file(
            &path,
            "a species folder's metadata file must be a JSON object",
        ));
    };
    let mut says = Vec::new();
    for (k, v) in obj {
        let text = match v {
            serde_json::Value::String(s) => s.clone(),
            serde_json::Value::Bool(_) | serde_json::Value::Number(_) => v.to_string(),
            // A `synthetic` entry of another type (null, a list) is no label either.
            _ if k.trim().eq_ignore_ascii_case("synthetic") => v.to_string(),
            _ => continue,
        };
        super::label::check_synthetic_label(k, &text)
            .map_err(|m| Error::file(&path, format!("key \"{k}\": {m}")))?;
        says.extend(super::label::says_synthetic(k, &text));
    }
    Ok(if says.contains(&true) {
        Some(true)
    } else if says.contains(&false) {
        Some(false)
    } else {
        None
    })
}

/// Where the data read from `dir` (a species folder, or a file's folder) are labelled
/// measured, if they are: `synthetic: false` in the data, or in the folder's
/// `metadata.json`, and nothing saying synthetic. Reports say "labelled measured" then,
/// not "no synthetic label". Loading already checked the metadata file, so one that no
/// longer reads counts as no label.
pub fn measured_label(profile: &Profile, dir: &Path) -> Option<String> {
    if profile.is_synthetic() {
        None
    } else if profile.is_labelled_measured() {
        Some("synthetic: false".into())
    } else if folder_says_synthetic(dir).ok().flatten() == Some(false) {
        Some(format!(
            "synthetic: false in its folder's {FOLDER_METADATA}"
        ))
    } else {
        None
    }
}

/// Apply the label of `dir`'s `metadata.json` to `profile` (loaded from that folder) and
/// return the notes it warrants. A metadata file that does not read is an error, also for
/// a file named inside the folder: it may be what labels the data synthetic, and a
/// synthetic profile must never pass as measured.
pub(crate) fn apply_folder_label(profile: &mut Profile, dir: &Path) -> Result<Vec<String>> {
    let says = folder_says_synthetic(dir).map_err(|e| {
        Error::Invalid(format!(
            "{e} (it says whether the data beside it are synthetic: fix it, or move it away)"
        ))
    })?;
    let file = dir.join(FOLDER_METADATA);
    Ok(match (says, profile.is_synthetic()) {
        (Some(true), false) => {
            profile.set_meta("synthetic", "true");
            vec![format!(
                "{} labels the data synthetic (the profile file does not say so)",
                file.display()
            )]
        }
        (Some(false), true) => vec![format!(
            "{} says synthetic: false, but the profile file labels its data synthetic: \
             treated as synthetic",
            file.display()
        )],
        _ => Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::Sample;

    fn profile(meta: &[(&str, &str)]) -> Profile {
        let mut p = Profile::default();
        p.samples.push(Sample::new(0.0, 0.0, 0.0, 1.0));
        for (k, v) in meta {
            p.set_meta(k, *v);
        }
        p
    }

    #[test]
    fn folder_metadata_adds_the_synthetic_label_but_never_removes_it() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let write = |text: &str| std::fs::write(dir.join(FOLDER_METADATA), text).unwrap();

        // No metadata file: nothing changes.
        let mut p = profile(&[]);
        assert!(apply_folder_label(&mut p, dir).unwrap().is_empty());
        assert!(!p.is_synthetic());

        for text in [
            r#"{"synthetic": true}"#,
            r#"{"synthetic": "yes"}"#,
            r#"{"synthetic": 1}"#,
            r#"{"Synthetic": "TRUE"}"#,
            r#"{"source": "Synthetic: furfit synth + noise"}"#,
            r#"{"source": "simulated with our own ray tracer"}"#,
        ] {
            write(text);
            let mut p = profile(&[]);
            let notes = apply_folder_label(&mut p, dir).unwrap();
            assert!(p.is_synthetic(), "{text}");
            assert_eq!(notes.len(), 1, "{text}: {notes:?}");
            // Already labelled: no note.
            assert!(apply_folder_label(&mut p, dir).unwrap().is_empty());
        }

        write(r#"{"synthetic": false, "what": "lab"}"#);
        let mut p = profile(&[]);
        assert!(apply_folder_label(&mut p, dir).unwrap().is_empty());
        assert!(!p.is_synthetic());
        let mut p = profile(&[("synthetic", "true")]);
        let notes = apply_folder_label(&mut p, dir).unwrap();
        assert!(p.is_synthetic());
        assert!(notes[0].contains("treated as synthetic"), "{notes:?}");

        // Unreadable: an error naming the file (and the line).
        write("[1, 2]");
        let e = apply_folder_label(&mut profile(&[]), dir).unwrap_err();
        assert!(e.to_string().contains(FOLDER_METADATA), "{e}");
        write("{\"synthetic\": tru}");
        let e = apply_folder_label(&mut profile(&[]), dir).unwrap_err();
        assert!(e.to_string().contains(":1:"), "no line in: {e}");
    }

    /// An explicit `synthetic: false`, in the data or the folder's metadata.json, is a
    /// label: reports say "labelled measured", not "no synthetic label".
    #[test]
    fn explicit_false_is_a_measured_label() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        assert_eq!(measured_label(&profile(&[]), dir), None);
        let no = profile(&[("Synthetic", "No")]);
        assert_eq!(
            measured_label(&no, dir).as_deref(),
            Some("synthetic: false")
        );
        // A source saying synthetic outweighs it.
        let both = profile(&[("synthetic", "false"), ("source", "simulated")]);
        assert_eq!(measured_label(&both, dir), None);
        std::fs::write(dir.join(FOLDER_METADATA), r#"{"synthetic": false}"#).unwrap();
        assert_eq!(
            measured_label(&profile(&[]), dir).as_deref(),
            Some("synthetic: false in its folder's metadata.json")
        );
    }
}
