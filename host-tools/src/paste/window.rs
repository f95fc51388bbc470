//! The design's part of a job, and what it sets on the way: the window in time that
//! `timebased` resamples and `cure-check` checks, and every line of state inside it (fan,
//! temperatures, pauses, raw commands, the design's comments) with the time it takes effect,
//! so the time-based file keeps them where they happened.
//!
//! **Where the design starts.** Our writer marks the design between [`DESIGN_BEGIN`] and
//! [`DESIGN_END`] (after the printer's start code, before its end code), so everything the
//! design prints comes through — also what it prints before its first layer mark (a prime
//! line, a floor ring). A slicer's file has no such tags: its design starts at its first
//! explicit layer mark (slicer comment, `M73 L`, our `;TURN`) — its start code's purge line is
//! not the design — and a file with neither at its first printing move. The design ends with
//! its last printing move; state lines after it count up to [`DESIGN_END`] (or up to that
//! move in a file without the tag).
//!
//! **Which lines are state.** Every line of the window except motion and what the samples
//! already carry: moves, arcs, dwells, homing, `G92`, the G90/G91/M82/M83/G20/G21 modes, M204
//! accelerations (the samples are timed with them), M73 progress (the source's estimate) and
//! layer-marker comments (the time-based file writes its own). A line's time is when the
//! motion before it has ended: the start of the first move after it.

use crate::design::motion::{MoveKind, Trajectory};
pub use crate::design::writer::{DESIGN_BEGIN, DESIGN_END};
use crate::gcode::read::LayerSource;
use firmware::gcode::{parse_line, Command, Heater};
use firmware::gcode::{HeatCommand, MotionCommand, ReportCommand, SettingsCommand};

/// The design's part of a job.
#[derive(Clone, Debug, PartialEq)]
pub struct Window {
    /// Start of the design's first printing move, s.
    pub t0_s: f64,
    /// End of its last printing move, s.
    pub t1_s: f64,
    /// Lines of state inside the window, in file order, each with its time.
    pub state: Vec<StateLine>,
    /// Hot-end and bed targets in force where the window starts (set before it), °C.
    pub hotend_c: Option<f64>,
    /// See `hotend_c`.
    pub bed_c: Option<f64>,
    /// The part-fan line in force where the window starts (set before it), e.g. `M106 S255`.
    pub fan: Option<String>,
    /// First and last source line of the design (1-based).
    pub lines: (u32, u32),
    /// Start time of every move, by source line (for [`Window::time_of_line`]).
    starts: Vec<(u32, f64)>,
    duration_s: f64,
}

impl Window {
    /// When source line `line` takes effect: the start of the first move on it or after it
    /// (the end of the job when none follows), within the window. (A layer mark's line is the
    /// line of the move it is placed before.)
    pub fn time_of_line(&self, line: u32) -> f64 {
        let k = self.starts.partition_point(|s| s.0 < line);
        self.starts
            .get(k)
            .map_or(self.duration_s, |s| s.1)
            .clamp(self.t0_s, self.t1_s)
    }
}

/// One line of state: its text (trimmed) and when it takes effect.
#[derive(Clone, Debug, PartialEq)]
pub struct StateLine {
    /// Time, s from the start of the job.
    pub t_s: f64,
    /// 1-based line of the source.
    pub line: u32,
    /// The line as written (without its line break).
    pub text: String,
}

/// Lines of the source, 1-based, without their line breaks.
fn lines(src: &[u8]) -> impl Iterator<Item = (u32, &[u8])> {
    src.split(|&b| b == b'\n').enumerate().map(|(i, l)| {
        let l = l.strip_suffix(b"\r").unwrap_or(l);
        (u32::try_from(i + 1).unwrap_or(u32::MAX), l)
    })
}

fn is_tag(line: &[u8], tag: &str) -> bool {
    line.trim_ascii() == tag.as_bytes()
}

/// True for comments the time-based file writes itself or that only mean something at the
/// top of a file: layer markers (every family the firmware knows), `;Z:`, `;HEIGHT:`,
/// `;LAYER_COUNT:`, `;FLAVOR:` and our design tags.
fn is_frame_comment(comment: &[u8]) -> bool {
    let c = String::from_utf8_lossy(comment)
        .trim_start()
        .to_ascii_uppercase();
    [
        "Z:",
        "HEIGHT:",
        "LAYER_COUNT",
        "FLAVOR:",
        "DESIGN_BEGIN",
        "DESIGN_END",
    ]
    .iter()
    .any(|p| c.starts_with(p))
}

/// What a parsed line is for the window.
enum Kind {
    /// Motion or something the samples already carry: not copied.
    Frame,
    /// A temperature target.
    Temp(Heater, f64),
    /// The part fan.
    Fan,
    /// Anything else the design set: copied.
    State,
}

fn classify(text: &[u8]) -> Kind {
    let Ok(line) = parse_line(text) else {
        return Kind::State;
    };
    let Some(cmd) = &line.command else {
        return match line.comment {
            Some(c)
                if !is_frame_comment(c)
                    && !firmware::layer::LayerDetector::new().is_marker(&line) =>
            {
                Kind::State
            }
            _ => Kind::Frame,
        };
    };
    match cmd {
        Command::Motion(MotionCommand::Move { .. })
        | Command::Motion(MotionCommand::Arc { .. })
        | Command::Motion(MotionCommand::Dwell { .. })
        | Command::Motion(MotionCommand::Retract)
        | Command::Motion(MotionCommand::Recover)
        | Command::Motion(MotionCommand::Inches)
        | Command::Motion(MotionCommand::Millimetres)
        | Command::Motion(MotionCommand::Home(_))
        | Command::Motion(MotionCommand::Absolute)
        | Command::Motion(MotionCommand::Relative)
        | Command::Motion(MotionCommand::SetPosition(_))
        | Command::Motion(MotionCommand::AbsoluteE)
        | Command::Motion(MotionCommand::RelativeE)
        | Command::Report(ReportCommand::Progress(_))
        | Command::Settings(SettingsCommand::Acceleration { .. })
        | Command::Report(ReportCommand::SetLineNumber(_))
        | Command::Report(ReportCommand::PrintStatsInfo { .. }) => Kind::Frame,
        Command::Heat(HeatCommand::SetTemperature {
            heater, s: Some(c), ..
        }) => Kind::Temp(*heater, f64::from(*c)),
        Command::Heat(HeatCommand::FanOn { .. }) | Command::Heat(HeatCommand::FanOff { .. }) => {
            Kind::Fan
        }
        _ => Kind::State,
    }
}

/// The line of the last layer marker (comment or command) at or before line `line` (`line`
/// itself when none is found).
fn marker_line_before(src: &[u8], line: u32) -> u32 {
    let detector = firmware::layer::LayerDetector::new();
    let mut found = line;
    for (n, l) in lines(src) {
        if n > line {
            break;
        }
        // Only comments and M73 / Klipper commands can be markers: parse just those.
        let t = l.trim_ascii_start();
        if matches!(t.first(), Some(b';' | b'M' | b'm' | b'S' | b's'))
            && parse_line(t).is_ok_and(|p| detector.is_marker(&p))
        {
            found = n;
        }
    }
    found
}

/// The part-fan duty (0..=1) a line sets, if it is `M106`/`M107` (of the part fan).
pub fn fan_duty(line: &[u8]) -> Option<f64> {
    match parse_line(line).ok()?.command? {
        Command::Heat(HeatCommand::FanOn {
            speed,
            fan: None | Some(0),
        }) => Some(f64::from(speed.unwrap_or(255.0)).clamp(0.0, 255.0) / 255.0),
        Command::Heat(HeatCommand::FanOff {
            fan: None | Some(0),
        }) => Some(0.0),
        _ => None,
    }
}

/// The part-fan duty the last `M106`/`M107` of `text` leaves, if any.
pub fn last_fan_duty(text: &str) -> Option<f64> {
    text.lines().rev().find_map(|l| fan_duty(l.as_bytes()))
}

/// The design's window of `traj` (planned from `src`) with its state lines; `None` when
/// nothing prints.
pub fn design_window(traj: &Trajectory, src: &[u8]) -> Option<Window> {
    let (mut begin, mut end) = (None, None);
    for (n, l) in lines(src) {
        if begin.is_none() && is_tag(l, DESIGN_BEGIN) {
            begin = Some(n);
        } else if is_tag(l, DESIGN_END) {
            end = Some(n);
        }
    }
    let prints = || traj.segments.iter().filter(|s| s.kind == MoveKind::Print);
    // Without our tag: the first explicit layer mark (a slicer's start code is not the
    // design), else the first printing move.
    let from_line = begin.unwrap_or_else(|| {
        traj.layers
            .iter()
            .find(|m| {
                matches!(
                    m.source,
                    LayerSource::Comment | LayerSource::Command | LayerSource::Turn
                )
            })
            .map_or(0, |m| m.line)
    });
    let first = prints().find(|s| s.line >= from_line)?;
    let last = prints().next_back()?;
    let (t0_s, t1_s) = (first.t_start_s, last.t_end_s().max(first.t_start_s));
    // A mark's line is that of the move it goes before: the design starts at the marker
    // itself (its comment or command), so what the slicer sets right after it is the design's.
    let start_line = begin.unwrap_or(if from_line > 0 {
        marker_line_before(src, from_line)
    } else {
        first.line
    });
    let end_line = end.unwrap_or(last.line);
    let mut w = Window {
        t0_s,
        t1_s,
        state: Vec::new(),
        hotend_c: None,
        bed_c: None,
        fan: None,
        lines: (start_line, end_line),
        starts: traj
            .segments
            .iter()
            .map(|s| (s.line, s.t_start_s))
            .collect(),
        duration_s: traj.duration_s,
    };
    for (n, l) in lines(src) {
        if n > end_line {
            break;
        }
        let text = l.trim_ascii();
        if text.is_empty() {
            continue;
        }
        let kind = classify(text);
        if n < start_line {
            // Before the design: only what stays in force matters.
            match kind {
                Kind::Temp(Heater::Hotend, c) => w.hotend_c = Some(c),
                Kind::Temp(Heater::Bed, c) => w.bed_c = Some(c),
                Kind::Fan => w.fan = Some(String::from_utf8_lossy(text).into_owned()),
                _ => {}
            }
            continue;
        }
        if matches!(kind, Kind::Frame) {
            continue;
        }
        w.state.push(StateLine {
            t_s: w.time_of_line(n),
            line: n,
            text: String::from_utf8_lossy(text).into_owned(),
        });
    }
    Some(w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::motion::MotionLimits;
    use crate::design::profile::Profile;

    fn window(src: &str) -> Window {
        let traj = Trajectory::from_gcode(
            src.as_bytes(),
            MotionLimits::from_profile(&Profile::ender3()),
        )
        .expect("plan");
        design_window(&traj, src.as_bytes()).expect("window")
    }

    #[test]
    fn tags_keep_the_prelude_and_state_lines() {
        let src = "M104 S200\nM106 S100\nG1 X0 Y0 Z5 E3 F1200\n;DESIGN_BEGIN\nM82\nG92 E0\n\
                   M106 S255\nG1 X10 Y0 Z0.2 E1 F1200\n;LAYER_CHANGE\n;Z:0.2\nM601\n\
                   G1 X20 E2\nM107\n;DESIGN_END\nM104 S0\n";
        let w = window(src);
        let texts: Vec<&str> = w.state.iter().map(|s| s.text.as_str()).collect();
        assert_eq!(texts, ["M106 S255", "M601", "M107"]);
        assert_eq!(w.hotend_c, Some(200.0));
        assert_eq!(w.fan.as_deref(), Some("M106 S100"));
        // The prelude's move (before the layer mark) is in the window.
        assert!(w.t0_s > 0.0 && w.state[0].t_s == w.t0_s);
        assert!(w.state[1].t_s > w.t0_s && w.state[2].t_s == w.t1_s);
    }

    #[test]
    fn without_tags_the_first_mark_starts_the_design() {
        let src = "G1 X0 Y0 Z0.3 F1200\nG1 X50 E5\n;LAYER_CHANGE\n;Z:0.2\nM106 S255\n\
                   G1 X60 Y10 Z0.2 E6\n";
        let w = window(src);
        assert_eq!(w.state.len(), 1);
        assert_eq!(w.state[0].text, "M106 S255");
        assert!(w.t0_s > 2.5, "the purge line is not the design: {}", w.t0_s);
    }
}
