//! Layer detection: turns slicer markers (or, in files without any, Z rising before an
//! extruding move) into [`LayerMark`] events placed in the command stream, so the planner can
//! hold a pause exactly at a layer boundary.
//!
//! # Use
//! Feed every line, in order, **after** the machine state has applied its command, with the
//! facts of the move it made (if any). A returned mark must be queued **before** that line's
//! command:
//!
//! ```
//! use firmware::config::MachineConfig;
//! use firmware::gcode::parse_line;
//! use firmware::layer::{LayerDetector, MoveFacts};
//! use firmware::machine::MachineState;
//! let cfg = MachineConfig::ENDER3;
//! let mut m = MachineState::new(&cfg);
//! let mut d = LayerDetector::new();
//! let mut marks = 0;
//! for text in [";LAYER_CHANGE", ";Z:0.2", "G1 Z0.2 F600", "G1 X10 E1", ";LAYER_CHANGE", ";Z:0.4", "G1 Z0.4"] {
//!     let line = parse_line(text.as_bytes()).unwrap();
//!     let before = m.position_steps(&cfg);
//!     if let Some(cmd) = &line.command {
//!         m.apply(cmd, &cfg).unwrap();
//!     }
//!     let facts = MoveFacts::between(&before, &m.position_steps(&cfg), &cfg);
//!     if let Some(mark) = d.feed(&line, facts) {
//!         // queue `mark`, then the line's action
//!         assert_eq!(mark.layer, marks);
//!         marks += 1;
//!     }
//! }
//! assert_eq!(marks, 2);
//! ```
//!
//! # Markers accepted
//! | source | spelling | mark placed |
//! |---|---|---|
//! | PrusaSlicer, SuperSlicer, OrcaSlicer, Bambu | `;LAYER_CHANGE` (height from a following `;Z:<mm>`; `;HEIGHT:` is ignored — it also appears mid-layer) | before the first motion command after the marker, i.e. before the layer's Z move |
//! | Cura, ideaMaker | `;LAYER:<n>` (`;LAYER_COUNT:` is not a marker; a following `;Z:` gives the height, else the first move after the marker) | before the first motion command after the marker; Cura has already moved Z (except before layer 0), so the Z move sits just before the mark, the first extrusion after it |
//! | Simplify3D | `; layer <n>, Z = <mm>` | before the first motion command after the marker |
//! | Klipper macros | `SET_PRINT_STATS_INFO CURRENT_LAYER=<n>` | before that command |
//! | Orca/Bambu/Prusa progress | `M73 L<n>` | before that command |
//! | this project's host compiler (helical prints) | `;TURN` or `;TURN:<n>`, one per helix turn | before the first motion command after the marker ([`LayerSource::Turn`]) |
//! | none of the above | Z higher at the start of an extruding move than at the end of the previous extruding move (first extruding move: layer 0) | before that extruding move |
//!
//! An *extruding move* moves X or Y and advances E. Z-hops (up, travel, down, extrude at the
//! same height) and helices (Z rising *during* extrusion) start no layer.
//!
//! # The boundary
//! For every source: every extruding move of layer k is before the mark of layer k+1 and every
//! extruding move of layer k+1 after it. Non-extruding moves between the two layers (retract,
//! Z move, travel) and commands that do not move (fan, temperature) sit on either side depending on the slicer: PrusaSlicer's marker precedes its
//! Z move, Cura's follows it, the Z-rise fallback can only tell at the first extrusion. A pause
//! held at the mark therefore always stops after the last extrusion of layer k and before the
//! first of layer k+1.
//!
//! # No double counting
//! The first explicit marker family seen (PrusaSlicer, Cura, Simplify3D, Klipper, M73, turn)
//! wins for the rest of the file: other families, and the Z-rise fallback, are ignored from then
//! on (Orca writes both `;LAYER_CHANGE` and `M73 L`; PrusaSlicer for Klipper writes both
//! `;LAYER_CHANGE` and `SET_PRINT_STATS_INFO`). A repeated `M73 L`/`CURRENT_LAYER` with the
//! same number is not a new layer. Marks produced by the Z-rise fallback before the first
//! explicit marker (e.g. a purge line in start G-code at another height) stay.
//!
//! [`LayerMark::layer`] counts marks from 0 in file order: it equals Cura's `;LAYER:n` for a
//! Cura file and is PrusaSlicer's GUI layer number minus one.

use crate::config::MachineConfig;
use crate::gcode::{Command, Line};
use crate::motion::{Axis, LayerMark, LayerSource, StepPos};

mod height;
#[cfg(test)]
mod tests;

/// What a command did to the head, for the Z-rise fallback and for mark heights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MoveFacts {
    /// Z before the command, µm.
    pub z_start_um: i32,
    /// Z after the command, µm.
    pub z_end_um: i32,
    /// The command moved X or Y and advanced E (a printing move).
    pub extrudes: bool,
    /// The command moved any axis.
    pub moved: bool,
}

impl MoveFacts {
    /// Facts of the motion between two step positions (before and after a command). Works for
    /// lines without motion too (then nothing moved and nothing extrudes).
    pub fn between(before: &StepPos, after: &StepPos, cfg: &MachineConfig) -> Self {
        let z = |s: i32| {
            let spm = f64::from(cfg.axis(Axis::Z).steps_per_mm);
            if spm > 0.0 {
                crate::machine::round_i32(f64::from(s) * 1000.0 / spm).unwrap_or(0)
            } else {
                0
            }
        };
        let (x, y, zi, e) = (
            Axis::X.index(),
            Axis::Y.index(),
            Axis::Z.index(),
            Axis::E.index(),
        );
        MoveFacts {
            z_start_um: z(before[zi]),
            z_end_um: z(after[zi]),
            extrudes: after[e] > before[e] && (after[x] != before[x] || after[y] != before[y]),
            moved: after != before,
        }
    }
}

/// Marker families; the first one seen locks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Family {
    Prusa,
    Cura,
    Simplify3d,
    Klipper,
    M73,
    Turn,
}

/// A marker seen in a comment, waiting for the next command to be placed before.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Pending {
    source: LayerSource,
    /// The slicer's own layer number, if the marker carries one.
    number: Option<u32>,
    z_um: Option<i32>,
}

/// The streaming layer detector. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayerDetector {
    /// Marks emitted.
    count: u32,
    /// Unnumbered markers of the locked family (`;LAYER_CHANGE`, `;TURN`) or height-rule
    /// layers seen: the number of the next such layer.
    counted: u32,
    /// Number of the last mark (the next unnumbered one follows it).
    last_number: Option<u32>,
    family: Option<Family>,
    pending: Option<Pending>,
    /// Extrusion heights (the comment-free rule).
    heights: height::Heights,
    /// Last known Z, µm.
    z_um: Option<i32>,
    /// Last layer number seen in an `M73 L` / `CURRENT_LAYER=`.
    last_numbered: Option<u32>,
    /// The end of printing was marked; no other end mark until something extrudes again.
    ended: bool,
    /// Mark the end of printing ([`LayerDetector::with_end_mark`]).
    end_mark: bool,
}

impl Default for LayerDetector {
    fn default() -> Self {
        Self::new()
    }
}

impl LayerDetector {
    /// A detector at the start of a file: no layer yet, no marker family.
    pub const fn new() -> Self {
        LayerDetector {
            count: 0,
            counted: 0,
            last_number: None,
            family: None,
            pending: None,
            heights: height::Heights::new(),
            z_um: None,
            last_numbered: None,
            ended: false,
            end_mark: false,
        }
    }

    /// Also mark the end of printing (the printer's detector): the first end-code command
    /// after an extrusion — a heater switched off (`M104 S0`, `M140 S0`, ...) or the motors
    /// disabled (`M84`/`M18` without a timeout) — gets a mark ([`LayerSource::End`], numbered
    /// one after the last layer), so a `layer` pause requested in the last layer stops at the
    /// end of that layer instead of after the end code, and its speed-up stops there too. The
    /// mark ends a layer but starts none: layer counts (host-tools' `stats`) leave it out.
    pub const fn with_end_mark(mut self) -> Self {
        self.end_mark = true;
        self
    }

    /// Feed one parsed line with the facts of the move its command made (use
    /// [`MoveFacts::between`] with the step positions before and after applying it). Returns the
    /// mark to queue **before** this line's command, if a layer starts here.
    pub fn feed(&mut self, line: &Line<'_>, facts: MoveFacts) -> Option<LayerMark> {
        let mut out = None;
        // A comment marker: it becomes pending (an earlier pending one is flushed first; no
        // command came between them, so its place is the same).
        if let Some(comment) = line.comment {
            match classify_comment(comment) {
                // `accept_family` locks the family on the first marker.
                Some(CommentMarker::Layer(family, source, number, z))
                    if self.accept_family(family) =>
                {
                    out = self.pending.take().map(|p| self.emit(p));
                    self.pending = Some(Pending {
                        source,
                        number,
                        z_um: z,
                    });
                }
                Some(CommentMarker::Z(z)) => {
                    if let Some(p) = &mut self.pending {
                        p.z_um = Some(z);
                    }
                }
                Some(CommentMarker::Header(family)) => {
                    let _ = self.accept_family(family);
                }
                _ => {}
            }
        }
        let Some(cmd) = &line.command else {
            return out;
        };
        // A motion command: a pending mark goes before it, with the height this move reaches
        // if the marker gave none (Cura's first layer moves Z after `;LAYER:0`).
        if out.is_none() && facts.moved {
            out = self.pending.take().map(|mut p| {
                p.z_um = p.z_um.or(Some(facts.z_end_um));
                self.emit(p)
            });
        }
        // Command markers.
        let numbered = match cmd {
            Command::Progress(p) => p.layer.map(|l| (Family::M73, l)),
            Command::PrintStatsInfo {
                current_layer: Some(l),
                ..
            } => Some((Family::Klipper, *l)),
            _ => None,
        };
        if let Some((family, n)) = numbered {
            if self.last_numbered != Some(n) && self.accept_family(family) {
                self.last_numbered = Some(n);
                if out.is_none() {
                    out = Some(self.emit(Pending {
                        source: LayerSource::Command,
                        number: Some(n),
                        z_um: None,
                    }));
                }
            }
        }
        // The end of printing: the first end-code command after an extrusion.
        if out.is_none()
            && self.end_mark
            && is_end_command(cmd)
            && self.heights.printed()
            && !self.ended
        {
            self.ended = true;
            out = Some(self.emit(Pending {
                source: LayerSource::End,
                number: None,
                z_um: None,
            }));
        }
        if facts.extrudes {
            self.ended = false;
            // The height rule, only while no marker family is known.
            let starts = self.heights.extrusion(facts.z_start_um, facts.z_end_um);
            if starts && self.family.is_none() && out.is_none() {
                self.z_um = Some(facts.z_start_um);
                out = Some(self.emit(Pending {
                    source: LayerSource::ZRise,
                    number: None,
                    z_um: Some(facts.z_start_um),
                }));
            }
        }
        self.z_um = Some(facts.z_end_um);
        out
    }

    /// Place a pending marker now instead of before the next motion command: at the end of
    /// a file (a marker after the last command still counts as a layer), and in the firmware
    /// for M400 and when a layer pause finds the machine idle with a marker pending (everything
    /// before it has run, so the boundary is here; the next motion command gets no mark).
    pub fn finish(&mut self) -> Option<LayerMark> {
        self.pending.take().map(|p| self.emit(p))
    }

    /// Number of marks emitted so far.
    pub fn layers(&self) -> u32 {
        self.count
    }

    /// True once an explicit marker (or a slicer header naming the marker family) has been
    /// seen: the height rule is off.
    pub fn has_explicit_markers(&self) -> bool {
        self.family.is_some()
    }

    fn accept_family(&mut self, f: Family) -> bool {
        match self.family {
            None => {
                self.family = Some(f);
                true
            }
            Some(g) => g == f,
        }
    }

    fn emit(&mut self, p: Pending) -> LayerMark {
        // The slicer's own number when the marker has one; else the count of the family's
        // unnumbered markers (from 0), or one more than the last mark (the end mark).
        let layer = match (p.number, p.source) {
            (Some(n), _) => n,
            (None, LayerSource::End) => self.last_number.map_or(0, |n| n.saturating_add(1)),
            (None, _) => {
                let n = self.counted;
                self.counted = self.counted.saturating_add(1);
                n
            }
        };
        self.last_number = Some(layer);
        let mark = LayerMark {
            layer,
            z_um: p.z_um.or(self.z_um),
            source: p.source,
        };
        self.count = self.count.saturating_add(1);
        mark
    }
}

/// End-code commands: a heater switched off (`M104 S0`, `M140 S0`, `M109 S0`...) or the
/// motors disabled (`M84`/`M18` without a timeout).
fn is_end_command(cmd: &Command) -> bool {
    match cmd {
        Command::SetTemperature { s, r, .. } => {
            let off = |v: &Option<f32>| v.is_some_and(|t| t <= 0.0);
            (off(s) && r.is_none()) || (off(r) && s.is_none()) || (off(s) && off(r))
        }
        Command::DisableSteppers { s: None, .. } => true,
        _ => false,
    }
}

/// What a comment says about layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CommentMarker {
    /// A layer starts (family, source, the slicer's number, height if the marker has them).
    Layer(Family, LayerSource, Option<u32>, Option<i32>),
    /// `;Z:<mm>`: height of the pending layer.
    Z(i32),
    /// A header naming the slicer, so its marker family before its first marker (the start
    /// code's purge line is then no layer of its own).
    Header(Family),
}

fn strip_prefix_ci<'a>(s: &'a [u8], prefix: &[u8]) -> Option<&'a [u8]> {
    let head = s.get(..prefix.len())?;
    if head.eq_ignore_ascii_case(prefix) {
        s.get(prefix.len()..)
    } else {
        None
    }
}

fn trim(s: &[u8]) -> &[u8] {
    let start = s.iter().position(|c| !c.is_ascii_whitespace());
    let end = s.iter().rposition(|c| !c.is_ascii_whitespace());
    match (start, end) {
        (Some(a), Some(b)) => s.get(a..=b).unwrap_or(&[]),
        _ => &[],
    }
}

/// A decimal in mm → µm, if the text is one.
fn mm_to_um(s: &[u8]) -> Option<i32> {
    let v = crate::gcode::decimal(trim(s))?;
    if !v.is_finite() || v.abs() > 1.0e6 {
        return None;
    }
    Some(libm::roundf(v * 1000.0) as i32)
}

/// A layer number: digits, or a negative number (Cura's raft layers), which counts as 0.
fn layer_number(s: &[u8]) -> Option<u32> {
    let (neg, digits) = match s.strip_prefix(b"-") {
        Some(d) => (true, d),
        None => (false, s),
    };
    if digits.is_empty() || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    if neg {
        return Some(0);
    }
    let mut n: u32 = 0;
    for d in digits {
        n = n.saturating_mul(10).saturating_add(u32::from(d - b'0'));
    }
    Some(n)
}

fn classify_comment(c: &[u8]) -> Option<CommentMarker> {
    let t = trim(c);
    if t == b"LAYER_CHANGE" {
        return Some(CommentMarker::Layer(
            Family::Prusa,
            LayerSource::Comment,
            None,
            None,
        ));
    }
    // Cura's header (`;FLAVOR:Marlin` first, `;Generated with Cura_SteamEngine`) and its
    // `;LAYER_COUNT:` announce `;LAYER:n` before the start code's purge line.
    if t.starts_with(b"FLAVOR:")
        || t.starts_with(b"LAYER_COUNT:")
        || t.starts_with(b"Generated with Cura")
    {
        return Some(CommentMarker::Header(Family::Cura));
    }
    if let Some(rest) = t.strip_prefix(b"generated by ") {
        let prusa_like: [&[u8]; 3] = [b"PrusaSlicer", b"SuperSlicer", b"OrcaSlicer"];
        if prusa_like.iter().any(|p| rest.starts_with(p)) {
            return Some(CommentMarker::Header(Family::Prusa));
        }
    }
    if let Some(rest) = t.strip_prefix(b"Z:") {
        return mm_to_um(rest).map(CommentMarker::Z);
    }
    if let Some(rest) = t.strip_prefix(b"LAYER:") {
        return layer_number(trim(rest))
            .map(|n| CommentMarker::Layer(Family::Cura, LayerSource::Comment, Some(n), None));
    }
    if t == b"TURN" {
        return Some(CommentMarker::Layer(
            Family::Turn,
            LayerSource::Turn,
            None,
            None,
        ));
    }
    if let Some(rest) = t.strip_prefix(b"TURN:") {
        return layer_number(trim(rest))
            .map(|n| CommentMarker::Layer(Family::Turn, LayerSource::Turn, Some(n), None));
    }
    // Simplify3D: "; layer 12, Z = 2.600".
    if let Some(rest) = strip_prefix_ci(t, b"layer ") {
        let digits = rest.iter().take_while(|c| c.is_ascii_digit()).count();
        let number = rest.get(..digits).and_then(layer_number);
        if digits > 0 && matches!(rest.get(digits), None | Some(b',')) {
            let z = rest
                .windows(3)
                .position(|w| w == b"Z =")
                .and_then(|p| rest.get(p + 3..))
                .and_then(mm_to_um);
            return Some(CommentMarker::Layer(
                Family::Simplify3d,
                LayerSource::Comment,
                number,
                z,
            ));
        }
    }
    None
}
