//! The motion family: moves, arcs, dwell, homing, positioning modes, units, the feed and
//! flow overrides and M400 — what the machine interpreter (`machine/`) turns into planner
//! work. Parse and write side by side; the executive's side is `printer/run.rs`'s motion
//! dispatch and the intake's interpreter (`printer/intake/interpret.rs`).

use super::format::{axes, flags, opt};
use super::{AxisFlags, AxisWords, ParseError, ParseErrorKind, Words};
use core::fmt::{self, Write};

/// A motion command (G0–G3, G4, G10/G11, G20/G21, G28, G90–G92, M82/M83, M220/M221, M400).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionCommand {
    /// `G0` (rapid = true) / `G1`: straight move; `F` is mm/min in the current units.
    Move {
        /// G0 rather than G1 (the firmware treats both alike).
        rapid: bool,
        /// Target (absolute or relative per the modal state).
        axes: AxisWords,
        /// `F`: feed rate, units/min.
        feed: Option<f32>,
    },
    /// `G2` (clockwise) / `G3`: arc in the XY plane with centre offset `I J` or radius `R`.
    Arc {
        /// G2 rather than G3.
        clockwise: bool,
        /// End point X Y, helical Z, extrusion E.
        axes: AxisWords,
        /// `I`: centre X offset from the start point.
        i: Option<f32>,
        /// `J`: centre Y offset from the start point.
        j: Option<f32>,
        /// `R`: radius (instead of I/J); negative picks the larger arc.
        r: Option<f32>,
        /// `P`: complete extra circles before the arc (Marlin's `ARC_P_CIRCLES`), 0 when not
        /// given, at most [`crate::gcode::ARC_MAX_CIRCLES`].
        circles: u8,
        /// `F`: feed rate, units/min.
        feed: Option<f32>,
    },
    /// `G4 P<ms>` / `G4 S<s>`: dwell.
    Dwell {
        /// `P`: milliseconds.
        ms: Option<f32>,
        /// `S`: seconds.
        s: Option<f32>,
    },
    /// `G10`: firmware retract.
    Retract,
    /// `G11`: firmware recover (un-retract).
    Recover,
    /// `G20`: units are inches.
    Inches,
    /// `G21`: units are millimetres.
    Millimetres,
    /// `G28 [X] [Y] [Z]`: home the named axes (none named = all); values after the letters are
    /// accepted and ignored, as Marlin does.
    Home(AxisFlags),
    /// `G90`: absolute positioning (E too, until M83).
    Absolute,
    /// `G91`: relative positioning (E too, until M82).
    Relative,
    /// `G92`: set the logical position of the given axes.
    SetPosition(AxisWords),
    /// `M82`: absolute extrusion.
    AbsoluteE,
    /// `M83`: relative extrusion.
    RelativeE,
    /// `M220 [S<percent>]`: feed rate override (no S: report).
    FeedOverride(Option<f32>),
    /// `M221 [S<percent>] [T]`: flow override (no S: report).
    FlowOverride(Option<f32>),
    /// `M400`: wait until all moves are done.
    WaitMoves,
}

/// Parse `code` if it is one of this family's; `None` = not this family's.
pub(super) fn build(code: (u8, u16), w: &Words<'_>) -> Result<Option<MotionCommand>, ParseError> {
    Ok(Some(match code {
        (b'G', n @ (0 | 1)) => {
            w.check(b"XYZEF", b"")?;
            MotionCommand::Move {
                rapid: n == 0,
                axes: w.axes()?,
                feed: w.f32(b'F')?,
            }
        }
        (b'G', n @ (2 | 3)) => {
            w.check(b"XYZEFIJRP", b"")?;
            // P: whole circles, 0..=100 as Marlin's G2_G3.cpp allows.
            let circles = w.u8(b'P')?.unwrap_or(0);
            if circles > crate::gcode::ARC_MAX_CIRCLES {
                return Err(w.refuse(b'P', ParseErrorKind::OutOfRange));
            }
            MotionCommand::Arc {
                clockwise: n == 2,
                axes: w.axes()?,
                i: w.f32(b'I')?,
                j: w.f32(b'J')?,
                r: w.f32(b'R')?,
                circles,
                feed: w.f32(b'F')?,
            }
        }
        (b'G', 4) => {
            w.check(b"PS", b"")?;
            MotionCommand::Dwell {
                ms: w.f32(b'P')?,
                s: w.f32(b'S')?,
            }
        }
        (b'G', 10) => {
            w.ignore_all()?;
            MotionCommand::Retract
        }
        (b'G', 11) => {
            w.ignore_all()?;
            MotionCommand::Recover
        }
        (b'G', 20) => {
            w.ignore_all()?;
            MotionCommand::Inches
        }
        (b'G', 21) => {
            w.ignore_all()?;
            MotionCommand::Millimetres
        }
        (b'G', 28) => {
            w.check(b"XYZ", b"XYZ")?;
            // Values are accepted (Marlin ignores them) but must be numbers.
            w.axes()?;
            MotionCommand::Home(w.flags())
        }
        (b'G', 90) => {
            w.ignore_all()?;
            MotionCommand::Absolute
        }
        (b'G', 91) => {
            w.ignore_all()?;
            MotionCommand::Relative
        }
        (b'G', 92) => {
            w.check(b"XYZE", b"")?;
            MotionCommand::SetPosition(w.axes()?)
        }
        (b'M', 82) => {
            w.ignore_all()?;
            MotionCommand::AbsoluteE
        }
        (b'M', 83) => {
            w.ignore_all()?;
            MotionCommand::RelativeE
        }
        (b'M', 220) => {
            w.check(b"S", b"")?;
            MotionCommand::FeedOverride(w.f32(b'S')?)
        }
        (b'M', 221) => {
            w.check(b"S", b"")?;
            MotionCommand::FlowOverride(w.f32(b'S')?)
        }
        (b'M', 400) => {
            w.ignore_all()?;
            MotionCommand::WaitMoves
        }
        _ => return Ok(None),
    }))
}

/// The G-code text of a command (what [`build`] reads back).
pub(super) fn write<W: Write>(w: &mut W, c: &MotionCommand) -> fmt::Result {
    match c {
        MotionCommand::Move {
            rapid,
            axes: a,
            feed,
        } => {
            w.write_str(if *rapid { "G0" } else { "G1" })?;
            axes(w, a)?;
            opt(w, 'F', *feed)
        }
        MotionCommand::Arc {
            clockwise,
            axes: a,
            i,
            j,
            r,
            circles,
            feed,
        } => {
            w.write_str(if *clockwise { "G2" } else { "G3" })?;
            axes(w, a)?;
            opt(w, 'I', *i)?;
            opt(w, 'J', *j)?;
            opt(w, 'R', *r)?;
            if *circles > 0 {
                write!(w, " P{circles}")?;
            }
            opt(w, 'F', *feed)
        }
        MotionCommand::Dwell { ms, s } => {
            w.write_str("G4")?;
            opt(w, 'P', *ms)?;
            opt(w, 'S', *s)
        }
        MotionCommand::Retract => w.write_str("G10"),
        MotionCommand::Recover => w.write_str("G11"),
        MotionCommand::Inches => w.write_str("G20"),
        MotionCommand::Millimetres => w.write_str("G21"),
        MotionCommand::Home(fl) => {
            w.write_str("G28")?;
            flags(w, fl)
        }
        MotionCommand::Absolute => w.write_str("G90"),
        MotionCommand::Relative => w.write_str("G91"),
        MotionCommand::SetPosition(a) => {
            w.write_str("G92")?;
            axes(w, a)
        }
        MotionCommand::AbsoluteE => w.write_str("M82"),
        MotionCommand::RelativeE => w.write_str("M83"),
        MotionCommand::FeedOverride(s) => {
            w.write_str("M220")?;
            opt(w, 'S', *s)
        }
        MotionCommand::FlowOverride(s) => {
            w.write_str("M221")?;
            opt(w, 'S', *s)
        }
        MotionCommand::WaitMoves => w.write_str("M400"),
    }
}
