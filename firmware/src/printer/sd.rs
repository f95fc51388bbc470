//! SD-card printing in the executive: the SD M-codes (Marlin's replies, `gcode/sd/M20.cpp` …
//! `M32.cpp` and `sd/cardreader.cpp`), and the card as a job source.
//!
//! The card itself ([`Card`]) belongs to the driver (the board's SDIO card, the sim's image);
//! the executive keeps what it knows of it and asks for what it needs through
//! [`Printer::service_card`], which the driver calls from its main loop with the card, as it
//! does [`Printer::service_store`] with the flash. A command that needs the card (M20, M21,
//! M22, M23, M32) holds its `ok` and the port's next line until the card has answered, so
//! its replies come in Marlin's order (`Begin file list` … `End file list`, then `ok`).
//!
//! A job from the card is fed line by line, with the host link's own line assembler
//! ([`FileLines`]), into the same line handler a host's lines go through, whenever the command
//! queue has room for a host line: pause (M25/M601 at the layer boundary), a scheduled pause
//! (M761), speed-up and resume behave as for a streamed job, and the slicer's layer comments
//! are always there. File lines are never answered `ok`; what they say goes to every port.
//! The byte offset of each line is known ([`Printer::sd_line_offset`]) for the power-cut
//! record. A host line waiting for room goes first.
//!
//! Fixed memory: one [`SD_CHUNK`]-byte read buffer and the line assembler (≈ 700 bytes).
//!
//! Here: the card's state, the job's lines and the service loop; `sd/commands.rs`: the
//! M-codes' replies; `sd/reopen.rs`: finding a power-cut job's file again (M1000).

mod commands;
mod reopen;

pub(super) use reopen::ReopenError;

use super::{Printer, LINE_LEN};
use crate::link::{FileLine, FileLines, HostAction, PortId, Response};
use crate::storage::sd::{Card, CardError, LONG_NAME_CAP};
use core::fmt::Write as _;
use embedded_sdmmc::BlockDevice;
use heapless::String;

/// Bytes read from the card at a time (one block).
pub const SD_CHUNK: usize = 512;
/// File lines handled per [`Printer::service_card`] call at most (the queue bounds it first).
pub const SD_LINES_PER_SERVICE: usize = 64;

/// The file selected or printing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct SdFile {
    /// Its short name as the card lists it.
    name: String<LONG_NAME_CAP>,
    /// Size, bytes.
    size: u32,
}

/// Where the card's job is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum SdJob {
    /// No file selected.
    None,
    /// M23 opened a file; M24 starts it at `start_at` (M26 moves it).
    Selected { file: SdFile, start_at: u32 },
    /// Lines are fed from the file. `read_at`: next byte to read from the card; `eof`: every
    /// line has been handed to the executive (the job ends when the queue has run dry).
    Printing {
        file: SdFile,
        read_at: u32,
        eof: bool,
    },
}

/// A command waiting for the card (its `ok` is owed to `port`; `None`: from a file, no `ok`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum CardRequest {
    /// M21, or the first service after power-up (`port` None: announce to every port).
    Mount { port: Option<PortId> },
    /// M22.
    Release { port: Option<PortId> },
    /// M20: the next entry to write is `next`.
    List {
        port: Option<PortId>,
        long: bool,
        next: usize,
    },
    /// M23 / M32 / [`Printer::start_sd_job`]: open `name`, then start at `offset` when
    /// `start`.
    Open {
        port: Option<PortId>,
        name: String<LONG_NAME_CAP>,
        start: bool,
        offset: u32,
    },
    /// M1000 of a job kept from the card: open the kept file and continue it (`recovery.rs`).
    Resume { port: Option<PortId> },
}

/// The executive's side of the card. See the module documentation.
#[derive(Clone, Debug)]
pub(super) struct SdLink {
    /// A driver services a card (else every SD command answers "No media").
    attached: bool,
    /// The card's volume is open, as far as the executive knows.
    mounted: bool,
    /// M22 released the card (the user may take it out): nothing mounts it but M21.
    released: bool,
    request: Option<CardRequest>,
    job: SdJob,
    lines: FileLines,
    /// Offset of the first byte of the line being assembled.
    line_start: u32,
    chunk: [u8; SD_CHUNK],
    chunk_len: usize,
    chunk_pos: usize,
    /// File offset of `chunk[0]`.
    chunk_at: u32,
    /// Offset of the file line being handled (inside `handle_line`).
    line_origin: Option<u32>,
    /// The card's job was cancelled and nothing has moved since: the printer reports
    /// `Cancelled` as after a host job's cancel (the host's own lines are not discarded: the
    /// host's stream was not the job).
    cancelled: bool,
    /// `M27 S<s>` period, µs (0 = off), and the next report time.
    auto_report_us: u64,
    next_report_us: u64,
}

impl SdLink {
    pub(super) const fn new() -> Self {
        Self {
            attached: false,
            mounted: false,
            released: false,
            request: None,
            job: SdJob::None,
            lines: FileLines::new(),
            line_start: 0,
            chunk: [0; SD_CHUNK],
            chunk_len: 0,
            chunk_pos: 0,
            chunk_at: 0,
            line_origin: None,
            cancelled: false,
            auto_report_us: 0,
            next_report_us: 0,
        }
    }

    /// Read from `offset` on: forget the buffered bytes and the line being assembled.
    fn seek(&mut self, offset: u32) {
        self.lines.clear();
        self.line_start = offset;
        self.chunk_len = 0;
        self.chunk_pos = 0;
        self.chunk_at = offset;
    }

    /// Bytes of the printing file handed to the line assembler.
    fn consumed(&self) -> u32 {
        self.chunk_at.saturating_add(self.chunk_pos as u32)
    }
}

fn short_text(s: &str) -> String<LONG_NAME_CAP> {
    let mut t = String::new();
    for c in s.chars() {
        if t.push(c).is_err() {
            break;
        }
    }
    t
}

impl Printer {
    /// A driver has a card slot: SD commands wait for [`Printer::service_card`] from now on,
    /// and the card is mounted at its first service (as Marlin mounts at boot).
    pub fn attach_card(&mut self) {
        if !self.sd.attached {
            self.sd.attached = true;
            self.sd.request = Some(CardRequest::Mount { port: None });
        }
    }

    /// Offset in the SD file of the line being handled, while a file line is handled (for
    /// the power-cut record: the first byte of the line that produced a layer boundary).
    pub fn sd_line_offset(&self) -> Option<u32> {
        self.sd.line_origin
    }

    /// The file selected or printing from the card (its short name).
    pub fn sd_file_path(&self) -> Option<&str> {
        match &self.sd.job {
            SdJob::None => None,
            SdJob::Selected { file, .. } | SdJob::Printing { file, .. } => Some(&file.name),
        }
    }

    /// Whether a job is being read from the card (until its last line has run).
    pub fn sd_printing(&self) -> bool {
        matches!(self.sd.job, SdJob::Printing { .. })
    }

    /// `(bytes read, file size)` of the card's job, as M27 reports it.
    pub fn sd_progress(&self) -> Option<(u32, u32)> {
        match &self.sd.job {
            SdJob::Printing { file, eof, .. } => {
                Some((if *eof { file.size } else { self.sd.consumed() }, file.size))
            }
            _ => None,
        }
    }

    /// Open `path` on the card and print it from byte `offset` (the offset is a line's first
    /// byte, as [`Printer::sd_line_offset`] gave it). M1000 does this for a kept SD job, after
    /// checking the file (see `recovery.rs`).
    pub fn start_sd_job(&mut self, path: &str, offset: u32) {
        self.sd.request = Some(CardRequest::Open {
            port: None,
            name: short_text(path),
            start: true,
            offset,
        });
    }

    /// Whether the card can take the parked intake's spill: mounted and not read for a job.
    pub(super) fn sd_spill_ready(&self) -> bool {
        self.sd.attached && self.sd.mounted && !self.sd_printing()
    }

    /// See [`SdLink::cancelled`].
    pub(super) fn sd_cancelled(&self) -> bool {
        self.sd.cancelled
    }

    /// Whether a command waits for the card (the board brings a lost card up again first;
    /// the port's next host line waits too).
    pub fn sd_request_pending(&self) -> bool {
        self.sd.request.is_some()
    }

    /// The port to answer later: none for a file line (no `ok`).
    fn asking_port(&self) -> Option<PortId> {
        if self.sd.line_origin.is_some() {
            None
        } else {
            Some(self.host.reply_port())
        }
    }

    /// M24 (hook in `request`): starts the selected file when no pause is to be resumed.
    /// Returns whether it did.
    pub(super) fn sd_start_on_resume(&mut self) -> bool {
        if !self.pause.running() {
            return false;
        }
        let SdJob::Selected { file, start_at } = &self.sd.job else {
            return false;
        };
        let (file, at) = (file.clone(), *start_at);
        self.sd.seek(at);
        self.sd.job = SdJob::Printing {
            file: file.clone(),
            read_at: at,
            eof: false,
        };
        self.sd.next_report_us = self.now_us.saturating_add(self.sd.auto_report_us);
        self.intake.forget_cancel();
        self.sd.cancelled = false;
        // A card job is a job of its own: its layers count from 1 (or from the kept layer).
        self.job_start();
        let mut t: String<{ LINE_LEN + LONG_NAME_CAP }> = String::new();
        let _ = write!(t, "SD printing {} from byte {at}", file.name);
        self.host
            .notify(Response::Action(HostAction::Notification, &t));
        true
    }

    /// M524 (hook in `request`): the card's job ends with the cancel. Returns whether one ran.
    pub(super) fn sd_cancel(&mut self) -> bool {
        if !self.sd_printing() {
            return false;
        }
        self.sd.job = SdJob::None;
        self.sd.seek(0);
        self.sd.cancelled = true;
        self.host.notify(Response::Action(
            HostAction::Notification,
            "SD print cancelled",
        ));
        true
    }

    /// The driver's card: answer the commands that wait for it, feed the job's lines while
    /// the queue has room, end the job when its last line has run, and send the `M27 S`
    /// reports. Call it from the main loop (each pass: it does a bounded amount of work).
    pub fn service_card<D: BlockDevice>(&mut self, card: &mut Card<D>, now_us: u64)
    where
        D::Error: core::fmt::Debug,
    {
        self.set_now(now_us);
        self.sd.attached = true;
        if self.pause.halted() {
            return;
        }
        if self.sd.cancelled && self.pause.running() && self.has_work() {
            // Something new runs (the cancel's own stop and park are not `Run`).
            self.sd.cancelled = false;
        }
        self.card_request(card);
        self.service_spill(card);
        self.feed_card_lines(card);
        self.sd_finish(card);
        self.sd_auto_report();
        self.update_state_record();
    }

    /// Answer a port (None: every port).
    pub(super) fn answer_to(&mut self, port: Option<PortId>, r: Response<'_>) {
        match port {
            Some(p) => {
                self.host.respond_on(p, r);
            }
            None => {
                if !matches!(r, Response::Ok) {
                    self.host.notify(r);
                }
            }
        }
    }

    fn card_request<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        let Some(req) = self.sd.request.take() else {
            return;
        };
        if let CardRequest::Mount { port: Some(port) } | CardRequest::Release { port: Some(port) } =
            req
        {
            if self.intake.spilled() > 0 {
                // The card holds job lines the host was told were taken.
                let n = self.intake.spilled();
                self.sd.request = None;
                let mut t: String<LINE_LEN> = String::new();
                let _ = write!(
                    t,
                    "refused: the SD card holds {n} job lines of the paused job"
                );
                self.answer_to(Some(port), Response::Echo(&t));
                self.answer_to(Some(port), Response::Ok);
                return;
            }
        }
        match req {
            CardRequest::Mount { port } => {
                self.sd_drop_job(card);
                self.sd.released = false;
                match card.mount() {
                    Ok(()) => {
                        self.sd.mounted = true;
                        self.answer_to(port, Response::Echo("SD card ok"));
                    }
                    Err(e) => {
                        self.sd.mounted = false;
                        let mut t: String<LINE_LEN> = String::new();
                        let _ = write!(t, "SD init fail ({e})");
                        self.answer_to(port, Response::Echo(&t));
                    }
                }
                self.answer_to(port, Response::Ok);
            }
            CardRequest::Release { port } => {
                self.sd_drop_job(card);
                card.release();
                self.sd.mounted = false;
                self.sd.released = true;
                self.answer_to(port, Response::Echo("SD card released"));
                self.answer_to(port, Response::Ok);
            }
            CardRequest::List { port, long, next } => self.card_list(card, port, long, next),
            CardRequest::Open {
                port,
                name,
                start,
                offset,
            } => self.card_open(card, port, &name, start, offset),
            CardRequest::Resume { port } => self.resume_sd_job(card, port),
        }
    }

    /// The card's job is forgotten (M21 again, M22): lines already queued still run.
    fn sd_drop_job<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        if self.sd_printing() {
            self.host
                .say(format_args!("SD print stopped: card released"));
        }
        self.sd.job = SdJob::None;
        card.close();
    }

    /// Whether a file line could be handled now: as a host line (queue room, nothing owed,
    /// no cancel parking), and no host line waiting for room.
    fn file_line_room(&self) -> bool {
        !self.pause.halted()
            && !self.intake.cutting_arc()
            && !self.intake.sync_owed()
            && !self.intake.has_held_line()
            && !self.pause.state().cancelling()
            && self.sd.request.is_none()
            && self.intake.line_room(self.pause.state())
    }

    fn feed_card_lines<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        for _ in 0..SD_LINES_PER_SERVICE {
            if !matches!(self.sd.job, SdJob::Printing { eof: false, .. }) || !self.file_line_room()
            {
                return;
            }
            match self.next_file_line(card) {
                Ok(Some((line, at))) => self.handle_file_line(line, at),
                Ok(None) => {}
                Err(e) => {
                    let mut t: String<LINE_LEN> = String::new();
                    let _ = write!(t, "SD read error ({e}): print stopped");
                    self.host.notify(Response::Echo(&t));
                    self.sd.job = SdJob::None;
                    card.close();
                    return;
                }
            }
        }
    }

    /// The next complete line of the file and the offset of its first byte; `None` when the
    /// file ended (the job's `eof` is then set).
    fn next_file_line<D: BlockDevice>(
        &mut self,
        card: &mut Card<D>,
    ) -> Result<Option<(FileLine, u32)>, CardError>
    where
        D::Error: core::fmt::Debug,
    {
        loop {
            if self.sd.chunk_pos >= self.sd.chunk_len {
                let SdJob::Printing { file, read_at, eof } = &mut self.sd.job else {
                    return Ok(None);
                };
                let n = if *read_at < file.size {
                    card.read_at(*read_at, &mut self.sd.chunk)?
                } else {
                    0
                };
                if n == 0 {
                    // The end: the last line may have no line end.
                    *eof = true;
                    let start = self.sd.line_start;
                    return Ok(self.sd.lines.finish().map(|l| (l, start)));
                }
                self.sd.chunk_at = *read_at;
                self.sd.chunk_len = n.min(SD_CHUNK);
                self.sd.chunk_pos = 0;
                *read_at = read_at.saturating_add(n as u32);
            }
            let Some(&b) = self.sd.chunk.get(self.sd.chunk_pos) else {
                self.sd.chunk_len = 0;
                continue;
            };
            self.sd.chunk_pos += 1;
            let start = self.sd.line_start;
            let line = self.sd.lines.push(b);
            if FileLines::is_line_end(b) {
                self.sd.line_start = self.sd.consumed();
            }
            if let Some(l) = line {
                return Ok(Some((l, start)));
            }
        }
    }

    fn handle_file_line(&mut self, line: FileLine, at: u32) {
        self.host.answer_file();
        self.intake.touch(self.now_us);
        match line {
            FileLine::Line(l) => {
                self.sd.line_origin = Some(at);
                self.handle_line(&l, false);
                self.sd.line_origin = None;
                self.feed_planner();
            }
            FileLine::Realtime(rt) => {
                let now = self.now_us;
                self.request(rt, now);
            }
            FileLine::TooLong => self.host.say(format_args!(
                "Line too long (max 128 bytes), ignored (SD byte {at})"
            )),
        }
    }

    /// The job ends when its last line has run: `Done printing file` (Marlin's
    /// `STR_FILE_PRINTED`), and the file is closed.
    fn sd_finish<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        let done = matches!(self.sd.job, SdJob::Printing { eof: true, .. })
            && self.pause.running()
            && !self.has_work()
            && !self.intake.cutting_arc();
        if done {
            self.sd.job = SdJob::None;
            card.close();
            self.host.notify(Response::Plain("Done printing file"));
            self.host.notify(Response::Action(
                HostAction::Notification,
                "Done printing file",
            ));
        }
    }

    /// `M27 S<s>`: `SD printing byte a/b` every s seconds while a card job runs.
    fn sd_auto_report(&mut self) {
        if self.sd.auto_report_us == 0 || self.now_us < self.sd.next_report_us {
            return;
        }
        self.sd.next_report_us = self.now_us.saturating_add(self.sd.auto_report_us);
        if let Some((a, b)) = self.sd_progress() {
            let mut t: String<LINE_LEN> = String::new();
            let _ = write!(t, "SD printing byte {a}/{b}");
            self.host.notify(Response::Plain(&t));
        }
    }
}
