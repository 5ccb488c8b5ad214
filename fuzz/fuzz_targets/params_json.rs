//! Parameter and fit JSON on arbitrary text: the JSON reader, then the parameter reader
//! with its bounds. An `Err` is fine, a panic is a bug.
#![no_main]

use furfit::FurParams;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(v) = furfit::io::parse_json(text, Path::new("fuzz.json")) {
        let _ = FurParams::from_json_value(&v);
        let _ = furfit::params::fit_channels(&v, "fuzz.json");
    }
});
