//! Records the git revision the binary is built from (`furfit::TOOL_VERSION`), so a fit
//! file or a report says which build made it: `+dirty` when the build inputs (`src/`,
//! `Cargo.toml`, `Cargo.lock`, this file) differ from that revision, `unknown` outside a
//! git checkout.

use std::path::Path;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    Command::new("git")
        .args(args)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
}

const INPUTS: [&str; 4] = ["src", "Cargo.toml", "Cargo.lock", "build.rs"];

fn main() {
    let rev = match git(&["rev-parse", "--short=12", "HEAD"]).filter(|s| !s.is_empty()) {
        Some(rev) => {
            let mut args = vec!["status", "--porcelain", "--untracked-files=no", "--"];
            args.extend(INPUTS);
            let dirty = git(&args).is_some_and(|s| !s.is_empty());
            format!("{rev}{}", if dirty { "+dirty" } else { "" })
        }
        None => "unknown".into(),
    };
    println!("cargo:rustc-env=FURFIT_GIT_REV={rev}");
    // Run again when HEAD moves (a commit, a checkout) or a build input changes. The git
    // directories are asked of git, so a worktree (where .git is a file) works too; only
    // paths that exist are named, as a missing one would rerun this on every build.
    let mut watch: Vec<String> = INPUTS.iter().map(|s| s.to_string()).collect();
    for dir in [
        git(&["rev-parse", "--git-dir"]),
        git(&["rev-parse", "--git-common-dir"]),
    ]
    .into_iter()
    .flatten()
    {
        for f in ["HEAD", "refs/heads", "packed-refs"] {
            watch.push(Path::new(&dir).join(f).display().to_string());
        }
    }
    for p in watch.iter().filter(|p| Path::new(p).exists()) {
        println!("cargo:rerun-if-changed={p}");
    }
}
