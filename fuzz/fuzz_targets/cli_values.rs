//! The values users type on the command line: angle grids, lobe lists, image sizes. An
//! `Err` is fine, a panic is a bug.
#![no_main]

use furfit::grid::{parse_phi_grid, parse_theta_grid};
use furfit::model::LobeSet;
use libfuzzer_sys::fuzz_target;
use std::cmp::Ordering;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // A range may expand to 10^7 values (grid::MAX_RANGE_VALUES), each rounded through
    // text: seconds per input, slow rather than wrong (the limit has its unit test), so
    // ranges past 10^4 values by Rust's own number syntax are skipped.
    let parts: Vec<f64> = text
        .split(':')
        .filter_map(|p| p.trim().parse().ok())
        .collect();
    // A NaN count (an infinite or zero step) counts as large too.
    let large = match parts[..] {
        [a, b, s] => ((b - a) / s).partial_cmp(&1e4) != Some(Ordering::Less),
        _ => false,
    };
    if !large {
        let _ = parse_phi_grid("--phi", text);
        let _ = parse_theta_grid("--theta-r", text);
    }
    let _ = LobeSet::parse(text);
    let _ = furfit::cli::parse_size("--size", text, 8192, 4096 * 4096);
});
