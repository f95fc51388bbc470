//! A 3D preview of a G-code job as one self-contained HTML file: no server, no network, no
//! library — the moves are embedded as JSON and drawn by a small script of our own on a 2D
//! canvas (a perspective projection, depth-sorted lines), so any browser opens it from disk.
//!
//! The designer can turn (drag), zoom (wheel, or +/-), pan (shift-drag), colour the printing
//! moves by speed, cross-section, layer or time, show or hide travels, and limit the layers
//! shown with two sliders. Moves come from the acceleration-aware motion model
//! ([`crate::design::motion`]) on the printer's own parser, so layers are the firmware's
//! (its layer detector) and time is what `host-tools stats` reports.

use crate::design::motion::{plan_gcode_with, MotionLimits, MoveKind, Segment};
use crate::design::profile::Profile;
use crate::job::read::{default_reader, BadLines, ReadError};
use std::fmt::Write as _;

/// What an HTML preview holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HtmlSummary {
    /// Printing moves embedded.
    pub print_moves: usize,
    /// Travels embedded.
    pub travels: usize,
    /// Layers (firmware marks).
    pub layers: u32,
    /// Duration of the job, s.
    pub time_s: f64,
}

/// Most moves embedded (about 60 bytes each: a 100 MB page at most). Longer jobs are refused
/// with a message rather than written as a page no browser opens.
pub const MAX_MOVES: usize = 1_500_000;

/// Builds the HTML page for `input` (G-code). Lines the printer's parser rejects are skipped
/// (as `stats` does).
pub fn html(input: &[u8], profile: &Profile, title: &str) -> Result<(String, HtmlSummary), String> {
    let limits = MotionLimits::from_profile(profile);
    let area = profile.filament_area_mm2();
    let mut data = String::with_capacity(input.len() / 2 + 4096);
    let mut n_print = 0usize;
    let mut n_travel = 0usize;
    let mut too_many = false;
    data.push('[');
    let mut sink = |s: Segment| {
        if s.kind == MoveKind::Extruder || too_many {
            return;
        }
        if n_print + n_travel >= MAX_MOVES {
            too_many = true;
            return;
        }
        let print = s.kind == MoveKind::Print;
        if print {
            n_print += 1;
        } else {
            n_travel += 1;
        }
        let cross = if print && s.len_mm > 0.0 {
            (s.end[3] - s.start[3]) * area / s.len_mm
        } else {
            0.0
        };
        if n_print + n_travel > 1 {
            data.push(',');
        }
        // x0,y0,z0,x1,y1,z1,kind,layer,t_s,speed,cross
        let _ = write!(
            data,
            "{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{:.2},{:.1},{:.4}",
            s.start[0],
            s.start[1],
            s.start[2],
            s.end[0],
            s.end[1],
            s.end[2],
            u8::from(print),
            s.layer,
            s.t_start_s,
            s.v_peak_mm_s,
            cross
        );
    };
    let mut reader = default_reader();
    reader.bad_line_policy = BadLines::Skip;
    let totals = plan_gcode_with(&mut reader, input, limits, &mut sink, &mut |_, _, _| {})
        .map_err(|e: ReadError| e.to_string())?;
    if too_many {
        return Err(format!(
            "more than {MAX_MOVES} moves: too many for one page (preview a range of layers)"
        ));
    }
    data.push(']');
    let b = &profile.bed;
    let meta = format!(
        "{{\"title\":{},\"bed\":[{},{},{},{}],\"profile\":{},\"time\":{:.1}}}",
        json_str(title),
        b.x_min_mm,
        b.y_min_mm,
        b.x_max_mm,
        b.y_max_mm,
        json_str(&profile.name),
        totals.time_s
    );
    let page = PAGE
        .replace("/*TITLE*/", &html_escape(title))
        .replace("/*META*/", &meta)
        .replace("/*DATA*/", &data);
    Ok((
        page,
        HtmlSummary {
            print_moves: n_print,
            travels: n_travel,
            layers: totals.layer_marks,
            time_s: totals.time_s,
        },
    ))
}

fn json_str(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into())
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The page: markup, style and the viewer script. `/*META*/` and `/*DATA*/` are replaced by
/// JSON; nothing is fetched.
const PAGE: &str = include_str!("preview_page.html");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_is_self_contained_and_holds_the_moves() {
        let g =
            b"G90\nM82\nG92 E0\n;LAYER_CHANGE\n;Z:0.2\nG0 X10 Y10 Z0.2 F6000\nG1 X20 E1 F1200\n\
                  ;LAYER_CHANGE\n;Z:0.4\nG1 Z0.4\nG1 X10 E2\n";
        let (page, s) = html(g, &Profile::ender3(), "t<1>").expect("page");
        assert_eq!(s.print_moves, 2);
        assert_eq!(s.layers, 2);
        assert!(s.travels >= 1);
        assert!(page.contains("t&lt;1&gt;"));
        for banned in ["http://", "https://", "<script src", "<link", "@import"] {
            assert!(!page.contains(banned), "{banned}");
        }
        assert!(page.contains("20.000,10.000,0.200"));
    }
}
