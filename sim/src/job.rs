//! The host's view of a job: every line parsed with the firmware's own parser
//! ([`firmware::gcode`]), the host-side modal state (positioning and extrusion modes, logical
//! position, feed) after each line, which lines move and which extrude, and the layer each line
//! belongs to (from the firmware's layer detector, [`firmware::layer`]).
//!
//! This is what a host (printcore, OctoPrint, the paper's system) knows about the file it
//! streams. It is used to classify what the firmware executed (was the stop at a layer
//! boundary?), to split moves for `host-split`, and to write host-split's pause and resume
//! sequences.

use firmware::gcode::{parse_line, Command};
use firmware::motion::AXES;

/// Host-side modal state after a line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HostState {
    /// G90 (true) or G91.
    pub abs_xyz: bool,
    /// M82 (true) or M83.
    pub abs_e: bool,
    /// Logical position X, Y, Z, E in mm (E as the file counts it).
    pub pos_mm: [f64; AXES],
    /// Last feed rate, mm/min.
    pub feed_mm_min: f64,
    /// G20 inches in effect.
    pub inches: bool,
}

impl Default for HostState {
    fn default() -> Self {
        Self {
            abs_xyz: true,
            abs_e: true,
            pos_mm: [0.0; AXES],
            feed_mm_min: 1500.0,
            inches: false,
        }
    }
}

/// What the host knows about one line of the job.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineInfo {
    /// A G0/G1/G2/G3 with some axis motion.
    pub is_move: bool,
    /// Moves X or Y while E advances by at least one step (the firmware's definition).
    pub extrudes: bool,
    /// Layer the line belongs to (`None` before the first layer).
    pub layer: Option<u32>,
    /// Logical position before the line, mm.
    pub start_mm: [f64; AXES],
    /// State after the line.
    pub after: HostState,
    /// The line did not parse (the firmware will answer with an error).
    pub parse_error: bool,
}

/// A parsed job.
#[derive(Clone, Debug, Default)]
pub struct JobInfo {
    /// One entry per line of the file.
    pub lines: Vec<LineInfo>,
    /// Index of the line where each layer starts (the marker line), by layer number.
    pub layer_starts: Vec<(u32, usize)>,
}

/// Apply one parsed command to the host state; returns (moves, extrudes).
fn apply(st: &mut HostState, cmd: &Command) -> (bool, bool) {
    let unit = if st.inches { 25.4 } else { 1.0 };
    match cmd {
        Command::Move { axes, feed, .. } | Command::Arc { axes, feed, .. } => {
            if let Some(f) = feed {
                st.feed_mm_min = f64::from(*f) * unit;
            }
            let before = st.pos_mm;
            for (i, w) in axes.0.iter().enumerate() {
                if let Some(v) = w {
                    let v = f64::from(*v) * unit;
                    let abs = if i == 3 { st.abs_e } else { st.abs_xyz };
                    st.pos_mm[i] = if abs { v } else { st.pos_mm[i] + v };
                }
            }
            let xyz = (0..3).any(|i| (st.pos_mm[i] - before[i]).abs() > 1e-9);
            let de = st.pos_mm[3] - before[3];
            let moves = xyz || de.abs() > 1e-9;
            (moves, xyz && de > 1e-9)
        }
        Command::Absolute => {
            st.abs_xyz = true;
            st.abs_e = true;
            (false, false)
        }
        Command::Relative => {
            st.abs_xyz = false;
            st.abs_e = false;
            (false, false)
        }
        Command::AbsoluteE => {
            st.abs_e = true;
            (false, false)
        }
        Command::RelativeE => {
            st.abs_e = false;
            (false, false)
        }
        Command::Inches => {
            st.inches = true;
            (false, false)
        }
        Command::Millimetres => {
            st.inches = false;
            (false, false)
        }
        Command::SetPosition(axes) => {
            for (i, w) in axes.0.iter().enumerate() {
                if let Some(v) = w {
                    st.pos_mm[i] = f64::from(*v) * unit;
                }
            }
            (false, false)
        }
        Command::Home(flags) => {
            for i in 0..3 {
                if flags.includes(firmware::motion::Axis::ALL[i]) {
                    st.pos_mm[i] = 0.0;
                }
            }
            (true, false)
        }
        _ => (false, false),
    }
}

impl JobInfo {
    /// Parse every line and find the layers.
    pub fn parse(lines: &[String]) -> Self {
        let mut st = HostState::default();
        let mut out = Vec::with_capacity(lines.len());
        let facts = crate::layers::analyse(lines);
        let mut layer_starts = Vec::new();
        let mut cur_layer: Option<u32> = None;
        for (i, line) in lines.iter().enumerate() {
            let f = facts.get(i).copied().unwrap_or_default();
            if let Some(l) = f.mark {
                layer_starts.push((l, i));
                cur_layer = Some(l);
            }
            let start_mm = st.pos_mm;
            let (is_move, parse_error) = match parse_line(line.as_bytes()) {
                Ok(l) => match l.command {
                    Some(cmd) => (apply(&mut st, &cmd).0, false),
                    None => (false, false),
                },
                Err(_) => (false, true),
            };
            // Extruding as the firmware counts it (at least one E step with XY motion).
            let extrudes = f.extrudes;
            out.push(LineInfo {
                is_move,
                extrudes,
                layer: cur_layer,
                start_mm,
                after: st,
                parse_error,
            });
        }
        Self {
            lines: out,
            layer_starts,
        }
    }

    /// Index of the first line of the first layer that starts after line `index`.
    pub fn next_layer_start(&self, index: usize) -> Option<usize> {
        self.layer_starts
            .iter()
            .map(|(_, i)| *i)
            .find(|&i| i > index)
    }

    /// Host state before line `index` (the state after the previous line).
    pub fn state_before(&self, index: usize) -> HostState {
        match index.checked_sub(1).and_then(|i| self.lines.get(i)) {
            Some(l) => l.after,
            None => HostState::default(),
        }
    }
}
