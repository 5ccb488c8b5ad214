//! Angle grids on the command line (DATA.md): `start:stop:step` (both ends included when
//! they fall on the step) or a comma list, in degrees.

use crate::error::{Error, Result};

/// Most values a `start:stop:step` range may expand to.
const MAX_RANGE_VALUES: usize = 10_000_000;

/// Parse an angle grid. `what` names the option in errors (e.g. `--theta-r`).
pub fn parse_grid(what: &str, text: &str) -> Result<Vec<f64>> {
    let bad = |msg: String| Error::Invalid(format!("{what} {}: {msg}", crate::text::quoted(text)));
    let num = |s: &str| -> Result<f64> {
        // A file's number syntax: `1e-400` is refused, not read as 0.
        let v = crate::text::parse_number(s.trim()).map_err(bad)?;
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
        let n = ((b - a) / s + 1e-9).floor();
        if n >= MAX_RANGE_VALUES as f64 {
            return Err(bad(format!(
                "grid too large: {:.0} values (at most {MAX_RANGE_VALUES})",
                n + 1.0
            )));
        }
        let n = n as usize;
        // a + i*s, not repeated addition, so values are reproducible; rounded to the
        // decimals written, so 0:1:0.1 gives 0.3 (as a lab file writes it), not
        // 0.30000000000000004, which matches no other file's 0.3.
        let decimals = parts
            .iter()
            .map(|p| decimals_written(p))
            .collect::<Option<Vec<usize>>>()
            .and_then(|d| d.into_iter().max());
        Ok((0..=n)
            .map(|i| {
                let v = a + i as f64 * s;
                decimals.map_or(v, |d| format!("{v:.d$}").parse().unwrap_or(v))
            })
            .collect())
    } else {
        t.split(',').map(num).collect()
    }
}

/// Digits after the decimal point of a plain decimal (`None` for an exponent form or more
/// than 15 digits: no rounding then).
fn decimals_written(s: &str) -> Option<usize> {
    let s = s.trim();
    if s.contains(['e', 'E']) {
        return None;
    }
    let d = s.split_once('.').map_or(0, |(_, f)| f.len());
    (d <= 15).then_some(d)
}

/// Parse a relative-azimuth grid (degrees) and keep one spelling per direction: values are
/// wrapped to (-180, 180] (MODEL.md) and a value that repeats an earlier direction is
/// dropped and the result is sorted, so `-180:180:4` yields 90 distinct directions ending at 180, not 91 with
/// -180 and 180 both present (the same direction, which a profile may hold only once).
pub fn parse_phi_grid(what: &str, text: &str) -> Result<Vec<f64>> {
    let raw = parse_grid(what, text)?;
    // The range a profile file may hold (DATA.md): a grid the loaders would refuse to read
    // back is refused here.
    if let Some(v) = raw.iter().find(|v| v.abs() > 360.0) {
        return Err(Error::Invalid(format!(
            "{what} '{text}': {} is outside [-360, 360] deg",
            crate::error::Num(*v)
        )));
    }
    let mut out: Vec<f64> = raw.into_iter().map(wrap_deg).collect();
    // Sorted first, so repeats are neighbours (linear in the grid's length).
    out.sort_by(f64::total_cmp);
    out.dedup_by(|b, a| (*b - *a).abs() < 1e-9);
    Ok(out)
}

/// Parse an inclination grid and drop exact repeats (first occurrence kept, order
/// otherwise unchanged): a profile holds each direction once, and `0,0` would otherwise
/// write every sample twice.
pub fn parse_theta_grid(what: &str, text: &str) -> Result<Vec<f64>> {
    let mut seen = std::collections::HashSet::new();
    Ok(parse_grid(what, text)?
        .into_iter()
        // + 0.0 turns -0.0 into 0.0, the same angle.
        .filter(|v| seen.insert((v + 0.0).to_bits()))
        .collect())
}

/// Check the angles `values` (degrees) of the grid `what`: at least one, each finite and
/// within `[-lim, lim]`. The grids [`parse_grid`] returns are never empty nor hold a
/// non-finite value; angles handed over as numbers (the Python module's arrays) may.
pub fn check_angles(what: &str, values: &[f64], lim: f64) -> Result<()> {
    if values.is_empty() {
        return Err(Error::Invalid(format!("{what}: no angles (an empty grid)")));
    }
    if let Some(v) = values.iter().find(|v| !v.is_finite()) {
        return Err(Error::Invalid(format!(
            "{what}: angle {} is not a finite number of degrees",
            crate::error::Num(*v)
        )));
    }
    if let Some(v) = values.iter().find(|v| v.abs() > lim) {
        return Err(Error::Invalid(format!(
            "{what}: angle {} is outside [-{lim}, {lim}] degrees",
            crate::error::Num(*v)
        )));
    }
    Ok(())
}

/// Most samples a grid command (`synth`, `simulate`) will hold in memory: `simulate`
/// peaks at ~165 bytes per sample (1.07 GB measured for 6.5 M), so ~1.7 GB here; a 1 deg
/// grid over every angle is 5.9 M. Beyond, it refuses instead of failing an allocation
/// mid-run.
pub const MAX_GRID_SAMPLES: usize = 10_000_000;

/// Refuse a grid `theta_i x theta_r x phi` of more than [`MAX_GRID_SAMPLES`] samples over
/// all its `channels` (a multi-channel fit's synthesis holds one profile per channel).
pub fn check_grid_size(theta_i: usize, theta_r: usize, phi: usize, channels: usize) -> Result<()> {
    let n = (theta_i as u128)
        .saturating_mul(theta_r as u128)
        .saturating_mul(phi as u128)
        .saturating_mul(channels.max(1) as u128);
    if n > MAX_GRID_SAMPLES as u128 {
        let ch = if channels > 1 {
            format!(" x {channels} channels")
        } else {
            String::new()
        };
        return Err(Error::Invalid(format!(
            "the grid has {theta_i} x {theta_r} x {phi}{ch} = {n} samples, more than the limit \
             of {MAX_GRID_SAMPLES}; use coarser steps or split it into several runs"
        )));
    }
    Ok(())
}

/// A note when a grid of at least three values reaches out to pi/2, pi or 2 pi (to 0.01)
/// and no further: the bounds of a grid written in radians (`-3.14:3.14:0.01`), which
/// furfit would take as a few degrees. Grids are degrees; a real sweep that happens to
/// end at 3.14 degrees gets a harmless note.
pub fn radians_note(what: &str, values: &[f64]) -> Option<String> {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let largest = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let radian_bound = [FRAC_PI_2, PI, TAU]
        .iter()
        .any(|b| (largest - b).abs() <= 0.01);
    (values.len() >= 3 && radian_bound).then(|| {
        format!(
            "note: {what} reaches only {} degrees, a bound of radians (pi/2, pi, 2 pi); grids are in degrees",
            crate::error::Num(largest)
        )
    })
}

/// Wrap degrees to (-180, 180], as the profile loaders wrap a file's phi
/// ([`crate::profile::wrap_phi`]), so a grid and a file name one direction alike.
pub fn wrap_deg(v: f64) -> f64 {
    crate::profile::wrap_phi(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_angles_refuses_empty_non_finite_and_out_of_range() {
        assert!(check_angles("theta_i", &[-90.0, 0.0, 90.0], 90.0).is_ok());
        for (v, want) in [
            (&[][..], "theta_i: no angles (an empty grid)"),
            (
                &[0.0, f64::NAN][..],
                "theta_i: angle NaN is not a finite number of degrees",
            ),
            (
                &[f64::NEG_INFINITY][..],
                "theta_i: angle -inf is not a finite number of degrees",
            ),
            (
                &[90.5][..],
                "theta_i: angle 90.5 is outside [-90, 90] degrees",
            ),
        ] {
            assert_eq!(
                check_angles("theta_i", v, 90.0).unwrap_err().to_string(),
                want
            );
        }
    }

    /// A value below the f64 range is refused as in a file, not read as 0; a zero spelled
    /// with an exponent is still 0.
    #[test]
    fn values_below_the_f64_range_are_refused() {
        let e = parse_grid("--theta-i", "0,1e-400").unwrap_err().to_string();
        assert!(e.contains("'1e-400' is below the f64 range"), "{e}");
        assert_eq!(parse_grid("--theta-i", "0e-400").unwrap(), vec![0.0]);
        assert!(crate::cli::number("1e-400").is_err());
        assert_eq!(crate::cli::number(" -2.5 "), Ok(-2.5));
    }

    /// Values are the decimals written (0.3 is the f64 nearest 0.3, as a file's "0.3"
    /// parses), and an exponent form is left unrounded.
    #[test]
    fn range_values_round_to_the_decimals_written() {
        let g = parse_grid("--theta-r", "0:1:0.1").unwrap();
        assert_eq!(g.len(), 11);
        assert_eq!(g[3], 0.3);
        assert_eq!(g[6], 0.6);
        assert_eq!(g[10], 1.0);
        let g = parse_grid("--theta-r", "-60:60:2.5").unwrap();
        assert_eq!(g[1], -57.5);
        let g = parse_grid("--phi", "0:3e-1:1e-1").unwrap();
        assert_eq!(g[3], 3.0 * 0.1, "exponent form: a + i s as computed");
    }

    #[test]
    fn phi_grid_refuses_what_a_file_may_not_hold() {
        let e = parse_phi_grid("--phi", "0:720:10").unwrap_err().to_string();
        assert!(
            e.contains("--phi") && e.contains("370") && e.contains("[-360, 360]"),
            "{e}"
        );
        // 270 wraps to -90 and 360 repeats 0: four directions, sorted.
        assert_eq!(
            parse_phi_grid("--phi", "0:360:90").unwrap(),
            vec![-90.0, 0.0, 90.0, 180.0]
        );
    }

    #[test]
    fn theta_grid_drops_repeats_in_order() {
        assert_eq!(
            parse_theta_grid("x", "30,0,-0,30,15").unwrap(),
            vec![30.0, 0.0, 15.0]
        );
    }

    #[test]
    fn phi_grid_merges_the_same_direction() {
        let g = parse_phi_grid("x", "-180:180:90").unwrap();
        assert_eq!(g, vec![-90.0, 0.0, 90.0, 180.0]);
    }

    #[test]
    fn radian_bounds_get_a_note() {
        let g = parse_phi_grid("--phi", "-3.14:3.14:0.01").unwrap();
        let n = radians_note("--phi", &g).expect("a note");
        assert!(n.contains("--phi reaches only 3.14 degrees"), "{n}");
        assert!(radians_note("--phi", &parse_grid("p", "0:6.28:0.02").unwrap()).is_some());
        assert!(radians_note("--theta-r", &parse_grid("t", "-1.57,0,1.57").unwrap()).is_some());
        // Degrees as a sweep has them, and a single value, get none.
        assert!(radians_note("--phi", &parse_grid("p", "-180:180:2").unwrap()).is_none());
        assert!(radians_note("--phi", &parse_grid("p", "0:3:1").unwrap()).is_none());
        assert!(radians_note("--phi", &[std::f64::consts::PI]).is_none());
    }

    #[test]
    fn grid_size_limit() {
        assert!(check_grid_size(4, 61, 181, 1).is_ok());
        let e = check_grid_size(91, 1801, 3601, 1).unwrap_err().to_string();
        assert!(e.contains("590") && e.contains("limit"), "{e}");
        // No overflow on absurd axis lengths.
        assert!(check_grid_size(usize::MAX, usize::MAX, 2, 1).is_err());
        // 4 M samples pass alone, not over 3 channels.
        assert!(check_grid_size(100, 100, 400, 1).is_ok());
        let e = check_grid_size(100, 100, 400, 3).unwrap_err().to_string();
        assert!(e.contains("x 3 channels = 12000000"), "{e}");
    }

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

    #[test]
    fn phi_grid_has_one_spelling_per_direction() {
        let g = parse_phi_grid("--phi", "-180:180:4").unwrap();
        assert_eq!(g.len(), 90);
        assert_eq!(g[0], -176.0);
        assert_eq!(*g.last().unwrap(), 180.0);
        assert_eq!(
            parse_phi_grid("--phi", "0,360,90").unwrap(),
            vec![0.0, 90.0]
        );
        assert_eq!(wrap_deg(-180.0), 180.0);
    }
}
