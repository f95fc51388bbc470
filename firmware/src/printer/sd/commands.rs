//! The SD M-codes (M20 list, M21/M22 card, M23/M32 select, M26 seek, M27 status, M27 S
//! reports, M27 C current file) with Marlin's replies (`gcode/sd/M20.cpp` … `M32.cpp`,
//! `sd/cardreader.cpp`). The card is read only.

use super::{short_text, CardRequest, SdFile, SdJob};
use crate::gcode::SdCommand;
use crate::link::{PortId, Response, LINK_RESERVE};
use crate::printer::{Printer, LINE_LEN};
use crate::storage::sd::{Card, CardEntry, CardError, CARD_PATH_CAP, LONG_PATH_CAP};
use core::fmt::Write as _;
use embedded_sdmmc::BlockDevice;
use heapless::String;

/// Free output bytes a port needs before the next M20 entry is written to it (the listing
/// goes out over several service calls when the ring is full; nothing is dropped).
const LIST_ROOM: usize = LINK_RESERVE + 2 * ENTRY_CAP;
/// Longest M20 L line: short path, size, long path.
const ENTRY_CAP: usize = CARD_PATH_CAP + 12 + LONG_PATH_CAP;

impl Printer {
    /// SD commands. Returns true when the `ok` is owed (sent once the card has answered).
    pub(in crate::printer) fn sd_command(&mut self, c: &SdCommand) -> bool {
        let port = self.asking_port();
        let needs_card = !matches!(
            c,
            SdCommand::Seek(_) | SdCommand::AutoReport(_) | SdCommand::CurrentFile
        );
        if needs_card && !self.sd.attached {
            self.host.respond(Response::Echo("No media"));
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
                    self.host
                        .warn(format_args!("SD printing: cancel it first (M524)"));
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
                    SdJob::Selected { .. } => {
                        self.host.warn(format_args!("M26: beyond the file's end"))
                    }
                    SdJob::Printing { .. } => {
                        self.host.warn(format_args!("M26: not while SD printing"))
                    }
                    SdJob::None => {
                        self.host.respond(Response::Echo("No file selected"));
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
                self.host.respond(Response::Echo(&t));
                return false;
            }
        }
        true
    }

    /// M27: `SD printing byte a/b`, or false when no card job runs (the caller then says
    /// `Not SD printing`).
    pub(in crate::printer) fn sd_status(&mut self) -> bool {
        let Some((a, b)) = self.sd_progress() else {
            return false;
        };
        let mut t: String<LINE_LEN> = String::new();
        let _ = write!(t, "SD printing byte {a}/{b}");
        self.host.respond(Response::Plain(&t));
        true
    }

    /// M20: `Begin file list`, `NAME SIZE` (M20 L: `NAME SIZE LONGNAME`) per file, `End file
    /// list`, `ok` (Marlin's `CardReader::ls`). Written a few entries per call while the
    /// port's output ring has room, so a long list is never cut.
    pub(super) fn card_list<D: BlockDevice>(
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
        let room = |p: &Self| port.map_or(usize::MAX / 2, |q| p.host.output_free_on(q));
        if next == 0 {
            if room(self) < LIST_ROOM {
                self.sd.request = Some(CardRequest::List { port, long, next });
                return;
            }
            self.answer_to(port, Response::Plain("Begin file list"));
        }
        // Entries `next..next+batch` go out now (each line at most ENTRY_CAP bytes).
        let batch = (room(self).saturating_sub(LINK_RESERVE) / ENTRY_CAP).min(8);
        let mut written = 0;
        let result = card.for_each_file(|i, e: &CardEntry| {
            if i >= next && written < batch {
                let mut t: String<ENTRY_CAP> = String::new();
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
    pub(super) fn card_open<D: BlockDevice>(
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
                self.select_entry(port, &e, offset.min(e.size));
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
}

impl Printer {
    /// `e` is the selected file, to start at byte `start_at`: Marlin's `File opened: NAME
    /// Size: N` and `File selected` to `port` (M23, M32, and M1000 of a kept SD job).
    pub(super) fn select_entry(&mut self, port: Option<PortId>, e: &CardEntry, start_at: u32) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = write!(t, "File opened: {} Size: {}", file_name(&e.short), e.size);
        self.answer_to(port, Response::Plain(&t));
        self.answer_to(port, Response::Plain("File selected"));
        self.sd.job = SdJob::Selected {
            file: SdFile {
                name: short_text(&e.short),
                size: e.size,
            },
            start_at,
        };
    }
}

/// The file's own name, the last component of its path (what Marlin's `File opened:` shows).
fn file_name(path: &str) -> &str {
    path.bytes()
        .rposition(|b| b == b'/')
        .and_then(|i| path.get(i + 1..))
        .unwrap_or(path)
}
