//! The species folder's `metadata.json` as a source of the synthetic/measured label.
//!
//! DATA.md puts "what the data is and where it came from" in a small metadata file beside
//! a species' profiles, and synthetic data must always be labelled as such. A profile
//! converted from synthetic data (Yan text keeps no header, numpy writes no `meta_json`)
//! may carry no label itself, so the folder's file counts too: either saying "synthetic"
//! makes the data synthetic (the label can only be added, never removed).

use super::Profile;
use crate::error::{Error, Result};
use std::path::Path;

/// The metadata file of a species folder.
pub const FOLDER_METADATA: &str = "metadata.json";

/// What a folder's `metadata.json` says of the data: `Some(true)` for `synthetic: true`
/// (or "true"/"yes") or a `source` mentioning "synthetic", `Some(false)` for an explicit
/// `synthetic: false`, `None` when it says neither or does not exist.
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
    let flag = match obj.get("synthetic") {
        Some(serde_json::Value::Bool(b)) => Some(*b),
        Some(serde_json::Value::String(s)) => {
            let s = s.trim().to_ascii_lowercase();
            Some(s == "true" || s == "yes")
        }
        _ => None,
    };
    let source = obj
        .get("source")
        .and_then(|s| s.as_str())
        .is_some_and(|s| s.to_ascii_lowercase().contains("synthetic"));
    Ok(if source { Some(true) } else { flag })
}

/// Apply the label of `dir`'s `metadata.json` to `profile` (loaded from that folder) and
/// return the notes it warrants. `strict`: a metadata file that does not read is an error
/// (a species folder named as such); otherwise it is a note (a lone file whose folder
/// holds some other `metadata.json`).
pub(crate) fn apply_folder_label(
    profile: &mut Profile,
    dir: &Path,
    strict: bool,
) -> Result<Vec<String>> {
    let says = match folder_says_synthetic(dir) {
        Ok(s) => s,
        Err(e) if !strict => {
            return Ok(vec![format!(
                "{} not read for the data's synthetic/measured label: {e}",
                dir.join(FOLDER_METADATA).display()
            )]);
        }
        Err(e) => return Err(e),
    };
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
        assert!(apply_folder_label(&mut p, dir, true).unwrap().is_empty());
        assert!(!p.is_synthetic());

        for text in [
            r#"{"synthetic": true}"#,
            r#"{"synthetic": "yes"}"#,
            r#"{"source": "Synthetic: furfit synth + noise"}"#,
        ] {
            write(text);
            let mut p = profile(&[]);
            let notes = apply_folder_label(&mut p, dir, true).unwrap();
            assert!(p.is_synthetic(), "{text}");
            assert_eq!(notes.len(), 1, "{text}: {notes:?}");
            // Already labelled: no note.
            assert!(apply_folder_label(&mut p, dir, true).unwrap().is_empty());
        }

        write(r#"{"synthetic": false, "what": "lab"}"#);
        let mut p = profile(&[]);
        assert!(apply_folder_label(&mut p, dir, true).unwrap().is_empty());
        assert!(!p.is_synthetic());
        let mut p = profile(&[("synthetic", "true")]);
        let notes = apply_folder_label(&mut p, dir, true).unwrap();
        assert!(p.is_synthetic());
        assert!(notes[0].contains("treated as synthetic"), "{notes:?}");

        // Unreadable: an error naming the file for a folder, a note for a lone file.
        write("[1, 2]");
        let e = apply_folder_label(&mut profile(&[]), dir, true).unwrap_err();
        assert!(e.to_string().contains(FOLDER_METADATA), "{e}");
        write("{\"synthetic\": tru}");
        let e = apply_folder_label(&mut profile(&[]), dir, true).unwrap_err();
        assert!(e.to_string().contains(":1:"), "no line in: {e}");
        let notes = apply_folder_label(&mut profile(&[]), dir, false).unwrap();
        assert!(notes[0].contains("not read"), "{notes:?}");
    }
}
