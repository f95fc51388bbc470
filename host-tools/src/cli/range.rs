//! Value parsers that bound every numeric option at the command line, so no option can ask
//! for an unbounded allocation, an endless loop or a number the G-code reader rejects. The
//! limits are documented in `docs/design.md` ("Limits").

/// A parser for a number within `lo..=hi` (finite), for `#[arg(value_parser = ...)]`.
pub fn within(lo: f64, hi: f64) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |s: &str| {
        let v: f64 = s
            .trim()
            .parse()
            .map_err(|_| format!("`{s}` is not a number"))?;
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            return Err(format!("{v} is outside {lo}..={hi}"));
        }
        Ok(v)
    }
}

/// A parser for a count within `lo..=hi`.
pub fn count(lo: usize, hi: usize) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync {
    move |s: &str| {
        let v: usize = s
            .trim()
            .parse()
            .map_err(|_| format!("`{s}` is not a whole number"))?;
        if !(lo..=hi).contains(&v) {
            return Err(format!("{v} is outside {lo}..={hi}"));
        }
        Ok(v)
    }
}

/// Layer heights, mm: 0.01 mm (below any nozzle's useful layer) to 50 mm (paste beads).
pub const LAYER_MM: (f64, f64) = (0.01, 50.0);
/// Line widths, mm: 0.05 mm to 50 mm (paste beads are ~10 mm).
pub const LINE_WIDTH_MM: (f64, f64) = (0.05, 50.0);
/// Sizes and offsets, mm: within ±10 m, far beyond any bed.
pub const SIZE_MM: f64 = 10_000.0;
/// Speeds, mm/s.
pub const SPEED_MM_S: (f64, f64) = (0.01, 10_000.0);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_and_garbage() {
        let p = within(0.01, 50.0);
        assert_eq!(p("0.2"), Ok(0.2));
        assert!(p("1e-9").is_err());
        assert!(p("1e9").is_err());
        assert!(p("nan").is_err());
        assert!(p("inf").is_err());
        assert!(p("x").is_err());
        let c = count(1, 100);
        assert_eq!(c("4"), Ok(4));
        assert!(c("0").is_err());
        assert!(c("4294967295").is_err());
        assert!(c("-1").is_err());
    }
}
