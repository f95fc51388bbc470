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

use super::{Printer, LINE_LEN};
use crate::gcode::SdCommand;
use crate::link::{FileLine, FileLines, HostAction, PortId, Response, LINK_RESERVE};
use crate::storage::sd::{Card, CardEntry, CardError, LONG_NAME_CAP};
use core::fmt::Write as _;
use embedded_sdmmc::BlockDevice;
use heapless::String;

/// Bytes read from the card at a time (one block).
pub const SD_CHUNK: usize = 512;
/// File lines handled per [`Printer::service_card`] call at most (the queue bounds it first).
pub const SD_LINES_PER_SERVICE: usize = 64;
/// Free output bytes a port needs before the next M20 entry is written to it (the listing
/// goes out over several service calls when the ring is full; nothing is dropped).
const LIST_ROOM: usize = LINK_RESERVE + 2 * LONG_NAME_CAP;

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

/// Why a kept SD job cannot continue from its offset (M1000).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ReopenError {
    /// The card or the file could not be had.
    Card(CardError),
    /// The file's size is not the kept one, or the offset is not the first byte of a line:
    /// not the file that was printing.
    Changed { size: u32 },
}

impl core::fmt::Display for ReopenError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ReopenError::Card(CardError::NoCard) => f.write_str("No media"),
            ReopenError::Card(e) => write!(f, "open failed ({e})"),
            ReopenError::Changed { size } => write!(
                f,
                "the file changed (now {size} bytes, or the kept offset is not a line start)"
            ),
        }
    }
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

    /// A driver services a card slot.
    pub(super) fn card_attached(&self) -> bool {
        self.sd.attached
    }

    /// M1000 asks for the card (its `ok` waits for the answer; see `recovery.rs`).
    pub(super) fn request_card_resume(&mut self) {
        let port = self.asking_port();
        self.sd.request = Some(CardRequest::Resume { port });
    }

    /// Select `name` to start at `offset` (a kept job's file, M1000): mounted when not yet
    /// (power-up), the file checked to be of `size` bytes and the offset to be the first byte
    /// of a line in it (byte 0, or the byte before it a line end), so a file replaced since the
    /// power cut is not fed from the middle of a line. `File opened` / `File selected` go to
    /// `port` as for M23.
    pub(super) fn sd_select_at<D: BlockDevice>(
        &mut self,
        card: &mut Card<D>,
        port: Option<PortId>,
        name: &str,
        offset: u32,
        size: u32,
    ) -> Result<(), ReopenError>
    where
        D::Error: core::fmt::Debug,
    {
        self.sd.job = SdJob::None;
        if !self.sd.mounted {
            // Power-up, or a card inserted or released (M22) since: mount it now.
            self.sd.mounted = card.mount().is_ok();
            if self.sd.mounted {
                self.sd.released = false;
            }
        }
        if !self.sd.mounted {
            return Err(ReopenError::Card(CardError::NoCard));
        }
        let e = card.open(name).map_err(ReopenError::Card)?;
        let line_start = match offset.checked_sub(1) {
            _ if e.size != size => false,
            None => true,
            Some(before) if offset <= e.size => {
                let mut b = [0u8; 1];
                let n = card.read_at(before, &mut b).map_err(ReopenError::Card)?;
                n == 1 && FileLines::is_line_end(b[0])
            }
            Some(_) => false,
        };
        if !line_start {
            card.close();
            return Err(ReopenError::Changed { size: e.size });
        }
        let mut t: String<LINE_LEN> = String::new();
        let _ = write!(t, "File opened: {} Size: {}", e.short, e.size);
        self.answer_to(port, Response::Plain(&t));
        self.answer_to(port, Response::Plain("File selected"));
        self.sd.job = SdJob::Selected {
            file: SdFile {
                name: short_text(&e.short),
                size: e.size,
            },
            start_at: offset,
        };
        Ok(())
    }

    /// Forget the selected file (M1000 refused after [`Printer::sd_select_at`]).
    pub(super) fn sd_unselect<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        if !self.sd_printing() {
            self.sd.job = SdJob::None;
            card.close();
        }
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
            Some(self.link.reply_port())
        }
    }

    /// SD commands. Returns true when the `ok` is owed (sent once the card has answered).
    pub(super) fn sd_command(&mut self, c: &SdCommand) -> bool {
        let port = self.asking_port();
        let needs_card = !matches!(
            c,
            SdCommand::Seek(_) | SdCommand::AutoReport(_) | SdCommand::CurrentFile
        );
        if needs_card && !self.sd.attached {
            self.link.respond(Response::Echo("No media"));
            return false;
        }
        match c {
            SdCommand::Init => self.sd.request = Some(CardRequest::Mount { port }),
            SdCommand::Release => self.sd.request = Some(CardRequest::Release { port }),
            SdCommand::List { long } => {
                self.sd.request = Some(CardRequest::List {
                    port,
                    long: *long,
                    next: 0,
                })
            }
            SdCommand::Select(name) | SdCommand::SelectAndStart(name) => {
                if self.sd_printing() {
                    self.warn(format_args!("SD printing: cancel it first (M524)"));
                    return false;
                }
                self.sd.request = Some(CardRequest::Open {
                    port,
                    name: short_text(name),
                    start: matches!(c, SdCommand::SelectAndStart(_)),
                    offset: 0,
                });
            }
            SdCommand::Seek(s) => {
                match &mut self.sd.job {
                    SdJob::Selected { file, start_at } if *s <= file.size => *start_at = *s,
                    SdJob::Selected { .. } => self.warn(format_args!("M26: beyond the file's end")),
                    SdJob::Printing { .. } => self.warn(format_args!("M26: not while SD printing")),
                    SdJob::None => {
                        self.link.respond(Response::Echo("No file selected"));
                    }
                }
                return false;
            }
            SdCommand::AutoReport(s) => {
                self.sd.auto_report_us = u64::from(*s) * 1_000_000;
                self.sd.next_report_us = self.now_us.saturating_add(self.sd.auto_report_us);
                return false;
            }
            SdCommand::CurrentFile => {
                let mut t: String<LINE_LEN> = String::new();
                match self.sd_file_path() {
                    Some(n) => {
                        let _ = write!(t, "Current file: {n}");
                    }
                    None => {
                        let _ = t.push_str("Current file: (no file)");
                    }
                }
                self.link.respond(Response::Echo(&t));
                return false;
            }
        }
        true
    }

    /// M27: `SD printing byte a/b`, or false when no card job runs (the caller then says
    /// `Not SD printing`).
    pub(super) fn sd_status(&mut self) -> bool {
        let Some((a, b)) = self.sd_progress() else {
            return false;
        };
        let mut t: String<LINE_LEN> = String::new();
        let _ = write!(t, "SD printing byte {a}/{b}");
        self.link.respond(Response::Plain(&t));
        true
    }

    /// M24 (hook in `request`): starts the selected file when no pause is to be resumed.
    /// Returns whether it did.
    pub(super) fn sd_start_on_resume(&mut self) -> bool {
        if !matches!(self.pause, super::state::Pause::Run) {
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
        self.lines.after_cancel = None;
        self.sd.cancelled = false;
        let mut t: String<LINE_LEN> = String::new();
        let _ = write!(t, "SD printing {} from byte {at}", file.name);
        self.link
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
        self.link.notify(Response::Action(
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
        if self.is_halted() {
            return;
        }
        if self.sd.cancelled && matches!(self.pause, super::state::Pause::Run) && self.has_work() {
            // Something new runs (the cancel's own stop and park are not `Run`).
            self.sd.cancelled = false;
        }
        self.card_request(card);
        self.feed_card_lines(card);
        self.sd_finish(card);
        self.sd_auto_report();
        self.update_state_record();
    }

    /// Answer a port (None: every port).
    pub(super) fn answer_to(&mut self, port: Option<PortId>, r: Response<'_>) {
        match port {
            Some(p) => {
                self.link.respond_on(p, r);
            }
            None => {
                if !matches!(r, Response::Ok) {
                    self.link.notify(r);
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

    /// M20: `Begin file list`, `NAME SIZE` (M20 L: `NAME SIZE LONGNAME`) per file, `End file
    /// list`, `ok` (Marlin's `CardReader::ls`). Written a few entries per call while the
    /// port's output ring has room, so a long list is never cut.
    fn card_list<D: BlockDevice>(
        &mut self,
        card: &mut Card<D>,
        port: Option<PortId>,
        long: bool,
        next: usize,
    ) where
        D::Error: core::fmt::Debug,
    {
        if !self.sd.mounted {
            self.answer_to(port, Response::Echo("No media"));
            self.answer_to(port, Response::Ok);
            return;
        }
        // A list for every port (M20 in a file) does not wait for room: a port nobody reads
        // must not stall the card; what does not fit is dropped there (and counted).
        let room = |p: &Self| port.map_or(usize::MAX / 2, |q| p.link.output_free_on(q));
        if next == 0 {
            if room(self) < LIST_ROOM {
                self.sd.request = Some(CardRequest::List { port, long, next });
                return;
            }
            self.answer_to(port, Response::Plain("Begin file list"));
        }
        // Entries `next..next+batch` go out now (each line at most ≈ 130 bytes).
        let batch = (room(self).saturating_sub(LINK_RESERVE) / (LONG_NAME_CAP + 32)).min(8);
        let mut written = 0;
        let result = card.for_each_file(|i, e: &CardEntry| {
            if i >= next && written < batch {
                let mut t: String<{ LONG_NAME_CAP + 32 }> = String::new();
                let _ = write!(t, "{} {}", e.short, e.size);
                if let (true, Some(l)) = (long, &e.long) {
                    let _ = write!(t, " {l}");
                }
                self.answer_to(port, Response::Plain(&t));
                written += 1;
            }
        });
        match result {
            Ok(total) if next + written < total => {
                self.sd.request = Some(CardRequest::List {
                    port,
                    long,
                    next: next + written,
                });
            }
            Ok(_) => {
                self.answer_to(port, Response::Plain("End file list"));
                self.answer_to(port, Response::Ok);
            }
            Err(e) => {
                let mut t: String<LINE_LEN> = String::new();
                let _ = write!(t, "SD read error ({e})");
                self.answer_to(port, Response::Echo(&t));
                self.answer_to(port, Response::Plain("End file list"));
                self.answer_to(port, Response::Ok);
            }
        }
    }

    /// M23/M32: `File opened: NAME Size: N` and `File selected`, or `open failed, File:
    /// NAME.` (Marlin's `CardReader::openFileRead`).
    fn card_open<D: BlockDevice>(
        &mut self,
        card: &mut Card<D>,
        port: Option<PortId>,
        name: &str,
        start: bool,
        offset: u32,
    ) where
        D::Error: core::fmt::Debug,
    {
        if self.sd_printing() {
            self.answer_to(
                port,
                Response::Echo("refused: SD printing: cancel it first (M524)"),
            );
            self.answer_to(port, Response::Ok);
            return;
        }
        self.sd.job = SdJob::None;
        if !self.sd.mounted && !self.sd.released {
            // Not mounted yet (a power-cut resume right after power-up, a card inserted
            // since): try once.
            self.sd.mounted = card.mount().is_ok();
        }
        let opened = if self.sd.mounted {
            card.open(name)
        } else {
            Err(CardError::NoCard)
        };
        match opened {
            Ok(e) => {
                let mut t: String<LINE_LEN> = String::new();
                let _ = write!(t, "File opened: {} Size: {}", e.short, e.size);
                self.answer_to(port, Response::Plain(&t));
                self.answer_to(port, Response::Plain("File selected"));
                self.sd.job = SdJob::Selected {
                    file: SdFile {
                        name: short_text(&e.short),
                        size: e.size,
                    },
                    start_at: offset.min(e.size),
                };
                if start {
                    self.sd_start_on_resume();
                }
            }
            Err(CardError::NoCard) => self.answer_to(port, Response::Echo("No media")),
            Err(_) => {
                let mut t: String<LINE_LEN> = String::new();
                let _ = write!(t, "open failed, File: {name}.");
                self.answer_to(port, Response::Plain(&t));
            }
        }
        self.answer_to(port, Response::Ok);
    }

    /// The card's job is forgotten (M21 again, M22): lines already queued still run.
    fn sd_drop_job<D: BlockDevice>(&mut self, card: &mut Card<D>)
    where
        D::Error: core::fmt::Debug,
    {
        if self.sd_printing() {
            self.say(format_args!("SD print stopped: card released"));
        }
        self.sd.job = SdJob::None;
        card.close();
    }

    /// Whether a file line could be handled now: as a host line (queue room, nothing owed,
    /// no cancel parking), and no host line waiting for room.
    fn file_line_room(&self) -> bool {
        !self.is_halted()
            && self.arc.is_none()
            && !self.lines.sync_ok_owed
            && self.lines.held_line.is_none()
            && !self.pause.cancelling()
            && self.sd.request.is_none()
            && self.line_room()
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
                    self.link.notify(Response::Echo(&t));
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
        self.link.answer_file();
        self.last_activity_us = self.now_us;
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
            FileLine::TooLong => self.say(format_args!(
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
            && matches!(self.pause, super::state::Pause::Run)
            && !self.has_work()
            && self.arc.is_none();
        if done {
            self.sd.job = SdJob::None;
            card.close();
            self.link.notify(Response::Plain("Done printing file"));
            self.link.notify(Response::Action(
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
            self.link.notify(Response::Plain(&t));
        }
    }
}
