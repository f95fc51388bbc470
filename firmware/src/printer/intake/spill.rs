//! The parked intake's spill: job lines a host streams into a parked printer, kept on the SD
//! card once the RAM slots ([`super::PARKED_EXTRA`]) are full, and fed back, in order, after
//! the resume. With it a one-line-per-`ok` host (printcore) gets an `ok` every
//! [`super::PARKED_PACE_US`] for as long as the pause lasts, so its console lines (M105, jogs,
//! M602, M524) always get out (docs/frontend.md, "Host rules", rule 5).
//!
//! A spilled line is kept as the host sent it — its text (comments kept as the link kept them)
//! and its line number — one per file line: `<number> <text>\n`, or `- <text>\n` for an
//! unnumbered line; a `+` before the number marks the first line after the host reset its
//! line numbers (`M110`: a new job starts there, and its layers count from 1 only once the
//! lines of the job before have run). It is interpreted only when it is fed back, through the
//! same line handler as every host line (as an SD job's lines are), so the machine state, the
//! layer detector and the power-cut notes see exactly the stream the host sent, in its order;
//! its `ok` went out when it was taken.
//!
//! Memory: [`SPILL_STAGE`] bytes of lines not yet on the card, a [`SPILL_CHUNK`]-byte read
//! buffer. The card is written by the driver's card service (the executive never blocks on
//! it), in appends of at least [`SPILL_FLUSH`] bytes (an 8-hour pause at one line a second is
//! ≈ 30 000 lines, ≈ 1 MB, ≈ 2 000 appends). The card keeps the file open from its first
//! append to its deletion, so an append and a replay read cost the same few blocks at any
//! length of the file (`Card::spill_append`).
//!
//! Failures lose nothing the card did not lose: lines not yet written stay in RAM and are fed
//! back from there; a failed write stops the spilling (the host waits, with `busy:`, as
//! without a card); a spill file that cannot be read back cancels the job (its lines are
//! gone with the card; the cancel parks the head off the part).

use super::Intake;
use crate::link::{PortId, ReceivedLine, LINE_CAP};
use crate::printer::host::Host;
use crate::storage::sd::{Card, SPILL_NAME};
use core::fmt::Write as _;
use embedded_sdmmc::BlockDevice;
use heapless::{String, Vec};

/// Bytes of spilled lines kept in RAM until the card takes them.
pub const SPILL_STAGE: usize = 1024;
/// The stage is written to the card once it holds this much (lines that never fill it run
/// from RAM after the card's).
pub const SPILL_FLUSH: usize = 512;
/// Read buffer of the replay (a spilled line is at most 12 + [`LINE_CAP`] + 1 bytes).
pub const SPILL_CHUNK: usize = 512;
/// The most a spilled line takes: reset mark, number, blank, text, line end.
const SPILL_LINE_MAX: usize = 12 + LINE_CAP + 1;

/// The spill's state (see the module documentation).
#[derive(Clone, Debug)]
pub(super) struct Spill {
    /// Lines taken, not yet on the card, oldest first.
    stage: Vec<u8, SPILL_STAGE>,
    /// Bytes of the spill file known good (written by this pause's appends).
    on_card: u32,
    /// Next byte of the spill file to feed back.
    replay_at: u32,
    /// Bytes read from the card at `replay_at` and not yet fed back.
    chunk: Vec<u8, SPILL_CHUNK>,
    /// Lines taken / fed back since the spill was last empty.
    lines_in: u32,
    lines_out: u32,
    /// A write failed: no more lines are spilled until the spill is empty again.
    failed: bool,
    /// The file is to be deleted (emptied, cancelled, or left by an earlier power-up).
    remove: bool,
}

impl Spill {
    pub(super) const fn new() -> Self {
        Self {
            stage: Vec::new(),
            on_card: 0,
            replay_at: 0,
            chunk: Vec::new(),
            lines_in: 0,
            lines_out: 0,
            failed: false,
            remove: true,
        }
    }

    /// Lines taken and not yet fed back.
    pub(super) fn pending(&self) -> u32 {
        self.lines_in.saturating_sub(self.lines_out)
    }

    /// A write failed (no more spilling until the spill is empty again).
    pub(super) fn failed(&self) -> bool {
        self.failed
    }

    /// The stage has room for `line`.
    pub(super) fn has_room(&self, line: &ReceivedLine) -> bool {
        !self.failed && self.stage.len() + line.text().len() + 13 <= SPILL_STAGE
    }

    /// Forget every line (a cancel: they belong to the dropped job) and delete the file;
    /// returns how many there were.
    pub(super) fn drop_all(&mut self) -> u32 {
        let n = self.pending();
        *self = Self::new();
        n
    }
}

/// A spilled line fed back.
pub(in crate::printer) enum Replay {
    /// The next line; `reset`: a new job starts with it.
    Line(ReceivedLine),
    /// Nothing readable now.
    Wait,
    /// The file is unreadable or not ours: its lines are lost.
    Lost(u32),
}

impl Intake {
    /// Lines waiting in the spill.
    pub(in crate::printer) fn spilled(&self) -> u32 {
        self.spill.pending()
    }

    /// Take a job line into the spill, and answer its `ok`; `reset`: a job starts at this line
    /// (the host reset its line numbers before it).
    pub(in crate::printer) fn spill_line(
        &mut self,
        line: &ReceivedLine,
        reset: bool,
        port: PortId,
        now_us: u64,
        host: &mut Host,
    ) {
        if self.spill.pending() == 0 {
            host.say(format_args!(
                "pause: job lines from here kept on the SD card ({SPILL_NAME}) until the resume"
            ));
        }
        let mut head: String<13> = String::new();
        if reset {
            let _ = head.push('+');
        }
        let _ = match line.number() {
            Some(n) => write!(head, "{n} "),
            None => head.write_str("- "),
        };
        let s = &mut self.spill.stage;
        // The caller checked the room (`intake_due`).
        let _ = s.extend_from_slice(head.as_bytes());
        let _ = s.extend_from_slice(line.text());
        let _ = s.push(b'\n');
        self.spill.lines_in = self.spill.lines_in.saturating_add(1);
        self.took_line(line.number(), Some(port), now_us);
        host.ok();
    }

    /// A cancel drops the spilled lines with the rest of the job.
    pub(in crate::printer) fn say_spill_dropped(n: u32, host: &mut Host) {
        if n > 0 {
            host.say(format_args!(
                "cancelled: dropped {n} job lines kept on the SD card"
            ));
        }
    }

    /// The driver's card: write the stage, delete the file when asked.
    pub(in crate::printer) fn service_spill<D: BlockDevice>(
        &mut self,
        card: &mut Card<D>,
        host: &mut Host,
    ) where
        D::Error: core::fmt::Debug,
    {
        let sp = &mut self.spill;
        if sp.remove {
            if sp.pending() > 0 {
                // Lines taken since the file was emptied: they are in the stage; delete
                // only when nothing is on the card.
                if sp.on_card == 0 {
                    sp.remove = false;
                }
            } else if card.spill_remove().is_ok() {
                sp.remove = false;
            }
        }
        // Appends of at least SPILL_FLUSH bytes, parked or not: after the resume an append
        // moves the card's file position to the end, so the replay's next read walks the
        // cluster chain from the start once (`Card::spill_read_at`); one append per line
        // taken would do that for every line.
        let flush = sp.stage.len() >= SPILL_FLUSH && !sp.failed && !sp.remove;
        if flush {
            match card.spill_append(&sp.stage) {
                Ok(len) => {
                    if sp.on_card == 0 {
                        // A file that could not be deleted: its old bytes are not ours.
                        sp.replay_at = len.saturating_sub(sp.stage.len() as u32);
                    }
                    sp.on_card = len;
                    sp.stage.clear();
                }
                Err(e) => {
                    // The file may now hold part of this append: nothing more is appended
                    // (the replay reads the card up to `on_card`, then the stage).
                    sp.failed = true;
                    host.say(format_args!(
                        "SD write error ({e}): job lines kept in RAM; the host waits"
                    ));
                }
            }
        }
    }

    /// The next spilled line to feed back: from the card up to what was written, then from
    /// the stage.
    pub(in crate::printer) fn next_spilled<D: BlockDevice>(&mut self, card: &mut Card<D>) -> Replay
    where
        D::Error: core::fmt::Debug,
    {
        if self.spill.pending() == 0 {
            return Replay::Wait;
        }
        match read_spilled(&mut self.spill, card) {
            Ok(Some(line)) => {
                self.spill.lines_out = self.spill.lines_out.saturating_add(1);
                Replay::Line(line)
            }
            Ok(None) => Replay::Wait,
            Err(()) => Replay::Lost(self.spill.drop_all()),
        }
    }

    /// Every spilled line has run: said once, and the spill starts afresh.
    pub(in crate::printer) fn spill_done(&mut self, host: &mut Host) {
        if self.spill.pending() == 0 && self.spill.lines_in > 0 {
            let n = self.spill.lines_in;
            let bytes = self.spill.on_card;
            host.say(format_args!(
                "resume: {n} job lines kept on the SD card have run ({bytes} bytes of {SPILL_NAME})"
            ));
            self.spill = Spill::new();
        }
    }
}

/// The next spilled line: from the card up to what was written, then from the stage.
/// `Ok(None)`: nothing readable now; `Err`: the file is unreadable or not ours.
fn read_spilled<D: BlockDevice>(
    sp: &mut Spill,
    card: &mut Card<D>,
) -> Result<Option<ReceivedLine>, ()>
where
    D::Error: core::fmt::Debug,
{
    if sp.chunk.is_empty() && sp.replay_at >= sp.on_card {
        // Everything on the card has run: the stage's first line.
        let Some(end) = sp.stage.iter().position(|&b| b == b'\n') else {
            return Ok(None);
        };
        let line = parse_spilled(sp.stage.get(..end).unwrap_or(&[]));
        let rest = sp.stage.len() - end - 1;
        sp.stage.copy_within(end + 1.., 0);
        sp.stage.truncate(rest);
        return line.map(Some).ok_or(());
    }
    if !sp.chunk.contains(&b'\n') {
        // Refill: the unread bytes start at `replay_at`.
        let mut buf = [0u8; SPILL_CHUNK];
        let want = (sp.on_card.saturating_sub(sp.replay_at) as usize).min(SPILL_CHUNK);
        let n = card
            .spill_read_at(sp.replay_at, buf.get_mut(..want).unwrap_or(&mut []))
            .map_err(|_| ())?;
        if n == 0 {
            return Err(());
        }
        sp.chunk.clear();
        let _ = sp.chunk.extend_from_slice(buf.get(..n).unwrap_or(&[]));
        if !sp.chunk.contains(&b'\n') {
            return Err(());
        }
    }
    let end = sp.chunk.iter().position(|&b| b == b'\n').ok_or(())?;
    let line = parse_spilled(sp.chunk.get(..end).unwrap_or(&[]));
    sp.replay_at = sp.replay_at.saturating_add(end as u32 + 1);
    let rest = sp.chunk.len() - end - 1;
    sp.chunk.copy_within(end + 1.., 0);
    sp.chunk.truncate(rest);
    line.map(Some).ok_or(())
}

/// `[+]<number> <text>` or `[+]- <text>` back into a line.
fn parse_spilled(b: &[u8]) -> Option<ReceivedLine> {
    let (reset, b) = match b.strip_prefix(b"+") {
        Some(rest) => (true, rest),
        None => (false, b),
    };
    let blank = b.iter().position(|&c| c == b' ')?;
    let (head, text) = (b.get(..blank)?, b.get(blank + 1..)?);
    let number = if head == b"-" {
        None
    } else {
        Some(core::str::from_utf8(head).ok()?.parse::<u32>().ok()?)
    };
    if text.len() > SPILL_LINE_MAX {
        return None;
    }
    ReceivedLine::kept(text, number, reset)
}
