//! Merging profiles and collapsing repeated directions: [`merge`], [`merge_loaded`], the
//! sample comparisons ([`same_sample`]) and the duplicate rules every reader shares
//! ([`dedupe`], [`wrap_conflict`]).

use super::checks::{canonical_phi, converts_phi, wrap_phi};
use super::sample::{
    place_text, Field, Format, Layout, LoadOptions, Loaded, Origin, Profile, Sample,
};
use crate::error::{Error, Num, Result};
use std::collections::HashMap;
use std::path::Path;

/// The message for two conflicting samples of one file that are one direction only because
/// their phi, written differently, wrapped alike (a full sweep's 0 and 360, or -180 and
/// 180); `None` when both were written alike (an ordinary duplicate). `raw_first` and
/// `raw_repeat` are the phi as written, `first_at` the first one's place (`line 2`,
/// `element 0`), `c` the conflict, `cells` optional extra context after the difference
/// (npz cells). Shared by the readers so they word it alike.
pub(crate) fn wrap_conflict(
    raw_first: f64,
    raw_repeat: f64,
    first_at: &str,
    c: &Conflict,
    cells: &str,
    opts: &LoadOptions,
) -> Option<String> {
    if raw_first == raw_repeat {
        return None;
    }
    let (diff, phi) = (&c.diff, c.phi);
    let head = if raw_first == phi && !converts_phi(opts) {
        format!("phi {raw_repeat} wraps to {phi}, which {first_at} already holds with a different {diff}{cells}")
    } else {
        let how = if converts_phi(opts) {
            "after --flip-phi / --phi-offset and the wrap to (-180, 180]"
        } else {
            "once wrapped to (-180, 180]"
        };
        format!(
            "phi {raw_repeat} and phi {raw_first} on {first_at} are the same direction (both {phi} {how}), with a different {diff}{cells}"
        )
    };
    Some(format!("{head}; drop one of the two endpoint measurements"))
}

/// Merge profiles into one: channels are matched by name (the union, in order of first
/// appearance; parts with one unnamed channel merge with each other, and mixing them with
/// named channels is an error: which channel they belong to is not known),
/// metadata entries are concatenated with exact repeats dropped, samples concatenated. A sample present in two parts with a different value is an error naming
/// both sources; identical copies are collapsed (their count is returned).
pub fn merge(parts: Vec<Profile>) -> Result<(Profile, usize)> {
    merge_with(parts, |_, _| None)
}

/// [`merge`], adding `hint(first_part, repeat_part)` (if any) to a conflict's error.
fn merge_with(
    parts: Vec<Profile>,
    hint: impl Fn(usize, usize) -> Option<String>,
) -> Result<(Profile, usize)> {
    let mut out = Profile::default();
    let mut origin: Vec<usize> = Vec::new();
    let sources: Vec<String> = parts
        .iter()
        .map(|p| {
            p.source
                .as_ref()
                .map(|s| s.display().to_string())
                .unwrap_or_else(|| "<memory>".into())
        })
        .collect();
    let unnamed = parts.iter().position(|p| p.channels.is_empty());
    let named = parts.iter().position(|p| !p.channels.is_empty());
    if let (Some(u), Some(n)) = (unnamed, named) {
        return Err(Error::Invalid(format!(
            "{} has no channel name but {} names its channels ({}): say which channel the \
             unnamed samples are (a `channel` column) or fit the files separately",
            sources[u],
            sources[n],
            parts[n].channels.join(", ")
        )));
    }
    for (k, part) in parts.into_iter().enumerate() {
        let file_base = out.files.len() as u32;
        let mut layouts = part.layouts;
        layouts.resize(part.files.len(), Layout::Unknown);
        out.layouts.extend(layouts);
        out.files.extend(part.files);
        let mut map = Vec::new();
        if part.channels.is_empty() {
            // One unnamed channel, merged with the other unnamed parts.
            map.push(0);
        }
        for name in &part.channels {
            let idx = match out.channels.iter().position(|c| c == name) {
                Some(i) => i,
                None => {
                    out.channels.push(name.clone());
                    out.channels.len() - 1
                }
            };
            map.push(idx);
        }
        for kv in part.metadata {
            if !out.metadata.contains(&kv) {
                out.metadata.push(kv);
            }
        }
        for mut s in part.samples {
            s.channel = *map.get(s.channel).ok_or_else(|| {
                Error::Invalid(format!(
                    "{}: sample channel {} out of range",
                    sources[k], s.channel
                ))
            })?;
            s.origin.file += file_base;
            out.samples.push(s);
            origin.push(k);
        }
    }
    // The dedupe holds the samples; a conflict names its two rows from a copy of the origins.
    let origins: Vec<Origin> = out.samples.iter().map(|s| s.origin).collect();
    let (files, layouts) = (out.files.clone(), out.layouts.clone());
    let collapsed = dedupe(&mut out.samples, &out.channels, |c| {
        let (a, b) = (origin[c.first], origin[c.repeat]);
        let hint = hint(a, b).map(|h| format!("; {h}")).unwrap_or_default();
        // Each copy named as its own file's duplicate error would name it.
        let name = |i: usize, part: usize| {
            place_text(&files, &layouts, origins[i], c.field)
                .unwrap_or_else(|| sources[part].clone())
        };
        Error::Invalid(format!(
            "{}: {}; the first copy is in {}{hint}",
            name(c.repeat, b),
            c.what(),
            name(c.first, a)
        ))
    })?;
    Ok((out, collapsed))
}

/// The loader note for `collapsed` duplicate samples found across `parts` (files, inputs)
/// by [`merge_loaded`], if any.
pub(crate) fn collapsed_note(collapsed: usize, parts: &str) -> Option<String> {
    (collapsed > 0).then(|| {
        format!(
            "{collapsed} identical duplicate sample(s) across {parts} collapsed (values equal \
             to 1e-12 of themselves: computed copies may differ in the last digits)"
        )
    })
}

/// [`merge`] of parts loaded with `opts` (files, or folders from [`load_dir`](super::load::load_dir)). When a
/// conflicting sample lies in two parts made only of Yan-2015 files and `opts.theta_i`
/// gave their incident angle, the error adds that `--theta-i` applies to every Yan file:
/// the usual cause is a folder of files without `# theta_i:` lines read with one
/// `--theta-i`, which puts every file at the same incident angle.
pub fn merge_loaded(parts: Vec<Loaded>, opts: &LoadOptions) -> Result<(Profile, usize)> {
    let all_yan: Vec<bool> = parts
        .iter()
        .map(|l| l.files.iter().all(|f| f.format == Format::Yan))
        .collect();
    let hint = |a: usize, b: usize| -> Option<String> {
        let t = opts.theta_i.as_deref()?;
        (all_yan[a] && all_yan[b]).then(|| {
            let t = t.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
            // Beside a lone .npy, files with their own line keep it.
            let which = if opts.theta_i_for_npy {
                " without a '# theta_i:' line"
            } else {
                ""
            };
            format!(
                "--theta-i {t} applies to every Yan-2015 file{which} (each file of a folder \
                 too), so they all read as theta_i {t}; give each file its own \
                 '# theta_i: <deg>' line"
            )
        })
    };
    merge_with(parts.into_iter().map(|l| l.profile).collect(), hint)
}

/// Same f64, treating NaN as equal to NaN (for duplicate checks and round-trip tests).
pub fn same_f64(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || a == b
}

fn same_opt(a: Option<f64>, b: Option<f64>) -> bool {
    both(a, b, same_f64)
}

/// Do two incident azimuths `phi_i` name one direction? Wrapped to (-180, 180] as every
/// loader wraps phi ([`read_phi`](super::checks::read_phi)), so `5` and `-355` (one sweep written two ways) agree.
fn same_azimuth(a: Option<f64>, b: Option<f64>) -> bool {
    both(a, b, |x, y| same_f64(wrap_phi(x), wrap_phi(y)))
}

/// Both absent, or both present and `eq`.
fn both(a: Option<f64>, b: Option<f64>, eq: fn(f64, f64) -> bool) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(x), Some(y)) => eq(x, y),
        _ => false,
    }
}

/// Do two copies of one direction agree on the value? Equal to [`VALUE_MATCH`] (NaN equal
/// to NaN), or both no-signal markers (NaN, `<= 0`): a sweep's 0 and 360 may mark one gap
/// as NaN and -1, and no value of either enters a fit, so they are one invalid sample, not
/// a conflict.
fn same_value(a: &Sample, b: &Sample) -> bool {
    close_f64(a.value, b.value) || (!a.is_valid() && !b.is_valid())
}

/// Equal to [`VALUE_MATCH`] (NaN equal to NaN; an infinity only to itself).
pub(super) fn close_f64(a: f64, b: f64) -> bool {
    same_f64(a, b)
        || (a.is_finite() && b.is_finite() && (a - b).abs() <= VALUE_MATCH * a.abs().max(b.abs()))
}

/// Both absent, or both present and [`close_f64`] (a sigma, like a value, computed twice).
fn close_opt(a: Option<f64>, b: Option<f64>) -> bool {
    both(a, b, close_f64)
}

/// Relative difference within which two copies of one direction are one value (the first
/// kept). Computed profiles differ there only by rounding: `synth` sums a direction's
/// terms in an order that depends on the rest of its grid, so two overlapping grids agree
/// to a few ulp, not bit for bit (audit, 2026-11-28: merging them failed). No measurement
/// is written to 12 digits, so a real conflict is never this close.
const VALUE_MATCH: f64 = 1e-12;

/// Do two samples agree in every field (NaN equal to NaN)?
pub fn same_sample(a: &Sample, b: &Sample) -> bool {
    same_f64(a.theta_i, b.theta_i)
        && same_f64(a.theta_r, b.theta_r)
        && same_f64(a.phi, b.phi)
        && a.channel == b.channel
        && same_f64(a.value, b.value)
        && same_opt(a.sigma, b.sigma)
        && same_opt(a.phi_i, b.phi_i)
}

/// Two samples of one direction that differ, as [`dedupe`] reports them.
#[derive(Clone, Debug)]
pub(crate) struct Conflict {
    /// Index (into the samples given to [`dedupe`]) of the first occurrence.
    pub first: usize,
    /// Index of the repeat that differs from it.
    pub repeat: usize,
    /// What differs, e.g. `value (1 vs 1.1)`.
    pub diff: String,
    /// The field that differs (the first of value, sigma, phi_i that does).
    pub field: Field,
    /// The direction, e.g. `theta_i 30, theta_r 10, phi 0, channel r` (the channel by its
    /// name; none for the one channel of a profile without names).
    pub at: String,
    /// The direction's phi as stored (both samples' phi, once wrapped).
    pub phi: f64,
}

impl Conflict {
    /// `duplicate sample (<at>) with a different <diff>`.
    pub(crate) fn what(&self) -> String {
        format!(
            "duplicate sample ({}) with a different {}",
            self.at, self.diff
        )
    }
}

/// [`dedupe`], returning the loader notes it warrants (one line when rows were collapsed).
/// `raw_phi` holds each sample's phi as written: a collapse of two rows that wrote one
/// direction as two phi (0 and 360, -180 and 180: a sweep's endpoint measured twice) is
/// counted apart, with an example.
pub(crate) fn dedupe_notes<F>(
    samples: &mut Vec<Sample>,
    channels: &[String],
    raw_phi: &[f64],
    what: &str,
    conflict: F,
) -> Result<Vec<String>>
where
    F: Fn(Conflict) -> Error,
{
    let (pairs, markers) = dedupe_pairs(samples, channels, conflict)?;
    if pairs.is_empty() {
        return Ok(Vec::new());
    }
    let wrapped: Vec<&(usize, usize)> = pairs
        .iter()
        .filter(|(i, j)| raw_phi.get(*i) != raw_phi.get(*j))
        .collect();
    let mut why = match wrapped.first() {
        Some((i, j)) => format!(
            " ({} of them the same direction written as two phi, e.g. {} and {}: wrapped alike)",
            wrapped.len(),
            raw_phi[*i],
            raw_phi[*j]
        ),
        None => String::new(),
    };
    // Two different no-signal markers (NaN and -1) collapse too ([`same_value`]): said, so
    // the kept one's spelling is no surprise.
    if let Some((a, b)) = markers.first() {
        why.push_str(&format!(
            " ({} of them not identical but both without signal, e.g. values {} and {}: one \
             invalid sample, the first kept)",
            markers.len(),
            Num(*a),
            Num(*b)
        ));
    }
    Ok(vec![format!(
        "{} {what} collapsed into their first occurrence{why}",
        pairs.len()
    )])
}

/// [`dedupe_notes`] for a text loader (CSV, Yan): sample `k` came from line
/// `samples[k].origin.line` of `path`, its phi written as `raw_phi[k]`. A clash is named on
/// `phi_column` when only the wrap made the two rows one direction ([`wrap_conflict`]),
/// else on the column of the field that differs (`column`: its label).
pub(crate) fn dedupe_rows(
    samples: &mut Vec<Sample>,
    channels: &[String],
    raw_phi: &[f64],
    path: &Path,
    opts: &LoadOptions,
    phi_column: &str,
    column: &dyn Fn(Field) -> String,
) -> Result<Vec<String>> {
    let lines: Vec<usize> = samples.iter().map(|s| s.origin.line as usize).collect();
    dedupe_notes(
        samples,
        channels,
        raw_phi,
        "identical duplicate row(s)",
        |c| {
            let (i, j) = (c.first, c.repeat);
            let first_at = format!("line {}", lines[i]);
            let (column, msg) = match wrap_conflict(raw_phi[i], raw_phi[j], &first_at, &c, "", opts)
            {
                Some(m) => (phi_column.to_string(), m),
                None => (
                    column(c.field),
                    format!("{}; first on {first_at}", c.what()),
                ),
            };
            Error::Parse {
                file: path.to_path_buf(),
                line: lines[j],
                column,
                msg,
            }
        },
    )
}

/// An optional sample field as a message shows it: the number, or "none".
fn opt_text(v: Option<f64>) -> String {
    v.map_or_else(|| "none".to_string(), |x| Num(x).to_string())
}

/// Remove identical duplicate samples (same `theta_i, theta_r, phi, channel` and the same
/// value, or two no-signal values ([`same_value`]), sigma and phi_i), keeping the first;
/// returns how many were removed. A repeat
/// with any different field is an error built by `conflict` from the [`Conflict`] (indices
/// into the original `samples`); `channels` are the names of the samples' channel indices.
pub(crate) fn dedupe<F>(
    samples: &mut Vec<Sample>,
    channels: &[String],
    conflict: F,
) -> Result<usize>
where
    F: Fn(Conflict) -> Error,
{
    Ok(dedupe_pairs(samples, channels, conflict)?.0.len())
}

/// [`dedupe`], returning the `(kept, removed)` index pairs (into the original `samples`)
/// and the two values of each pair of different no-signal markers collapsed
/// ([`same_value`]).
#[allow(clippy::type_complexity)]
fn dedupe_pairs<F>(
    samples: &mut Vec<Sample>,
    channels: &[String],
    conflict: F,
) -> Result<(Vec<(usize, usize)>, Vec<(f64, f64)>)>
where
    F: Fn(Conflict) -> Error,
{
    let mut seen: HashMap<(u64, u64, u64, usize), usize> = HashMap::with_capacity(samples.len());
    let mut drop = vec![false; samples.len()];
    let mut pairs = Vec::new();
    let mut markers = Vec::new();
    for (j, s) in samples.iter().enumerate() {
        let key = (
            (s.theta_i + 0.0).to_bits(),
            (s.theta_r + 0.0).to_bits(),
            canonical_phi(s.phi).to_bits(),
            s.channel,
        );
        match seen.get(&key) {
            None => {
                seen.insert(key, j);
            }
            Some(&i) => {
                let a = &samples[i];
                // Two copies without signal are one invalid sample whatever their sigma or
                // phi_i say: none of it enters a fit (README: they collapse).
                let no_signal = !a.is_valid() && !s.is_valid();
                let diff = if !same_value(a, s) {
                    Some((
                        Field::Value,
                        format!("value ({} vs {})", Num(a.value), Num(s.value)),
                    ))
                } else if no_signal {
                    None
                } else if !close_opt(a.sigma, s.sigma) {
                    Some((
                        Field::Sigma,
                        format!("sigma ({} vs {})", opt_text(a.sigma), opt_text(s.sigma)),
                    ))
                } else if !same_azimuth(a.phi_i, s.phi_i) {
                    Some((
                        Field::PhiI,
                        format!("phi_i ({} vs {})", opt_text(a.phi_i), opt_text(s.phi_i)),
                    ))
                } else {
                    None
                };
                if let Some((field, diff)) = diff {
                    return Err(conflict(Conflict {
                        first: i,
                        repeat: j,
                        diff,
                        field,
                        at: format!(
                            "theta_i {}, theta_r {}, phi {}{}",
                            Num(s.theta_i),
                            Num(s.theta_r),
                            Num(s.phi),
                            // The name the file gives; an index would mean nothing to
                            // the reader (and a merge renumbers them).
                            channels
                                .get(s.channel)
                                .map(|n| format!(", channel {n}"))
                                .unwrap_or_default()
                        ),
                        phi: s.phi,
                    }));
                }
                let same_fields = same_f64(a.value, s.value)
                    && same_opt(a.sigma, s.sigma)
                    && same_opt(a.phi_i, s.phi_i);
                if no_signal && !same_fields {
                    markers.push((a.value, s.value));
                }
                drop[j] = true;
                pairs.push((i, j));
            }
        }
    }
    if !pairs.is_empty() {
        let mut k = 0;
        samples.retain(|_| {
            let keep = !drop[k];
            k += 1;
            keep
        });
    }
    Ok((pairs, markers))
}
