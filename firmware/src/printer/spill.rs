//! The parked intake's spill: job lines a host streams into a parked printer, kept on the SD
//! card once the RAM slots ([`super::PARKED_EXTRA`]) are full, and fed back, in order, after
//! the resume. With it a one-line-per-`ok` host (printcore) gets an `ok` every
//! [`super::PARKED_PACE_US`] for as long as the pause lasts, so its console lines (M105, jogs,
//! M602, M524) always get out (docs/frontend.md, "Host rules", rule 5).
//!
//! A spilled line is kept as the host sent it — its text (comments kept as the link kept them)
//! and its line number — one per file line: `<number> <text>\n`, or `- <text>\n` for an
//! unnumbered line. It is interpreted only when it is fed back, through the same line handler
//! as every host line (as an SD job's lines are), so the machine state, the layer detector
//! and the power-cut notes see exactly the stream the host sent, in its order; its `ok` went
//! out when it was taken.
//!
//! Memory: [`SPILL_STAGE`] bytes of lines not yet on the card, a [`SPILL_CHUNK`]-byte read
//! buffer. The card is written by the driver's [`Printer::service_card`] (the executive never
//! blocks on it), in appends of at least [`SPILL_FLUSH`] bytes while parked (an 8-hour pause
//! at one line a second is ≈ 30 000 lines, ≈ 1 MB, ≈ 2 000 appends).
//!
//! Failures lose nothing the card did not lose: lines not yet written stay in RAM and are fed
//! back from there; a failed write stops the spilling (the host waits, with `busy:`, as
//! without a card); a spill file that cannot be read back cancels the job (its lines are
//! gone with the card; the cancel parks the head off the part).

use super::state::Pause;
use super::{Printer, LINE_LEN};
use crate::link::{ReceivedLine, Response, LINE_CAP};
use crate::motion::Realtime;
use crate::storage::sd::{Card, SPILL_NAME};
use core::fmt::Write as _;
use embedded_sdmmc::BlockDevice;
use heapless::{String, Vec};

/// Bytes of spilled lines kept in RAM until the card takes them.
pub const SPILL_STAGE: usize = 1024;
/// While parked the stage is written to the card once it holds this much (after the resume,
/// at once).
pub const SPILL_FLUSH: usize = 512;
/// Read buffer of the replay (a spilled line is at most 11 + [`LINE_CAP`] + 1 bytes).
pub const SPILL_CHUNK: usize = 512;
/// The most a spilled line takes: number, blank, text, line end.
const SPILL_LINE_MAX: usize = 11 + LINE_CAP + 1;
/// Spilled lines fed back per service at most (the command queue bounds it first).
const SPILL_LINES_PER_SERVICE: usize = 64;

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

    /// Forget every line (a cancel: they belong to the dropped job) and delete the file.
    fn drop_all(&mut self) -> u32 {
        let n = self.pending();
        *self = Self::new();
        n
    }
}

impl Printer {
    /// Whether a job line can go to the spill now: a card is mounted, no job is read from it,
    /// no write failed, and the stage has room for the line.
    pub(super) fn spill_room(&self, line: &ReceivedLine) -> bool {
        self.sd_spill_ready()
            && !self.spill.failed
            && self.spill.stage.len() + line.text().len() + 12 <= SPILL_STAGE
    }

    /// Whether the card can hold spilled lines (mounted, not reading a job).
    pub(super) fn spill_possible(&self) -> bool {
        self.sd_spill_ready() && !self.spill.failed
    }

    /// Take a job line into the spill (its `ok` is answered by the caller's rule: here).
    pub(super) fn spill_line(&mut self, line: &ReceivedLine) {
        if self.spill.pending() == 0 {
            self.say(format_args!(
                "pause: job lines from here kept on the SD card ({SPILL_NAME}) until the resume"
            ));
        }
        let mut head: String<12> = String::new();
        let _ = match line.number() {
            Some(n) => write!(head, "{n} "),
            None => head.write_str("- "),
        };
        let s = &mut self.spill.stage;
        // The caller checked the room (`spill_room`).
        let _ = s.extend_from_slice(head.as_bytes());
        let _ = s.extend_from_slice(line.text());
        let _ = s.push(b'\n');
        self.spill.lines_in = self.spill.lines_in.saturating_add(1);
        if line.number().is_some() {
            self.lines.host_numbers = true;
            self.lines.last_line_no = line.number();
        }
        self.lines.job_port = Some(self.link.reply_port());
        self.last_activity_us = self.now_us;
        self.link.respond(Response::Ok);
    }

    /// A cancel drops the spilled lines with the rest of the job.
    pub(super) fn spill_drop(&mut self) {
        let n = self.spill.drop_all();
        if n > 0 {
            self.say(format_args!(
                "cancelled: dropped {n} job lines kept on the SD card"
            ));
        }
    }

    /// The driver's card, from [`Printer::service_card`]: write the stage, delete the file
    /// when asked, feed spilled lines back while the queue has room.
    pub(super) fn service_spill<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        if !self.sd_spill_ready() {
            return;
        }
        if self.spill.remove {
            if self.spill.pending() > 0 {
                // Lines taken since the file was emptied: they are in the stage; delete
                // only when nothing is on the card.
                if self.spill.on_card == 0 {
                    self.spill.remove = false;
                }
            } else if card.spill_remove().is_ok() {
                self.spill.remove = false;
            }
        }
        let parked = matches!(self.pause, Pause::Parked { .. } | Pause::Parking { .. });
        let flush = !self.spill.stage.is_empty()
            && !self.spill.failed
            && !self.spill.remove
            && (self.spill.stage.len() >= SPILL_FLUSH || !parked);
        if flush {
            match card.spill_append(&self.spill.stage) {
                Ok(len) => {
                    if self.spill.on_card == 0 {
                        // A file that could not be deleted: its old bytes are not ours.
                        self.spill.replay_at = len.saturating_sub(self.spill.stage.len() as u32);
                    }
                    self.spill.on_card = len;
                    self.spill.stage.clear();
                }
                Err(e) => {
                    // The file may now hold part of this append: nothing more is appended
                    // (the replay reads the card up to `on_card`, then the stage).
                    self.spill.failed = true;
                    self.say(format_args!(
                        "SD write error ({e}): job lines kept in RAM; the host waits"
                    ));
                }
            }
        }
        self.feed_spill_lines(card);
    }

    /// Whether a spilled line could be handled now: as a host line (queue room, nothing owed,
    /// no cancel parking).
    fn spill_line_room(&self) -> bool {
        !self.is_halted()
            && self.arc.is_none()
            && !self.lines.sync_ok_owed
            && !self.pause.cancelling()
            && self.line_room()
    }

    fn feed_spill_lines<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        for _ in 0..SPILL_LINES_PER_SERVICE {
            if self.spill.pending() == 0 || !self.spill_line_room() {
                break;
            }
            match self.next_spilled(card) {
                Ok(Some(line)) => {
                    self.spill.lines_out = self.spill.lines_out.saturating_add(1);
                    // Its `ok` went out when it was taken: answered as a file line.
                    self.link.answer_file();
                    self.last_activity_us = self.now_us;
                    self.handle_line(&line, false);
                    self.feed_planner();
                }
                Ok(None) => break,
                Err(()) => {
                    let n = self.spill.pending();
                    let mut t: String<LINE_LEN> = String::new();
                    let _ = write!(t, "SD read error: {n} kept job lines lost; cancelling");
                    self.link.notify(Response::Error(&t));
                    let now = self.now_us;
                    self.spill.drop_all();
                    self.request(Realtime::Cancel, now);
                    return;
                }
            }
        }
        if self.spill.pending() == 0 && self.spill.lines_in > 0 {
            let n = self.spill.lines_in;
            self.say(format_args!(
                "resume: {n} job lines kept on the SD card have run"
            ));
            self.spill = Spill::new();
        }
    }

    /// The next spilled line: from the card up to what was written, then from the stage.
    /// `Ok(None)`: nothing readable now; `Err`: the file is unreadable or not ours.
    fn next_spilled<D: BlockDevice>(
        &mut self,
        card: &mut Card<D>,
    ) -> Result<Option<ReceivedLine>, ()>
    where
        D::Error: core::fmt::Debug,
    {
        let sp = &mut self.spill;
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
}

/// `<number> <text>` or `- <text>` back into a line.
fn parse_spilled(b: &[u8]) -> Option<ReceivedLine> {
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
    ReceivedLine::kept(text, number)
}
