//! The known G/M/T codes: the letters each takes and the [`Command`] it builds. The families
//! with modules of their own (settings, SD, reports, drivers, power-cut resume) are handed to
//! them.

use super::words::Words;
use super::{
    driver, err, recovery, report, sd, settings, Command, FilamentChange, Heater, ParseError,
    ParseErrorKind, PauseParams, PauseSchedule, Progress,
};

/// Build a known command from its code and words; `None` = unknown code.
pub(super) fn build_known(code: (u8, u16), w: &Words<'_>) -> Option<Result<Command, ParseError>> {
    let r = (|| -> Result<Option<Command>, ParseError> {
        let none = || -> Result<(), ParseError> { w.check(b"", b"") };
        // Marlin's handler reads no parameter: words are taken and ignored (`M400 P100`).
        let ignore = || w.ignore_all();
        let c = match code {
            (b'G', n @ (0 | 1)) => {
                w.check(b"XYZEF", b"")?;
                Command::Move {
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
                Command::Arc {
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
                Command::Dwell {
                    ms: w.f32(b'P')?,
                    s: w.f32(b'S')?,
                }
            }
            (b'G', 10) => {
                ignore()?;
                Command::Retract
            }
            (b'G', 11) => {
                ignore()?;
                Command::Recover
            }
            (b'G', 20) => {
                ignore()?;
                Command::Inches
            }
            (b'G', 21) => {
                ignore()?;
                Command::Millimetres
            }
            (b'G', 28) => {
                w.check(b"XYZ", b"XYZ")?;
                // Values are accepted (Marlin ignores them) but must be numbers.
                w.axes()?;
                Command::Home(w.flags())
            }
            (b'G', 90) => {
                ignore()?;
                Command::Absolute
            }
            (b'G', 91) => {
                ignore()?;
                Command::Relative
            }
            (b'G', 92) => {
                w.check(b"XYZE", b"")?;
                Command::SetPosition(w.axes()?)
            }
            (b'M', n @ (0 | 1)) => {
                w.check(b"PS", b"")?;
                Command::Stop {
                    optional: n == 1,
                    ms: w.f32(b'P')?,
                    s: w.f32(b'S')?,
                }
            }
            (b'M', 17) => {
                w.check(b"XYZE", b"XYZE")?;
                Command::EnableSteppers(w.flags())
            }
            (b'M', n @ (18 | 84)) => {
                w.check(b"XYZES", b"XYZE")?;
                Command::DisableSteppers {
                    m18: n == 18,
                    axes: w.flags(),
                    s: w.f32(b'S')?,
                }
            }
            (b'M', n @ (24 | 602)) => {
                none()?;
                Command::Resume { m602: n == 602 }
            }
            (b'M', n @ (25 | 601)) => {
                w.check(b"S", b"")?;
                Command::Pause {
                    m601: n == 601,
                    now: w.bool01(b'S')?,
                }
            }
            (b'M', 82) => {
                ignore()?;
                Command::AbsoluteE
            }
            (b'M', 83) => {
                ignore()?;
                Command::RelativeE
            }
            (b'M', n @ (104 | 109 | 140 | 190)) => {
                let hotend = matches!(n, 104 | 109);
                let wait = matches!(n, 109 | 190);
                match (hotend, wait) {
                    (true, true) => w.check(b"SRT", b"")?,
                    (true, false) => w.check(b"ST", b"")?,
                    (false, true) => w.check(b"SR", b"")?,
                    (false, false) => w.check(b"S", b"")?,
                }
                Command::SetTemperature {
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
                Command::ReportTemperatures
            }
            (b'M', 106) => {
                w.check(b"SP", b"")?;
                let speed = w.f32(b'S')?;
                if speed.is_some_and(|s| !(0.0..=255.0).contains(&s)) {
                    return Err(w.refuse(b'S', ParseErrorKind::OutOfRange));
                }
                Command::FanOn {
                    speed,
                    fan: w.u8(b'P')?,
                }
            }
            (b'M', 107) => {
                w.check(b"P", b"")?;
                Command::FanOff { fan: w.u8(b'P')? }
            }
            (b'M', 108) => {
                ignore()?;
                Command::BreakWait
            }
            (b'M', 110) => {
                w.check(b"N", b"")?;
                // printcore opens a session with `N-1 M110` / `M110 N-1` (Marlin accepts it):
                // -1 is "before line 0", kept as u32::MAX so the next expected line wraps to 0.
                let n = match w.u32(b'N') {
                    Ok(n) => n,
                    Err(e) if w.i32(b'N') == Ok(Some(-1)) => {
                        let _ = e;
                        Some(u32::MAX)
                    }
                    Err(e) => return Err(e),
                };
                Command::SetLineNumber(n)
            }
            (b'M', 112) => {
                ignore()?;
                Command::EmergencyStop
            }
            (b'M', 114) => {
                // Marlin's D (detail), E (stepper E), R (real) are accepted and ignored.
                w.check(b"DER", b"DER")?;
                Command::ReportPosition
            }
            (b'M', 115) => {
                ignore()?;
                Command::FirmwareInfo
            }
            (b'M', 73) => {
                w.check(b"PRQSCL", b"")?;
                Command::Progress(Progress {
                    percent: w.f32(b'P')?,
                    remaining_min: w.f32(b'R')?,
                    silent_percent: w.f32(b'Q')?,
                    silent_remaining_min: w.f32(b'S')?,
                    change_min: w.f32(b'C')?,
                    layer: w.u32(b'L')?,
                })
            }
            (b'M', 204) => {
                w.check(b"PRTS", b"")?;
                Command::SetAcceleration {
                    print: w.f32(b'P')?,
                    retract: w.f32(b'R')?,
                    travel: w.f32(b'T')?,
                    s: w.f32(b'S')?,
                }
            }
            (b'M', 220) => {
                w.check(b"S", b"")?;
                Command::FeedOverride(w.f32(b'S')?)
            }
            (b'M', 221) => {
                w.check(b"S", b"")?;
                Command::FlowOverride(w.f32(b'S')?)
            }
            (b'M', 400) => {
                ignore()?;
                Command::WaitMoves
            }
            (b'M', 410) => {
                ignore()?;
                Command::QuickStop
            }
            (b'M', 524) => {
                ignore()?;
                Command::Cancel
            }
            (b'M', 600) => {
                w.check(b"XYZELUB", b"")?;
                Command::FilamentChange(FilamentChange {
                    axes: w.axes()?,
                    load_mm: w.f32(b'L')?,
                    unload_mm: w.f32(b'U')?,
                    beeps: w.u32(b'B')?,
                })
            }
            (b'M', n @ (301 | 304)) => {
                w.check(b"PID", b"")?;
                Command::SetPid {
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
                Command::Autotune {
                    heater_index: w.i32(b'E')?,
                    target_c: w.f32(b'S')?,
                    cycles: w.u32(b'C')?,
                    use_result: w.bool01(b'U')?,
                }
            }
            (b'M', 760) => {
                w.check(b"RZXYFSVLT", b"")?;
                Command::PauseParams(PauseParams {
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
                Command::SchedulePause(s)
            }
            (b'M', 302) => {
                w.check(b"SP", b"")?;
                let allow = match w.find(b'P') {
                    None => None,
                    Some(_) => Some(w.bool01(b'P')?),
                };
                Command::ColdExtrusion {
                    min_temp_c: w.f32(b'S')?,
                    allow,
                }
            }
            (b'M', 119) => {
                ignore()?;
                Command::ReportEndstops
            }
            (b'M', n) if settings::is_settings_code(n) => Command::Settings(settings::build(n, w)?),
            (b'M', n) if sd::is_sd_code(n, w) => Command::Sd(sd::build(n, w)?),
            (b'M', n) if report::is_report_code(n) => Command::Report(report::build(n, w)?),
            (b'M', n) if driver::is_driver_code(n) => Command::Driver(driver::build(n, w)?),
            (b'M', n) if recovery::is_recovery_code(n) => Command::Recovery(recovery::build(w)?),
            (b'T', n) => {
                none()?;
                match u8::try_from(n) {
                    Ok(t) => Command::Tool(t),
                    Err(_) => return Err(err(ParseErrorKind::OutOfRange, 0)),
                }
            }
            _ => return Ok(None),
        };
        Ok(Some(c))
    })();
    match r {
        Ok(Some(c)) => Some(Ok(c)),
        Ok(None) => None,
        Err(e) => Some(Err(e)),
    }
}
