//! Layer detection: turns slicer markers (or, in a stream without any, the heights and the
//! path of the extruding moves) into [`LayerMark`] events placed in the command stream, so the
//! planner can hold a pause exactly at a layer boundary.
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
//! let mut layers = Vec::new();
//! for text in [";LAYER_CHANGE", ";Z:0.2", "G1 Z0.2 F600", "G1 X10 E1", ";LAYER_CHANGE", ";Z:0.4", "G1 Z0.4"] {
//!     let line = parse_line(text.as_bytes()).unwrap();
//!     let before = m;
//!     if let Some(cmd) = &line.command {
//!         m.apply(cmd, &cfg).unwrap();
//!     }
//!     if let Some(mark) = d.feed(&line, MoveFacts::of(&before, &m, &cfg)) {
//!         layers.push(mark.layer); // queue `mark`, then the line's action
//!     }
//! }
//! assert_eq!(layers, [1, 2]);
//! ```
//!
//! # Markers accepted
//! Recognised by what the file writes, never by its header (OrcaSlicer writes PrusaSlicer's or
//! BambuStudio's markers depending on the printer, whatever its header says), with or without a
//! space after the `;`:
//!
//! | source | spelling | mark placed |
//! |---|---|---|
//! | PrusaSlicer, SuperSlicer, Slic3r PE, OrcaSlicer | `;LAYER_CHANGE` (height from a following `;Z:<mm>`; `;HEIGHT:` is ignored — it also appears mid-layer) | before the first motion command after the marker, i.e. before the layer's Z move |
//! | BambuStudio, OrcaSlicer for Bambu printers, Creality Print 5+ | `; CHANGE_LAYER` (height from `; Z_HEIGHT: <mm>`) | the same |
//! | Cura, ideaMaker, MatterControl, Creality Print 4 | `;LAYER:<n>`, `; LAYER:<n>` (`;LAYER_COUNT:` is not a marker; a following `;Z:` gives the height, else the first move after the marker) | before the first motion command after the marker; Cura has already moved Z (except before its first layer) |
//! | Simplify3D | `; layer <n>, Z = <mm>` | before the first motion command after the marker |
//! | FlashPrint | `;layer:<layer height>` (lower case, a decimal: `;layer:0.19`) | the same |
//! | KISSlicer | `; BEGIN_LAYER_OBJECT z=<mm>` | the same |
//! | Kiri:Moto | `;; --- layer <n> (<height> @ <z>) ---` | the same |
//! | IceSL | `; <layer>` | the same |
//! | Klipper macros | `SET_PRINT_STATS_INFO CURRENT_LAYER=<n>` | before that command |
//! | Orca/Bambu/Prusa progress | `M73 L<n>` | before that command |
//! | this project's host compiler (helical prints) | `;TURN` or `;TURN:<n>`, one per helix turn | before the first motion command after the marker ([`LayerSource::Turn`]) |
//! | none of the above | the heights and the path of the extruding moves (module `height`): Z rose (or dropped: sequential printing) beyond the layer's band before an extruding move, or a spiral came round | before that extruding move |
//!
//! An *extruding move* moves X or Y and advances E, as commanded (a vase piece that feeds less
//! than one E step still belongs to its turn).
//!
//! # The boundary
//! For every source: every extruding move of layer k is before the mark of layer k+1 and every
//! extruding move of layer k+1 after it. Non-extruding moves between the two layers (retract,
//! Z move, travel) and commands that do not move (fan, temperature) sit on either side depending
//! on the slicer: PrusaSlicer's marker precedes its Z move, Cura's follows it, the height rule
//! can only tell at the first extrusion. A pause held at the mark therefore always stops after
//! the last extrusion of layer k and before the first of layer k+1.
//!
//! # Numbering: the physical layer, from 1
//! [`LayerMark::layer`] is the number of the layer that starts at the mark, counted **from 1
//! in print order within the job** — the number PrusaSlicer's and Cura's previews show (their
//! G-code's `[layer_num]` and `;LAYER:n` are that number minus one), and what `SET_PRINT_STATS_INFO
//! CURRENT_LAYER=` and `M73 L` write. Every source counts the same way, so a stream with its
//! comments stripped numbers the same physical layer as the file with them: the slicer's own
//! numbers only tell a new layer from a repeated command (`M73 L5` twice is one layer; `M73 L0`
//! is none). What prints before the first layer (a purge line) is no layer: before a header's
//! family's first marker, or, by the height rule, a single layer left downwards before anything
//! rose ([`height`]). The end mark ([`LayerSource::End`]) is numbered one after the last layer.
//!
//! # Jobs
//! The count restarts at a job's start: [`LayerDetector::restart`] (the executive calls it when
//! the host resets its line numbers — `M110`, which OctoPrint and printcore send at every print
//! — and when an SD file starts), and by itself when something extrudes after the end of the
//! job (the end code's heater off or motors off).
//!
//! # No double counting
//! The first explicit marker family seen wins for the rest of the job: other families, and the
//! height rule, are ignored from then on (Orca writes both `;LAYER_CHANGE` and `M73 L`;
//! PrusaSlicer for Klipper writes both `;LAYER_CHANGE` and `SET_PRINT_STATS_INFO`). Before the
//! first marker the height rule runs: what it found there was the start code's (a purge line),
//! and the slicer's first layer is numbered 1 — as the height rule numbers it when the comments
//! are stripped ([`height`]: a purge line is a prelude), so both ways count the same layers.

use crate::config::MachineConfig;
use crate::gcode::{Command, Line};
use crate::gcode::{DriverCommand, HeatCommand, ReportCommand};
use crate::motion::{Axis, LayerMark, LayerSource, StepPos};
use markers::{classify_comment, CommentMarker, Family};

mod height;
mod markers;
#[cfg(test)]
mod tests;

pub use height::{TURN_AWAY_UM, TURN_CLOSE_UM};

/// What a command did to the head, for the height rule and for mark heights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MoveFacts {
    /// X, Y, Z before the command, µm (machine coordinates as commanded).
    pub start_um: [i32; 3],
    /// X, Y, Z after the command, µm.
    pub end_um: [i32; 3],
    /// The command moved X or Y and advanced E (a printing move).
    pub extrudes: bool,
    /// The command moved any axis.
    pub moved: bool,
}

/// mm → µm, rounded; 0 for what is no position (NaN, beyond ±2147 m: the machine state
/// refuses such moves before they get here).
fn um(mm: f64) -> i32 {
    crate::motion::round_i32(mm * 1000.0).unwrap_or(0)
}

impl MoveFacts {
    /// Facts of a command that took the head from `start` to `end` (X, Y, Z, E in mm, machine
    /// coordinates as commanded): what the G-code says, at its own resolution (µm). A vase
    /// piece that feeds 0.009 mm of filament (less than one E step) still extrudes: it is part
    /// of its turn, as the slicer wrote it. The interpreter's side gives these from its machine
    /// state (`MoveFacts::of`, in `machine`).
    pub fn commanded(start: &[f64; 4], end: &[f64; 4]) -> Self {
        let (start_um, end_um) = (
            [um(start[0]), um(start[1]), um(start[2])],
            [um(end[0]), um(end[1]), um(end[2])],
        );
        MoveFacts {
            start_um,
            end_um,
            extrudes: end[3] > start[3] && (start_um[0] != end_um[0] || start_um[1] != end_um[1]),
            moved: start_um != end_um || end[3] != start[3],
        }
    }

    /// Facts of the motion between two step positions (positions from the steps). Works for
    /// lines without motion too (then nothing moved and nothing extrudes).
    pub fn between(before: &StepPos, after: &StepPos, cfg: &MachineConfig) -> Self {
        let mm = |p: &StepPos, a: Axis| {
            let spm = f64::from(cfg.axis(a).steps_per_mm);
            let v = if spm > 0.0 {
                f64::from(p[a.index()]) / spm
            } else {
                0.0
            };
            um(v)
        };
        let xyz = |p: &StepPos| [mm(p, Axis::X), mm(p, Axis::Y), mm(p, Axis::Z)];
        let (x, y, e) = (Axis::X.index(), Axis::Y.index(), Axis::E.index());
        MoveFacts {
            start_um: xyz(before),
            end_um: xyz(after),
            extrudes: after[e] > before[e] && (after[x] != before[x] || after[y] != before[y]),
            moved: after != before,
        }
    }

    /// A line that does not move the head, at `at_um`.
    pub const fn still(at_um: [i32; 3]) -> Self {
        MoveFacts {
            start_um: at_um,
            end_um: at_um,
            extrudes: false,
            moved: false,
        }
    }
}

/// A marker seen in a comment, waiting for the next command to be placed before.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Pending {
    source: LayerSource,
    z_um: Option<i32>,
}

/// The streaming layer detector. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayerDetector {
    /// Marks emitted since power-up.
    count: u32,
    /// Number of the next layer of this job (from 1).
    next: u32,
    family: Option<Family>,
    pending: Option<Pending>,
    /// Extrusion heights and spiral turns (the comment-free rule).
    heights: height::Heights,
    /// Last known Z, µm.
    z_um: Option<i32>,
    /// Last layer number seen in an `M73 L` / `CURRENT_LAYER=`.
    last_numbered: Option<u32>,
    /// The end of printing was seen (heater off, motors off after an extrusion): the next
    /// extrusion belongs to a new job.
    ended: bool,
    /// Mark the end of printing ([`LayerDetector::with_end_mark`]).
    end_mark: bool,
    /// The job started at its beginning (not continued after a power cut): what prints before
    /// the first layer is a prelude, whose layers the count forgets.
    from_start: bool,
}

impl Default for LayerDetector {
    fn default() -> Self {
        Self::new()
    }
}

impl LayerDetector {
    /// A detector at the start of a job: no layer yet, no marker family.
    pub const fn new() -> Self {
        LayerDetector {
            count: 0,
            next: 1,
            family: None,
            pending: None,
            heights: height::Heights::new(),
            z_um: None,
            last_numbered: None,
            ended: false,
            end_mark: false,
            from_start: true,
        }
    }

    /// Also mark the end of printing (the printer's detector): the first end-code command
    /// after an extrusion — the hotend switched off (`M104 S0`, `M109 S0`) or the motors
    /// disabled (`M84`/`M18` without a timeout, X or Y included) — gets a mark
    /// ([`LayerSource::End`], numbered one after the last layer), so a `layer` pause requested
    /// in the last layer stops at the end of that layer instead of after the end code, and its
    /// speed-up stops there too. The mark ends a layer but starts none: layer counts
    /// (host-tools' `stats`) leave it out.
    pub const fn with_end_mark(mut self) -> Self {
        self.end_mark = true;
        self
    }

    /// A new job starts here: the next layer is numbered `first`, and everything known about
    /// markers and heights is forgotten. `first` is 1 for a new print; for a print continued
    /// from the start of layer `first` (M1000 after a power cut) no prelude is looked for, and
    /// the continued stream's first layer start — its first extrusion, or a resent `M73 L` —
    /// is numbered `first`.
    pub fn restart(&mut self, first: u32) {
        let first = first.max(1);
        let mut heights = height::Heights::new();
        if first > 1 {
            heights.no_prelude();
        }
        *self = LayerDetector {
            count: self.count,
            next: first,
            end_mark: self.end_mark,
            from_start: first == 1,
            heights,
            ..LayerDetector::new()
        };
    }

    /// Number of the next layer of this job.
    pub fn next_layer(&self) -> u32 {
        self.next
    }

    /// Feed one parsed line with the facts of the move its command made (use
    /// [`MoveFacts::of`] with the machine state before and after applying it). Returns the
    /// mark to queue **before** this line's command, if a layer starts here.
    pub fn feed(&mut self, line: &Line<'_>, facts: MoveFacts) -> Option<LayerMark> {
        if self.ended && (facts.extrudes || self.is_marker(line)) {
            // Something prints (or a slicer starts a layer) after the end of a job: a new job.
            self.restart(1);
        }
        let mut out = None;
        // A comment marker: it becomes pending (an earlier pending one is flushed first; no
        // command came between them, so its place is the same).
        if let Some(comment) = line.comment {
            match classify_comment(comment) {
                // `accept_family` locks the family on the first marker.
                Some(CommentMarker::Layer(family, turn, z)) if self.accept_family(family) => {
                    out = self.pending.take().map(|p| self.emit(p));
                    self.pending = Some(Pending {
                        source: if turn {
                            LayerSource::Turn
                        } else {
                            LayerSource::Comment
                        },
                        z_um: z,
                    });
                }
                Some(CommentMarker::Z(z)) => {
                    if let Some(p) = &mut self.pending {
                        p.z_um = Some(z);
                    }
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
                p.z_um = p.z_um.or(Some(facts.end_um[2]));
                self.emit(p)
            });
        }
        // Command markers: a new number starts a layer (0: before the first layer).
        if let Some((family, n)) = command_marker(cmd) {
            if self.last_numbered != Some(n) && self.accept_family(family) {
                self.last_numbered = Some(n);
                if out.is_none() && n > 0 {
                    out = Some(self.emit(Pending {
                        source: LayerSource::Command,
                        z_um: None,
                    }));
                }
            }
        }
        // The end of printing: the first end-code command after an extrusion.
        if is_end_command(cmd) && self.heights.printed() && !self.ended {
            self.ended = true;
            if out.is_none() && self.end_mark {
                out = Some(self.emit(Pending {
                    source: LayerSource::End,
                    z_um: None,
                }));
            }
        }
        if facts.extrudes {
            let start = self.heights.extrusion(&facts.start_um, &facts.end_um);
            // The height rule, only while no marker family is known.
            if self.family.is_none() && out.is_none() {
                if start == height::Start::Restart && self.from_start {
                    // What came before was a prelude (a purge line): this is the first layer.
                    self.next = 1;
                }
                if start != height::Start::Same {
                    self.z_um = Some(facts.start_um[2]);
                    out = Some(self.emit(Pending {
                        source: LayerSource::ZRise,
                        z_um: Some(facts.start_um[2]),
                    }));
                }
            }
        }
        self.z_um = Some(facts.end_um[2]);
        out
    }

    /// Place a pending marker now instead of before the next motion command: at the end of
    /// a file (a marker after the last command still counts as a layer), and in the firmware
    /// for M400 and when a layer pause finds the machine idle with a marker pending (everything
    /// before it has run, so the boundary is here; the next motion command gets no mark).
    pub fn finish(&mut self) -> Option<LayerMark> {
        self.pending.take().map(|p| self.emit(p))
    }

    /// Number of marks emitted so far (every job since power-up).
    pub fn layers(&self) -> u32 {
        self.count
    }

    /// True once an explicit marker (or a slicer header naming the marker family) has been
    /// seen in this job: the height rule is off.
    pub fn has_explicit_markers(&self) -> bool {
        self.family.is_some()
    }

    /// Whether `line` carries a layer marker of any family (used to keep marker lines in the
    /// queue: see `printer/host.rs`).
    pub fn is_marker(&self, line: &Line<'_>) -> bool {
        let comment = line
            .comment
            .and_then(classify_comment)
            .is_some_and(|c| matches!(c, CommentMarker::Layer(..)));
        comment || line.command.as_ref().and_then(command_marker).is_some()
    }

    /// Lock the family `f` (the first seen wins); whether `f` is the job's family.
    fn accept_family(&mut self, f: Family) -> bool {
        match self.family {
            None => {
                self.family = Some(f);
                // Layers the height rule found before the slicer's first marker were the start
                // code's (a purge line): the slicer's first layer is the first.
                if self.from_start {
                    self.next = 1;
                }
                true
            }
            Some(g) => g == f,
        }
    }

    fn emit(&mut self, p: Pending) -> LayerMark {
        let layer = self.next;
        if p.source != LayerSource::End {
            self.next = self.next.saturating_add(1);
        }
        let mark = LayerMark {
            layer,
            z_um: p.z_um.or(self.z_um),
            source: p.source,
        };
        self.count = self.count.saturating_add(1);
        mark
    }
}

/// The layer number of a command marker (`M73 L<n>`, `SET_PRINT_STATS_INFO CURRENT_LAYER=<n>`).
fn command_marker(cmd: &Command) -> Option<(Family, u32)> {
    match cmd {
        Command::Report(ReportCommand::Progress(p)) => p.layer.map(|l| (Family::M73, l)),
        Command::Report(ReportCommand::PrintStatsInfo {
            current_layer: Some(l),
            ..
        }) => Some((Family::Klipper, *l)),
        _ => None,
    }
}

/// End-code commands: the hotend switched off (`M104 S0`, `M109 S0`) or the motors disabled
/// (`M84`/`M18` without a timeout, all axes or X or Y). The bed alone switched off is not the
/// end: some users switch it off part-way through a print.
fn is_end_command(cmd: &Command) -> bool {
    match cmd {
        Command::Heat(HeatCommand::SetTemperature {
            heater: crate::gcode::Heater::Hotend,
            s,
            r,
            ..
        }) => {
            let off = |v: &Option<f32>| v.is_some_and(|t| t <= 0.0);
            (off(s) && r.is_none()) || (off(r) && s.is_none()) || (off(s) && off(r))
        }
        Command::Driver(DriverCommand::DisableSteppers { axes, s: None, .. }) => {
            axes.is_empty() || axes.includes(Axis::X) || axes.includes(Axis::Y)
        }
        _ => false,
    }
}
