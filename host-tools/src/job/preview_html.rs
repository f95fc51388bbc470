//! A 3D preview of a G-code job as one self-contained HTML file: no server, no network, no
//! library — the moves are embedded as JSON and drawn by a WebGL 2 viewer of our own
//! (`preview_gl.js`, `preview_view.js`, inlined), so any browser opens it from disk.
//!
//! Each printing move is a lit tube of its bead's real width and height
//! ([`crate::job::preview_moves::bead_mm`]), so a vase wall's ripples, seams and layer lines
//! show as they will print; travels are thin lines on demand. The designer turns (drag), zooms
//! (wheel, +/-) and pans (shift- or right-drag), colours the printing moves by speed, commanded
//! feed, width, cross-section, layer or time — the scale and legend follow the layers the two
//! sliders leave visible — hovers a move for its source line, feed, layer, E and bead, and sees
//! the design's `;ANNOTATION:` comments as labels where they apply. Moves come from the
//! acceleration-aware motion model ([`crate::design::motion`]) on the printer's own parser, so
//! layers are the firmware's (its layer detector and its numbers, as `stats` reports them) and
//! time is what `host-tools stats` reports.
//!
//! Why hand-written WebGL rather than three.js or plotly: the viewer needs instanced tubes,
//! an id buffer for picking and a layer range — about 400 lines — while three.js (~600 KB
//! minified) or plotly.js (~3.5 MB) would have to be inlined into every page.

use crate::design::motion::{plan_marks, prelude_marks, LayerMark, MotionLimits, Segment};
use crate::design::profile::Profile;
use crate::gcode::number::push_num;
use crate::gcode::read::{default_reader, BadLines, ReadError};
use crate::job::preview_moves::{scan_annotations, scan_beads, PageData};
use std::cell::RefCell;

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
    /// Annotations shown (placed at a move).
    pub annotations: usize,
    /// Annotations beyond [`crate::job::preview_moves::MAX_ANNOTATIONS`], left out (the page
    /// says how many).
    pub annotations_dropped: usize,
}

/// Most moves embedded (about 50–70 bytes each: a page of about 100 MB at most). Longer jobs
/// are refused with a message rather than written as a page no browser opens.
pub const MAX_MOVES: usize = 1_500_000;

/// Builds the HTML page for `input` (G-code). Lines the printer's parser rejects are skipped
/// (as `stats` does).
pub fn html(input: &[u8], profile: &Profile, title: &str) -> Result<(String, HtmlSummary), String> {
    let limits = MotionLimits::from_profile(profile);
    let area = profile.filament_area_mm2();
    let nozzle = profile.nozzle_diameter_mm;
    let (mut notes, dropped) = scan_annotations(input);
    let data = RefCell::new(PageData::with_capacity(
        input.len() / 2 + 4096,
        scan_beads(input),
    ));
    let mut too_many = false;
    let mut sink = |s: Segment| {
        let mut d = data.borrow_mut();
        if too_many || d.len() >= MAX_MOVES {
            too_many = true;
            return;
        }
        d.push(&s, &mut notes, area, nozzle);
    };
    let mut layer = |m: LayerMark| data.borrow_mut().mark(m);
    let mut reader = default_reader();
    reader.bad_line_policy = BadLines::Skip;
    let totals = plan_marks(&mut reader, input, limits, &mut sink, &mut layer)
        .map_err(|e: ReadError| e.to_string())?;
    if too_many {
        return Err(format!(
            "more than {MAX_MOVES} moves: too many for one page (preview a range of layers)"
        ));
    }
    let mut d = data.into_inner();
    d.finish_notes(&mut notes);
    let prelude = prelude_marks(&d.marks);
    let b = &profile.bed;
    let meta = format!(
        "{{\"title\":{},\"bed\":[{},{},{},{}],\"profile\":{},\"time\":{:.1},\"notes_dropped\":{},\"prelude\":{}}}",
        script_json(title),
        b.x_min_mm,
        b.y_min_mm,
        b.x_max_mm,
        b.y_max_mm,
        script_json(&profile.name),
        totals.time_s,
        dropped,
        prelude
    );
    // Layer index k (k ≥ 1) is the k-th mark: [firmware number, the height the layer prints
    // at or null]. The first `prelude` marks are the start code's (a purge line the firmware
    // numbers before its count starts again at the first layer): the page shows them as the
    // start, as `stats` counts their time before the first layer.
    let mut layers = String::from("[");
    for (k, m) in d.marks.iter().enumerate().skip(prelude) {
        if k > prelude {
            layers.push(',');
        }
        layers.push('[');
        layers.push_str(&m.number.to_string());
        layers.push(',');
        match d.heights.get(k as u32 + 1).or(m.z_mm) {
            Some(z) => push_num(&mut layers, z, 3),
            None => layers.push_str("null"),
        }
        layers.push(']');
    }
    layers.push(']');
    // Annotations: [text, line, x, y, z, layer index].
    let mut shown = 0usize;
    let mut notes_json = String::from("[");
    for n in &notes {
        let Some((at, layer)) = n.at else { continue };
        if shown > 0 {
            notes_json.push(',');
        }
        shown += 1;
        notes_json.push('[');
        notes_json.push_str(&script_json(&n.text));
        notes_json.push(',');
        notes_json.push_str(&n.line.to_string());
        for v in at {
            notes_json.push(',');
            push_num(&mut notes_json, v, 3);
        }
        notes_json.push(',');
        notes_json.push_str(&layer.to_string());
        notes_json.push(']');
    }
    notes_json.push(']');
    let page = fill(
        PAGE,
        &[
            ("/*TITLE*/", &html_escape(title)),
            ("/*META*/", &meta),
            ("/*MOVES*/", &format!("[{}]", d.moves)),
            ("/*JUMPS*/", &format!("[{}]", d.jumps)),
            ("/*LAYERS*/", &layers),
            ("/*NOTES*/", &notes_json),
            ("/*GL*/", GL_JS),
            ("/*VIEW*/", VIEW_JS),
        ],
    );
    Ok((
        page,
        HtmlSummary {
            print_moves: d.print_moves,
            travels: d.travels,
            layers: totals.layer_marks.saturating_sub(prelude as u32),
            time_s: totals.time_s,
            annotations: shown,
            annotations_dropped: dropped,
        },
    ))
}

/// Replaces each placeholder of `template` by its value in one pass, so a value (a title, an
/// annotation) that happens to contain a placeholder is never expanded itself.
fn fill(template: &str, values: &[(&str, &str)]) -> String {
    let extra: usize = values.iter().map(|(_, v)| v.len()).sum();
    let mut out = String::with_capacity(template.len() + extra);
    let mut rest = template;
    while let Some((at, key, value)) = values
        .iter()
        .filter_map(|(k, v)| rest.find(k).map(|i| (i, *k, *v)))
        .min_by_key(|(i, _, _)| *i)
    {
        out.push_str(&rest[..at]);
        out.push_str(value);
        rest = &rest[at + key.len()..];
    }
    out.push_str(rest);
    out
}

/// A JSON string that is safe inside `<script>`: `<` is written as `\u003c`, so a text holding
/// `</script>` cannot end the script.
fn script_json(s: &str) -> String {
    serde_json::to_string(s)
        .unwrap_or_else(|_| "\"\"".into())
        .replace('<', "\\u003c")
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The page: markup and style, with placeholders for the data and the two scripts.
const PAGE: &str = include_str!("preview_page.html");
/// The WebGL 2 renderer: tube and line programs, instanced draws over a range, id picking.
const GL_JS: &str = include_str!("preview_gl.js");
/// The viewer: data, camera, controls, colour scale and legend, hover readout, annotations.
const VIEW_JS: &str = include_str!("preview_view.js");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn page_is_self_contained_and_holds_the_moves() {
        let g = b"G90\nM82\nG92 E0\n;LAYER_CHANGE\n;Z:0.2\nG0 X10 Y10 Z0.2 F6000\n\
                  ; ANNOTATION: </script><b>x</b> /*DATA*/\nG1 X20 E1 F1200\n\
                  ;LAYER_CHANGE\n;Z:0.4\nG1 Z0.4\nG1 X10 E2\n";
        let (page, s) = html(g, &Profile::ender3(), "t<1> /*META*/").expect("page");
        assert_eq!(s.print_moves, 2);
        assert_eq!(s.layers, 2);
        assert_eq!(s.annotations, 1);
        assert!(s.travels >= 1);
        assert!(page.contains("t&lt;1&gt;"));
        for banned in ["http://", "https://", "<script src", "<link", "@import"] {
            assert!(!page.contains(banned), "{banned}");
        }
        // One </script>: the page's own (the annotation's is escaped).
        assert_eq!(page.matches("</script>").count(), 1);
        // Placeholders in values are not expanded.
        assert!(page.contains("/*DATA*/") && page.contains("/*META*/"));
        // The print move on line 8 (flags 1, layer 1) ends at X20 Y10 Z0.2 at 20 mm/s
        // commanded; the annotation sits at the end of the travel before it (10, 10, 0.2).
        assert!(page.contains(",1,1,8,20,10,0.2,"), "{page}");
        assert!(page.contains(",7,10,10,0.2,1]"), "{page}");
    }

    /// The page's moves as rows of numbers.
    fn moves(page: &str) -> Vec<Vec<f64>> {
        let at = page.find("const MOVES = [").expect("moves") + 15;
        let end = at + page[at..].find(']').expect("end");
        let v: Vec<f64> = page[at..end]
            .split(',')
            .map(|x| x.parse().expect("number"))
            .collect();
        v.chunks(crate::job::preview_moves::MOVE_FIELDS)
            .map(<[f64]>::to_vec)
            .collect()
    }

    #[test]
    fn bead_height_is_the_rise_over_the_last_printed_layer() {
        // Layers at Z 0.2 (on the bed), 0.5, 0.8 (travel only), 1.0; E for 0.3 mm² beads,
        // drawn as FullControl's rectangles; then the same declared as stadiums.
        let area = Profile::ender3().filament_area_mm2();
        let e = |mm: f64| 0.3 * mm / area;
        for (decl, stadium) in [("", false), (";AREA_MODEL:stadium\n", true)] {
            let g = format!(
                "G90\nM82\nG92 E0\n{decl};LAYER_CHANGE\n;Z:0.2\nG0 X10 Y10 Z0.2 F6000\n\
                 G1 X20 E{:.5} F1200\n;LAYER_CHANGE\n;Z:0.5\nG0 Z0.5\nG1 X10 E{:.5}\n\
                 ;LAYER_CHANGE\n;Z:0.8\nG0 Z0.8\nG0 X20\n;LAYER_CHANGE\n;Z:1.0\nG0 Z1.0\n\
                 G1 X10 E{:.5}\n",
                e(10.0),
                e(20.0),
                e(30.0)
            );
            let (page, s) = html(g.as_bytes(), &Profile::ender3(), "h").expect("page");
            assert_eq!(s.print_moves, 3);
            let printed: Vec<(f64, f64)> = moves(&page)
                .iter()
                .filter(|m| m[0] as u32 & 1 == 1)
                .map(|m| (m[10], m[11]))
                .collect();
            let heights: Vec<f64> = printed.iter().map(|p| p.1).collect();
            assert_eq!(heights, vec![0.2, 0.3, 0.5]);
            // Width: the declared model of 0.3 mm² at that height (to the page's 3 decimals).
            for (w, h) in printed {
                let round = if stadium {
                    h * (1.0 - std::f64::consts::FRAC_PI_4)
                } else {
                    0.0
                };
                let expected = 0.3 / h + round;
                assert!((w - expected).abs() < 2e-3, "{w} vs {expected} at h {h}");
            }
        }
    }

    #[test]
    fn fill_expands_each_placeholder_once() {
        let t = "a /*X*/ b /*Y*/ c /*X*/";
        assert_eq!(
            fill(t, &[("/*X*/", "/*Y*/"), ("/*Y*/", "y")]),
            "a /*Y*/ b y c /*Y*/"
        );
    }
}
