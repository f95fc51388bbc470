//! The pause family: pause, resume, stop for the user, cancel, the emergency and quick stops,
//! the heater-wait break, filament change, the pause values (M760) and the scheduled pause
//! (M761). Parse and write side by side; the pause mode is decided here, once (`M25`/`M601`
//! with or without `S1`), and the link (`link/realtime.rs`) and the executive (the pause
//! part, `printer/pause/`) take it as parsed.

use super::format::{axes, opt, opt_int};
use super::{AxisWords, ParseError, ParseErrorKind, Words};
use crate::motion::PauseMode;
use core::fmt::{self, Write};

/// M760 parameters: the pause behaviour (see [`crate::config::PauseConfig`]); `None` = keep.
/// All `None` means "report the current values".
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PauseParams {
    /// `R`: retract length, mm.
    pub retract_mm: Option<f32>,
    /// `Z`: Z lift, mm.
    pub lift_z_mm: Option<f32>,
    /// `X`: park X, mm.
    pub park_x_mm: Option<f32>,
    /// `Y`: park Y, mm.
    pub park_y_mm: Option<f32>,
    /// `F`: park travel feed, mm/min (as written; divide by 60 for mm/s).
    pub park_feed_mm_min: Option<f32>,
    /// `S`: speed-up factor for the rest of the layer after a pause request.
    pub speedup_factor: Option<f32>,
    /// `V`: maximum volumetric flow, mm³/s.
    pub max_volumetric_mm3_s: Option<f32>,
    /// `L`: planner segment length, mm.
    pub segment_len_mm: Option<f32>,
    /// `T`: seconds parked before the nozzle heater goes off (0 = never; see
    /// [`crate::thermal::IdleConfig`]).
    pub nozzle_timeout_s: Option<f32>,
}

impl PauseParams {
    /// True when no parameter is given (M760 alone: report).
    pub fn is_empty(&self) -> bool {
        *self == PauseParams::default()
    }

    /// The M760 that sets the pause values `c` (every word given; the park feed in mm/min, as
    /// written) and `nozzle_timeout_s` (`T`, kept apart: it is the heaters' setting, not
    /// saved with the pause values).
    pub fn from_config(c: &crate::config::PauseConfig, nozzle_timeout_s: Option<f32>) -> Self {
        PauseParams {
            retract_mm: Some(c.retract_mm),
            lift_z_mm: Some(c.lift_z_mm),
            park_x_mm: Some(c.park_x_mm),
            park_y_mm: Some(c.park_y_mm),
            park_feed_mm_min: Some(c.park_feed_mm_s * 60.0),
            speedup_factor: Some(c.speedup_factor),
            max_volumetric_mm3_s: Some(c.max_volumetric_mm3_s),
            segment_len_mm: Some(c.segment_len_mm),
            nozzle_timeout_s,
        }
    }
}

/// M761: when to pause.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PauseSchedule {
    /// `M761`: report the scheduled pause.
    Report,
    /// `M761 L<n>`: pause at the start of layer n (the n-th layer printed in the job, from 1, as
    /// [`crate::layer`] counts: docs/planner.md, "What a layer is").
    Layer(u32),
    /// `M761 Z<mm>`: pause at the first layer at or above this height.
    Z(f32),
    /// `M761 C`: clear the schedule.
    Clear,
}

/// M600 filament change parameters (Marlin spelling); `None` = use the default.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FilamentChange {
    /// `X`, `Y`, `Z` change position and `E` retract length, mm.
    pub axes: AxisWords,
    /// `L`: load length, mm.
    pub load_mm: Option<f32>,
    /// `U`: unload length, mm.
    pub unload_mm: Option<f32>,
    /// `B`: number of beeps.
    pub beeps: Option<u32>,
}

/// A pause command (M0/M1, M24/M602, M25/M601, M108, M112, M410, M524, M600, M760, M761).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PauseCommand {
    /// `M0` / `M1` (optional = true): stop and wait for the user, or `P` ms / `S` s.
    Stop {
        /// M1 rather than M0.
        optional: bool,
        /// `P`: milliseconds.
        ms: Option<f32>,
        /// `S`: seconds.
        s: Option<f32>,
    },
    /// `M24` / `M602`: resume. Also a realtime request on the host link.
    Resume {
        /// Written as M602 rather than M24.
        m602: bool,
    },
    /// `M25` / `M601 [S1]`: pause at the layer boundary, or at once with `S1`. Also a realtime
    /// request on the host link.
    Pause {
        /// Written as M601 rather than M25.
        m601: bool,
        /// At the layer boundary ([`PauseMode::Layer`]), or with `S1` at once (feed hold,
        /// [`PauseMode::Now`]).
        mode: PauseMode,
    },
    /// `M108`: break out of a heater wait. Also a realtime request on the host link.
    BreakWait,
    /// `M112`: emergency stop. Also a realtime request on the host link.
    EmergencyStop,
    /// `M410`: quick stop. Also a realtime request on the host link.
    QuickStop,
    /// `M524`: cancel the job. Also a realtime request on the host link.
    Cancel,
    /// `M600`: filament change.
    FilamentChange(FilamentChange),
    /// `M760`: set (or with no parameter report) the pause parameters. Firmware-specific.
    Params(PauseParams),
    /// `M761`: schedule a pause at a layer or height, clear, or report. Firmware-specific.
    Schedule(PauseSchedule),
}

/// Parse `code` if it is one of this family's; `None` = not this family's.
pub(super) fn build(code: (u8, u16), w: &Words<'_>) -> Result<Option<PauseCommand>, ParseError> {
    Ok(Some(match code {
        (b'M', n @ (0 | 1)) => {
            w.check(b"PS", b"")?;
            PauseCommand::Stop {
                optional: n == 1,
                ms: w.f32(b'P')?,
                s: w.f32(b'S')?,
            }
        }
        (b'M', n @ (24 | 602)) => {
            w.check(b"", b"")?;
            PauseCommand::Resume { m602: n == 602 }
        }
        (b'M', n @ (25 | 601)) => {
            w.check(b"S", b"")?;
            PauseCommand::Pause {
                m601: n == 601,
                mode: if w.bool01(b'S')? {
                    PauseMode::Now
                } else {
                    PauseMode::Layer
                },
            }
        }
        (b'M', 108) => {
            w.ignore_all()?;
            PauseCommand::BreakWait
        }
        (b'M', 112) => {
            w.ignore_all()?;
            PauseCommand::EmergencyStop
        }
        (b'M', 410) => {
            w.ignore_all()?;
            PauseCommand::QuickStop
        }
        (b'M', 524) => {
            w.ignore_all()?;
            PauseCommand::Cancel
        }
        (b'M', 600) => {
            w.check(b"XYZELUB", b"")?;
            PauseCommand::FilamentChange(FilamentChange {
                axes: w.axes()?,
                load_mm: w.f32(b'L')?,
                unload_mm: w.f32(b'U')?,
                beeps: w.u32(b'B')?,
            })
        }
        (b'M', 760) => {
            w.check(b"RZXYFSVLT", b"")?;
            PauseCommand::Params(PauseParams {
                retract_mm: w.f32(b'R')?,
                lift_z_mm: w.f32(b'Z')?,
                park_x_mm: w.f32(b'X')?,
                park_y_mm: w.f32(b'Y')?,
                park_feed_mm_min: w.f32(b'F')?,
                speedup_factor: w.f32(b'S')?,
                max_volumetric_mm3_s: w.f32(b'V')?,
                segment_len_mm: w.f32(b'L')?,
                nozzle_timeout_s: w.f32(b'T')?,
            })
        }
        (b'M', 761) => {
            w.check(b"LZC", b"C")?;
            if w.words.len() > 1 {
                return Err(w.refuse_nth(1, ParseErrorKind::BadValue));
            }
            let s = if w.has(b'C') {
                if w.find(b'C').is_some_and(|c| c.num.is_some()) {
                    return Err(w.refuse(b'C', ParseErrorKind::BadValue));
                }
                PauseSchedule::Clear
            } else if let Some(l) = w.u32(b'L')? {
                PauseSchedule::Layer(l)
            } else if let Some(z) = w.f32(b'Z')? {
                PauseSchedule::Z(z)
            } else {
                PauseSchedule::Report
            };
            PauseCommand::Schedule(s)
        }
        _ => return Ok(None),
    }))
}

/// The G-code text of a command (what [`build`] reads back).
pub(super) fn write<W: Write>(w: &mut W, c: &PauseCommand) -> fmt::Result {
    match c {
        PauseCommand::Stop { optional, ms, s } => {
            w.write_str(if *optional { "M1" } else { "M0" })?;
            opt(w, 'P', *ms)?;
            opt(w, 'S', *s)
        }
        PauseCommand::Resume { m602 } => w.write_str(if *m602 { "M602" } else { "M24" }),
        PauseCommand::Pause { m601, mode } => {
            w.write_str(if *m601 { "M601" } else { "M25" })?;
            if *mode == PauseMode::Now {
                w.write_str(" S1")?;
            }
            Ok(())
        }
        PauseCommand::BreakWait => w.write_str("M108"),
        PauseCommand::EmergencyStop => w.write_str("M112"),
        PauseCommand::QuickStop => w.write_str("M410"),
        PauseCommand::Cancel => w.write_str("M524"),
        PauseCommand::FilamentChange(fc) => {
            w.write_str("M600")?;
            axes(w, &fc.axes)?;
            opt(w, 'L', fc.load_mm)?;
            opt(w, 'U', fc.unload_mm)?;
            opt_int(w, 'B', fc.beeps)
        }
        PauseCommand::Params(p) => {
            w.write_str("M760")?;
            opt(w, 'R', p.retract_mm)?;
            opt(w, 'Z', p.lift_z_mm)?;
            opt(w, 'X', p.park_x_mm)?;
            opt(w, 'Y', p.park_y_mm)?;
            opt(w, 'F', p.park_feed_mm_min)?;
            opt(w, 'S', p.speedup_factor)?;
            opt(w, 'V', p.max_volumetric_mm3_s)?;
            opt(w, 'L', p.segment_len_mm)?;
            opt(w, 'T', p.nozzle_timeout_s)
        }
        PauseCommand::Schedule(s) => {
            w.write_str("M761")?;
            match s {
                PauseSchedule::Report => Ok(()),
                PauseSchedule::Layer(l) => write!(w, " L{l}"),
                PauseSchedule::Z(z) => write!(w, " Z{z}"),
                PauseSchedule::Clear => w.write_str(" C"),
            }
        }
    }
}
