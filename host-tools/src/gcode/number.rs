//! Compact decimal numbers for JSON and comments: at most a given number of decimals, no
//! trailing zeros, never `-0` or `NaN` (JSON has neither).

use std::fmt::Write as _;

/// Writes `v` with at most `dec` decimals and no trailing zeros (`0.200` → `0.2`); a value
/// that is not finite is written as 0 (JSON has no NaN).
pub fn push_num(out: &mut String, v: f64, dec: usize) {
    let v = if v.is_finite() { v } else { 0.0 };
    let at = out.len();
    let _ = write!(out, "{v:.dec$}");
    if dec > 0 {
        let trimmed = out[at..].trim_end_matches('0').trim_end_matches('.').len();
        out.truncate(at + trimmed);
    }
    if &out[at..] == "-0" {
        out.truncate(at);
        out.push('0');
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_and_valid_json() {
        let mut s = String::new();
        for (v, d) in [
            (0.2, 3),
            (12.0, 3),
            (-0.0001, 3),
            (f64::NAN, 2),
            (1.23456, 2),
            (7.0, 0),
        ] {
            push_num(&mut s, v, d);
            s.push(' ');
        }
        assert_eq!(s, "0.2 12 0 0 1.23 7 ");
    }
}
