//! A species folder as `fit` and `inspect` read it: `metadata.json` (its synthetic label
//! and parameters) beside one CSV profile. The input is split at the first NUL byte into
//! the metadata text and the CSV. An `Err` is fine, a panic is a bug.
#![no_main]

use furfit::profile::{load_dir, LoadOptions};
use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

/// One folder per fuzzing process, rewritten for each input.
fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("furfit-fuzz-folder-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("temp folder");
        d
    })
}

fuzz_target!(|data: &[u8]| {
    let (meta, csv) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &b"theta_i,theta_r,phi,value\n0,0,0,1\n"[..]),
    };
    let dir = folder();
    std::fs::write(dir.join("metadata.json"), meta).expect("write metadata");
    std::fs::write(dir.join("profile.csv"), csv).expect("write profile");
    if let Ok(loaded) = load_dir(dir, &LoadOptions::default()) {
        let _ = furfit::profile::provenance::measured_label(&loaded.profile, dir);
    }
});
