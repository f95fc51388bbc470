//! The bead's cross-section model, as a design declares it and the 3D page draws it
//! (FullControl's `area_model`): written by the design compiler as one comment and read back
//! by the preview, both here, so the two cannot drift apart.
//!
//! ```text
//! ;AREA_MODEL:stadium      beads from here on are stadiums (rectangles with round sides)
//! ;AREA_MODEL:rectangle    width × height (FullControl's default, and the default here)
//! ```
//!
//! Spaces are allowed after the `;` and around the `:`, the words in any case.

/// How a bead's width, height and cross-section relate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AreaModel {
    /// width × height (FullControl's default).
    #[default]
    Rectangle,
    /// A rectangle with semicircular sides: (width − height)·height + π(height/2)² (as
    /// PrusaSlicer models a bead).
    Stadium,
}

/// The comment's keyword.
const KEY: &str = "AREA_MODEL";

impl AreaModel {
    /// Its name in scripts and comments.
    pub fn name(self) -> &'static str {
        match self {
            AreaModel::Rectangle => "rectangle",
            AreaModel::Stadium => "stadium",
        }
    }

    /// The model called `name` (`"rectangle"`, `"stadium"`, any case).
    pub fn from_name(name: &str) -> Option<AreaModel> {
        match name.trim().to_ascii_lowercase().as_str() {
            "rectangle" => Some(AreaModel::Rectangle),
            "stadium" => Some(AreaModel::Stadium),
            _ => None,
        }
    }

    /// The comment's text (without the `;`).
    pub fn comment(self) -> String {
        format!("{KEY}:{}", self.name())
    }

    /// The model a G-code line declares, if it is this comment.
    pub fn parse_comment(line: &[u8]) -> Option<AreaModel> {
        let text = std::str::from_utf8(line).ok()?;
        let comment = text.trim_start().strip_prefix(';')?.trim_start();
        let (key, value) = comment.split_once(':')?;
        key.trim()
            .eq_ignore_ascii_case(KEY)
            .then(|| AreaModel::from_name(value))
            .flatten()
    }

    /// The width of a bead of cross-section `cross_mm2` and height `h_mm` under this model,
    /// mm; `None` when the cross-section is too small for a stadium of that height (it would
    /// be narrower than high).
    pub fn width_mm(self, cross_mm2: f64, h_mm: f64) -> Option<f64> {
        let w = match self {
            AreaModel::Rectangle => cross_mm2 / h_mm,
            AreaModel::Stadium => cross_mm2 / h_mm + h_mm * (1.0 - std::f64::consts::FRAC_PI_4),
        };
        (w.is_finite() && w >= h_mm).then_some(w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comment_round_trip_and_widths() {
        for m in [AreaModel::Rectangle, AreaModel::Stadium] {
            let line = format!(";{}", m.comment());
            assert_eq!(AreaModel::parse_comment(line.as_bytes()), Some(m));
        }
        assert_eq!(
            AreaModel::parse_comment(b" ; area_model : Stadium"),
            Some(AreaModel::Stadium)
        );
        assert_eq!(AreaModel::parse_comment(b";AREA_MODEL:circle"), None);
        assert_eq!(AreaModel::parse_comment(b";AREA_MODELS:stadium"), None);
        assert_eq!(AreaModel::parse_comment(b"G1 X1 ;AREA_MODEL:stadium"), None);
        // A 0.5 × 0.25 rectangle is 0.5 wide as a rectangle, wider as a stadium.
        let r = AreaModel::Rectangle.width_mm(0.125, 0.25);
        assert!(r.is_some_and(|w| (w - 0.5).abs() < 1e-12));
        let s = AreaModel::Stadium.width_mm(0.125, 0.25).unwrap_or(0.0);
        assert!((s - (0.5 + 0.25 * (1.0 - std::f64::consts::FRAC_PI_4))).abs() < 1e-12);
        assert_eq!(AreaModel::Rectangle.width_mm(0.01, 0.25), None);
    }
}
