//! `furfit view --serve DIR`: a small static file server on 127.0.0.1 (std::net: a page
//! of four files needs GET and HEAD only, and no dependency is worth that).

use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};

/// Bind `127.0.0.1:port` (0 = any free port) for `dir`, which must hold a view.
pub fn bind(dir: &Path, port: u16) -> crate::Result<TcpListener> {
    if !dir.join("index.html").is_file() {
        return Err(crate::Error::file(
            dir,
            "holds no index.html: not a view (write one with furfit view --params FIT --out DIR)",
        ));
    }
    TcpListener::bind(("127.0.0.1", port)).map_err(|e| {
        if e.kind() == std::io::ErrorKind::AddrInUse {
            crate::Error::Invalid(format!(
                "--port {port}: 127.0.0.1:{port} is in use by another program; choose another --port (0 picks a free one)"
            ))
        } else {
            crate::Error::Invalid(format!("--port {port}: cannot listen on 127.0.0.1:{port}: {e}"))
        }
    })
}

/// Serve `dir` on `listener` until the process ends (one thread per connection).
pub fn run(dir: &Path, listener: TcpListener) -> crate::Result<()> {
    let root = dir.canonicalize().map_err(|e| crate::Error::io(dir, e))?;
    for stream in listener.incoming() {
        let Ok(stream) = stream else { continue };
        let root = root.clone();
        std::thread::spawn(move || {
            let _ = handle(&root, stream);
        });
    }
    Ok(())
}

/// The URL a listener serves.
pub fn url(addr: SocketAddr) -> String {
    format!("http://{addr}/")
}

fn content_type(p: &Path) -> &'static str {
    match p.extension().and_then(|e| e.to_str()) {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript; charset=utf-8",
        Some("json") => "application/json",
        Some("png") => "image/png",
        Some("css") => "text/css",
        _ => "application/octet-stream",
    }
}

/// The file under `root` a request path names, if it is one (no `..`, no hidden files).
fn resolve(root: &Path, target: &str) -> Option<PathBuf> {
    let path = target.split(['?', '#']).next().unwrap_or("/");
    let mut p = root.to_path_buf();
    for part in path.split('/').filter(|s| !s.is_empty()) {
        if part == ".." || part.starts_with('.') || part.contains('\\') {
            return None;
        }
        p.push(part);
    }
    if p.is_dir() {
        p.push("index.html");
    }
    p.is_file().then_some(p)
}

fn handle(root: &Path, mut stream: TcpStream) -> std::io::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut line = String::new();
    reader.read_line(&mut line)?;
    // Drain the headers.
    let mut h = String::new();
    while reader.read_line(&mut h)? > 2 {
        h.clear();
    }
    let mut parts = line.split_whitespace();
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or("/"));
    let respond = |s: &mut TcpStream, code: &str, ctype: &str, body: &[u8], head: bool| {
        write!(s, "HTTP/1.1 {code}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n", body.len())?;
        if !head {
            s.write_all(body)?;
        }
        s.flush()
    };
    if method != "GET" && method != "HEAD" {
        return respond(
            &mut stream,
            "405 Method Not Allowed",
            "text/plain",
            b"GET only\n",
            false,
        );
    }
    match resolve(root, target).and_then(|p| std::fs::read(&p).ok().map(|b| (p, b))) {
        Some((p, body)) => respond(
            &mut stream,
            "200 OK",
            content_type(&p),
            &body,
            method == "HEAD",
        ),
        None => respond(
            &mut stream,
            "404 Not Found",
            "text/plain",
            b"not found\n",
            method == "HEAD",
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_stay_inside_the_root() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("index.html"), "x").unwrap();
        std::fs::write(dir.path().join(".secret"), "x").unwrap();
        assert!(resolve(dir.path(), "/").is_some());
        assert!(resolve(dir.path(), "/index.html?x=1").is_some());
        assert!(resolve(dir.path(), "/../etc/passwd").is_none());
        assert!(resolve(dir.path(), "/.secret").is_none());
        assert!(resolve(dir.path(), "/missing.js").is_none());
    }
}
