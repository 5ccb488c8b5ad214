//! Library error type. Every variant names the place that is wrong: a file with line and
//! column, an array in an npz archive, or a parameter with its bound. The binary adds
//! context with `anyhow`; the library never panics on user input.

use std::path::PathBuf;

/// Result alias used across the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Errors a user can cause with bad input or a bad environment.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file system refused an operation on `path`.
    /// The OS error is part of the message, not a `#[source]`: `{:#}` printing of the
    /// chain would otherwise say it twice.
    #[error("{}: {err}", path.display())]
    Io {
        /// The file or directory the operation was on.
        path: PathBuf,
        /// What the OS said.
        err: std::io::Error,
    },
    /// A text file is malformed at a known line (1-based) and column.
    /// `column` is a human label: "column 3 (phi)" or "column 12".
    #[error("{}:{line}: {column}: {msg}", file.display())]
    Parse {
        /// The file, as the user named it.
        file: PathBuf,
        /// Line number, 1-based.
        line: usize,
        /// Human label of the column ("column 3 (phi)").
        column: String,
        /// What is wrong there.
        msg: String,
    },
    /// A binary array file (npy/npz) is malformed; `array` names the array.
    #[error("{}: array '{array}': {msg}", file.display())]
    Array {
        /// The `.npy` or `.npz` file.
        file: PathBuf,
        /// The array's name in the archive (`value`, `theta_i`, ...).
        array: String,
        /// What is wrong with it.
        msg: String,
    },
    /// A parameter is outside its hard bound, or a parameter file is malformed.
    #[error("parameter '{key}': {msg}")]
    Param {
        /// The parameter's file key (`beta_m`) or the offending key of the file.
        key: String,
        /// What is wrong (the bound it breaks, ...).
        msg: String,
    },
    /// A file as a whole is unusable (empty, unknown format, no valid sample ...).
    #[error("{}: {msg}", file.display())]
    File {
        /// The file.
        file: PathBuf,
        /// Why it cannot be used.
        msg: String,
    },
    /// Invalid option or argument that is not tied to a file.
    #[error("{0}")]
    Invalid(String),
    /// The caller cancelled the call ([`crate::cancel::Cancel`]); nothing was returned.
    #[error("interrupted")]
    Interrupted,
}

impl Error {
    /// Wrap an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err: source,
        }
    }

    /// A parse error of `file` at `line` (1-based) and `column` (as messages name it).
    pub fn parse(file: impl Into<PathBuf>, line: usize, column: String, msg: String) -> Self {
        Error::Parse {
            file: file.into(),
            line,
            column,
            msg,
        }
    }

    /// A whole-file error.
    pub fn file(file: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::File {
            file: file.into(),
            msg: msg.into(),
        }
    }
}

/// A number as messages show it: `{}` at moderate magnitudes, `{:e}` when `|x| >= 1e6` or
/// `0 < |x| < 1e-4`, where `{}` would spell out every digit (`1e-300` as 300 zeros). Both
/// are the shortest text that reads back as `x`. Data files keep their own formats.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num(pub f64);

impl std::fmt::Display for Num {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let a = self.0.abs();
        if a.is_finite() && (a >= 1e6 || (a > 0.0 && a < 1e-4)) {
            write!(f, "{:e}", self.0)
        } else {
            write!(f, "{}", self.0)
        }
    }
}

/// `x` to `digits` significant digits (at least 1): plain decimals for magnitudes in
/// [1e-4, 1e6), else exponent form as [`Num`] writes them. Standard errors
/// and fitted - true differences span decades across parameters; a fixed count of
/// decimals printed an SE of 0.00034 as 0.000.
pub fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return "-".into();
    }
    if x == 0.0 {
        return "0".into();
    }
    let d = digits.max(1);
    // Round first: 0.0995 to two digits is 0.10, whose decimals follow from 0.1.
    let r: f64 = format!("{:.*e}", d - 1, x).parse().unwrap_or(x);
    let a = r.abs();
    if !(1e-4..1e6).contains(&a) {
        return format!("{:.*e}", d - 1, r);
    }
    let decimals = d as i32 - 1 - a.log10().floor() as i32;
    format!("{:.*}", decimals.max(0) as usize, r)
}

#[cfg(test)]
mod tests {
    use super::Num;

    #[test]
    fn num_is_compact_at_extreme_magnitudes_and_reads_back() {
        for (x, want) in [
            (0.0, "0"),
            (-0.0, "-0"),
            (0.39, "0.39"),
            (1e-4, "0.0001"),
            (-123456.5, "-123456.5"),
            (1e6, "1e6"),
            (8.600000000000001e11, "8.600000000000001e11"),
            (-1e-300, "-1e-300"),
            (5e-324, "5e-324"),
            (f64::MAX, "1.7976931348623157e308"),
            (f64::INFINITY, "inf"),
            (f64::NAN, "NaN"),
        ] {
            let s = Num(x).to_string();
            assert_eq!(s, want);
            // Exactly the number: no digit is lost to make it short.
            if !x.is_nan() {
                assert_eq!(s.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{s}");
            }
        }
    }
}
