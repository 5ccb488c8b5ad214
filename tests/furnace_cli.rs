//! `furfit furnace`, `--medulla-energy`, `--sampling` and `--energy-weights` from the
//! command line: output format, bad input refused with messages that name it.
use std::process::Command;

fn furfit(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// 19 inclinations from -90 to 90 and the last line `max albedo A min albedo B`, with A
/// and B the extremes of the printed rows.
#[test]
fn furnace_prints_albedo_rows_and_the_extremes_last() {
    let (ok, out, err) = furfit(&["furnace", "--params", "red-fox", "--samples", "2000"]);
    assert!(ok, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    let rows: Vec<(f64, f64)> = lines
        .iter()
        .filter_map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .filter_map(|x| x.parse().ok())
                .collect();
            (v.len() == 3).then(|| (v[0], v[1]))
        })
        .collect();
    assert_eq!(rows.len(), 19, "{out}");
    assert_eq!(rows[0].0, -90.0);
    assert_eq!(rows[18].0, 90.0);
    let last = lines.last().unwrap();
    let w: Vec<&str> = last.split_whitespace().collect();
    assert_eq!(
        (w[0], w[1], w[3], w[4]),
        ("max", "albedo", "min", "albedo"),
        "{last}"
    );
    let (a, b): (f64, f64) = (w[2].parse().unwrap(), w[5].parse().unwrap());
    let hi = rows.iter().map(|r| r.1).fold(f64::MIN, f64::max);
    let lo = rows.iter().map(|r| r.1).fold(f64::MAX, f64::min);
    // Printed to 4 decimals both ways.
    assert!(
        (a - hi).abs() < 1e-4 && (b - lo).abs() < 1e-4,
        "{last} vs {hi} {lo}"
    );
    assert!(b > 0.0 && a <= 1.0 + 0.05, "red fox absorbs: {last}");
}

#[test]
fn bad_energy_mode_sampling_model_and_weights_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let out = out.to_str().unwrap();
    let missing = dir.path().join("gone.bin");
    let missing = missing.to_str().unwrap();
    for (args, want) in [
        (
            vec!["furnace", "--params", "red-fox", "--medulla-energy", "glow"],
            vec!["--medulla-energy", "glow", "strand"],
        ),
        (
            vec!["furnace", "--params", "red-fox", "--model", "chiang2016"],
            vec!["--model", "yan2017"],
        ),
        (
            vec![
                "furnace",
                "--params",
                "red-fox",
                "--energy-weights",
                missing,
            ],
            vec!["gone.bin", "furfit tables strand"],
        ),
        (
            vec![
                "render",
                "--params",
                "red-fox",
                "--size",
                "8x8",
                "--spp",
                "1",
                "--sampling",
                "magic",
                "--out",
                out,
            ],
            vec!["--sampling", "magic", "ishair"],
        ),
        (
            vec![
                "render",
                "--params",
                "red-fox",
                "--size",
                "8x8",
                "--spp",
                "1",
                "--medulla-energy",
                "x",
                "--out",
                out,
            ],
            vec!["--medulla-energy", "strand"],
        ),
        (
            vec![
                "render",
                "--params",
                "red-fox",
                "--size",
                "8x8",
                "--spp",
                "1",
                "--energy-weights",
                missing,
                "--out",
                out,
            ],
            vec!["gone.bin", "furfit tables strand"],
        ),
        (
            vec![
                "render-convergence",
                "--samplings",
                "ishair,nope",
                "--out",
                dir.path().to_str().unwrap(),
            ],
            vec!["--samplings", "nope"],
        ),
    ] {
        let (ok, _, err) = furfit(&args);
        assert!(!ok, "{args:?} succeeded");
        for w in want {
            assert!(err.contains(w), "{args:?}: '{w}' not in: {err}");
        }
    }
}
