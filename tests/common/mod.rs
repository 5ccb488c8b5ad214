//! Helpers shared by several end-to-end test files (`mod common;` in each). Each test
//! crate uses only some of them, hence the `allow`.
#![allow(dead_code)]

/// A fit file with r, g, b channels (written here by hand in the layout `fit` writes: the
/// primary channel at the top level, every channel in `channels`).
pub fn rgb_fit(dir: &std::path::Path) -> std::path::PathBuf {
    let ch = |name: &str, sigma: f64, k: f64| {
        let mut p = furfit::FurParams::preset("cat").unwrap().to_json_value();
        p["sigma_c_a"] = serde_json::json!(sigma);
        serde_json::json!({"params": p, "exposure": k, "data": {"channel": name}})
    };
    let chans = vec![ch("r", 0.1, 2.0), ch("g", 0.4, 3.0), ch("b", 1.6, 5.0)];
    let mut top = chans[0].clone();
    top["channels"] = serde_json::Value::Array(chans);
    let path = dir.join("rgb.json");
    std::fs::write(&path, serde_json::to_string_pretty(&top).unwrap()).unwrap();
    path
}

/// Helpers of the `fit` and `report` end-to-end files.
pub mod fit;
