//! The heat family: heater targets and waits, the temperature report, the fan, PID gains and
//! autotune, cold-extrusion protection. Parse and write side by side; the executive's side is
//! the heat part (`printer/heat.rs`).

use super::format::{opt, opt_int};
use super::{ParseError, ParseErrorKind, Words};
use core::fmt::{self, Write};

/// Which heater a command names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Heater {
    /// The hot end (`M104`/`M109`/`M301`).
    Hotend,
    /// The bed (`M140`/`M190`/`M304`).
    Bed,
}

impl Heater {
    /// The M-code that sets this heater's target: M104/M140, or with `wait` M109/M190.
    pub fn target_code(self, wait: bool) -> &'static str {
        match (self, wait) {
            (Heater::Hotend, false) => "M104",
            (Heater::Hotend, true) => "M109",
            (Heater::Bed, false) => "M140",
            (Heater::Bed, true) => "M190",
        }
    }
}

/// A heat command (M104/M109/M140/M190, M105, M106/M107, M301/M304, M303, M302).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HeatCommand {
    /// `M104`/`M109` (hotend) and `M140`/`M190` (bed): set a target, optionally waiting.
    SetTemperature {
        /// Which heater.
        heater: Heater,
        /// M109/M190 rather than M104/M140.
        wait: bool,
        /// `S`: target °C (M109/M190: wait only while heating).
        s: Option<f32>,
        /// `R`: target °C, wait while heating or cooling (M109/M190).
        r: Option<f32>,
        /// `T`: tool index (hotend only).
        tool: Option<u8>,
    },
    /// `M105 [T]`: report temperatures.
    Report,
    /// `M106 [S<0-255>] [P<fan>]`: fan on.
    FanOn {
        /// `S`: speed 0..=255 (default 255).
        speed: Option<f32>,
        /// `P`: fan index.
        fan: Option<u8>,
    },
    /// `M107 [P<fan>]`: fan off.
    FanOff {
        /// `P`: fan index.
        fan: Option<u8>,
    },
    /// `M301` (hotend) / `M304` (bed) `[P] [I] [D]`: set PID gains (none given: report).
    SetPid {
        /// Which heater.
        heater: Heater,
        /// `P`: proportional gain.
        p: Option<f32>,
        /// `I`: integral gain (Marlin units).
        i: Option<f32>,
        /// `D`: derivative gain (Marlin units).
        d: Option<f32>,
    },
    /// `M303 [E<-1|0>] [S<°C>] [C<cycles>] [U<0|1>]`: PID autotune (E-1 = bed).
    Autotune {
        /// `E`: heater index, -1 = bed, 0 = hotend.
        heater_index: Option<i32>,
        /// `S`: target temperature °C.
        target_c: Option<f32>,
        /// `C`: number of cycles.
        cycles: Option<u32>,
        /// `U1`: use the result.
        use_result: bool,
    },
    /// `M302 [S<°C>] [P<0|1>]`: cold-extrusion protection as in Marlin: `S` sets the lowest
    /// hotend temperature at which E may move, `P1` allows cold extrusion, `P0` forbids it
    /// again; with neither, report.
    ColdExtrusion {
        /// `S`: minimum extrusion temperature, °C.
        min_temp_c: Option<f32>,
        /// `P`: allow cold extrusion (`P1`) or not (`P0`).
        allow: Option<bool>,
    },
}

/// Parse `code` if it is one of this family's; `None` = not this family's.
pub(super) fn build(code: (u8, u16), w: &Words<'_>) -> Result<Option<HeatCommand>, ParseError> {
    Ok(Some(match code {
        (b'M', n @ (104 | 109 | 140 | 190)) => {
            let hotend = matches!(n, 104 | 109);
            let wait = matches!(n, 109 | 190);
            match (hotend, wait) {
                (true, true) => w.check(b"SRT", b"")?,
                (true, false) => w.check(b"ST", b"")?,
                (false, true) => w.check(b"SR", b"")?,
                (false, false) => w.check(b"S", b"")?,
            }
            HeatCommand::SetTemperature {
                heater: if hotend { Heater::Hotend } else { Heater::Bed },
                wait,
                s: w.f32(b'S')?,
                r: w.f32(b'R')?,
                tool: w.u8(b'T')?,
            }
        }
        (b'M', 105) => {
            // Marlin takes T and R; both are ignored (one hotend, one bed).
            w.check(b"TR", b"TR")?;
            HeatCommand::Report
        }
        (b'M', 106) => {
            w.check(b"SP", b"")?;
            let speed = w.f32(b'S')?;
            if speed.is_some_and(|s| !(0.0..=255.0).contains(&s)) {
                return Err(w.refuse(b'S', ParseErrorKind::OutOfRange));
            }
            HeatCommand::FanOn {
                speed,
                fan: w.u8(b'P')?,
            }
        }
        (b'M', 107) => {
            w.check(b"P", b"")?;
            HeatCommand::FanOff { fan: w.u8(b'P')? }
        }
        (b'M', n @ (301 | 304)) => {
            w.check(b"PID", b"")?;
            HeatCommand::SetPid {
                heater: if n == 301 {
                    Heater::Hotend
                } else {
                    Heater::Bed
                },
                p: w.f32(b'P')?,
                i: w.f32(b'I')?,
                d: w.f32(b'D')?,
            }
        }
        (b'M', 303) => {
            w.check(b"ESCU", b"")?;
            HeatCommand::Autotune {
                heater_index: w.i32(b'E')?,
                target_c: w.f32(b'S')?,
                cycles: w.u32(b'C')?,
                use_result: w.bool01(b'U')?,
            }
        }
        (b'M', 302) => {
            w.check(b"SP", b"")?;
            let allow = match w.find(b'P') {
                None => None,
                Some(_) => Some(w.bool01(b'P')?),
            };
            HeatCommand::ColdExtrusion {
                min_temp_c: w.f32(b'S')?,
                allow,
            }
        }
        _ => return Ok(None),
    }))
}

/// The G-code text of a command (what [`build`] reads back).
pub(super) fn write<W: Write>(w: &mut W, c: &HeatCommand) -> fmt::Result {
    match c {
        HeatCommand::SetTemperature {
            heater,
            wait,
            s,
            r,
            tool,
        } => {
            let code = heater.target_code(*wait);
            w.write_str(code)?;
            opt(w, 'S', *s)?;
            opt(w, 'R', *r)?;
            opt_int(w, 'T', *tool)
        }
        HeatCommand::Report => w.write_str("M105"),
        HeatCommand::FanOn { speed, fan } => {
            w.write_str("M106")?;
            opt(w, 'S', *speed)?;
            opt_int(w, 'P', *fan)
        }
        HeatCommand::FanOff { fan } => {
            w.write_str("M107")?;
            opt_int(w, 'P', *fan)
        }
        HeatCommand::SetPid { heater, p, i, d } => {
            w.write_str(match heater {
                Heater::Hotend => "M301",
                Heater::Bed => "M304",
            })?;
            opt(w, 'P', *p)?;
            opt(w, 'I', *i)?;
            opt(w, 'D', *d)
        }
        HeatCommand::Autotune {
            heater_index,
            target_c,
            cycles,
            use_result,
        } => {
            w.write_str("M303")?;
            opt_int(w, 'E', *heater_index)?;
            opt(w, 'S', *target_c)?;
            opt_int(w, 'C', *cycles)?;
            if *use_result {
                w.write_str(" U1")?;
            }
            Ok(())
        }
        HeatCommand::ColdExtrusion { min_temp_c, allow } => {
            w.write_str("M302")?;
            opt(w, 'S', *min_temp_c)?;
            match allow {
                Some(a) => write!(w, " P{}", u8::from(*a)),
                None => Ok(()),
            }
        }
    }
}
