//! The one annotation comment of a G-code file (FullControl's `PlotAnnotation`, for viewers
//! such as the 3D page): written by a design's `t.annotate(…)` ([`comment`]) and read by the
//! preview ([`parse`]), so the two cannot drift apart.
//!
//! ```text
//! ;ANNOTATION: text                 at the nozzle's position at that line
//! ;ANNOTATION X10 Y-2.5 Z0.2: text  at that point (mm; any of X, Y, Z; the others the nozzle's)
//! ```
//!
//! Spaces are allowed after the `;` and between the words, the keyword and the axis letters in
//! any case, the comment alone on its line or after a command. The text is everything after
//! the first `:`, trimmed. Anything else (`;ANNOTATIONS`, `;ANNOTATION X1 oops: t`, an axis
//! twice, a number that is not finite) is not an annotation.

use crate::gcode::number::push_num;

/// The keyword after the `;`.
const KEY: &[u8] = b"annotation";

/// An annotation as written in a comment.
#[derive(Clone, Debug, PartialEq)]
pub struct Note {
    /// The point's coordinates that were given (X, Y, Z; mm); `None` ones are the nozzle's.
    pub point: [Option<f64>; 3],
    /// The label.
    pub text: String,
}

/// The comment's text (without the `;`): `ANNOTATION: label` or, with a point,
/// `ANNOTATION X<x> Y<y> Z<z>: label` (mm, at most three decimals). Control characters of
/// the label (a line break) become spaces, so it stays on one line. `None` when a coordinate
/// is not finite.
pub fn comment(at: Option<[f64; 3]>, label: &str) -> Option<String> {
    let mut out = String::from("ANNOTATION");
    if let Some(p) = at {
        for (axis, v) in ['X', 'Y', 'Z'].into_iter().zip(p) {
            if !v.is_finite() {
                return None;
            }
            out.push(' ');
            out.push(axis);
            push_num(&mut out, v, 3);
        }
    }
    out.push_str(": ");
    let label: String = label
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    out.push_str(label.trim());
    Some(out)
}

/// The annotation of one G-code line (without its `\n`), if it has one.
pub fn parse(line: &[u8]) -> Option<Note> {
    let semi = line.iter().position(|&b| b == b';')?;
    let rest = line[semi + 1..].trim_ascii_start();
    if rest.len() < KEY.len() || !rest[..KEY.len()].eq_ignore_ascii_case(KEY) {
        return None;
    }
    let rest = &rest[KEY.len()..];
    let colon = rest.iter().position(|&b| b == b':')?;
    let mut point = [None; 3];
    let words = &rest[..colon];
    // The keyword must end here: a space or the colon (not `ANNOTATIONS`).
    if !words.is_empty() && !words[0].is_ascii_whitespace() {
        return None;
    }
    for word in words
        .split(|b| b.is_ascii_whitespace())
        .filter(|w| !w.is_empty())
    {
        let axis = match word[0].to_ascii_uppercase() {
            b'X' => 0,
            b'Y' => 1,
            b'Z' => 2,
            _ => return None,
        };
        let v: f64 = std::str::from_utf8(&word[1..]).ok()?.parse().ok()?;
        if !v.is_finite() || point[axis].replace(v).is_some() {
            return None;
        }
    }
    Some(Note {
        point,
        text: String::from_utf8_lossy(rest[colon + 1..].trim_ascii()).into_owned(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn note(s: &str) -> Option<(Vec<Option<f64>>, String)> {
        parse(s.as_bytes()).map(|n| (n.point.to_vec(), n.text))
    }

    #[test]
    fn written_comments_read_back() {
        let c = comment(Some([1.5, -2.0, 0.25]), "corner\nhere ").expect("finite");
        assert_eq!(c, "ANNOTATION X1.5 Y-2 Z0.25: corner here");
        let line = format!("; {c}");
        assert_eq!(
            note(&line),
            Some((
                vec![Some(1.5), Some(-2.0), Some(0.25)],
                "corner here".into()
            ))
        );
        let c = comment(None, "seam: left").expect("no point");
        assert_eq!(c, "ANNOTATION: seam: left");
        assert_eq!(note(&c[..]).map(|n| n.1), None, "no ';'");
        assert_eq!(
            note(&format!(";{c}")),
            Some((vec![None; 3], "seam: left".into()))
        );
        assert_eq!(comment(Some([f64::NAN, 0.0, 0.0]), "x"), None);
    }

    #[test]
    fn other_comments_are_not_annotations() {
        assert_eq!(
            note("G1 X2 ;annotation:  after a move "),
            Some((vec![None; 3], "after a move".into()))
        );
        assert_eq!(
            note(";Annotation z3 x1 : top"),
            Some((vec![Some(1.0), None, Some(3.0)], "top".into()))
        );
        for not in [
            ";ANNOTATIONS are not: x",
            "; note: no",
            ";ANNOTATION no colon",
            ";ANNOTATION X1 oops: t",
            ";ANNOTATION X1 X2: twice",
            ";ANNOTATION Xinf: infinite",
            ";ANNOTATION E1: not an axis",
            "G1 X1 ANNOTATION: not a comment",
        ] {
            assert_eq!(note(not), None, "{not}");
        }
    }
}
