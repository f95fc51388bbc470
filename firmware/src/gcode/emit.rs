//! The emitter: [`Command`] → G-code text, symmetrical with the parser.
//!
//! Numbers are written with Rust's shortest round-trip decimal (`{}` of `f32`), which the parser
//! reads back to the same bits, so `parse_line(emit(c)) == c` for every command whose numbers are
//! in range (property-tested). Canonical spelling: upper-case letters, one space between words,
//! codes without leading zeros.

use super::{AxisFlags, AxisWords, Command, Heater, Line, PauseSchedule};
use core::fmt::{self, Write};

/// Write ` L<v>` if the value is present.
fn opt<W: Write>(w: &mut W, letter: char, v: Option<f32>) -> fmt::Result {
    match v {
        Some(v) => write!(w, " {letter}{v}"),
        None => Ok(()),
    }
}

/// Write ` L<v>` for an integer value if present.
fn opt_int<W: Write, T: fmt::Display>(w: &mut W, letter: char, v: Option<T>) -> fmt::Result {
    match v {
        Some(v) => write!(w, " {letter}{v}"),
        None => Ok(()),
    }
}

fn axes<W: Write>(w: &mut W, a: &AxisWords) -> fmt::Result {
    for (letter, v) in ['X', 'Y', 'Z', 'E'].into_iter().zip(a.0) {
        opt(w, letter, v)?;
    }
    Ok(())
}

fn flags<W: Write>(w: &mut W, f: &AxisFlags) -> fmt::Result {
    for (letter, on) in ['X', 'Y', 'Z', 'E'].into_iter().zip(f.0) {
        if on {
            write!(w, " {letter}")?;
        }
    }
    Ok(())
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_command(f, self)
    }
}

/// Write a command as one line of G-code (no line end).
pub fn write_command<W: Write>(w: &mut W, c: &Command) -> fmt::Result {
    match c {
        Command::Move {
            rapid,
            axes: a,
            feed,
        } => {
            w.write_str(if *rapid { "G0" } else { "G1" })?;
            axes(w, a)?;
            opt(w, 'F', *feed)
        }
        Command::Arc {
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
        Command::Dwell { ms, s } => {
            w.write_str("G4")?;
            opt(w, 'P', *ms)?;
            opt(w, 'S', *s)
        }
        Command::Retract => w.write_str("G10"),
        Command::Recover => w.write_str("G11"),
        Command::Inches => w.write_str("G20"),
        Command::Millimetres => w.write_str("G21"),
        Command::Home(fl) => {
            w.write_str("G28")?;
            flags(w, fl)
        }
        Command::Absolute => w.write_str("G90"),
        Command::Relative => w.write_str("G91"),
        Command::SetPosition(a) => {
            w.write_str("G92")?;
            axes(w, a)
        }
        Command::Stop { optional, ms, s } => {
            w.write_str(if *optional { "M1" } else { "M0" })?;
            opt(w, 'P', *ms)?;
            opt(w, 'S', *s)
        }
        Command::EnableSteppers(fl) => {
            w.write_str("M17")?;
            flags(w, fl)
        }
        Command::DisableSteppers { m18, axes: fl, s } => {
            w.write_str(if *m18 { "M18" } else { "M84" })?;
            flags(w, fl)?;
            opt(w, 'S', *s)
        }
        Command::Resume { m602 } => w.write_str(if *m602 { "M602" } else { "M24" }),
        Command::Pause { m601, now } => {
            w.write_str(if *m601 { "M601" } else { "M25" })?;
            if *now {
                w.write_str(" S1")?;
            }
            Ok(())
        }
        Command::AbsoluteE => w.write_str("M82"),
        Command::RelativeE => w.write_str("M83"),
        Command::SetTemperature {
            heater,
            wait,
            s,
            r,
            tool,
        } => {
            let code = match (heater, wait) {
                (Heater::Hotend, false) => "M104",
                (Heater::Hotend, true) => "M109",
                (Heater::Bed, false) => "M140",
                (Heater::Bed, true) => "M190",
            };
            w.write_str(code)?;
            opt(w, 'S', *s)?;
            opt(w, 'R', *r)?;
            opt_int(w, 'T', *tool)
        }
        Command::ReportTemperatures => w.write_str("M105"),
        Command::FanOn { speed, fan } => {
            w.write_str("M106")?;
            opt(w, 'S', *speed)?;
            opt_int(w, 'P', *fan)
        }
        Command::FanOff { fan } => {
            w.write_str("M107")?;
            opt_int(w, 'P', *fan)
        }
        Command::BreakWait => w.write_str("M108"),
        Command::SetLineNumber(n) => {
            w.write_str("M110")?;
            opt_int(w, 'N', *n)
        }
        Command::EmergencyStop => w.write_str("M112"),
        Command::ReportPosition => w.write_str("M114"),
        Command::FirmwareInfo => w.write_str("M115"),
        Command::Message(t) => text(w, "M117", t),
        Command::Echo(t) => text(w, "M118", t),
        Command::Progress(p) => {
            w.write_str("M73")?;
            opt(w, 'P', p.percent)?;
            opt(w, 'R', p.remaining_min)?;
            opt(w, 'Q', p.silent_percent)?;
            opt(w, 'S', p.silent_remaining_min)?;
            opt(w, 'C', p.change_min)?;
            opt_int(w, 'L', p.layer)
        }
        Command::SetAcceleration {
            print,
            retract,
            travel,
            s,
        } => {
            w.write_str("M204")?;
            opt(w, 'P', *print)?;
            opt(w, 'R', *retract)?;
            opt(w, 'T', *travel)?;
            opt(w, 'S', *s)
        }
        Command::FeedOverride(s) => {
            w.write_str("M220")?;
            opt(w, 'S', *s)
        }
        Command::FlowOverride(s) => {
            w.write_str("M221")?;
            opt(w, 'S', *s)
        }
        Command::WaitMoves => w.write_str("M400"),
        Command::QuickStop => w.write_str("M410"),
        Command::Cancel => w.write_str("M524"),
        Command::FilamentChange(fc) => {
            w.write_str("M600")?;
            axes(w, &fc.axes)?;
            opt(w, 'L', fc.load_mm)?;
            opt(w, 'U', fc.unload_mm)?;
            opt_int(w, 'B', fc.beeps)
        }
        Command::SetPid { heater, p, i, d } => {
            w.write_str(match heater {
                Heater::Hotend => "M301",
                Heater::Bed => "M304",
            })?;
            opt(w, 'P', *p)?;
            opt(w, 'I', *i)?;
            opt(w, 'D', *d)
        }
        Command::Autotune {
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
        Command::PauseParams(p) => {
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
        Command::SchedulePause(s) => {
            w.write_str("M761")?;
            match s {
                PauseSchedule::Report => Ok(()),
                PauseSchedule::Layer(l) => write!(w, " L{l}"),
                PauseSchedule::Z(z) => write!(w, " Z{z}"),
                PauseSchedule::Clear => w.write_str(" C"),
            }
        }
        Command::ColdExtrusion { min_temp_c, allow } => {
            w.write_str("M302")?;
            opt(w, 'S', *min_temp_c)?;
            match allow {
                Some(a) => write!(w, " P{}", u8::from(*a)),
                None => Ok(()),
            }
        }
        Command::ReportEndstops => w.write_str("M119"),
        Command::Settings(c) => super::settings::write(w, c),
        Command::Report(c) => super::report::write(w, c),
        Command::Driver(c) => super::driver::write(w, c),
        Command::Sd(c) => super::sd::write(w, c),
        Command::Recovery(c) => super::recovery::write(w, c),
        Command::Tool(t) => write!(w, "T{t}"),
        Command::PrintStatsInfo {
            current_layer,
            total_layer,
        } => {
            w.write_str("SET_PRINT_STATS_INFO")?;
            if let Some(l) = current_layer {
                write!(w, " CURRENT_LAYER={l}")?;
            }
            if let Some(l) = total_layer {
                write!(w, " TOTAL_LAYER={l}")?;
            }
            Ok(())
        }
        Command::Unknown(t) => w.write_str(t),
    }
}

fn text<W: Write>(w: &mut W, code: &str, t: &str) -> fmt::Result {
    w.write_str(code)?;
    if !t.is_empty() {
        w.write_char(' ')?;
        w.write_str(t)?;
    }
    Ok(())
}

impl fmt::Display for Line<'_> {
    /// The command, then ` ;comment` if there is one (non-UTF-8 comment bytes are written as
    /// U+FFFD).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(c) = &self.command {
            write_command(f, c)?;
        }
        if let Some(comment) = self.comment {
            if self.command.is_some() {
                f.write_char(' ')?;
            }
            f.write_char(';')?;
            for chunk in comment.utf8_chunks() {
                f.write_str(chunk.valid())?;
                if !chunk.invalid().is_empty() {
                    f.write_char('\u{FFFD}')?;
                }
            }
        }
        Ok(())
    }
}
