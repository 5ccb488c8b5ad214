//! Angle grids on the command line (DATA.md): `start:stop:step` (both ends included when
//! they fall on the step) or a comma list, in degrees.

use crate::error::{Error, Result};

/// Parse an angle grid. `what` names the option in errors (e.g. `--theta-r`).
pub fn parse_grid(what: &str, text: &str) -> Result<Vec<f64>> {
    let bad = |msg: String| Error::Invalid(format!("{what} '{text}': {msg}"));
    let num = |s: &str| -> Result<f64> {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| bad(format!("'{}' is not a number", s.trim())))?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(bad(format!("'{}' is not finite", s.trim())))
        }
    };
    let t = text.trim();
    if t.is_empty() {
        return Err(bad("empty grid".into()));
    }
    if t.contains(':') {
        let parts: Vec<&str> = t.split(':').collect();
        if parts.len() != 3 {
            return Err(bad("expected start:stop:step".into()));
        }
        let (a, b, s) = (num(parts[0])?, num(parts[1])?, num(parts[2])?);
        if s <= 0.0 {
            return Err(bad("step must be > 0".into()));
        }
        if b < a {
            return Err(bad("stop must be >= start".into()));
        }
        // Count with a tolerance so 0:1:0.1 includes 1 despite rounding.
        let n = ((b - a) / s + 1e-9).floor() as usize;
        if n > 10_000_000 {
            return Err(bad("grid too large".into()));
        }
        // a + i*s, not repeated addition, so values are reproducible.
        Ok((0..=n).map(|i| a + i as f64 * s).collect())
    } else {
        t.split(',').map(num).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_and_lists() {
        assert_eq!(parse_grid("x", "0:10:5").unwrap(), vec![0.0, 5.0, 10.0]);
        assert_eq!(parse_grid("x", "0:9:5").unwrap(), vec![0.0, 5.0]);
        assert_eq!(parse_grid("x", "0,15,30").unwrap(), vec![0.0, 15.0, 30.0]);
        assert_eq!(parse_grid("x", "0:1:0.1").unwrap().len(), 11);
        assert!(parse_grid("x", "0:1:0").is_err());
        assert!(parse_grid("x", "a,b")
            .unwrap_err()
            .to_string()
            .contains("'a'"));
        assert!(parse_grid("x", "").is_err());
    }
}
