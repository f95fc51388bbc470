//! Modal machine state: what a G-code command means given everything before it.
//!
//! [`MachineState::apply`] turns a parsed [`Command`] into an [`Action`] for the executive: a
//! straight move in absolute integer steps ([`MoveRequest`]), an arc cut into straight moves
//! ([`ArcMoves`], an allocation-free iterator), homing, a dwell, nothing (a modal change), or
//! "yours" ([`Action::Executive`]: temperatures, reports, pause, ...).
//!
//! Modal state kept here, as Marlin documents it:
//! - G90/G91 absolute/relative positioning; they set the E mode too, and M82/M83 set E alone
//!   afterwards (the last of the four wins for E);
//! - G92 logical position per axis (X Y Z as an offset from the machine position; E as the
//!   logical E counter);
//! - G20/G21 inches/millimetres (X Y Z E I J R and F are scaled);
//! - modal feed: `F` in units/min, kept in mm/s;
//! - M220 feed override (applied to the feed of every new move) and M221 flow override (applied
//!   to every E distance), both in percent, 10..=999;
//! - G10/G11 firmware retract with [`crate::config::PauseConfig::retract_mm`] at
//!   `retract_feed_mm_s` (the logical E does not change, as in Marlin).
//!
//! Positions are kept as absolute millimetres in `f64` and converted to steps by rounding the
//! absolute position (`round(mm × steps/mm)`) for every move, never by adding rounded deltas, so
//! no rounding error accumulates over a job.
//!
//! Every error leaves the state exactly as it was (tested), so the executive can report the
//! error and go on. The state is `Clone`: the executive saves it at a pause and restores it on
//! resume.
//!
//! ```
//! use firmware::config::MachineConfig;
//! use firmware::gcode::parse_line;
//! use firmware::machine::{Action, MachineState};
//! let cfg = MachineConfig::ENDER3;
//! let mut m = MachineState::new(&cfg);
//! let line = parse_line(b"G1 X10 Y20 F3000").unwrap();
//! let Ok(Action::Move(mv)) = m.apply(line.command.as_ref().unwrap(), &cfg) else { panic!() };
//! assert_eq!(mv.target, [800, 1600, 0, 0]);
//! assert_eq!(mv.feed_mm_s, 50.0);
//! // Outside the build volume: an error, and nothing changed.
//! let far = parse_line(b"G1 X400").unwrap().command.unwrap();
//! assert!(m.apply(&far, &cfg).is_err());
//! assert_eq!(m.position_steps(&cfg), [800, 1600, 0, 0]);
//! ```

mod arc;
mod error;
mod interp;
mod limits;

pub use arc::{
    ArcMoves, ARC_CHORD_TOLERANCE_MM, ARC_MAX_CIRCLES, ARC_MAX_SEGMENTS, ARC_MIN_SEGMENT_MM,
};
pub use error::MachineError;
pub use interp::{Interpreter, Step};
pub(crate) use limits::to_steps;
pub use limits::{dwell_ms, BOUNDS_TOLERANCE_MM, MIN_FEED_MM_MIN, OVERRIDE_RANGE_PCT};

use crate::config::MachineConfig;
use crate::gcode::MotionCommand;
use crate::gcode::{AxisFlags, AxisWords, Command};
use crate::motion::{Axis, MoveRequest, StepPos, AXES};
use limits::{check_axis, check_bounds, check_override};

/// Millimetres per inch (G20).
pub const MM_PER_INCH: f64 = 25.4;

/// What the executive must do for a command, after the machine state has taken it in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Nothing to execute: the command only changed modal state (G90, M83, G92, `G1 F…`, M220
    /// S…), or a move ended where the head already is.
    None,
    /// One straight move.
    Move(MoveRequest),
    /// An arc, cut into straight moves: iterate and queue each.
    Arc(ArcMoves),
    /// Home these axes (X Y Z; all when the command named none). The state already holds the
    /// home position (each axis at its `min_mm`) with its G92 offset cleared.
    Home(AxisFlags),
    /// Wait this long after the queued moves have finished (G4).
    Dwell {
        /// Milliseconds.
        ms: u32,
    },
    /// Not a machine-state command: the executive handles it (temperatures, fans, reports,
    /// pause/resume, M0, M400, M600, M760/M761, M117/M118, unknown commands, ...).
    Executive,
}

/// The modal state of the G-code interpreter: modes, offsets, feed, overrides and the commanded
/// position. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineState {
    relative_xyz: bool,
    relative_e: bool,
    inches: bool,
    feed_mm_s: f32,
    feed_pct: f32,
    flow_pct: f32,
    /// Machine position, mm: X Y Z in machine coordinates, E as filament fed (flow applied).
    pos_mm: [f64; AXES],
    /// G92 offset of X Y Z: machine = logical + offset (index 3 unused).
    offset_mm: [f64; AXES],
    /// The logical E counter (what G92 E and absolute E words refer to).
    logical_e_mm: f64,
    /// G10 has retracted and G11 has not recovered yet.
    retracted: bool,
    /// Sequence number of the next move.
    next_seq: u32,
    /// `pos_mm` in steps (rounded once per commit).
    steps: StepPos,
}

impl MachineState {
    /// Power-on state: absolute positioning and extrusion, millimetres, the configured default
    /// feed, overrides 100 %, position 0 on every axis (until homing says otherwise), first
    /// sequence number 1.
    pub fn new(cfg: &MachineConfig) -> Self {
        MachineState {
            relative_xyz: false,
            relative_e: false,
            inches: false,
            feed_mm_s: cfg.default_feed_mm_s,
            feed_pct: 100.0,
            flow_pct: 100.0,
            pos_mm: [0.0; AXES],
            offset_mm: [0.0; AXES],
            logical_e_mm: 0.0,
            retracted: false,
            next_seq: 1,
            steps: [0; AXES],
        }
    }

    /// Interpret one command. On error nothing changes.
    pub fn apply(&mut self, cmd: &Command, cfg: &MachineConfig) -> Result<Action, MachineError> {
        match cmd {
            Command::Motion(MotionCommand::Move { axes, feed, .. }) => {
                self.linear(axes, *feed, cfg)
            }
            Command::Motion(MotionCommand::Arc {
                clockwise,
                axes,
                i,
                j,
                r,
                circles,
                feed,
            }) => self.arc(*clockwise, axes, (*i, *j, *r), *circles, *feed, cfg),
            Command::Motion(MotionCommand::Dwell { ms, s }) => {
                let ms = dwell_ms(*ms, *s)?;
                Ok(Action::Dwell { ms })
            }
            Command::Motion(MotionCommand::Retract) => self.firmware_retract(true, cfg),
            Command::Motion(MotionCommand::Recover) => self.firmware_retract(false, cfg),
            Command::Motion(MotionCommand::Inches) => {
                self.inches = true;
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::Millimetres) => {
                self.inches = false;
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::Home(flags)) => {
                let mut done = [false; AXES];
                let mut pos = self.pos_mm;
                for axis in [Axis::X, Axis::Y, Axis::Z] {
                    if flags.includes(axis) {
                        let min = cfg.axis(axis).min_mm;
                        pos[axis.index()] = if min.is_finite() { f64::from(min) } else { 0.0 };
                        done[axis.index()] = true;
                    }
                }
                self.steps = to_steps(&pos, cfg)?;
                self.pos_mm = pos;
                for (i, d) in done.iter().enumerate() {
                    if *d {
                        // M206: logical = machine + home offset (machine = logical + offset).
                        let home = cfg.home_offset_mm.get(i).copied().unwrap_or(0.0);
                        self.offset_mm[i] = -f64::from(home);
                    }
                }
                Ok(Action::Home(AxisFlags(done)))
            }
            Command::Motion(MotionCommand::Absolute) => {
                self.relative_xyz = false;
                self.relative_e = false;
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::Relative) => {
                self.relative_xyz = true;
                self.relative_e = true;
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::AbsoluteE) => {
                self.relative_e = false;
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::RelativeE) => {
                self.relative_e = true;
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::SetPosition(axes)) => {
                for axis in [Axis::X, Axis::Y, Axis::Z] {
                    if let Some(v) = axes.get(axis) {
                        let i = axis.index();
                        self.offset_mm[i] = self.pos_mm[i] - self.units(v);
                    }
                }
                if let Some(v) = axes.get(Axis::E) {
                    self.logical_e_mm = self.units(v);
                }
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::FeedOverride(Some(pct))) => {
                self.feed_pct = check_override(*pct)?;
                Ok(Action::None)
            }
            Command::Motion(MotionCommand::FlowOverride(Some(pct))) => {
                self.flow_pct = check_override(*pct)?;
                Ok(Action::None)
            }
            _ => Ok(Action::Executive),
        }
    }

    /// Value of a length word in mm.
    fn units(&self, v: f32) -> f64 {
        let v = f64::from(v);
        if self.inches {
            v * MM_PER_INCH
        } else {
            v
        }
    }

    /// A new modal feed from an `F` word, or the current one.
    fn feed_from(&self, feed: Option<f32>) -> Result<f32, MachineError> {
        match feed {
            Some(f) if f <= 0.0 => Err(MachineError::BadFeed),
            Some(f) if self.units(f) < MIN_FEED_MM_MIN => Err(MachineError::FeedTooLow),
            Some(f) => Ok((self.units(f) / 60.0) as f32),
            None => Ok(self.feed_mm_s),
        }
    }

    /// The end position (machine mm) and new logical E of a move with these words.
    fn target(&self, axes: &AxisWords) -> ([f64; AXES], f64) {
        let mut pos = self.pos_mm;
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            if let Some(v) = axes.get(axis) {
                let i = axis.index();
                let v = self.units(v);
                pos[i] = if self.relative_xyz {
                    self.pos_mm[i] + v
                } else {
                    v + self.offset_mm[i]
                };
            }
        }
        let mut logical_e = self.logical_e_mm;
        if let Some(v) = axes.get(Axis::E) {
            let v = self.units(v);
            logical_e = if self.relative_e {
                self.logical_e_mm + v
            } else {
                v
            };
            let de = logical_e - self.logical_e_mm;
            pos[Axis::E.index()] =
                self.pos_mm[Axis::E.index()] + de * f64::from(self.flow_pct) / 100.0;
        }
        (pos, logical_e)
    }

    fn linear(
        &mut self,
        axes: &AxisWords,
        feed: Option<f32>,
        cfg: &MachineConfig,
    ) -> Result<Action, MachineError> {
        let feed_mm_s = self.feed_from(feed)?;
        let (pos, logical_e) = self.target(axes);
        check_bounds(&pos, cfg)?;
        let target = to_steps(&pos, cfg)?;
        let before = self.steps;
        // Commit.
        self.feed_mm_s = feed_mm_s;
        self.pos_mm = pos;
        self.steps = target;
        self.logical_e_mm = logical_e;
        if target == before {
            return Ok(Action::None);
        }
        let seq = self.take_seq(1);
        Ok(Action::Move(MoveRequest {
            target,
            feed_mm_s: self.feed_mm_s * self.feed_pct / 100.0,
            seq,
        }))
    }

    fn arc(
        &mut self,
        clockwise: bool,
        axes: &AxisWords,
        (i, j, r): (Option<f32>, Option<f32>, Option<f32>),
        circles: u8,
        feed: Option<f32>,
        cfg: &MachineConfig,
    ) -> Result<Action, MachineError> {
        let feed_mm_s = self.feed_from(feed)?;
        let (end, logical_e) = self.target(axes);
        let centre = match (i.or(j), r) {
            (Some(_), Some(_)) => return Err(MachineError::ArcCentreAndRadius),
            (None, None) => return Err(MachineError::ArcNoCentre),
            (Some(_), None) => {
                arc::Centre::Offset([self.units(i.unwrap_or(0.0)), self.units(j.unwrap_or(0.0))])
            }
            (None, Some(r)) => arc::Centre::Radius(self.units(r)),
        };
        let plan = arc::plan(&self.pos_mm, &end, centre, clockwise, circles)?;
        check_bounds(&end, cfg)?;
        let end_steps = to_steps(&end, cfg)?;
        let moves = ArcMoves::new(
            plan,
            self.pos_mm,
            end,
            self.next_seq,
            feed_mm_s * self.feed_pct / 100.0,
            cfg,
        );
        moves.check_bounds(cfg)?;
        // Commit.
        self.feed_mm_s = feed_mm_s;
        self.take_seq(moves.segments());
        self.pos_mm = end;
        self.steps = end_steps;
        self.logical_e_mm = logical_e;
        Ok(Action::Arc(moves))
    }

    fn firmware_retract(
        &mut self,
        retract: bool,
        cfg: &MachineConfig,
    ) -> Result<Action, MachineError> {
        if self.retracted == retract {
            return Ok(Action::None);
        }
        let mut pos = self.pos_mm;
        let len = f64::from(cfg.pause.retract_mm);
        pos[Axis::E.index()] += if retract { -len } else { len };
        let target = to_steps(&pos, cfg)?;
        self.pos_mm = pos;
        self.steps = target;
        self.retracted = retract;
        let seq = self.take_seq(1);
        Ok(Action::Move(MoveRequest {
            target,
            feed_mm_s: cfg.pause.retract_feed_mm_s,
            seq,
        }))
    }

    fn take_seq(&mut self, n: u32) -> u32 {
        let s = self.next_seq;
        self.next_seq = self.next_seq.saturating_add(n);
        s
    }

    /// The commanded machine position in steps (where the last queued move ends). The
    /// configuration argument is kept for symmetry with the other conversions; the steps are
    /// computed once when a position is committed.
    pub fn position_steps(&self, _cfg: &MachineConfig) -> StepPos {
        self.steps
    }

    /// The commanded machine position in mm (X Y Z machine coordinates; E = filament fed).
    pub fn machine_mm(&self) -> [f64; AXES] {
        self.pos_mm
    }

    /// The logical position in mm as G-code sees it (after G92), in millimetres even under
    /// G20; this is what M114 reports before `Count`.
    pub fn logical_mm(&self) -> [f64; AXES] {
        [
            self.pos_mm[0] - self.offset_mm[0],
            self.pos_mm[1] - self.offset_mm[1],
            self.pos_mm[2] - self.offset_mm[2],
            self.logical_e_mm,
        ]
    }

    /// Set the machine position from steps (after a quick stop discarded queued moves, or when
    /// the executive resumes at a position of its own). The G92 offsets stay, so the logical
    /// X Y Z follow; the logical E follows the change of E.
    pub fn set_position_steps(&mut self, steps: &StepPos, cfg: &MachineConfig) {
        for axis in Axis::ALL {
            let i = axis.index();
            let spm = f64::from(cfg.axis(axis).steps_per_mm);
            let mm = if spm > 0.0 {
                f64::from(steps[i]) / spm
            } else {
                0.0
            };
            if axis == Axis::E {
                let flow = f64::from(self.flow_pct) / 100.0;
                self.logical_e_mm += (mm - self.pos_mm[i]) / flow;
            }
            self.pos_mm[i] = mm;
        }
        self.steps = *steps;
    }

    /// The modal feed in mm/s, before the M220 override.
    pub fn feed_mm_s(&self) -> f32 {
        self.feed_mm_s
    }

    /// M220 feed override, percent.
    pub fn feed_override_pct(&self) -> f32 {
        self.feed_pct
    }

    /// M221 flow override, percent.
    pub fn flow_override_pct(&self) -> f32 {
        self.flow_pct
    }

    /// G91 in force for X Y Z.
    pub fn is_relative(&self) -> bool {
        self.relative_xyz
    }

    /// Relative extrusion in force (G91 or M83, whichever came last).
    pub fn is_relative_e(&self) -> bool {
        self.relative_e
    }

    /// G20 in force.
    pub fn is_inches(&self) -> bool {
        self.inches
    }

    /// G10 has retracted and G11 not yet recovered.
    pub fn is_retracted(&self) -> bool {
        self.retracted
    }

    /// The sequence number the next move will get.
    pub fn next_seq(&self) -> u32 {
        self.next_seq
    }

    // Power-cut resume (`crate::printer` recovery): the state saved at a layer boundary and
    // the state rebuilt from it after power-up, field for field.

    /// The modal state and exact commanded position, for the paused-job record.
    pub fn modal(&self) -> crate::storage::ModalState {
        crate::storage::ModalState {
            relative_xyz: self.relative_xyz,
            relative_e: self.relative_e,
            inches: self.inches,
            retracted: self.retracted,
            feed_mm_s: self.feed_mm_s,
            feed_pct: self.feed_pct,
            flow_pct: self.flow_pct,
            offset_mm: [self.offset_mm[0], self.offset_mm[1], self.offset_mm[2]],
            logical_e_mm: self.logical_e_mm,
            machine_mm: self.pos_mm,
        }
    }

    /// The state [`Self::modal`] saved, rebuilt (the next move sequence number starts at 1, as
    /// at power-on). Refused when the overrides or the position are out of range.
    pub fn from_modal(
        m: &crate::storage::ModalState,
        cfg: &MachineConfig,
    ) -> Result<Self, MachineError> {
        let steps = to_steps(&m.machine_mm, cfg)?;
        Ok(MachineState {
            relative_xyz: m.relative_xyz,
            relative_e: m.relative_e,
            inches: m.inches,
            feed_mm_s: m.feed_mm_s,
            feed_pct: check_override(m.feed_pct)?,
            flow_pct: check_override(m.flow_pct)?,
            pos_mm: m.machine_mm,
            offset_mm: [m.offset_mm[0], m.offset_mm[1], m.offset_mm[2], 0.0],
            logical_e_mm: m.logical_e_mm,
            retracted: m.retracted,
            next_seq: 1,
            steps,
        })
    }
}

#[cfg(test)]
mod tests;
