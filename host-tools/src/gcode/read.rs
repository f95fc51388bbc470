//! Reading G-code into motion events for `stats`, `preview`, the motion model and the
//! time-based resampler — with the printer's own parser, so the host reads exactly what the
//! printer reads.
//!
//! [`FirmwareReader`] (what [`default_reader`] returns) runs every line through
//! [`firmware::gcode::parse_line`] and finds layers with [`firmware::layer::LayerDetector`]
//! (slicer markers of every family the firmware knows, our `;LAYER_CHANGE`/`;TURN` per helix
//! turn, `M73 L`, Klipper's `SET_PRINT_STATS_INFO`, else Z rising before an extrusion). On top
//! of the parser it keeps the modal state that turns commands into absolute positions (G90/G91,
//! M82/M83, G20/G21, G92, G28) and expands G2/G3 arcs into chords. Values arrive as `f32` (the
//! firmware's precision) and are tracked in `f64`.
//!
//! Host-link framing is accepted as the printer's link accepts it: a leading `N<n>` line number
//! is dropped and a trailing `*<checksum>` is checked (a mismatch is an error with the line
//! number). Any line the firmware's parser rejects is an error with its line number; commands
//! that do not move the head (temperatures, fans, unknown codes) are counted as skipped.

use firmware::gcode::{parse_line, Command};
use firmware::gcode::{MotionCommand, SettingsCommand};
use firmware::layer::{LayerDetector, MoveFacts};
pub use firmware::motion::LayerSource;

/// An absolute position: X, Y, Z, E (E as a running total in mm of filament).
pub type Pos4 = [f64; 4];

/// One event read from G-code.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// A straight move (arcs arrive as several).
    Move {
        /// Start, absolute.
        from: Pos4,
        /// End, absolute.
        to: Pos4,
        /// Requested feed, mm/s.
        feed_mm_s: f64,
        /// 1-based line number.
        line: u32,
    },
    /// A layer starts here: every move before this event belongs to the previous layer (the
    /// firmware's [`LayerDetector`] decides, so this is where the printer's layer pause stops).
    Layer {
        /// 1-based line number of the line before whose command the layer starts.
        line: u32,
        /// Height of the new layer, mm, when known (from `;Z:`, the marker or the move).
        z_mm: Option<f64>,
        /// What produced the mark (slicer comment, command, our turn marker, or a Z rise).
        source: LayerSource,
        /// The firmware's number of the layer ([`firmware::motion::LayerMark::layer`]): the
        /// n-th layer printed, from 1 (the slicers' preview numbers).
        number: u32,
    },
    /// Dwell (G4), seconds.
    Dwell(f64),
    /// Acceleration change (M204): print (P or S) and travel (T), mm/s²; `None` = unchanged.
    Accel {
        /// Printing acceleration.
        print_mm_s2: Option<f64>,
        /// Travel acceleration.
        travel_mm_s2: Option<f64>,
    },
}

/// A G-code parse error with its line.
#[derive(Clone, Debug, thiserror::Error, PartialEq, serde::Serialize)]
#[error("line {line}: {msg}")]
pub struct ReadError {
    /// 1-based line number.
    pub line: u32,
    /// What is wrong.
    pub msg: String,
}

/// What a reader counted.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReadCounts {
    /// Non-empty lines read.
    pub lines: u64,
    /// Commands that do not move the head (temperatures, fans, unknown M-codes, ...).
    pub skipped: u64,
    /// Lines the firmware would reject, skipped under [`BadLines::Skip`].
    pub bad: u64,
}

/// What a [`FirmwareReader`] does with a line the firmware's parser rejects.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BadLines {
    /// Stop with the line's error (the default: tools that write or resample G-code must not
    /// guess).
    #[default]
    Refuse,
    /// Skip the line as the printer would (it answers `Error:` and does nothing), keep the
    /// first [`MAX_KEPT_BAD_LINES`] errors in [`FirmwareReader::bad_lines`] and count all.
    Skip,
}

/// Errors of skipped lines a reader keeps.
pub const MAX_KEPT_BAD_LINES: usize = 20;

/// A source of motion events.
pub trait GcodeReader {
    /// Reads all of `input`, calling `sink` for every event in order.
    fn read(&mut self, input: &[u8], sink: &mut dyn FnMut(Event)) -> Result<ReadCounts, ReadError>;
}

/// The reader the tools use: the firmware's parser ([`FirmwareReader`]).
pub fn default_reader() -> FirmwareReader {
    FirmwareReader::default()
}

/// Reader over the firmware's own parser and layer detector (see the module docs).
#[derive(Clone, Debug)]
pub struct FirmwareReader {
    pos: Pos4,
    abs_xyz: bool,
    abs_e: bool,
    inch: bool,
    feed_mm_s: f64,
    layers: LayerDetector,
    /// Last height converted to µm: (mm, µm).
    z_cache: (f64, i32),
    /// Longest chord used to expand G2/G3 arcs, mm.
    pub arc_seg_mm: f64,
    /// Rejected lines: refuse (default) or skip.
    pub bad_line_policy: BadLines,
    /// The first [`MAX_KEPT_BAD_LINES`] skipped lines' errors.
    pub bad_lines: Vec<ReadError>,
}

impl Default for FirmwareReader {
    fn default() -> Self {
        FirmwareReader {
            pos: [0.0; 4],
            abs_xyz: true,
            abs_e: true,
            inch: false,
            feed_mm_s: 25.0,
            layers: LayerDetector::new(),
            z_cache: (0.0, 0),
            arc_seg_mm: 0.5,
            bad_line_policy: BadLines::Refuse,
            bad_lines: Vec::new(),
        }
    }
}

/// Strips host-link framing as the printer's link does: a leading `N<digits>` and a trailing
/// `*<1–3 digits>` checksum (XOR of every byte before the `*`), which must match.
fn unframe(raw: &[u8]) -> Result<&[u8], &'static str> {
    let mut body = raw;
    // Trailing checksum: only the last few bytes are looked at (cheap on every line).
    let t = body.trim_ascii_end();
    let digits = t
        .iter()
        .rev()
        .take(4)
        .take_while(|c| c.is_ascii_digit())
        .count();
    if (1..=3).contains(&digits) && t.len() > digits && t[t.len() - digits - 1] == b'*' {
        let star = t.len() - digits - 1;
        let want = t[star + 1..]
            .iter()
            .fold(0u32, |a, d| a * 10 + u32::from(d - b'0'));
        if want > 255 || u32::from(firmware::link::checksum(&t[..star])) != want {
            return Err("checksum mismatch");
        }
        body = &t[..star];
    }
    // Leading line number.
    let lead = body.len() - body.trim_ascii_start().len();
    if let (Some(b'N' | b'n'), Some(d)) = (body.get(lead), body.get(lead + 1)) {
        if d.is_ascii_digit() || *d == b'-' {
            let rest = &body[lead + 2..];
            let n = rest.iter().take_while(|c| c.is_ascii_digit()).count();
            body = &rest[n..];
        }
    }
    Ok(body)
}

/// Height in µm as the layer detector wants it.
#[inline]
fn um(z_mm: f64) -> i32 {
    // Half away from zero, like `f64::round`, without the libm call (the cast truncates and
    // saturates).
    let v = z_mm * 1000.0;
    (if v >= 0.0 { v + 0.5 } else { v - 0.5 }) as i32
}

/// Centre of an arc from `from` to `to` given I/J offsets (already scaled) or a radius R
/// (negative R = the long way round).
fn arc_center(
    from: Pos4,
    to: Pos4,
    ij: Option<(f64, f64)>,
    r: Option<f64>,
    ccw: bool,
) -> Result<(f64, f64), &'static str> {
    match (ij, r) {
        (Some((i, j)), _) => Ok((from[0] + i, from[1] + j)),
        (None, Some(r)) => {
            let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
            let d = (dx * dx + dy * dy).sqrt();
            if d < 1e-9 || d > 2.0 * r.abs() + 1e-6 {
                return Err("arc radius too small for its end point");
            }
            let h = (r * r - 0.25 * d * d).max(0.0).sqrt();
            let sgn = if (r > 0.0) == ccw { 1.0 } else { -1.0 };
            Ok((
                from[0] + 0.5 * dx - sgn * h * dy / d,
                from[1] + 0.5 * dy + sgn * h * dx / d,
            ))
        }
        (None, None) => Err("G2/G3 needs I/J or R"),
    }
}

/// Emits an arc as chords no longer than `seg_mm`.
#[allow(clippy::too_many_arguments)]
fn expand_arc(
    from: Pos4,
    to: Pos4,
    (c, ccw, circles): ((f64, f64), bool, u8),
    seg_mm: f64,
    feed_mm_s: f64,
    line: u32,
    sink: &mut dyn FnMut(Event),
) {
    let (cx, cy) = c;
    let r = (from[0] - cx).hypot(from[1] - cy);
    let a0 = (from[1] - cy).atan2(from[0] - cx);
    let a1 = (to[1] - cy).atan2(to[0] - cx);
    let mut sweep = a1 - a0;
    if ccw {
        if sweep <= 1e-9 {
            sweep += std::f64::consts::TAU;
        }
    } else if sweep >= -1e-9 {
        sweep -= std::f64::consts::TAU;
    }
    // `P<n>`: n whole turns more, the same way round (Marlin's ARC_P_CIRCLES).
    sweep += sweep.signum() * std::f64::consts::TAU * f64::from(circles);
    let n = ((sweep.abs() * r / seg_mm).ceil() as usize).clamp(1, 10_000);
    let mut prev = from;
    for k in 1..=n {
        let t = k as f64 / n as f64;
        let p = if k == n {
            to
        } else {
            let a = a0 + sweep * t;
            [
                cx + r * a.cos(),
                cy + r * a.sin(),
                from[2] + (to[2] - from[2]) * t,
                from[3] + (to[3] - from[3]) * t,
            ]
        };
        sink(Event::Move {
            from: prev,
            to: p,
            feed_mm_s,
            line,
        });
        prev = p;
    }
}

/// What one command does, worked out before anything is emitted (the layer detector must see
/// the line first: a layer mark goes before the command's moves).
enum Action {
    /// Nothing to emit (modal change, G92, or not motion-related).
    None,
    /// A straight move to this point.
    Line(Pos4),
    /// The head goes to this point without a move to plan (homing: how far is unknown).
    Jump(Pos4),
    /// An arc to this point about this centre, counter-clockwise or not, with this many extra
    /// whole circles (`P`).
    Arc(Pos4, ((f64, f64), bool, u8)),
    /// An event to pass on as it is.
    Event(Event),
}

impl FirmwareReader {
    #[inline]
    fn scale(&self) -> f64 {
        if self.inch {
            25.4
        } else {
            1.0
        }
    }

    #[inline]
    fn target(&self, axes: &firmware::gcode::AxisWords) -> Pos4 {
        let scale = self.scale();
        let mut to = self.pos;
        for (k, v) in axes.0.iter().enumerate().take(4) {
            if let Some(v) = v {
                let v = f64::from(*v) * scale;
                let abs = if k == 3 { self.abs_e } else { self.abs_xyz };
                to[k] = if abs { v } else { to[k] + v };
            }
        }
        to
    }

    #[inline]
    fn set_feed(&mut self, f: Option<f32>) {
        if let Some(f) = f {
            if f > 0.0 {
                self.feed_mm_s = f64::from(f) * self.scale() / 60.0;
            }
        }
    }

    /// Works out one command and updates the modal state (not the position of moves, which
    /// `read` advances after emitting). `None` = not a motion-related command.
    fn action(&mut self, cmd: &Command) -> Result<Option<Action>, &'static str> {
        let scale = self.scale();
        Ok(Some(match *cmd {
            Command::Motion(MotionCommand::Move { axes, feed, .. }) => {
                self.set_feed(feed);
                Action::Line(self.target(&axes))
            }
            Command::Motion(MotionCommand::Arc {
                clockwise,
                axes,
                i,
                j,
                r,
                circles,
                feed,
            }) => {
                self.set_feed(feed);
                let to = self.target(&axes);
                let ij = match (i, j) {
                    (None, None) => None,
                    (i, j) => Some((
                        f64::from(i.unwrap_or(0.0)) * scale,
                        f64::from(j.unwrap_or(0.0)) * scale,
                    )),
                };
                let c = arc_center(
                    self.pos,
                    to,
                    ij,
                    r.map(|r| f64::from(r) * scale),
                    !clockwise,
                )?;
                Action::Arc(to, (c, !clockwise, circles))
            }
            Command::Motion(MotionCommand::Dwell { ms, s }) => {
                let t = f64::from(s.unwrap_or(0.0)) + f64::from(ms.unwrap_or(0.0)) / 1000.0;
                if t > 0.0 {
                    Action::Event(Event::Dwell(t))
                } else {
                    Action::None
                }
            }
            Command::Motion(MotionCommand::Inches) => {
                self.inch = true;
                Action::None
            }
            Command::Motion(MotionCommand::Millimetres) => {
                self.inch = false;
                Action::None
            }
            Command::Motion(MotionCommand::Absolute) => {
                self.abs_xyz = true;
                self.abs_e = true;
                Action::None
            }
            Command::Motion(MotionCommand::Relative) => {
                self.abs_xyz = false;
                self.abs_e = false;
                Action::None
            }
            Command::Motion(MotionCommand::AbsoluteE) => {
                self.abs_e = true;
                Action::None
            }
            Command::Motion(MotionCommand::RelativeE) => {
                self.abs_e = false;
                Action::None
            }
            Command::Motion(MotionCommand::SetPosition(axes)) => {
                // Coordinates change, the head does not move.
                if axes.is_empty() {
                    self.pos = [0.0; 4];
                }
                for (k, v) in axes.0.iter().enumerate().take(4) {
                    if let Some(v) = v {
                        self.pos[k] = f64::from(*v) * scale;
                    }
                }
                Action::None
            }
            Command::Motion(MotionCommand::Home(flags)) => {
                let mut to = self.pos;
                for (k, t) in to.iter_mut().enumerate().take(3) {
                    if flags.is_empty() || flags.0[k] {
                        *t = 0.0;
                    }
                }
                Action::Jump(to)
            }
            Command::Settings(SettingsCommand::Acceleration {
                print, travel, s, ..
            }) => Action::Event(Event::Accel {
                print_mm_s2: print.or(s).map(f64::from),
                travel_mm_s2: travel.or(s).map(f64::from),
            }),
            _ => return Ok(None),
        }))
    }

    /// Feeds the layer detector with one line and the motion it makes; emits a layer event.
    #[inline]
    fn layer(
        &mut self,
        line: &firmware::gcode::Line<'_>,
        from: &Pos4,
        to: &Pos4,
        line_no: u32,
        sink: &mut dyn FnMut(Event),
    ) {
        // Z rarely changes: convert each height to µm once.
        let z_start_um = self.z_um(from[2]);
        let z_end_um = self.z_um(to[2]);
        let facts = MoveFacts {
            start_um: [um(from[0]), um(from[1]), z_start_um],
            end_um: [um(to[0]), um(to[1]), z_end_um],
            extrudes: to[3] > from[3] && (to[0] != from[0] || to[1] != from[1]),
            moved: to != from,
        };
        if let Some(mark) = self.layers.feed(line, facts) {
            self.emit_layer(mark, line_no, sink);
        }
    }

    fn emit_layer(
        &self,
        mark: firmware::motion::LayerMark,
        line_no: u32,
        sink: &mut dyn FnMut(Event),
    ) {
        sink(Event::Layer {
            line: line_no,
            z_mm: mark.z_um.map(|z| f64::from(z) / 1000.0),
            source: mark.source,
            number: mark.layer,
        });
    }

    /// `z_mm` in µm, remembering the last conversion.
    #[inline]
    fn z_um(&mut self, z_mm: f64) -> i32 {
        if z_mm != self.z_cache.0 {
            self.z_cache = (z_mm, um(z_mm));
        }
        self.z_cache.1
    }

    /// Layer marks found so far.
    pub fn layers(&self) -> u32 {
        self.layers.layers()
    }
}

impl GcodeReader for FirmwareReader {
    fn read(&mut self, input: &[u8], sink: &mut dyn FnMut(Event)) -> Result<ReadCounts, ReadError> {
        let mut counts = ReadCounts::default();
        let mut line_no: u32 = 0;
        let mut start = 0usize;
        let ends = memchr::memchr_iter(b'\n', input).chain(std::iter::once(input.len()));
        for end in ends {
            let raw = input.get(start..end).unwrap_or(&[]);
            start = end + 1;
            line_no = line_no.saturating_add(1);
            let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
            if raw.is_empty() {
                continue;
            }
            counts.lines += 1;
            let err = |msg: String| ReadError { line: line_no, msg };
            // A rejected line: an error, or under `BadLines::Skip` noted and skipped.
            macro_rules! reject {
                ($msg:expr) => {{
                    let e = err($msg);
                    if self.bad_line_policy == BadLines::Refuse {
                        return Err(e);
                    }
                    counts.bad += 1;
                    if self.bad_lines.len() < MAX_KEPT_BAD_LINES {
                        self.bad_lines.push(e);
                    }
                    continue;
                }};
            }
            let text = match unframe(raw) {
                Ok(t) => t,
                Err(m) => reject!(m.into()),
            };
            // Borrowed in place: moving the parsed line (≈ 140 bytes) out of the `Result`
            // cost a measurable share of the reading time.
            let parsed = parse_line(text);
            let line = match &parsed {
                Ok(l) => l,
                Err(e) => reject!(e.to_string()),
            };
            let from = self.pos;
            let action = match &line.command {
                Some(cmd) => match self.action(cmd) {
                    Ok(Some(a)) => a,
                    Ok(None) => {
                        counts.skipped += 1;
                        Action::None
                    }
                    Err(m) => reject!(m.into()),
                },
                None => Action::None,
            };
            let to = match action {
                Action::Line(to) | Action::Jump(to) | Action::Arc(to, ..) => to,
                _ => from,
            };
            self.layer(line, &from, &to, line_no, sink);
            match action {
                Action::Line(to) => {
                    if to != from {
                        sink(Event::Move {
                            from,
                            to,
                            feed_mm_s: self.feed_mm_s,
                            line: line_no,
                        });
                    }
                }
                Action::Arc(to, arc) => expand_arc(
                    from,
                    to,
                    arc,
                    self.arc_seg_mm,
                    self.feed_mm_s,
                    line_no,
                    sink,
                ),
                Action::Event(e) => sink(e),
                Action::Jump(_) | Action::None => {}
            }
            self.pos = match action {
                Action::Line(to) | Action::Jump(to) | Action::Arc(to, ..) => to,
                _ => self.pos,
            };
        }
        if let Some(mark) = self.layers.finish() {
            self.emit_layer(mark, line_no, sink);
        }
        Ok(counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn events(src: &str) -> Vec<Event> {
        let mut v = Vec::new();
        let r = default_reader().read(src.as_bytes(), &mut |e| v.push(e));
        assert!(r.is_ok(), "{r:?}");
        v
    }

    fn moves(ev: &[Event]) -> Vec<Pos4> {
        ev.iter()
            .filter_map(|e| match e {
                Event::Move { to, .. } => Some(*to),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn modes_positions_and_feeds() {
        let ev = events(
            "G90\nM83\nG1 X10 Y0 E1 F600\nG1 X20 E1\nG91\nG1 X-5 Z0.5\nG90\nG92 E0\nM82\n\
             G1 E2\nG20\nG1 X1\nG21\nG28 X\n",
        );
        let m = moves(&ev);
        assert_eq!(m[0], [10.0, 0.0, 0.0, 1.0]);
        assert_eq!(m[1], [20.0, 0.0, 0.0, 2.0]);
        assert_eq!(m[2], [15.0, 0.0, 0.5, 2.0]);
        assert_eq!(
            m[3],
            [15.0, 0.0, 0.5, 2.0],
            "G92 E0 then M82 G1 E2: E 0 -> 2"
        );
        assert_eq!(m[4], [25.4, 0.0, 0.5, 2.0]);
        assert_eq!(m.len(), 5, "homing is not a planned move");
        match ev.iter().find(|e| matches!(e, Event::Move { .. })) {
            Some(Event::Move {
                feed_mm_s, line, ..
            }) => {
                assert_eq!(*feed_mm_s, 10.0);
                assert_eq!(*line, 3);
            }
            _ => panic!("no move"),
        }
        let ev = events("G1 X5 Y5 Z5\nG28 X\nG1 Y6\n");
        assert_eq!(moves(&ev)[1], [0.0, 6.0, 5.0, 0.0], "G28 X homes X only");
    }

    #[test]
    fn prusaslicer_markers_place_the_layer_before_its_z_move() {
        let ev = events(
            "G1 Z0.2 F600\n;LAYER_CHANGE\n;Z:0.2\nG1 X10 E1 F1200\n;LAYER_CHANGE\n;Z:0.4\n\
             G1 Z0.4\nG1 X0 E2\n",
        );
        let layers: Vec<_> = ev
            .iter()
            .enumerate()
            .filter_map(|(i, e)| match e {
                Event::Layer {
                    line, z_mm, source, ..
                } => Some((i, *line, *z_mm, *source)),
                _ => None,
            })
            .collect();
        assert_eq!(layers.len(), 2);
        // Event order: Z move, layer 0, X move, layer 1, Z move, X move.
        assert_eq!(layers[0].0, 1);
        assert_eq!(layers[0].1, 4);
        assert_eq!(layers[0].2, Some(0.2));
        assert_eq!(layers[0].3, LayerSource::Comment);
        assert_eq!(layers[1].0, 3);
        assert_eq!(layers[1].1, 7);
        assert_eq!(layers[1].2, Some(0.4));
    }

    #[test]
    fn z_rise_layers_without_markers() {
        let ev = events("G1 Z0.2 F600\nG1 X10 E1\nG1 Z0.4\nG1 X0 E2\nG1 Z0.6\nG0 X5\nG1 Z0.4\n");
        let z: Vec<_> = ev
            .iter()
            .filter_map(|e| match e {
                Event::Layer { z_mm, source, .. } => Some((*z_mm, *source)),
                _ => None,
            })
            .collect();
        // A travel at 0.6 without extrusion starts no layer.
        assert_eq!(
            z,
            vec![
                (Some(0.2), LayerSource::ZRise),
                (Some(0.4), LayerSource::ZRise)
            ]
        );
    }

    #[test]
    fn arcs_expand_into_short_chords_on_the_circle() {
        let ev = events("G0 X10 Y0\nG3 X0 Y10 I-10 J0 E1.5 F600\n");
        let m = moves(&ev);
        // Quarter circle of radius 10 (15.7 mm) in chords of at most 0.5 mm.
        assert_eq!(m.len(), 1 + 32);
        for p in &m[1..] {
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-9, "{p:?}");
        }
        let last = m[m.len() - 1];
        assert!(last[0].abs() < 1e-9 && (last[1] - 10.0).abs() < 1e-9);
        assert!((last[3] - 1.5).abs() < 1e-9);
        // Clockwise with R: the short way from (10,0) to (0,-10) about the origin.
        let ev = events("G0 X10 Y0\nG2 X0 Y-10 R10\n");
        for p in &moves(&ev)[1..] {
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-6 && p[0] >= -1e-9 && p[1] <= 1e-9);
        }
    }

    #[test]
    fn dwell_and_acceleration() {
        let ev = events("G4 P500\nG4 S2\nM204 P800 T1500\nM204 S700\nM104 S200\n");
        assert_eq!(ev[0], Event::Dwell(0.5));
        assert_eq!(ev[1], Event::Dwell(2.0));
        assert_eq!(
            ev[2],
            Event::Accel {
                print_mm_s2: Some(800.0),
                travel_mm_s2: Some(1500.0)
            }
        );
        assert_eq!(
            ev[3],
            Event::Accel {
                print_mm_s2: Some(700.0),
                travel_mm_s2: Some(700.0)
            }
        );
        let c = default_reader().read(b"M104 S200\nM862.3 P \"MK3\"\nG1 X1\n", &mut |_| {});
        assert_eq!(
            c,
            Ok(ReadCounts {
                lines: 3,
                skipped: 2,
                bad: 0
            })
        );
    }

    #[test]
    fn line_numbers_and_checksums_as_the_link_reads_them() {
        // N1 G1 X10*80 is the link's own doc example.
        let ev = events("N1 G1 X10*80\nN2 G1 X20\n");
        assert_eq!(moves(&ev).len(), 2);
        let e = default_reader().read(b"G1 X1\nN2 G1 X10*81\n", &mut |_| {});
        assert_eq!(e.err().map(|e| e.line), Some(2));
    }

    proptest::proptest! {
        #[test]
        fn any_bytes_read_without_panic(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..400)) {
            let mut n = 0usize;
            let _ = default_reader().read(&bytes, &mut |_| n += 1);
        }

        #[test]
        fn gcode_like_lines_read_without_panic(
            lines in proptest::collection::vec(
                "(N[0-9]{1,3} )?(G[0-3]|G28|G9[012]|M8[23]|G4|M204|;LAYER_CHANGE|;Z:[0-9.]{1,4})( [XYZEFIJRPST]-?[0-9]{0,4}(\\.[0-9]{0,3})?){0,5}(\\*[0-9]{1,3})?",
                0..40,
            )
        ) {
            let text = lines.join("\n");
            let r = default_reader().read(text.as_bytes(), &mut |e| {
                if let Event::Move { from, to, feed_mm_s, .. } = e {
                    assert!(from.iter().chain(&to).all(|v| v.is_finite()), "{from:?} {to:?}");
                    assert!(feed_mm_s > 0.0);
                }
            });
            if let Err(e) = r {
                proptest::prop_assert!(e.line >= 1 && e.line as usize <= lines.len().max(1));
            }
        }
    }

    #[test]
    fn garbage_is_an_error_with_line() {
        let e = default_reader().read(b"G1 X1\nG1 X#\n", &mut |_| {});
        assert_eq!(e.err().map(|e| e.line), Some(2));
        let e = default_reader().read(b"G1 X1\nG1 Xnan\n", &mut |_| {});
        assert_eq!(e.err().map(|e| e.line), Some(2));
        let e = default_reader().read(b"G1 X1 X2\n", &mut |_| {});
        assert!(e.is_err());
        let e = default_reader().read(b"G2 X1 Y1\n", &mut |_| {});
        assert_eq!(e.err().map(|e| e.line), Some(1), "arc without I/J/R");
    }
}
