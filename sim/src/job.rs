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
    /// One entry per line of the file (empty for [`JobInfo::parse_layers`]).
    pub lines: Vec<LineInfo>,
    /// Index of the line where each layer starts (the marker line), by layer number.
    pub layer_starts: Vec<(u32, usize)>,
    /// Per line: extrudes (1 byte per line, kept by both parses).
    extruding: Vec<bool>,
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
    pub fn parse<S: AsRef<str>>(lines: &[S]) -> Self {
        Self::parse_lines(lines.iter().map(AsRef::as_ref), lines.len())
    }

    /// [`JobInfo::parse`] of a [`JobLines`].
    pub fn parse_job(job: &JobLines) -> Self {
        Self::parse_lines(job.iter(), job.len())
    }

    /// Only what the pause metrics read — which lines extrude, where layers start — in about
    /// one byte per line ([`JobInfo::lines`] stays empty, [`JobInfo::state_before`] answers the
    /// default state): what `sim run` keeps of a long job.
    pub fn parse_layers(job: &JobLines) -> Self {
        let mut an = crate::layers::Analyser::new();
        let mut layer_starts = Vec::new();
        let mut extruding = Vec::with_capacity(job.len());
        for (i, text) in job.iter().enumerate() {
            let f = an.feed(text);
            if let Some(l) = f.mark {
                layer_starts.push((l, i));
            }
            extruding.push(f.extrudes);
        }
        Self {
            lines: Vec::new(),
            layer_starts,
            extruding,
        }
    }

    /// Line `i` moves X or Y while E advances by at least one step.
    pub fn extrudes(&self, i: usize) -> bool {
        self.extruding.get(i).copied().unwrap_or(false)
    }

    /// The layer line `i` belongs to (the last layer mark at or before it).
    pub fn layer_of(&self, i: usize) -> Option<u32> {
        if i >= self.extruding.len() {
            return None;
        }
        let k = self.layer_starts.partition_point(|(_, at)| *at <= i);
        k.checked_sub(1).map(|k| self.layer_starts[k].0)
    }

    /// Number of lines.
    pub fn len(&self) -> usize {
        self.extruding.len()
    }

    /// True for a job without lines.
    pub fn is_empty(&self) -> bool {
        self.extruding.is_empty()
    }

    fn parse_lines<'a>(lines: impl Iterator<Item = &'a str> + Clone, n: usize) -> Self {
        let mut st = HostState::default();
        let mut out = Vec::with_capacity(n);
        let facts = crate::layers::analyse_lines(lines.clone(), n);
        let mut layer_starts = Vec::new();
        let mut cur_layer: Option<u32> = None;
        for (i, line) in lines.enumerate() {
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
        let extruding = out.iter().map(|l| l.extrudes).collect();
        Self {
            lines: out,
            layer_starts,
            extruding,
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

/// The lines of a job held in one text buffer with the start of each line (4 bytes per line
/// instead of a `String` each, ≈ 40 bytes): a 42 MB slicer file takes 42 MB + 6.5 MB, shared by
/// every engine of a run ([`JobLines`] is a cheap `Arc` clone). Lines as [`str::lines`] splits
/// them (`\n`, one trailing `\r` dropped).
#[derive(Clone, Debug, Default)]
pub struct JobLines(std::sync::Arc<JobText>);

#[derive(Debug, Default)]
struct JobText {
    text: String,
    /// Byte offset of each line's start; the line ends before the next start's `\n`.
    starts: Vec<u32>,
}

impl JobLines {
    /// Split `text` into lines. Fails for a text of 4 GiB or more (offsets are 32-bit).
    pub fn from_text(text: String) -> anyhow::Result<Self> {
        if u32::try_from(text.len()).is_err() {
            anyhow::bail!("job of {} bytes: at most 4 GiB", text.len());
        }
        let mut starts = Vec::new();
        let mut at = 0usize;
        while at < text.len() {
            // Below 4 GiB: checked above.
            starts.push(at as u32);
            at = match text[at..].find('\n') {
                Some(i) => at + i + 1,
                None => text.len(),
            };
        }
        starts.shrink_to_fit();
        Ok(Self(std::sync::Arc::new(JobText { text, starts })))
    }

    /// From separate lines (each must not contain `\n`).
    pub fn from_lines<S: AsRef<str>>(lines: &[S]) -> Self {
        let mut text = String::with_capacity(lines.iter().map(|l| l.as_ref().len() + 1).sum());
        for l in lines {
            text.push_str(l.as_ref());
            text.push('\n');
        }
        // Lines given one by one are small (tests, generated jobs).
        Self::from_text(text).unwrap_or_default()
    }

    /// Number of lines.
    pub fn len(&self) -> usize {
        self.0.starts.len()
    }

    /// True when the job has no line.
    pub fn is_empty(&self) -> bool {
        self.0.starts.is_empty()
    }

    /// Line `i` without its line end, or `None` past the end.
    pub fn get(&self, i: usize) -> Option<&str> {
        let t = &self.0;
        let start = *t.starts.get(i)? as usize;
        let end = match t.starts.get(i + 1) {
            Some(&next) => next as usize - 1,
            None => t.text.len(),
        };
        let line = &t.text[start..end];
        let line = line.strip_suffix('\n').unwrap_or(line);
        Some(line.strip_suffix('\r').unwrap_or(line))
    }

    /// Line `i` (empty past the end).
    pub fn line(&self, i: usize) -> &str {
        self.get(i).unwrap_or("")
    }

    /// Every line in order.
    pub fn iter(&self) -> impl Iterator<Item = &str> + Clone + '_ {
        (0..self.len()).map(|i| self.line(i))
    }

    /// The lines as owned strings (for callers that edit the job).
    pub fn to_vec(&self) -> Vec<String> {
        self.iter().map(str::to_string).collect()
    }
}

impl From<Vec<String>> for JobLines {
    fn from(lines: Vec<String>) -> Self {
        Self::from_lines(&lines)
    }
}

impl From<&[String]> for JobLines {
    fn from(lines: &[String]) -> Self {
        Self::from_lines(lines)
    }
}

#[cfg(test)]
mod job_lines_tests {
    use super::JobLines;

    #[test]
    fn splits_like_str_lines() {
        for text in ["", "a", "a\n", "a\r\nb", "\n\nx\r\n", "G1 X1\nG1 X2\n\n;c"] {
            let j = JobLines::from_text(text.to_string()).unwrap();
            let want: Vec<&str> = text.lines().collect();
            let got: Vec<&str> = j.iter().collect();
            assert_eq!(got, want, "{text:?}");
            assert_eq!(j.get(want.len()), None);
        }
        let j = JobLines::from_lines(&["G28".to_string(), String::new(), "G1 X1".into()]);
        assert_eq!(j.to_vec(), vec!["G28", "", "G1 X1"]);
    }
}
