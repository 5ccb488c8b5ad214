//! Every profile loader on arbitrary bytes, through `profile::parse_bytes` as a file is
//! read: an `Err` is fine, a panic is a bug (nothing panics on user input). The first
//! byte picks the format and the loader options, so one corpus serves all four formats. Whatever loads is also summarised (as `inspect` does) and
//! written as CSV and `.npz`, and the CSV must read back with the same samples: a profile
//! furfit accepts is one it can write.
#![no_main]

use furfit::profile::{csv, npz, parse_bytes, summary::Summary, Format, LoadOptions};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Some((&sel, bytes)) = data.split_first() else {
        return;
    };
    let grids = sel & 0x80 != 0;
    let opts = LoadOptions {
        flip_phi: sel & 0x10 != 0,
        flip_theta_r: sel & 0x20 != 0,
        phi_offset: if sel & 0x40 != 0 { 90.0 } else { 0.0 },
        theta_i: grids.then(|| vec![0.0, 30.0]),
        theta_r: grids.then(|| vec![-30.0, 0.0, 30.0]),
        phi: grids.then(|| vec![-90.0, 0.0, 90.0, 180.0]),
        ..LoadOptions::default()
    };
    let path = Path::new("fuzz.input");
    let format = [Format::Csv, Format::Yan, Format::Npz, Format::Npy][(sel & 0x3) as usize];
    let Ok((profile, _notes)) = parse_bytes(format, bytes, path, &opts) else {
        return;
    };
    let _ = Summary::of(&profile);
    let _ = npz::to_bytes(&profile);
    if let Ok(text) = csv::to_string(&profile) {
        let back = csv::parse(text.as_bytes(), Path::new("fuzz.csv"));
        let (again, _) = back.unwrap_or_else(|e| panic!("written CSV does not read back: {e}"));
        assert_eq!(
            again.samples.len(),
            profile.samples.len(),
            "samples lost in a round trip"
        );
    }
});
