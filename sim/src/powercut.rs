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

use crate::port::Lane;
use crate::recorder::SegRecord;
use anyhow::{bail, Context};
use firmware::motion::StepPos;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Where a head without a `--machine` file starts: 10 mm from each switch (Ender-3 steps).
pub const FIRST_START: StepPos = [800, 800, 4_000, 0];

/// The head's true position, kept in a file between sessions.
pub struct MachineBody {
    path: PathBuf,
    written: StepPos,
}

impl MachineBody {
    /// Open (or start) the file; returns the body and where the head is.
    pub fn open(path: &Path) -> anyhow::Result<(Self, StepPos)> {
        let pos = match std::fs::read_to_string(path) {
            Ok(text) => {
                let v: Vec<i32> = text
                    .split_whitespace()
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .with_context(|| format!("{}: not a machine position", path.display()))?;
                let Ok(pos) = <[i32; 4]>::try_from(v) else {
                    bail!("{}: not a machine position (4 numbers)", path.display());
                };
                pos
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => FIRST_START,
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        };
        let mut b = Self {
            path: path.to_path_buf(),
            written: pos,
        };
        b.write(pos)?;
        Ok((b, pos))
    }

    fn write(&mut self, pos: StepPos) -> anyhow::Result<()> {
        let text = format!("{} {} {} {}\n", pos[0], pos[1], pos[2], pos[3]);
        // Written whole to a new file, then renamed: a kill never leaves half a position.
        let tmp = self.path.with_extension("tmp");
        std::fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
        std::fs::rename(&tmp, &self.path)
            .with_context(|| format!("writing {}", self.path.display()))?;
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
            let job = r.tag.lane == Lane::Job && r.tag.seq != u32::MAX;
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
