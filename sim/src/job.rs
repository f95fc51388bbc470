//! The host's view of a job: every line parsed with the firmware's own parser
//! ([`firmware::gcode`]), the host-side modal state (positioning and extrusion modes, logical
//! position, feed) after each line, which lines move and which extrude, and the layer each line
//! belongs to (from the firmware's layer detector, [`firmware::layer`]).
//!
//! This is what a host (printcore, OctoPrint, the paper's system) knows about the file it
//! streams. It is used to classify what the firmware executed (was the stop at a layer
//! boundary?), to split moves for `host-split`, and to write host-split's pause and resume
//! sequences.

use firmware::gcode::MotionCommand;
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
        Command::Motion(MotionCommand::Move { axes, feed, .. })
        | Command::Motion(MotionCommand::Arc { axes, feed, .. }) => {
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
        Command::Motion(MotionCommand::Absolute) => {
            st.abs_xyz = true;
            st.abs_e = true;
            (false, false)
        }
        Command::Motion(MotionCommand::Relative) => {
            st.abs_xyz = false;
            st.abs_e = false;
            (false, false)
        }
        Command::Motion(MotionCommand::AbsoluteE) => {
            st.abs_e = true;
            (false, false)
        }
        Command::Motion(MotionCommand::RelativeE) => {
            st.abs_e = false;
            (false, false)
        }
        Command::Motion(MotionCommand::Inches) => {
            st.inches = true;
            (false, false)
        }
        Command::Motion(MotionCommand::Millimetres) => {
            st.inches = false;
            (false, false)
        }
        Command::Motion(MotionCommand::SetPosition(axes)) => {
            for (i, w) in axes.0.iter().enumerate() {
                if let Some(v) = w {
                    st.pos_mm[i] = f64::from(*v) * unit;
                }
            }
            (false, false)
        }
        Command::Motion(MotionCommand::Home(flags)) => {
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

    /// [`JobInfo::parse`] of a [`JobLines`] (its lines held for the parse: host-split's jobs).
    pub fn parse_job(job: &JobLines) -> std::io::Result<Self> {
        Ok(Self::parse(&job.to_vec()?))
    }

    /// Only what the pause metrics read — which lines extrude, where layers start — in about
    /// one byte per line ([`JobInfo::lines`] stays empty, [`JobInfo::state_before`] answers the
    /// default state): what `sim run` keeps of a long job.
    pub fn parse_layers(job: &JobLines) -> std::io::Result<Self> {
        let mut an = crate::layers::Analyser::new();
        let mut layer_starts = Vec::new();
        let mut extruding = Vec::with_capacity(job.len());
        job.for_each(|i, text| {
            let f = an.feed(text);
            if let Some(l) = f.mark {
                layer_starts.push((l, i));
            }
            extruding.push(f.extrudes);
        })?;
        Ok(Self {
            lines: Vec::new(),
            layer_starts,
            extruding,
        })
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

/// The lines of a job, read in order by each engine of a run ([`JobLines::reader`]): either
/// one text buffer with the start of each line (generated jobs, tests: 4 bytes per line), or
/// a file streamed from disk (`sim run`: [`JobLines::open`]), so a job of any size costs one
/// read buffer per engine, never the whole file (issue 24: a 2 GB file was read whole). Lines
/// as [`str::lines`] splits them (`\n`, one trailing `\r` dropped); a line longer than
/// [`MAX_LINE_BYTES`] is cut there (the firmware takes 128 bytes of a command and drops long
/// comments, so what is cut is never read by it either; [`JobReader::cut_lines`] counts them).
/// [`JobLines`] is a cheap `Arc` clone.
#[derive(Clone, Debug, Default)]
pub struct JobLines(std::sync::Arc<JobText>);

/// Longest line a [`JobReader`] hands out, bytes (the rest of a longer line is skipped).
pub const MAX_LINE_BYTES: usize = 4096;

#[derive(Debug, Default)]
struct JobText {
    /// The text (empty for a file).
    text: String,
    /// Byte offset of each line's start; the line ends before the next start's `\n`.
    starts: Vec<u32>,
    /// The file the lines are read from, and their count.
    file: Option<(std::path::PathBuf, usize)>,
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
        Ok(Self(std::sync::Arc::new(JobText {
            text,
            starts,
            file: None,
        })))
    }

    /// The lines of the file at `path`, streamed from it whenever they are read (one pass here
    /// counts them). The file must not change during the run.
    pub fn open(path: &std::path::Path) -> anyhow::Result<Self> {
        use anyhow::Context;
        let mut r = JobReader::from_file(path)?;
        let mut n = 0usize;
        while r
            .next_line()
            .with_context(|| format!("reading {}", path.display()))?
        {
            n += 1;
        }
        Ok(Self(std::sync::Arc::new(JobText {
            text: String::new(),
            starts: Vec::new(),
            file: Some((path.to_path_buf(), n)),
        })))
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
        match &self.0.file {
            Some((_, n)) => *n,
            None => self.0.starts.len(),
        }
    }

    /// True when the job has no line.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the lines are streamed from a file (not held in memory).
    pub fn is_streamed(&self) -> bool {
        self.0.file.is_some()
    }

    /// A reader of the lines from the first (each engine has its own).
    pub fn reader(&self) -> std::io::Result<JobReader> {
        match &self.0.file {
            Some((p, _)) => JobReader::from_file(p),
            None => Ok(JobReader {
                src: ReaderSource::Text(self.clone(), 0),
                line: String::new(),
                raw: Vec::new(),
                cut_lines: 0,
            }),
        }
    }

    /// Line `i` of a job held in memory (`None` past the end or for a streamed job).
    fn text_line(&self, i: usize) -> Option<&str> {
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

    /// Every line in order, each call to `f` with its index (streamed jobs are read from the
    /// file once more). Stops at the first read error.
    pub fn for_each(&self, mut f: impl FnMut(usize, &str)) -> std::io::Result<()> {
        let mut r = self.reader()?;
        let mut i = 0;
        while r.next_line()? {
            f(i, r.line());
            i += 1;
        }
        Ok(())
    }

    /// The lines as owned strings (for callers that edit the job: host-split; small jobs).
    pub fn to_vec(&self) -> std::io::Result<Vec<String>> {
        let mut v = Vec::with_capacity(self.len());
        self.for_each(|_, l| v.push(l.to_string()))?;
        Ok(v)
    }
}

enum ReaderSource {
    /// A job in memory and the next line's index.
    Text(JobLines, usize),
    File(std::io::BufReader<std::fs::File>),
}

/// The lines of a [`JobLines`] one after the other ([`JobLines::reader`]): [`JobReader::next_line`]
/// moves to the next one, [`JobReader::line`] is it.
pub struct JobReader {
    src: ReaderSource,
    line: String,
    /// Bytes of the current line read from a file (at most [`MAX_LINE_BYTES`]).
    raw: Vec<u8>,
    cut_lines: u64,
}

impl std::fmt::Debug for JobReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JobReader")
            .field("line", &self.line)
            .field("cut_lines", &self.cut_lines)
            .finish()
    }
}

impl JobReader {
    fn from_file(path: &std::path::Path) -> std::io::Result<Self> {
        Ok(Self {
            src: ReaderSource::File(std::io::BufReader::with_capacity(
                64 * 1024,
                std::fs::File::open(path)?,
            )),
            line: String::new(),
            raw: Vec::new(),
            cut_lines: 0,
        })
    }

    /// Move to the next line; false at the end.
    pub fn next_line(&mut self) -> std::io::Result<bool> {
        self.line.clear();
        match &mut self.src {
            ReaderSource::Text(job, i) => match job.text_line(*i) {
                Some(l) => {
                    let cut = floor_char_boundary(l, MAX_LINE_BYTES);
                    if cut < l.len() {
                        self.cut_lines += 1;
                    }
                    self.line.push_str(&l[..cut]);
                    *i += 1;
                    Ok(true)
                }
                None => Ok(false),
            },
            ReaderSource::File(r) => {
                use std::io::BufRead;
                self.raw.clear();
                let mut any = false;
                let mut cut = false;
                loop {
                    let buf = r.fill_buf()?;
                    if buf.is_empty() {
                        break;
                    }
                    any = true;
                    let (take, end) = match buf.iter().position(|&b| b == b'\n') {
                        Some(k) => (k, true),
                        None => (buf.len(), false),
                    };
                    let room = MAX_LINE_BYTES.saturating_sub(self.raw.len());
                    cut |= take > room;
                    self.raw.extend_from_slice(&buf[..take.min(room)]);
                    r.consume(take + usize::from(end));
                    if end {
                        break;
                    }
                }
                if !any {
                    return Ok(false);
                }
                self.cut_lines += u64::from(cut);
                if self.raw.last() == Some(&b'\r') {
                    self.raw.pop();
                }
                self.line.push_str(&String::from_utf8_lossy(&self.raw));
                Ok(true)
            }
        }
    }

    /// The current line (after [`Self::next_line`] returned true).
    pub fn line(&self) -> &str {
        &self.line
    }

    /// Lines longer than [`MAX_LINE_BYTES`] read so far (cut there).
    pub fn cut_lines(&self) -> u64 {
        self.cut_lines
    }
}

/// The largest index ≤ `at` that is a char boundary of `s`.
fn floor_char_boundary(s: &str, at: usize) -> usize {
    if at >= s.len() {
        return s.len();
    }
    (0..=at).rev().find(|&i| s.is_char_boundary(i)).unwrap_or(0)
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
    use super::{JobLines, MAX_LINE_BYTES};

    fn lines(j: &JobLines) -> Vec<String> {
        j.to_vec().unwrap()
    }

    #[test]
    fn splits_like_str_lines_in_memory_and_from_a_file() {
        let dir = std::env::temp_dir().join(format!("joblines-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (k, text) in ["", "a", "a\n", "a\r\nb", "\n\nx\r\n", "G1 X1\nG1 X2\n\n;c"]
            .into_iter()
            .enumerate()
        {
            let want: Vec<&str> = text.lines().collect();
            let j = JobLines::from_text(text.to_string()).unwrap();
            assert_eq!(lines(&j), want, "{text:?}");
            assert_eq!(j.len(), want.len());
            let p = dir.join(format!("{k}.gcode"));
            std::fs::write(&p, text).unwrap();
            let f = JobLines::open(&p).unwrap();
            assert!(f.is_streamed());
            assert_eq!(f.len(), want.len(), "{text:?}");
            assert_eq!(lines(&f), want, "{text:?}");
        }
        let j = JobLines::from_lines(&["G28".to_string(), String::new(), "G1 X1".into()]);
        assert_eq!(lines(&j), vec!["G28", "", "G1 X1"]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_huge_line_is_cut_and_never_held_whole() {
        // 3 MB without a line end, then a short line: the reader holds MAX_LINE_BYTES of it.
        let p = std::env::temp_dir().join(format!("joblines-long-{}", std::process::id()));
        let mut text = vec![b'x'; 3 << 20];
        text.extend_from_slice(b"\nG1 X1\n");
        std::fs::write(&p, &text).unwrap();
        let j = JobLines::open(&p).unwrap();
        assert_eq!(j.len(), 2);
        let mut r = j.reader().unwrap();
        assert!(r.next_line().unwrap());
        assert_eq!(r.line().len(), MAX_LINE_BYTES);
        assert!(r.next_line().unwrap());
        assert_eq!(r.line(), "G1 X1");
        assert!(!r.next_line().unwrap());
        assert_eq!(r.cut_lines(), 1);
        let _ = std::fs::remove_file(&p);
    }
}
