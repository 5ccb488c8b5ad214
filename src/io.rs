//! Small file helpers shared by every writer: atomic writes, so that nothing a user had is
//! lost or half-written when a run is interrupted.

use crate::error::{Error, Result};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Temporaries being filled or awaiting their rename ([`write_temp`] to [`commit`]): what
/// [`install_interrupt_cleanup`]'s handler removes. A group write's backups are not
/// listed: the handler waits for the group ([`COMMIT`]), which removes them itself.
static IN_FLIGHT: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Held by a group write ([`write_atomic_all`]) from its backups to its last rename or
/// rollback, and by the interrupt handler before it cleans up: a signal then lets the
/// group land whole (or roll back) instead of leaving some files new and some old.
static COMMIT: Mutex<()> = Mutex::new(());

fn lock<T>(m: &'static Mutex<T>) -> std::sync::MutexGuard<'static, T> {
    // A panic while holding the lock leaves the data usable.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

fn in_flight() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    lock(&IN_FLIGHT)
}

fn forget_temp(tmp: &Path) {
    in_flight().retain(|p| p != tmp);
}

/// Remove a temporary that will not be committed, and unlist it.
fn discard_temp(tmp: &Path) {
    let _ = std::fs::remove_file(tmp);
    forget_temp(tmp);
}

/// On SIGINT, SIGTERM or SIGHUP: let a group write in progress finish, remove the
/// temporaries of writes in flight, then die of the signal as if there were no handler
/// (so a shell loop around furfit still stops on Ctrl-C, and the exit status says which
/// signal), instead of leaving a hidden, half-written `.<name>.tmp-<pid>` beside the
/// target (the target itself is never touched before the rename). A signal the process
/// was started ignoring (SIGHUP under `nohup`, SIGINT in a background job) stays
/// ignored. The binary calls this once at start; if the handler cannot be set up the
/// default actions stay (stale temporaries are still removed by the next write to the
/// same path, see `remove_stale_siblings`).
#[cfg(unix)]
pub fn install_interrupt_cleanup() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let wanted: Vec<i32> = [SIGINT, SIGTERM, SIGHUP]
        .into_iter()
        .filter(|&s| !signal_ignored(s))
        .collect();
    let Ok(mut signals) = signal_hook::iterator::Signals::new(&wanted) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            let _group = lock(&COMMIT);
            // Held until the process ends: no new temporary is created after the sweep.
            let mut list = in_flight();
            for p in list.drain(..) {
                let _ = std::fs::remove_file(p);
            }
            let _ = signal_hook::low_level::emulate_default_handler(sig);
            std::process::exit(128 + sig);
        }
    });
}

#[cfg(not(unix))]
pub fn install_interrupt_cleanup() {}

/// Was the process started with `sig` ignored (`SIG_IGN`)?
#[cfg(unix)]
fn signal_ignored(sig: i32) -> bool {
    // SAFETY: sigaction with a null new action only reads the current one into `old`.
    unsafe {
        let mut old: libc::sigaction = std::mem::zeroed();
        libc::sigaction(sig, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
    }
}

/// Write `bytes` to `path` atomically: write a temporary file in the same directory, flush
/// and sync it, then rename it over `path` (rename is atomic on POSIX file systems).
/// Creates the parent directory if needed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Like [`write_atomic`] but lets the caller stream into the temporary file.
pub fn write_atomic_with<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut std::fs::File) -> std::io::Result<()>,
{
    let tmp = write_temp(path, fill)?;
    commit(&tmp, path)
}

/// Write several files as one: every file goes to a temporary beside its target first, and
/// only when all are written are they renamed into place, so a failure (a full disk, a
/// directory in the way) leaves none of them new or half-written. A target that is an
/// existing directory is refused before anything is written; should a rename still fail
/// after others succeeded, those are rolled back to their previous content (or removed if
/// they are new).
pub fn write_atomic_all(files: &[(PathBuf, Vec<u8>)]) -> Result<()> {
    for (i, (p, _)) in files.iter().enumerate() {
        if files[..i].iter().any(|(q, _)| q == p) {
            // Two writes to one path would share a temporary and a backup.
            return Err(Error::file(p, "given twice in one group write"));
        }
    }
    write_all_with(files, |from, to| std::fs::rename(from, to))
}

/// [`write_atomic_all`] with the rename of the commit phase given (tests inject failures).
fn write_all_with(
    files: &[(PathBuf, Vec<u8>)],
    rename: impl Fn(&Path, &Path) -> std::io::Result<()>,
) -> Result<()> {
    for (path, _) in files {
        if path.is_dir() {
            return Err(Error::file(path, "is a directory; nothing was written"));
        }
    }
    let mut temps: Vec<PathBuf> = Vec::with_capacity(files.len());
    let remove_all = |paths: &mut dyn Iterator<Item = &PathBuf>| {
        for p in paths {
            discard_temp(p);
        }
    };
    for (path, bytes) in files {
        match write_temp(path, |w| w.write_all(bytes)) {
            Ok(t) => temps.push(t),
            Err(e) => {
                remove_all(&mut temps.iter());
                return Err(e);
            }
        }
    }
    // From here to the last rename or rollback, an interrupt waits (see COMMIT).
    let _group = lock(&COMMIT);
    // Backups of the targets that exist (hard links: no copy of the bytes), to roll back.
    let mut backups: Vec<Option<PathBuf>> = Vec::with_capacity(files.len());
    for (path, _) in files {
        // Anything but a directory (refused above) is backed up, a symlink included (a hard
        // link to a symlink is the symlink itself on Linux).
        let b = if path.symlink_metadata().is_ok() {
            let b = sibling(path, "bak");
            let _ = std::fs::remove_file(&b);
            match std::fs::hard_link(path, &b).or_else(|_| std::fs::copy(path, &b).map(drop)) {
                Ok(()) => Some(b),
                Err(e) => {
                    // A copy may have failed half-way.
                    let _ = std::fs::remove_file(&b);
                    remove_all(&mut temps.iter().chain(backups.iter().flatten()));
                    return Err(Error::io(path, e));
                }
            }
        } else {
            None
        };
        backups.push(b);
    }
    for (i, (tmp, (path, _))) in temps.iter().zip(files).enumerate() {
        if let Err(e) = rename(tmp, path) {
            for (j, (p, _)) in files[..i].iter().enumerate() {
                match &backups[j] {
                    Some(b) => {
                        let _ = std::fs::rename(b, p);
                    }
                    None => {
                        let _ = std::fs::remove_file(p);
                    }
                }
            }
            remove_all(&mut temps[i..].iter().chain(backups[i..].iter().flatten()));
            return Err(Error::io(path, e));
        }
        forget_temp(tmp);
    }
    remove_all(&mut backups.iter().flatten());
    Ok(())
}

/// Check, before any work, that the directory `dir` exists or can be created: every
/// existing ancestor must be a directory. Long jobs call this (and [`check_out_file`])
/// first, so a bad `--out` fails at once instead of after the computation.
pub fn check_out_dir(dir: &Path) -> Result<()> {
    for a in dir.ancestors().filter(|a| !a.as_os_str().is_empty()) {
        match std::fs::metadata(a) {
            Ok(m) if m.is_dir() => return Ok(()),
            Ok(_) => {
                return Err(Error::file(
                    dir,
                    format!("cannot write here: {} is not a directory", a.display()),
                ))
            }
            // A link to nothing: the folder could not be created there (the run failed
            // only when it wrote, after the work; review, 2026-11-28).
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && is_dangling_link(a) => {
                return Err(Error::file(
                    dir,
                    format!(
                        "cannot write here: {} is a symbolic link to a missing target",
                        a.display()
                    ),
                ))
            }
            // Not found, or below a file (ENOTDIR): the ancestor in the way decides.
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
                ) =>
            {
                continue
            }
            Err(e) => return Err(Error::io(a, e)),
        }
    }
    Ok(())
}

/// [`check_out_dir`] for the directory of the file `path`, which must not itself be a
/// directory, nor name one (`out.json/`: `Path` drops the trailing `/`, the OS does not).
pub fn check_out_file(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::file(path, "is a directory, expected a file path"));
    }
    // The write would replace the link itself, a file the user made (audit, 2026-11-28).
    if is_dangling_link(path) {
        return Err(Error::file(
            path,
            "is a symbolic link to a missing target: not replaced (remove it first)",
        ));
    }
    let text = path.as_os_str().to_string_lossy();
    if matches!(
        text.rsplit(std::path::is_separator).next(),
        Some("" | "." | "..")
    ) {
        return Err(Error::file(path, "names a directory, expected a file path"));
    }
    check_out_dir(&parent_dir(path))
}

/// Whether the file `path` can be written, before a long job computes it: a probe file in
/// its directory, or (when that does not exist yet, as `fits/` on a first fit) in the
/// nearest existing ancestor, where the directory would be created. Creates nothing that
/// stays. [`check_out_file`] first.
pub fn probe_file_writable(path: &Path) -> Result<()> {
    check_out_file(path)?;
    let dir = parent_dir(path);
    let Some(existing) = dir
        .ancestors()
        .find(|a| a.as_os_str().is_empty() || a.is_dir())
    else {
        return Ok(());
    };
    let existing = if existing.as_os_str().is_empty() {
        Path::new(".")
    } else {
        existing
    };
    probe_dir(existing).map_err(|e| {
        Error::file(
            path,
            format!(
                "cannot be written: no file can be created in {} ({e}); nothing was run",
                existing.display()
            ),
        )
    })
}

/// Create and remove a probe file in the existing directory `dir`: whether a file can be
/// created there. A name no other probe holds is taken (a killed run's leftover of a
/// reused pid is skipped).
fn probe_dir(dir: &Path) -> std::io::Result<()> {
    let mut attempt = 0u32;
    loop {
        let probe = dir.join(format!(".furfit-probe-{}-{attempt}", std::process::id()));
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&probe)
        {
            Ok(_) => {
                let _ = std::fs::remove_file(&probe);
                return Ok(());
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && attempt < 64 => attempt += 1,
            Err(e) => return Err(e),
        }
    }
}

/// What marks a [`kept_path`] in a file name.
const KEPT: &str = ".kept-";

/// A path beside `path` that nothing holds yet, for a result that may not go to `path`:
/// `<name>.kept-<pid>`, then `-2`, `-3`, ... (`None` after 99 taken names).
pub fn kept_path(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_string_lossy().into_owned();
    let pid = std::process::id();
    (1..100)
        .map(|k| {
            let suffix = if k == 1 {
                format!("{pid}")
            } else {
                format!("{pid}-{k}")
            };
            parent_dir(path).join(format!("{name}{KEPT}{suffix}"))
        })
        .find(|p| std::fs::symlink_metadata(p).is_err())
}

/// Whether `path` is named like a [`kept_path`] (a result kept from a refused run).
pub fn is_kept_path(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n.to_string_lossy().contains(KEPT))
}

/// Whether `path` is a symbolic link whose target does not exist (`exists()` says false,
/// yet an atomic write's rename would replace the link).
pub fn is_dangling_link(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.is_symlink()) && !path.exists()
}

/// The directory `path` is in (`.` for a bare file name).
pub(crate) fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A hidden file beside `path` for this process: `.<name>.<what>-<pid>`.
fn sibling(path: &Path, what: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    parent_dir(path).join(format!(".{name}.{what}-{}", std::process::id()))
}

/// Fill a synced temporary file beside `path` (its directory created if needed) and return
/// its path; on failure it is removed.
fn write_temp<F>(path: &Path, fill: F) -> Result<PathBuf>
where
    F: FnOnce(&mut std::fs::File) -> std::io::Result<()>,
{
    let dir = parent_dir(path);
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    if path.file_name().is_none() {
        return Err(Error::file(path, "not a file path"));
    }
    let tmp = sibling(path, "tmp");
    let result = (|| {
        // Listed and created under the lock, so the interrupt handler's sweep cannot miss
        // a temporary created while it runs.
        let mut f = {
            let mut list = in_flight();
            list.push(tmp.clone());
            std::fs::File::create(&tmp)?
        };
        fill(&mut f)?;
        f.flush()?;
        f.sync_all()?;
        Ok(())
    })();
    if let Err(e) = result {
        discard_temp(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(tmp)
}

/// Rename a temporary from [`write_temp`] over `path` (atomic on POSIX file systems).
fn commit(tmp: &Path, path: &Path) -> Result<()> {
    std::fs::rename(tmp, path).map_err(|e| {
        discard_temp(tmp);
        Error::io(path, e)
    })?;
    forget_temp(tmp);
    Ok(())
}

/// `path` made absolute with symbolic links and `..` resolved as far as it exists (the
/// rest appended as written): a file about to be written has no canonical path yet.
pub fn resolve_path(path: &Path) -> PathBuf {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut rest = Vec::new();
    let mut head = abs.as_path();
    loop {
        if let Ok(c) = head.canonicalize() {
            return rest
                .iter()
                .rev()
                .fold(c, |acc: PathBuf, part| acc.join(part));
        }
        match (head.parent(), head.file_name()) {
            (Some(p), Some(name)) => {
                rest.push(name.to_owned());
                head = p;
            }
            _ => return abs,
        }
    }
}

/// The relative path from the directory `base` to `target`, both absolute (as from
/// [`resolve_path`]): `..` for each of `base`'s components past their common prefix.
pub fn relative_path(base: &Path, target: &Path) -> PathBuf {
    let b: Vec<_> = base.components().collect();
    let t: Vec<_> = target.components().collect();
    let common = b.iter().zip(&t).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c);
    }
    out
}

/// Read and parse a JSON file; a syntax error names the file, line and column.
pub fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_json(&text, path)
}

/// Parse JSON text read from `path`; a syntax error, or a key repeated in one object
/// (serde_json would silently keep the last: `"l": 0.68, "l": 0.7`), names the file, line
/// and column. A leading UTF-8 byte-order mark (Windows editors save one) is skipped.
pub fn parse_json(text: &str, path: &Path) -> Result<serde_json::Value> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if let Some((line, column, msg)) = underflowing_number(text) {
        return Err(Error::Parse {
            file: path.into(),
            line,
            column: format!("column {column}"),
            msg,
        });
    }
    serde_json::from_str::<UniqueKeys>(text)
        .map(|u| u.0)
        .map_err(|e| Error::Parse {
            file: path.into(),
            line: e.line(),
            // serde_json counts columns from 1 but reports 0 at the start of a line.
            column: format!("column {}", e.column().max(1)),
            msg: if text.trim().is_empty() {
                "empty file, expected a JSON object".into()
            } else {
                // serde_json ends its message with the place, which the error leads with.
                let m = e.to_string();
                let place = format!(" at line {} column {}", e.line(), e.column());
                format!("invalid JSON: {}", m.strip_suffix(&place).unwrap_or(&m))
            },
        })
}

/// The first number of JSON `text` (outside strings) below the f64 range, which serde_json
/// would read as 0 (`"kappa": 1e-400`), as (line, column, message); the same rule as a
/// profile file's numbers ([`crate::text::parse_number`]).
fn underflowing_number(text: &str) -> Option<(usize, usize, String)> {
    // Columns in bytes from 1, as serde_json counts them for its own errors.
    let (mut line, mut line_start) = (1, 0);
    let (mut in_string, mut escaped) = (false, false);
    let mut chars = text.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        if c == '\n' {
            (line, line_start) = (line + 1, i + 1);
            continue;
        }
        if in_string {
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => in_string = false,
                _ => {}
            }
            continue;
        }
        if c == '"' {
            in_string = true;
        } else if c == '-' || c.is_ascii_digit() {
            let mut end = i + 1;
            while let Some(&(j, d)) = chars.peek() {
                if !(d.is_ascii_digit() || matches!(d, '.' | 'e' | 'E' | '+' | '-')) {
                    break;
                }
                end = j + 1;
                chars.next();
            }
            // Only the below-range rule: a malformed number is serde_json's to report.
            let token = &text[i..end];
            if let (Ok(0.0), Err(m)) = (token.parse::<f64>(), crate::text::parse_number(token)) {
                return Some((line, i - line_start + 1, m));
            }
        }
    }
    None
}

/// A JSON value read with every object's keys checked to be distinct ([`parse_json`]).
struct UniqueKeys(serde_json::Value);

impl<'de> serde::Deserialize<'de> for UniqueKeys {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_any(UniqueKeysVisitor)
    }
}

struct UniqueKeysVisitor;

impl<'de> serde::de::Visitor<'de> for UniqueKeysVisitor {
    type Value = UniqueKeys;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> std::result::Result<UniqueKeys, E> {
        Ok(UniqueKeys(v.into()))
    }
    fn visit_i64<E>(self, v: i64) -> std::result::Result<UniqueKeys, E> {
        Ok(UniqueKeys(v.into()))
    }
    fn visit_u64<E>(self, v: u64) -> std::result::Result<UniqueKeys, E> {
        Ok(UniqueKeys(v.into()))
    }
    fn visit_f64<E>(self, v: f64) -> std::result::Result<UniqueKeys, E> {
        Ok(UniqueKeys(v.into()))
    }
    fn visit_str<E>(self, v: &str) -> std::result::Result<UniqueKeys, E> {
        Ok(UniqueKeys(v.into()))
    }
    fn visit_unit<E>(self) -> std::result::Result<UniqueKeys, E> {
        Ok(UniqueKeys(serde_json::Value::Null))
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(
        self,
        mut seq: A,
    ) -> std::result::Result<UniqueKeys, A::Error> {
        let mut v = Vec::new();
        while let Some(UniqueKeys(x)) = seq.next_element()? {
            v.push(x);
        }
        Ok(UniqueKeys(v.into()))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(
        self,
        mut map: A,
    ) -> std::result::Result<UniqueKeys, A::Error> {
        let mut m = serde_json::Map::new();
        while let Some(k) = map.next_key::<String>()? {
            if m.contains_key(&k) {
                return Err(serde::de::Error::custom(format!(
                    "key \"{k}\" appears twice in one object"
                )));
            }
            let UniqueKeys(v) = map.next_value()?;
            m.insert(k, v);
        }
        Ok(UniqueKeys(m.into()))
    }
}

/// Content hash (SHA-256, lower-case hex) of a byte string; fits record the hash of the data
/// they were made from.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    let digest = Sha256::digest(bytes);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// Make sure `dir` can take new files before a long job (the directory is created if
/// missing): a read-only folder otherwise failed `stability` after its two-minute sweep.
/// Returns whether it created the directory (the CLI says so: a mistyped path is then no
/// silent success).
pub fn probe_writable(dir: &Path) -> Result<bool> {
    check_out_dir(dir)?;
    let created = !dir.exists();
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    probe_dir(dir).map_err(|e| {
        Error::file(
            dir,
            format!("cannot write into this folder ({e}); nothing was run"),
        )
    })?;
    Ok(created)
}

/// The fit files of a folder, sorted by name: its `*.json` files except hidden ones (a
/// name starting with `.`), which are not fits (furfit's own [`LEDGER`] lands in a fits
/// folder that `render --out` wrote into). `report` and `render --all` read this list.
pub fn fit_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut paths: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("json"))
                && p.file_name()
                    .is_some_and(|n| !n.to_string_lossy().starts_with('.'))
        })
        .collect();
    paths.sort();
    Ok(paths)
}

/// The ledger furfit keeps in each directory that `render`, `render-convergence`,
/// `report`, `stability`, `se-calibration` and `bench-model` write into: the files it wrote there, each with
/// the SHA-256 of the bytes written. Those commands replace an existing file only when the
/// ledger lists it with its current content ([`check_replaceable`]), so a user's own file
/// of the same name (or a furfit output the user edited since) is never lost silently.
pub const LEDGER: &str = ".furfit-outputs.json";
/// The lock file beside a [`LEDGER`] that serialises its updates.
pub const LEDGER_LOCK: &str = ".furfit-outputs.lock";
/// What to do about a damaged ledger.
const LEDGER_FIX: &str = "delete it to start a new one (the files it listed are then \
    protected as files furfit did not write: replace them with --force)";

fn read_ledger(dir: &Path) -> Result<serde_json::Map<String, serde_json::Value>> {
    let path = dir.join(LEDGER);
    match std::fs::read_to_string(&path) {
        Ok(text) => match serde_json::from_str::<serde_json::Value>(&text) {
            Ok(serde_json::Value::Object(mut m)) => match m.remove("files") {
                Some(serde_json::Value::Object(files)) => Ok(files),
                _ => Err(Error::file(
                    &path,
                    format!("not a furfit ledger (no \"files\" object); {LEDGER_FIX}"),
                )),
            },
            _ => Err(Error::file(
                &path,
                format!("not a furfit ledger (not a JSON object); {LEDGER_FIX}"),
            )),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(serde_json::Map::new()),
        Err(e) => Err(Error::io(&path, e)),
    }
}

/// Refuse, unless `force`, any of `paths` that exists and is not a furfit output recorded
/// in its directory's [`LEDGER`] with its current content; checked before a long job runs.
pub fn check_replaceable(paths: &[PathBuf], force: bool) -> Result<()> {
    if force {
        return Ok(());
    }
    for p in paths {
        if is_dangling_link(p) {
            return Err(Error::file(
                p,
                "is a symbolic link to a missing target: not replaced (remove it, or give \
                 --force)",
            ));
        }
        if !p.exists() {
            continue;
        }
        let dir = parent_dir(p);
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
        let ledger = read_ledger(&dir)?;
        // A digest, or the two an interrupted write_output left (before and after).
        let recorded: Option<Vec<&str>> =
            name.as_deref()
                .and_then(|n| ledger.get(n))
                .map(|v| match v.as_array() {
                    Some(a) => a.iter().filter_map(|h| h.as_str()).collect(),
                    None => v.as_str().into_iter().collect(),
                });
        let why = match recorded {
            None => format!(
                "exists and was not written by furfit (it is not in {})",
                dir.join(LEDGER).display()
            ),
            Some(hashes) => {
                let bytes = std::fs::read(p).map_err(|e| Error::io(p, e))?;
                if hashes.contains(&sha256_hex(&bytes).as_str()) {
                    continue;
                }
                "was changed since furfit wrote it".to_string()
            }
        };
        return Err(Error::file(
            p,
            format!("{why}; give --force to replace it, or choose another --out"),
        ));
    }
    Ok(())
}

/// Remove the temporaries ([`sibling`] files `.<name>.<what>-<pid>`) that a furfit
/// process killed while writing `path` left beside it: those of processes no longer
/// running. Needs `/proc` to tell (Linux); elsewhere it leaves them.
fn remove_stale_siblings(path: &Path) {
    let (Some(name), true) = (path.file_name(), Path::new("/proc/self").exists()) else {
        return;
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    let Ok(rd) = std::fs::read_dir(parent_dir(path)) else {
        return;
    };
    for e in rd.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix) else {
            continue;
        };
        let pid = ["tmp-", "bak-"]
            .iter()
            .find_map(|w| rest.strip_prefix(w))
            .and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid {
            if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// [`write_atomic`] an output of a ledger-keeping command and record it in its folder's
/// [`LEDGER`] at once: a run stopped after it (an error, Ctrl-C) leaves it listed as
/// furfit's, so the next run replaces it without --force.
pub fn write_output(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = write_temp(path, |w| w.write_all(bytes))?;
    let new = sha256_hex(bytes);
    if let Err(e) = record_entries(vec![(path, pending_entry(path, &new))]) {
        discard_temp(&tmp);
        return Err(e);
    }
    commit(&tmp, path)?;
    remove_stale_siblings(path);
    record_entries(vec![(path, new.into())])
}

/// [`write_atomic_all`] a group of outputs of a ledger-keeping command and record them in
/// their folders' [`LEDGER`]s, as [`write_output`] does for one file: an interrupt lets
/// the group land whole, and at every moment each file is listed with what it holds (an
/// interrupt between the renames and a separate recording left the new files unlisted,
/// so the same command then refused to replace its own outputs; audit, 2026-12-02).
pub fn write_outputs(files: &[(PathBuf, Vec<u8>)]) -> Result<()> {
    let news = land_outputs(files)?;
    record_entries(
        files
            .iter()
            .zip(news)
            .map(|((p, _), new)| (p.as_path(), new.into()))
            .collect(),
    )
}

/// The part of [`write_outputs`] up to the renames: the files listed with both contents,
/// then written as a group. Returns the new contents' digests.
fn land_outputs(files: &[(PathBuf, Vec<u8>)]) -> Result<Vec<String>> {
    let news: Vec<String> = files.iter().map(|(_, b)| sha256_hex(b)).collect();
    record_entries(
        files
            .iter()
            .zip(&news)
            .map(|((p, _), new)| (p.as_path(), pending_entry(p, new)))
            .collect(),
    )?;
    write_atomic_all(files)?;
    for (p, _) in files {
        remove_stale_siblings(p);
    }
    Ok(news)
}

/// The ledger entry of `path` while its new content (digest `new`) is on the way: until
/// the rename the ledger accepts the content in place as well as the new one, so a kill
/// at any point leaves the file listed with what it holds.
fn pending_entry(path: &Path, new: &str) -> serde_json::Value {
    match std::fs::read(path) {
        Ok(old) => serde_json::json!([sha256_hex(&old), new]),
        Err(_) => new.into(),
    }
}

/// Record `paths` (just written by furfit) with their content in their directories'
/// [`LEDGER`]s (each written atomically), and remove what an interrupted earlier run left
/// of them ([`remove_stale_siblings`]).
pub fn record_outputs(paths: &[PathBuf]) -> Result<()> {
    let mut entries = Vec::with_capacity(paths.len());
    for p in paths {
        remove_stale_siblings(p);
        let bytes = std::fs::read(p).map_err(|e| Error::io(p, e))?;
        entries.push((p.as_path(), sha256_hex(&bytes).into()));
    }
    record_entries(entries)
}

/// Set each `(path, digest or digests)` in its directory's [`LEDGER`], one update per
/// directory.
fn record_entries(entries: Vec<(&Path, serde_json::Value)>) -> Result<()> {
    let mut by_dir: std::collections::BTreeMap<PathBuf, Vec<(String, serde_json::Value)>> =
        Default::default();
    for (p, digest) in entries {
        let Some(name) = p.file_name().map(|n| n.to_string_lossy().into_owned()) else {
            continue;
        };
        by_dir
            .entry(parent_dir(p))
            .or_default()
            .push((name, digest));
    }
    for (dir, entries) in by_dir {
        update_ledger(&dir, entries)?;
    }
    Ok(())
}

/// Set `entries` (file name, digest or digests) in `dir`'s [`LEDGER`], written atomically
/// under the lock beside it.
fn update_ledger(dir: &Path, entries: Vec<(String, serde_json::Value)>) -> Result<()> {
    // Two furfit runs writing into one folder at once would each read the ledger, add
    // their files and write it back, the later dropping the earlier's entries: the
    // read-modify-write holds an exclusive lock on a file beside it (released when the
    // handle drops, also if the process dies).
    let lock_path = dir.join(LEDGER_LOCK);
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(|e| Error::io(&lock_path, e))?;
    lock.lock().map_err(|e| Error::io(&lock_path, e))?;
    // A ledger that is not one (hand-edited) is replaced: it protects nothing then.
    let mut ledger = read_ledger(dir).unwrap_or_default();
    for (name, digest) in entries {
        ledger.insert(name, digest);
    }
    let v = serde_json::json!({
        "note": "files furfit wrote here, with the SHA-256 of their content: furfit replaces an existing file only if it is listed here unchanged (or with --force)",
        "files": ledger,
    });
    let text = serde_json::to_string_pretty(&v).expect("JSON of strings") + "\n";
    write_atomic(&dir.join(LEDGER), text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Recording an output removes the temporaries a killed run left of it (their process
    /// is gone), not those of a running process (this one), nor other files.
    #[cfg(target_os = "linux")]
    #[test]
    fn record_removes_temporaries_of_dead_runs() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let out = d.join("nrmse.md");
        std::fs::write(&out, "x").unwrap();
        // Above Linux's largest pid (2^22), so no process has it.
        let dead = [".nrmse.md.tmp-4194305", ".nrmse.md.bak-4194305"];
        let alive = format!(".nrmse.md.tmp-{}", std::process::id());
        let other = [".other.md.tmp-4194305", ".nrmse.md.tmp-x"];
        for n in dead.iter().chain(&other).chain([&alive.as_str()]) {
            std::fs::write(d.join(n), "t").unwrap();
        }
        record_outputs(std::slice::from_ref(&out)).unwrap();
        for n in dead {
            assert!(!d.join(n).exists(), "{n}");
        }
        for n in other.iter().chain([&alive.as_str()]) {
            assert!(d.join(n).exists(), "{n}");
        }
    }

    /// A dangling symbolic link on the way to an output is refused before the work (it
    /// was passed over as a missing folder, and the write failed after a whole fit), and
    /// fit files are listed without hidden files such as the ledger.
    #[cfg(unix)]
    #[test]
    fn dangling_link_is_refused_and_hidden_files_are_no_fits() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("fits");
        std::os::unix::fs::symlink(dir.path().join("missing"), &link).unwrap();
        let e = probe_file_writable(&link.join("mouse.json")).unwrap_err();
        assert!(e.to_string().contains("symbolic link"), "{e}");
        // The output itself a dangling link: refused too, by both checks.
        let out = dir.path().join("out.png");
        std::os::unix::fs::symlink(dir.path().join("gone.png"), &out).unwrap();
        for e in [
            check_out_file(&out).unwrap_err(),
            check_replaceable(std::slice::from_ref(&out), false).unwrap_err(),
        ] {
            assert!(e.to_string().contains("symbolic link"), "{e}");
        }
        std::fs::remove_file(&link).unwrap();
        std::fs::create_dir(&link).unwrap();
        probe_file_writable(&link.join("mouse.json")).unwrap();
        for n in ["b.json", "a.json", LEDGER, ".x.json", "c.txt"] {
            std::fs::write(link.join(n), "{}").unwrap();
        }
        assert_eq!(
            fit_files(&link).unwrap(),
            vec![link.join("a.json"), link.join("b.json")]
        );
    }

    /// Concurrent ledger updates into one folder keep every entry (each holds the lock
    /// for its read-modify-write; without it, runs lost each other's entries).
    #[test]
    fn concurrent_records_keep_every_entry() {
        let dir = tempfile::tempdir().unwrap();
        let paths: Vec<PathBuf> = (0..16)
            .map(|k| dir.path().join(format!("f{k}.png")))
            .collect();
        std::thread::scope(|sc| {
            for p in &paths {
                sc.spawn(move || {
                    write_atomic(p, p.to_string_lossy().as_bytes()).unwrap();
                    record_outputs(std::slice::from_ref(p)).unwrap();
                });
            }
        });
        check_replaceable(&paths, false).unwrap();
        let ledger = read_ledger(dir.path()).unwrap();
        assert_eq!(ledger.len(), paths.len());
    }

    /// A furfit output may be replaced while unchanged; a user's file of the same name, or
    /// an output edited since, only with force.
    #[test]
    fn ledger_protects_files_furfit_did_not_write() {
        let dir = tempfile::tempdir().unwrap();
        let (ours, theirs) = (dir.path().join("a.png"), dir.path().join("b.png"));
        let both = [ours.clone(), theirs.clone()];
        // Nothing exists yet: nothing to protect.
        check_replaceable(&both, false).unwrap();
        write_atomic(&ours, b"render 1").unwrap();
        std::fs::write(&theirs, b"my photo").unwrap();
        record_outputs(std::slice::from_ref(&ours)).unwrap();
        check_replaceable(std::slice::from_ref(&ours), false).unwrap();
        let e = check_replaceable(&both, false).unwrap_err().to_string();
        assert!(
            e.contains("b.png") && e.contains("not written by furfit"),
            "{e}"
        );
        check_replaceable(&both, true).unwrap();
        // An edited output is the user's now.
        std::fs::write(&ours, b"render 1, retouched").unwrap();
        let e = check_replaceable(std::slice::from_ref(&ours), false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("changed since furfit wrote it"), "{e}");
        // Recording again (after furfit rewrote it) makes it replaceable again.
        write_atomic(&ours, b"render 2").unwrap();
        record_outputs(std::slice::from_ref(&ours)).unwrap();
        check_replaceable(std::slice::from_ref(&ours), false).unwrap();
        assert_eq!(std::fs::read(&theirs).unwrap(), b"my photo");
    }

    /// A group of outputs is listed with what each file holds at every step: a run stopped
    /// right after the renames (before the final ledger update) leaves files the same
    /// command may replace without --force, and so does a finished one.
    #[test]
    fn group_outputs_stay_listed_through_an_interrupt() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("r.csv"), dir.path().join("r.md"));
        let both = [a.clone(), b.clone()];
        write_outputs(&[(a.clone(), b"v1".to_vec()), (b.clone(), b"m1".to_vec())]).unwrap();
        check_replaceable(&both, false).unwrap();
        // Stopped after the renames: the new contents are listed (beside the old ones).
        land_outputs(&[(a.clone(), b"v2".to_vec()), (b.clone(), b"m2".to_vec())]).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"v2");
        check_replaceable(&both, false).unwrap();
        // A later run lists only what the files hold.
        write_outputs(&[(a.clone(), b"v3".to_vec()), (b.clone(), b"m3".to_vec())]).unwrap();
        let ledger = read_ledger(dir.path()).unwrap();
        assert_eq!(ledger["r.csv"], serde_json::Value::from(sha256_hex(b"v3")));
        std::fs::write(&b, b"edited").unwrap();
        let e = check_replaceable(&both, false).unwrap_err().to_string();
        assert!(e.contains("r.md") && e.contains("changed since"), "{e}");
    }

    /// A key given twice in one object is an error naming the line (serde_json alone keeps
    /// the last value); the same key in two objects is fine.
    #[test]
    fn json_keys_repeated_in_one_object_are_refused() {
        let p = Path::new("p.json");
        let e = parse_json("{\"l\": 0.68,\n \"l\": 0.7}", p)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("p.json:2") && e.contains("\"l\" appears twice"),
            "{e}"
        );
        let v = parse_json("{\"a\": {\"l\": 1}, \"b\": [{\"l\": 2.5}, null, true]}", p).unwrap();
        assert_eq!(v["b"][0]["l"], 2.5);
        assert_eq!(v["a"]["l"], 1);
    }

    /// A number below the f64 range is refused at its line and column (serde_json reads it
    /// as 0); zeros, subnormals and such text inside strings are fine.
    #[test]
    fn json_numbers_below_the_f64_range_are_refused() {
        let p = Path::new("p.json");
        let e = parse_json("{\"eta\": 1.5,\n \"kappa\": -1e-400}", p)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.json:2: column 11: '-1e-400' is below the f64 range"),
            "{e}"
        );
        // Columns count bytes, as serde_json's own errors do.
        let e = parse_json("{\"ü\": 1e-400}", p).unwrap_err().to_string();
        assert!(e.starts_with("p.json:1: column 8:"), "{e}");
        let v = parse_json(
            "{\"a\": 0e-400, \"b\": 5e-324, \"c\": \"1e-400 \\\" 1e-400\"}",
            p,
        )
        .unwrap();
        assert_eq!(v["a"], 0.0);
        assert_eq!(v["b"], 5e-324);
        assert_eq!(v["c"], "1e-400 \" 1e-400");
    }

    #[test]
    fn relative_paths_between_folders() {
        let r = |b: &str, t: &str| relative_path(Path::new(b), Path::new(t));
        assert_eq!(r("/a/fits", "/a/data/x.csv"), Path::new("../data/x.csv"));
        assert_eq!(r("/a", "/a/x.csv"), Path::new("x.csv"));
        assert_eq!(r("/a/b/c", "/d/x.csv"), Path::new("../../../d/x.csv"));
        // A file to be written below a folder that does not exist yet resolves as written.
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().canonicalize().unwrap();
        assert_eq!(
            resolve_path(&dir.path().join("new/../new2/f.json")),
            real.join("new/../new2/f.json")
        );
        assert_eq!(resolve_path(&dir.path().join(".")), real);
    }

    /// JSON errors give the place once, up front, and call an empty file empty.
    #[test]
    fn json_errors_name_the_place_once() {
        let p = Path::new("p.json");
        let e = parse_json("", p).unwrap_err().to_string();
        assert_eq!(e, "p.json:1: column 1: empty file, expected a JSON object");
        let e = parse_json("{\"eta\": 1.5,\n \"kappa\": }", p)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.json:2: column 11: invalid JSON: expected value"),
            "{e}"
        );
        assert!(!e.contains("at line"), "{e}");
    }

    /// A byte-order mark (as Windows Notepad saves JSON) is not a syntax error.
    #[test]
    fn json_with_a_byte_order_mark_reads() {
        let v = parse_json("\u{feff}{\"synthetic\": true}", Path::new("m.json")).unwrap();
        assert_eq!(v["synthetic"], true);
    }

    #[test]
    fn out_checks_name_the_file_in_the_way() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("regular");
        std::fs::write(&file, b"x").unwrap();
        assert!(check_out_dir(&dir.path().join("new/deeper")).is_ok());
        assert!(check_out_dir(Path::new("relative-not-yet")).is_ok());
        let e = check_out_dir(&file.join("x")).unwrap_err().to_string();
        assert!(e.contains("regular is not a directory"), "{e}");
        let e = check_out_file(&file.join("a.png")).unwrap_err().to_string();
        assert!(e.contains("regular is not a directory"), "{e}");
        let e = check_out_file(dir.path()).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        assert!(check_out_file(&dir.path().join("a.png")).is_ok());
        for p in ["new.json/", "new.json/.", "new.json/.."] {
            let e = check_out_file(Path::new(p)).unwrap_err().to_string();
            assert!(e.contains("names a directory"), "{p}: {e}");
        }
    }

    #[test]
    fn atomic_write_replaces_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/out.txt");
        write_atomic(&p, b"first version, long").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        // No temporary file is left behind.
        let left: Vec<_> = std::fs::read_dir(p.parent().unwrap()).unwrap().collect();
        assert_eq!(left.len(), 1);
    }

    #[test]
    fn failed_fill_keeps_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("keep.txt");
        write_atomic(&p, b"precious").unwrap();
        let r = write_atomic_with(&p, |_| Err(std::io::Error::other("boom")));
        assert!(r.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"precious");
    }

    #[test]
    fn group_write_is_all_or_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.png");
        write_atomic(&a, b"old a").unwrap();
        // A directory in the way of the second file: nothing is written, a keeps its
        // content and no temporary is left.
        std::fs::create_dir(dir.path().join("b.exr")).unwrap();
        let files = vec![
            (a.clone(), b"new a".to_vec()),
            (dir.path().join("b.exr"), b"b".to_vec()),
        ];
        assert!(write_atomic_all(&files).is_err());
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
        // A file that cannot be created (its parent is a file): the others stay untouched.
        let files = vec![
            (a.clone(), b"new a".to_vec()),
            (a.join("c.png"), b"c".to_vec()),
        ];
        assert!(write_atomic_all(&files).is_err());
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
        // Otherwise every file lands.
        let files = vec![
            (a.clone(), b"new a".to_vec()),
            (dir.path().join("d/c.png"), b"c".to_vec()),
        ];
        write_atomic_all(&files).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"new a");
        assert_eq!(std::fs::read(dir.path().join("d/c.png")).unwrap(), b"c");
    }

    /// A rename failing after others succeeded: the files already renamed get their old
    /// content back (or disappear if they were new), and no temporary or backup is left.
    #[test]
    fn group_write_rolls_back_a_failed_commit() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (
            dir.path().join("a.png"),
            dir.path().join("b.png"),
            dir.path().join("c.exr"),
        );
        write_atomic(&a, b"old a").unwrap();
        let files = vec![
            (a.clone(), b"new a".to_vec()),
            (b.clone(), b"new b".to_vec()),
            (c.clone(), b"new c".to_vec()),
        ];
        let r = write_all_with(&files, |from, to| {
            if to == c.as_path() {
                Err(std::io::Error::other("injected"))
            } else {
                std::fs::rename(from, to)
            }
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert!(!b.exists() && !c.exists());
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, vec![std::ffi::OsString::from("a.png")]);
    }

    #[test]
    fn sha256_known_vector() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
