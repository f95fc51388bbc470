//! The machine's side of a power cut in `sim serve`, for the power-cut resume (M1000) checks:
//!
//! * `--machine FILE`: the printer's mechanics outlive the session. The axes get minimum
//!   endstops ([`crate::exec::SimEndstops`]: G28 homes through switches the sim places), and
//!   the head's true position (steps from the switches; E as steps fed) is kept in `FILE` and
//!   is where the head is at the next start: a power cut does not move the axes (Z is held by
//!   its lead screws; X/Y are homed again anyway). Without `FILE` the head starts 10 mm from
//!   each switch. Written whenever nothing moves, so a killed session (`kill -9`) keeps where a
//!   parked head is.
//! * `--trace FILE`: every executed job move as the sim saw its steps (not as the firmware
//!   reports it), one line per move, `x0 y0 z0 e0 x1 y1 z1 e1` (start and end, steps; X Y Z
//!   from the switches with `--machine`), appended whenever nothing moves and at the end. A
//!   move cut by a `now` pause appears as two lines; homing and the pause's own moves are not
//!   job moves and are left out.

use crate::machines::Machine;
use crate::port::Lane;
use crate::recorder::SegRecord;
use anyhow::Context;
use firmware::motion::StepPos;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The head's true position, kept in the machine file between sessions
/// ([`crate::machines`]: the file also says which printer this is).
pub struct MachineBody {
    path: PathBuf,
    /// The file's text (a TOML machine file; `None`: the older four-number form).
    profile: Option<String>,
    written: StepPos,
}

impl MachineBody {
    /// Open (or start) the file; returns the body, the machine it describes, and where the
    /// head is.
    pub fn open(path: &Path) -> anyhow::Result<(Self, Machine, StepPos)> {
        let (machine, profile) = match std::fs::read_to_string(path) {
            Ok(text) => {
                let m = Machine::parse(&text)
                    .with_context(|| format!("{}: not a machine file", path.display()))?;
                let profile = (!m.legacy).then_some(text);
                (m, profile)
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => (Machine::ender3(), None),
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let pos = machine
            .head_steps
            .unwrap_or_else(|| first_start(&machine.config));
        let mut b = Self {
            path: path.to_path_buf(),
            profile,
            written: pos,
        };
        b.write(pos)?;
        Ok((b, machine, pos))
    }

    fn write(&mut self, pos: StepPos) -> anyhow::Result<()> {
        let text = match &self.profile {
            Some(p) => crate::machines::with_head(p, pos),
            None => format!("{} {} {} {}\n", pos[0], pos[1], pos[2], pos[3]),
        };
        // Written whole to a new file, then renamed: a kill never leaves half a position.
        let tmp = self.path.with_extension("tmp");
        std::fs::write(&tmp, &text).with_context(|| format!("writing {}", tmp.display()))?;
        std::fs::rename(&tmp, &self.path)
            .with_context(|| format!("writing {}", self.path.display()))?;
        if let Some(p) = &mut self.profile {
            *p = text;
        }
        self.written = pos;
        Ok(())
    }

    /// Keep `pos` (call while nothing moves); a no-op when unchanged.
    pub fn keep(&mut self, pos: StepPos) -> anyhow::Result<()> {
        if pos != self.written {
            self.write(pos)?;
        }
        Ok(())
    }
}

/// Where a head without a recorded position starts: 10 mm from each switch.
pub fn first_start(cfg: &firmware::config::MachineConfig) -> StepPos {
    let steps = |k: usize| (10.0 * cfg.axes[k].steps_per_mm).round() as i32;
    [steps(0), steps(1), steps(2), 0]
}

/// The executed job moves, appended to a file.
pub struct MoveTrace {
    file: File,
    /// Records already written.
    done: usize,
}

impl MoveTrace {
    /// Open `path` for appending (created when missing).
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .with_context(|| format!("opening {}", path.display()))?;
        Ok(Self { file, done: 0 })
    }

    /// Append the moves among `records[done..]` (call while nothing moves: every record is
    /// complete then).
    pub fn flush(&mut self, records: &[SegRecord]) -> anyhow::Result<()> {
        let new = records.get(self.done..).unwrap_or(&[]);
        let mut text = String::new();
        let mut cur: Option<(u32, StepPos, StepPos)> = None;
        let emit = |m: Option<(u32, StepPos, StepPos)>, text: &mut String| {
            if let Some((_, s, e)) = m {
                text.push_str(&format!(
                    "{} {} {} {} {} {} {} {}\n",
                    s[0], s[1], s[2], s[3], e[0], e[1], e[2], e[3]
                ));
            }
        };
        for r in new {
            // Homing blocks run in the job lane with no job sequence number.
            let job = r.tag.lane == Lane::Job && r.tag.seq != crate::stream::HOMING_SEQ;
            match cur {
                Some((seq, s, _)) if job && seq == r.tag.seq => cur = Some((seq, s, r.end)),
                _ => {
                    emit(cur.take(), &mut text);
                    if job {
                        cur = Some((r.tag.seq, r.start, r.end));
                    }
                }
            }
        }
        emit(cur, &mut text);
        self.file
            .write_all(text.as_bytes())
            .context("writing the move trace")?;
        self.done = records.len();
        Ok(())
    }
}
