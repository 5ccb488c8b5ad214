//! `furfit view` end to end: a page is written and re-written, bad input fails clearly,
//! `--serve` serves the page and refuses a port in use. (The page in a browser:
//! tests/view_page.rs.)

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Command, Output, Stdio};

/// A small, quick view: chiang2016 tabulates in a fraction of a second.
const SMALL: [&str; 8] = [
    "--res", "16", "--shells", "4", "--fibers", "50", "--dirs", "4x6",
];

fn view(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_furfit"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("view")
        .args(args)
        .output()
        .unwrap()
}

fn page(out: &Path, extra: &[&str]) -> Output {
    let mut a = vec![
        "--params",
        "fits/chiang2016/deer.json",
        "--out",
        out.to_str().unwrap(),
    ];
    a.extend_from_slice(&SMALL);
    a.extend_from_slice(extra);
    view(&a)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn page_is_written_and_an_earlier_view_is_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v");
    let o = page(&out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["index.html", "viewer.js", "data.js", "textures.js"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let data = std::fs::read_to_string(out.join("data.js")).unwrap();
    assert!(data.starts_with("window.FURFIT = {") && data.contains("\"chiang2016\""));
    // Its own earlier output is replaced without --force.
    let o = page(&out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn out_with_other_files_needs_force() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
    let o = page(dir.path(), &[]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("notes.txt") && e.contains("--force"), "{e}");
    assert!(!dir.path().join("index.html").exists());
    let o = page(dir.path(), &["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read_to_string(dir.path().join("notes.txt")).unwrap(),
        "mine"
    );
    // A view file edited by hand is not an earlier view's any more.
    std::fs::remove_file(dir.path().join("notes.txt")).unwrap();
    assert!(page(dir.path(), &[]).status.success());
    std::fs::write(dir.path().join("index.html"), "edited").unwrap();
    let o = page(dir.path(), &[]);
    assert!(
        !o.status.success() && stderr(&o).contains("index.html"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn unreadable_fit_files_fail_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v");
    let missing = dir.path().join("missing.json");
    let o = view(&[
        "--params",
        missing.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("missing.json"), "{}", stderr(&o));
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{ not json").unwrap();
    let o = view(&[
        "--params",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("bad.json"), "{}", stderr(&o));
    assert!(!out.exists(), "nothing written on error");
}

#[test]
fn still_writes_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("s.png");
    let mut a = vec![
        "--params",
        "fits/chiang2016/deer.json",
        "--still",
        "--size",
        "40x30",
        "--out",
        png.to_str().unwrap(),
    ];
    a.extend_from_slice(&SMALL);
    let o = view(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (40, 30));
    assert!(
        img.pixels().any(|p| p.0 != img.get_pixel(0, 0).0),
        "a flat image"
    );
}

#[test]
fn serve_serves_the_page_and_refuses_a_port_in_use() {
    let dir = tempfile::tempdir().unwrap();
    assert!(page(dir.path(), &[]).status.success());
    // A port in use.
    let busy = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = busy.local_addr().unwrap().port().to_string();
    let o = view(&["--serve", dir.path().to_str().unwrap(), "--port", &port]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("in use") && e.contains(&port), "{e}");
    // Not a view.
    let empty = tempfile::tempdir().unwrap();
    let o = view(&["--serve", empty.path().to_str().unwrap(), "--port", "0"]);
    assert!(
        !o.status.success() && stderr(&o).contains("index.html"),
        "{}",
        stderr(&o)
    );
    // Served: the printed URL answers with the page.
    let mut child = Command::new(env!("CARGO_BIN_EXE_furfit"))
        .args([
            "view",
            "--serve",
            dir.path().to_str().unwrap(),
            "--port",
            "0",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .split("http://")
        .nth(1)
        .and_then(|s| s.split('/').next())
        .map(str::to_string);
    let get = |path: &str| {
        let mut s = TcpStream::connect(addr.as_deref().unwrap()).unwrap();
        write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
        let mut body = String::new();
        s.read_to_string(&mut body).unwrap();
        body
    };
    let index = get("/");
    let missing = get("/nope.js");
    let outside = get("/../Cargo.toml");
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(line.contains("http://127.0.0.1:"), "{line}");
    assert!(
        index.starts_with("HTTP/1.1 200") && index.contains("viewer.js"),
        "{index}"
    );
    assert!(missing.starts_with("HTTP/1.1 404"));
    assert!(outside.starts_with("HTTP/1.1 404"));
}
