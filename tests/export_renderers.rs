//! The exported materials checked by the real renderers' own code, in a Python virtual
//! environment (`.ci/run` makes it: `target/export-venv` with `mitsuba`, `materialx`,
//! `numpy`; `FURFIT_RENDERER_PYTHON` names another interpreter):
//! - Mitsuba 3 evaluates every shipped species' `furfit export --to mitsuba` averaged over
//!   the fiber offset at the data's angles and must reproduce furfit's chiang2016
//!   prediction within 0.5 % of the log range (`tests/export/mitsuba_check.py`);
//! - MaterialX loads, validates and generates GLSL for every `--to materialx` document,
//!   whose values must be the mapping's (`tests/export/materialx_check.py`).
//!
//! Without the environment these tests say so on stderr and pass, unless
//! `FURFIT_REQUIRE_RENDERERS=1` (set by `.ci/run`), where a missing renderer fails them.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The venv's Python, or `None` (with the reason) when it is missing.
fn python() -> Result<PathBuf, String> {
    let p = match std::env::var_os("FURFIT_RENDERER_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => root().join("target/export-venv/bin/python"),
    };
    if p.is_file() {
        Ok(p)
    } else {
        Err(format!(
            "no renderer environment at {} (python3 -m venv target/export-venv && \
             target/export-venv/bin/pip install mitsuba materialx numpy)",
            p.display()
        ))
    }
}

/// drjit's LLVM backend library: `DRJIT_LIBLLVM_PATH`, else Debian's libLLVM 19..16.
fn libllvm() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("DRJIT_LIBLLVM_PATH") {
        return Ok(PathBuf::from(p));
    }
    (16..=19)
        .rev()
        .map(|v| PathBuf::from(format!("/usr/lib/x86_64-linux-gnu/libLLVM-{v}.so")))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            "no LLVM >= 16 for Mitsuba's llvm_ad_rgb variant (apt-get install libllvm19, or set \
             DRJIT_LIBLLVM_PATH)"
                .to_string()
        })
}

/// Whether a missing environment fails the test (CI) or only skips it.
fn required() -> bool {
    std::env::var("FURFIT_REQUIRE_RENDERERS").is_ok_and(|v| v == "1")
}

/// Run `script` with the fits folder; the environment's absence skips or fails.
fn run_check(script: &str, needs_llvm: bool) {
    let env = python().and_then(|py| {
        let llvm = if needs_llvm { Some(libllvm()?) } else { None };
        Ok((py, llvm))
    });
    let (py, llvm) = match env {
        Ok(e) => e,
        Err(why) if required() => panic!("FURFIT_REQUIRE_RENDERERS=1 but {why}"),
        Err(why) => {
            eprintln!("skipped {script}: {why}");
            return;
        }
    };
    let mut c = Command::new(py);
    c.current_dir(root())
        .arg(Path::new("tests/export").join(script))
        .args(["--furfit", env!("CARGO_BIN_EXE_furfit")])
        .args(["--fits", "fits/chiang2016"]);
    if let Some(l) = llvm {
        c.env("DRJIT_LIBLLVM_PATH", l);
    }
    let o = c.output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    eprintln!("{out}");
    assert!(
        o.status.success(),
        "{script} failed:\n{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // A line for every shipped species (the script exits non-zero when any fails).
    for e in std::fs::read_dir(root().join("fits/chiang2016")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "json") {
            let stem = p.file_stem().unwrap().to_string_lossy().into_owned();
            assert!(
                out.lines().any(|l| l.starts_with(&format!("{stem}:"))),
                "no line for {stem}:\n{out}"
            );
        }
    }
}

#[test]
fn mitsuba_reproduces_furfit_for_every_species() {
    run_check("mitsuba_check.py", true);
}

#[test]
fn materialx_loads_and_validates_every_export() {
    run_check("materialx_check.py", false);
}

/// Opt-in (the `bpy` wheel is 374 MB; not installed by `.ci/run`): with
/// `target/bpy-venv` (or `FURFIT_BLENDER_PYTHON`) Blender runs the exported Cycles script,
/// the material must hold the fit's values, and Cycles renders a small frame of the lock
/// (`tests/export/blender_check.py`).
#[test]
fn blender_builds_and_renders_the_cycles_export() {
    let py = match std::env::var_os("FURFIT_BLENDER_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => root().join("target/bpy-venv/bin/python"),
    };
    if !py.is_file() {
        eprintln!(
            "skipped blender_check.py (opt-in): no {} (python3.11 -m venv target/bpy-venv && \
             target/bpy-venv/bin/pip install bpy==5.0.1 numpy)",
            py.display()
        );
        return;
    }
    let o = Command::new(py)
        .current_dir(root())
        .arg("tests/export/blender_check.py")
        .args(["--furfit", env!("CARGO_BIN_EXE_furfit")])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    eprintln!("{out}");
    assert!(
        o.status.success(),
        "blender_check.py failed:\n{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
}
