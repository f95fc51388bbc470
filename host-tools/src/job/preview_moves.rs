//! The moves, layers and annotations of a job as the 3D page ([`crate::job::preview_html`])
//! embeds them: each printing move with its bead (width × height, from E, the layer's rise and
//! the filament), its source line, commanded feed and the motion model's speed and time; the
//! firmware's layers; and the design's annotation comments ([`crate::gcode::annotation`]) placed
//! at their point or where the nozzle is.
//!
//! Everything is written straight into compact JSON number lists while the job streams through
//! the motion model, so a 1.5 M-move job costs its text, not a vector of structs.

use crate::design::motion::{LayerMark, PrintHeights};
use crate::design::motion::{MoveKind, Segment};
use crate::gcode::annotation;
use crate::gcode::bead::AreaModel;
use crate::gcode::number::push_num;
use std::fmt::Write as _;

/// Most annotations kept (the rest are counted and dropped).
pub const MAX_ANNOTATIONS: usize = 10_000;
/// Longest annotation text kept, characters (longer ones are cut).
pub const MAX_ANNOTATION_CHARS: usize = 200;

/// Numbers per move in [`PageData::moves`] (`flags, layer, line, x, y, z, t_s, v_peak, feed,
/// de, width, height`).
pub const MOVE_FIELDS: usize = 12;

/// An annotation comment of the G-code ([`crate::gcode::annotation`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Annotation {
    /// 1-based line of the comment.
    pub line: u32,
    /// The label, cut to [`MAX_ANNOTATION_CHARS`].
    pub text: String,
    /// The point the comment gives (X, Y, Z, mm; `None` ones are the nozzle's).
    pub point: [Option<f64>; 3],
    /// Where it is shown: the comment's point, completed by the nozzle's position at that line
    /// (the end of the last move before or on it, the start of the first move when none
    /// precedes it), mm; with that move's layer index (the label is hidden with that layer).
    pub at: Option<([f64; 3], u32)>,
}

/// Finds the annotations of `input` (each line read by [`crate::gcode::annotation::parse`]).
/// At most [`MAX_ANNOTATIONS`]; returns them (in line order) and how many more there were.
pub fn scan_annotations(input: &[u8]) -> (Vec<Annotation>, usize) {
    let mut out = Vec::new();
    let mut dropped = 0usize;
    for (i, raw) in input.split(|&b| b == b'\n').enumerate() {
        let Some(note) = annotation::parse(raw) else {
            continue;
        };
        if out.len() >= MAX_ANNOTATIONS {
            dropped += 1;
            continue;
        }
        out.push(Annotation {
            line: u32::try_from(i + 1).unwrap_or(u32::MAX),
            text: note.text.chars().take(MAX_ANNOTATION_CHARS).collect(),
            point: note.point,
            at: None,
        });
    }
    (out, dropped)
}

/// `nozzle` with the coordinates `point` gives.
fn place(point: [Option<f64>; 3], nozzle: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|k| point[k].unwrap_or(nozzle[k]))
}

/// The bead a printing move lays: `(width, height)` in mm.
///
/// The height is the layer's rise (`rise_mm`: the height this layer prints at over the layer
/// below, the bed for the first) when it is plausible (0.02 mm up to 1.5 nozzle diameters);
/// otherwise (a spiral whose layers were found per move, a purge line far above the bed) the
/// bead is taken as one nozzle wide. The width is the one `model` gives a bead of area
/// `cross_mm2` (ΔE × filament area ÷ length) and that height: `A/h` for FullControl's
/// rectangle (the default), `A/h + h(1 − π/4)` for a stadium (a rectangle with semicircular
/// sides, as PrusaSlicer models a bead) where the design declares one. A bead narrower than
/// high is drawn as the equal-area circle.
pub fn bead_mm(model: AreaModel, cross_mm2: f64, rise_mm: f64, nozzle_mm: f64) -> (f64, f64) {
    let nozzle = if nozzle_mm.is_finite() && nozzle_mm > 0.0 {
        nozzle_mm
    } else {
        0.4
    };
    let a = if cross_mm2.is_finite() && cross_mm2 > 0.0 {
        cross_mm2
    } else {
        return (0.0, 0.0);
    };
    let h = if rise_mm.is_finite() && (0.02..=1.5 * nozzle).contains(&rise_mm) {
        rise_mm
    } else {
        (a / nozzle).clamp(0.02, nozzle)
    };
    match model.width_mm(a, h) {
        Some(w) => (w, h),
        None => {
            let d = (4.0 * a / std::f64::consts::PI).sqrt();
            (d, d)
        }
    }
}

/// The bead models a job declares (`;AREA_MODEL:` comments, [`crate::gcode::bead`]): the
/// 1-based line of each and the model from there on.
pub fn scan_beads(input: &[u8]) -> Vec<(u32, AreaModel)> {
    let mut out = Vec::new();
    for (i, raw) in input.split(|&b| b == b'\n').enumerate() {
        if raw.contains(&b';') {
            if let Some(m) = AreaModel::parse_comment(raw) {
                out.push((u32::try_from(i + 1).unwrap_or(u32::MAX), m));
            }
        }
    }
    out
}

/// What the page embeds, built move by move.
#[derive(Debug, Default)]
pub struct PageData {
    /// `[f,l,line,x,y,z,t,v,feed,de,w,h, …]` (without brackets): per move `f` = 1 printing /
    /// 0 travel, + 2 when the move does not start where the previous one ended (its start is
    /// the next entry of `jumps`); `l` layer index (0 before the first layer mark); the end
    /// point; start time s; the motion model's peak speed and the commanded feed, mm/s; ΔE mm;
    /// bead width and height mm (0 for travels).
    pub moves: String,
    /// Start points of the moves flagged +2: `x,y,z, …`.
    pub jumps: String,
    /// Printing moves written.
    pub print_moves: usize,
    /// Travels written.
    pub travels: usize,
    /// The firmware's layer marks, in order (mark k starts index k + 1).
    pub marks: Vec<LayerMark>,
    /// The layer index printed last, the height it prints at and its rise over the layer
    /// printed before it (the bed for the first).
    printing: Option<(u32, f64, f64)>,
    /// The height each layer prints at (its first printing move's start).
    pub heights: PrintHeights,
    /// The job's bead declarations ([`scan_beads`]) and how many are in force.
    beads: Vec<(u32, AreaModel)>,
    next_bead: usize,
    bead: AreaModel,
    last_end: Option<[f64; 3]>,
    last_layer: u32,
    next_note: usize,
}

impl PageData {
    /// Empty, with room for about `bytes` of move text, drawing beads as `beads` declares
    /// ([`scan_beads`]).
    pub fn with_capacity(bytes: usize, beads: Vec<(u32, AreaModel)>) -> PageData {
        PageData {
            moves: String::with_capacity(bytes),
            beads,
            ..PageData::default()
        }
    }

    /// Moves written.
    pub fn len(&self) -> usize {
        self.print_moves + self.travels
    }

    /// Nothing written yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// A layer mark (the motion model's layer callback).
    pub fn mark(&mut self, m: LayerMark) {
        self.marks.push(m);
    }

    /// Places the annotations whose line comes before the move on `line` (at `start`, the
    /// nozzle's position then).
    fn place_notes(&mut self, notes: &mut [Annotation], line: u32, start: [f64; 3], layer: u32) {
        while let Some(n) = notes.get_mut(self.next_note) {
            if n.line >= line {
                break;
            }
            let (nozzle, layer) = match self.last_end {
                Some(end) => (end, self.last_layer),
                None => (start, layer),
            };
            n.at = Some((place(n.point, nozzle), layer));
            self.next_note += 1;
        }
    }

    /// Places the annotations after the last move at its end.
    pub fn finish_notes(&mut self, notes: &mut [Annotation]) {
        if let Some(end) = self.last_end {
            for n in notes.iter_mut().skip(self.next_note) {
                n.at = Some((place(n.point, end), self.last_layer));
            }
        }
        self.next_note = notes.len();
    }

    /// Adds one segment of the motion model (E-only moves are left out, as the page draws
    /// nothing for them). `area_mm2`: the filament's cross-section; `nozzle_mm` for
    /// [`bead_mm`]'s fallback.
    pub fn push(&mut self, s: &Segment, notes: &mut [Annotation], area_mm2: f64, nozzle_mm: f64) {
        let start = [s.start[0], s.start[1], s.start[2]];
        let end = [s.end[0], s.end[1], s.end[2]];
        self.place_notes(notes, s.line, start, s.layer);
        if s.kind == MoveKind::Extruder {
            return;
        }
        let print = s.kind == MoveKind::Print;
        let de = s.end[3] - s.start[3];
        self.heights.note(s);
        let (w, h) = if print {
            let rise = match self.printing {
                Some((l, _, rise)) if l == s.layer => rise,
                below => {
                    // The first printing move of a layer (layers only grow along the file):
                    // the height the layer prints at, never a marker's or a lift's.
                    let z = self.heights.get(s.layer).unwrap_or(start[2]);
                    let rise = z - below.map_or(0.0, |b| b.1);
                    self.printing = Some((s.layer, z, rise));
                    rise
                }
            };
            while let Some((line, m)) = self.beads.get(self.next_bead) {
                if *line > s.line {
                    break;
                }
                self.bead = *m;
                self.next_bead += 1;
            }
            let cross = if s.len_mm > 0.0 {
                de * area_mm2 / s.len_mm
            } else {
                0.0
            };
            bead_mm(self.bead, cross, rise, nozzle_mm)
        } else {
            (0.0, 0.0)
        };
        let jump = self
            .last_end
            .is_none_or(|e| (0..3).any(|k| (e[k] - start[k]).abs() > 5e-4));
        if !self.is_empty() {
            self.moves.push(',');
        }
        push_num(
            &mut self.moves,
            f64::from(u8::from(print) + 2 * u8::from(jump)),
            0,
        );
        let _ = write!(self.moves, ",{},{}", s.layer, s.line);
        for v in end {
            self.moves.push(',');
            push_num(&mut self.moves, v, 3);
        }
        for (v, dec) in [
            (s.t_start_s, 2),
            (s.v_peak_mm_s, 1),
            (s.feed_mm_s, 1),
            (de, 5),
            (w, 3),
            (h, 3),
        ] {
            self.moves.push(',');
            push_num(&mut self.moves, v, dec);
        }
        if jump {
            for v in start {
                if !self.jumps.is_empty() {
                    self.jumps.push(',');
                }
                push_num(&mut self.jumps, v, 3);
            }
        }
        if print {
            self.print_moves += 1;
        } else {
            self.travels += 1;
        }
        self.last_end = Some(end);
        self.last_layer = s.layer;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bead_is_the_declared_model_of_the_extruded_area() {
        use std::f64::consts::{FRAC_PI_4, PI};
        // FullControl's default: a 0.5 × 0.25 rectangle is drawn 0.5 wide (the issue's
        // 0.554 came from the stadium formula).
        let (w, h) = bead_mm(AreaModel::Rectangle, 0.125, 0.25, 0.4);
        assert!(
            (w - 0.5).abs() < 1e-12 && (h - 0.25).abs() < 1e-12,
            "{w} {h}"
        );
        // A stadium where the design declares one: 0.12 mm² at 0.3 mm layers is
        // w = 0.4 + 0.3·(1 − π/4), and its stadium area is the extruded area.
        let (w, h) = bead_mm(AreaModel::Stadium, 0.12, 0.3, 0.4);
        assert!((h - 0.3).abs() < 1e-12);
        assert!((w - (0.4 + 0.3 * (1.0 - FRAC_PI_4))).abs() < 1e-12);
        let area = (w - h) * h + PI * h * h / 4.0;
        assert!((area - 0.12).abs() < 1e-12);
        // An implausible rise (a spiral's per-move layers) falls back to a nozzle-wide bead.
        let (w, h) = bead_mm(AreaModel::Stadium, 0.12, 0.003, 0.4);
        assert!((h - 0.3).abs() < 1e-12 && w > 0.4, "{w} {h}");
        // Too little material for the model at that height: an equal-area circle.
        for m in [AreaModel::Rectangle, AreaModel::Stadium] {
            let (w, h) = bead_mm(m, 0.01, 0.3, 0.4);
            assert!((w - h).abs() < 1e-12 && (PI * w * w / 4.0 - 0.01).abs() < 1e-12);
            assert_eq!(bead_mm(m, -1.0, 0.2, 0.4), (0.0, 0.0));
        }
        assert_eq!(
            scan_beads(b"G1 X1\n;AREA_MODEL:stadium\nG1 X2\n; area_model: rectangle\n"),
            vec![(2, AreaModel::Stadium), (4, AreaModel::Rectangle)]
        );
    }

    #[test]
    fn annotations_are_found_on_their_lines() {
        let g = b"G1 X1\n; ANNOTATION: seam here\nG1 X2 ;annotation:  after a move \n;ANNOTATIONS are not\n; note: no\n; ANNOTATION X1 Z2: up\n";
        let (notes, dropped) = scan_annotations(g);
        assert_eq!(dropped, 0);
        let got: Vec<(u32, &str)> = notes.iter().map(|n| (n.line, n.text.as_str())).collect();
        assert_eq!(got, vec![(2, "seam here"), (3, "after a move"), (6, "up")]);
        assert_eq!(notes[2].point, [Some(1.0), None, Some(2.0)]);
        assert_eq!(place(notes[2].point, [5.0, 6.0, 7.0]), [1.0, 6.0, 2.0]);
        let many = ";ANNOTATION: n\n".repeat(MAX_ANNOTATIONS + 2);
        let (notes, dropped) = scan_annotations(many.as_bytes());
        assert_eq!((notes.len(), dropped), (MAX_ANNOTATIONS, 2));
        let long = format!(";ANNOTATION: {}\n", "é".repeat(500));
        let (notes, _) = scan_annotations(long.as_bytes());
        assert_eq!(notes[0].text.chars().count(), MAX_ANNOTATION_CHARS);
    }
}
