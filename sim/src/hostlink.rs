//! The host side of the serial link, modelled on what Pronterface/printcore and OctoPrint do:
//! every job line goes out as `N<n> <text>*<checksum>`, the next line only after the printer's
//! `ok`, `Resend: <n>` rewinds to that line, and realtime requests (pause, resume, ...) are
//! written at once, unnumbered, without waiting for `ok` (printcore's `send_now`).
//!
//! The wire is modelled in both directions at the configured baud rate and bits per byte
//! (115200 baud, 8N1 = 10 bits per byte by default): a chunk written at time `t` arrives when its
//! last byte has been clocked out, after whatever was already on the wire.
//!
//! The host knows nothing of motion; it only sends text and reads lines. What a line *is* (a job
//! line, a line the host inserted for its own pause sequence, a realtime request) is kept in
//! [`Origin`] so the recorder can tell job moves from service moves.

use crate::job::{JobLines, JobReader};
use std::collections::VecDeque;

/// Wire and protocol settings of the host.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkConfig {
    /// Baud rate of the serial line.
    pub baud: u32,
    /// Bits on the wire per byte (8N1: start + 8 data + stop = 10).
    pub bits_per_byte: u32,
    /// Send job lines with line numbers and checksums (printcore and OctoPrint do).
    pub numbered: bool,
    /// Drop comments and blank lines before sending (printcore and OctoPrint do).
    pub strip_comments: bool,
    /// Start the session with `M110 N0` (unnumbered, resetting the printer's line counter; the
    /// job then starts at `N1`). printcore writes `N-1 M110` instead, which the firmware's link
    /// rejects as a bad line number (and then takes `N0` for a duplicate): see docs/sim.md.
    pub reset_line: bool,
    /// The printer answers a realtime line with its own `ok` (the firmware's link does): the
    /// host counts it against that line, so exactly one job line is in flight at a time.
    pub realtime_ok: bool,
}

impl Default for LinkConfig {
    fn default() -> Self {
        Self {
            baud: 115_200,
            bits_per_byte: 10,
            numbered: true,
            strip_comments: true,
            reset_line: true,
            realtime_ok: true,
        }
    }
}

impl LinkConfig {
    /// Time one byte takes on the wire, in nanoseconds.
    pub fn byte_ns(&self) -> u64 {
        (u64::from(self.bits_per_byte) * 1_000_000_000) / u64::from(self.baud.max(1))
    }
}

/// Where a line sent by the host came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// Line `index` (0-based, counting the lines of the job as loaded, comments included).
    Job(usize),
    /// A line the host inserted itself (host-side pause and resume sequences), numbered in
    /// insertion order.
    Service(u32),
    /// Session setup (`M110`).
    Setup,
    /// A realtime request written at once.
    Realtime,
}

/// One line the host has written.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SentLine {
    /// Line number (`N`), or `None` when sent unnumbered.
    pub n: Option<i64>,
    /// The text as it went on the wire, without the newline.
    pub wire: String,
    /// What the line was.
    pub origin: Origin,
    /// Virtual time the host wrote it, µs.
    pub t_us: u64,
}

/// A line the printer sent back, as the host received it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Received {
    /// Arrival time at the host, µs.
    pub t_us: u64,
    /// The line without its newline.
    pub text: String,
}

/// printcore's checksum: XOR of every byte of `N<n> <command>`.
pub fn checksum(prefix: &str) -> u8 {
    prefix.bytes().fold(0u8, |a, b| a ^ b)
}

/// `N<n> <command>*<checksum>` as printcore writes it.
pub fn numbered_line(n: i64, command: &str) -> String {
    let prefix = format!("N{n} {command}");
    let cs = checksum(&prefix);
    format!("{prefix}*{cs}")
}

/// Strip a `;` comment and surrounding blanks, as printcore does before sending.
pub fn strip_comment(line: &str) -> &str {
    let code = match line.find(';') {
        Some(i) => &line[..i],
        None => line,
    };
    code.trim()
}

/// A chunk of bytes travelling on one direction of the wire.
#[derive(Clone, Debug)]
struct Chunk {
    arrive_us: u64,
    bytes: Vec<u8>,
}

/// One direction of a serial line: chunks queue behind each other at the byte rate.
#[derive(Clone, Debug, Default)]
pub struct Wire {
    byte_ns: u64,
    free_ns: u64,
    chunks: VecDeque<Chunk>,
    /// Bytes carried so far.
    pub bytes_total: u64,
}

impl Wire {
    /// An idle wire with the given byte time.
    pub fn new(byte_ns: u64) -> Self {
        Self {
            byte_ns,
            ..Self::default()
        }
    }

    /// Write `bytes` at `now_us`; returns the arrival time of the last byte, µs.
    pub fn write(&mut self, bytes: &[u8], now_us: u64) -> u64 {
        let start_ns = self.free_ns.max(now_us.saturating_mul(1000));
        let end_ns = start_ns + self.byte_ns * bytes.len() as u64;
        self.free_ns = end_ns;
        let arrive_us = end_ns.div_ceil(1000);
        self.bytes_total += bytes.len() as u64;
        self.chunks.push_back(Chunk {
            arrive_us,
            bytes: bytes.to_vec(),
        });
        arrive_us
    }

    /// Arrival time of the next chunk, µs.
    pub fn next_arrival_us(&self) -> Option<u64> {
        self.chunks.front().map(|c| c.arrive_us)
    }

    /// Take the next chunk if it has arrived by `now_us`.
    pub fn take_arrived(&mut self, now_us: u64) -> Option<Vec<u8>> {
        if self.chunks.front().is_some_and(|c| c.arrive_us <= now_us) {
            self.chunks.pop_front().map(|c| c.bytes)
        } else {
            None
        }
    }

    /// Nothing in flight.
    pub fn is_idle(&self) -> bool {
        self.chunks.is_empty()
    }
}

/// A job line the printer refused (`echo:refused: …`).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RefusedLine {
    /// Index of the line in the job as sent (0-based).
    pub index: usize,
    /// The line as sent, without its number and checksum.
    pub text: String,
    /// What the printer said.
    pub reply: String,
}

/// The job lines the printer refused: how many, and the first [`REFUSALS_KEPT`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Refusals {
    /// Job lines refused.
    pub count: u64,
    /// The first ones, in order.
    pub first: Vec<RefusedLine>,
}

/// Refused lines kept with their text ([`Refusals::first`]).
pub const REFUSALS_KEPT: usize = 10;

/// The host: a job to stream with `ok` flow control, plus lines it inserts itself.
#[derive(Debug)]
pub struct Host {
    cfg: LinkConfig,
    /// Lines of the job as loaded (comments included; stripping happens when sending).
    job: JobLines,
    /// Reads the job in order (`None` once it has ended or failed).
    reader: Option<JobReader>,
    /// Index of the line the reader gives next.
    read_at: usize,
    /// The next job line with something to send: its index and text (comments stripped).
    next: Option<(usize, String)>,
    /// Job lines longer than the reader's cap, cut ([`crate::job::MAX_LINE_BYTES`]).
    pub cut_lines: u64,
    /// The line whose `ok` is awaited (a refusal is about it).
    in_flight: Option<(Origin, String)>,
    /// Job lines the printer refused.
    pub refused: Refusals,
    /// Job lines the printer does not know (`echo:Unknown command: …`): start-code macros
    /// (`PRINT_START`, `BED_MESH_CALIBRATE`) that a Klipper host would run and the sim cannot.
    pub unknown: Refusals,
    cursor: usize,
    /// Lines the host sends before continuing the job (its own pause/resume sequences).
    inserts: VecDeque<(String, Origin)>,
    /// While true, no job line goes out (a host-side pause holds the stream).
    hold: bool,
    /// Job line index before which the host stops and sends `inserts_at_mark` (host-split's
    /// "after the current layer").
    stop_before: Option<usize>,
    stop_lines: Vec<(String, Origin)>,
    stop_hold: bool,
    next_n: i64,
    /// The last numbered lines sent ([`HISTORY_LINES`]), indexed by `n - first_n`, for
    /// resends.
    numbered: Vec<SentLine>,
    /// Line number of `numbered[0]`.
    first_n: i64,
    sent_log: Vec<SentLine>,
    resend_from: Option<i64>,
    clear: bool,
    started: bool,
    service_count: u32,
    /// Host → printer.
    pub tx: Wire,
    /// Printer → host.
    pub rx: Wire,
    rx_partial: Vec<u8>,
    /// The last lines received from the printer ([`HISTORY_LINES`]), in order.
    pub received: Vec<Received>,
    /// Count of `ok` lines received.
    pub oks: u64,
    /// Count of `Resend:` requests honoured.
    pub resends: u64,
    /// Lines whose `ok` is still outstanding (0 or 1 with this flow control).
    pub awaiting_ok: bool,
    realtime_oks: u32,
    last_resend: Option<(i64, u32)>,
    /// Set when the host gave up (the same line was asked for again too often), with why.
    pub aborted: Option<String>,
}

/// Lines of each log the host keeps (sent, numbered for resends, received): the newest
/// `HISTORY_LINES` to `2 × HISTORY_LINES`, so memory stays flat with job length (a printer asks
/// to resend one of the last few lines, never one thousands of lines back).
pub const HISTORY_LINES: usize = 4096;

/// Drop the oldest entries of a log once it holds twice `HISTORY_LINES` (amortised O(1) per
/// entry); returns how many were dropped.
fn trim_log<T>(log: &mut Vec<T>) -> usize {
    if log.len() < 2 * HISTORY_LINES {
        return 0;
    }
    let drop = log.len() - HISTORY_LINES;
    log.drain(..drop);
    drop
}

/// Consecutive `Resend:` requests for the same line after which the host gives up (OctoPrint
/// also stops on a resend storm rather than looping forever).
pub const MAX_RESENDS_OF_ONE_LINE: u32 = 8;

impl Host {
    /// A host about to stream `job` (one entry per line of the file). A job file that cannot
    /// be read ends the host at once ([`Self::aborted`] says why).
    pub fn new(cfg: LinkConfig, job: impl Into<JobLines>) -> Self {
        let byte_ns = cfg.byte_ns();
        let job = job.into();
        let (reader, aborted) = match job.reader() {
            Ok(r) => (Some(r), None),
            Err(e) => (None, Some(format!("reading the job: {e}"))),
        };
        let mut h = Self {
            cfg,
            job,
            reader,
            read_at: 0,
            next: None,
            cut_lines: 0,
            in_flight: None,
            refused: Refusals::default(),
            unknown: Refusals::default(),
            cursor: 0,
            inserts: VecDeque::new(),
            hold: false,
            stop_before: None,
            stop_lines: Vec::new(),
            stop_hold: false,
            next_n: 0,
            numbered: Vec::new(),
            first_n: 0,
            sent_log: Vec::new(),
            resend_from: None,
            clear: true,
            started: false,
            service_count: 0,
            tx: Wire::new(byte_ns),
            rx: Wire::new(byte_ns),
            rx_partial: Vec::new(),
            received: Vec::new(),
            oks: 0,
            resends: 0,
            awaiting_ok: false,
            realtime_oks: 0,
            last_resend: None,
            aborted,
        };
        h.fill_next();
        h
    }

    /// Read ahead to the next job line with something to send (comments and blank lines are
    /// skipped as printcore and OctoPrint skip them).
    fn fill_next(&mut self) {
        if self.next.is_some() {
            return;
        }
        let Some(r) = self.reader.as_mut() else {
            return;
        };
        loop {
            match r.next_line() {
                Ok(true) => {
                    let i = self.read_at;
                    self.read_at += 1;
                    let line = r.line();
                    let text = if self.cfg.strip_comments {
                        strip_comment(line)
                    } else {
                        line.trim()
                    };
                    if !text.is_empty() {
                        self.next = Some((i, text.to_string()));
                        self.cut_lines = r.cut_lines();
                        return;
                    }
                }
                Ok(false) => break,
                Err(e) => {
                    self.aborted = Some(format!("reading the job: {e}"));
                    break;
                }
            }
        }
        self.cut_lines = r.cut_lines();
        self.reader = None;
    }

    /// The link settings.
    pub fn config(&self) -> &LinkConfig {
        &self.cfg
    }

    /// The job lines as loaded.
    pub fn job(&self) -> &JobLines {
        &self.job
    }

    /// Index of the next job line the host will send.
    pub fn cursor(&self) -> usize {
        self.cursor
    }

    /// The last lines written ([`HISTORY_LINES`]), in order.
    pub fn sent(&self) -> &[SentLine] {
        &self.sent_log
    }

    /// The origin of numbered line `n`, if the host sent it.
    pub fn origin_of(&self, n: i64) -> Option<Origin> {
        let i = usize::try_from(n - self.first_n).ok()?;
        self.numbered.get(i).map(|l| l.origin)
    }

    /// Origin of the last numbered line written.
    pub fn last_numbered_origin(&self) -> Option<Origin> {
        self.numbered.last().map(|l| l.origin)
    }

    /// All job lines sent, all inserted lines sent, and every `ok` received.
    pub fn done(&self) -> bool {
        if self.aborted.is_some() {
            return self.tx.is_idle();
        }
        self.next_job_line().is_none()
            && self.inserts.is_empty()
            && !self.awaiting_ok
            && self.resend_from.is_none()
            && self.tx.is_idle()
    }

    /// Holding the stream (host-side pause in effect).
    pub fn holding(&self) -> bool {
        self.hold
    }

    /// Stop sending job lines after the current one; queued insert lines still go out.
    pub fn hold_now(&mut self) {
        self.hold = true;
    }

    /// Continue streaming the job after a hold.
    pub fn release(&mut self) {
        self.hold = false;
    }

    /// Queue lines the host sends before the next job line (in order). They are marked
    /// [`Origin::Service`].
    pub fn insert_lines<I: IntoIterator<Item = String>>(&mut self, lines: I) {
        for l in lines {
            let o = Origin::Service(self.service_count);
            self.service_count += 1;
            self.inserts.push_back((l, o));
        }
    }

    /// Before job line `index` goes out, send `lines` and hold the stream (host-split's pause
    /// appended after the current layer). If the cursor is already past `index`, they go out
    /// next.
    pub fn insert_and_hold_before(&mut self, index: usize, lines: Vec<String>) {
        self.insert_before(index, lines, true);
    }

    /// Before job line `index` goes out, send `lines` (marked [`Origin::Service`]); with `hold`
    /// the stream then stops until [`Self::release`].
    pub fn insert_before(&mut self, index: usize, lines: Vec<String>, hold: bool) {
        let mut tagged = Vec::with_capacity(lines.len());
        for l in lines {
            tagged.push((l, Origin::Service(self.service_count)));
            self.service_count += 1;
        }
        if index <= self.next_job_line().unwrap_or(self.job.len()) {
            self.inserts.extend(tagged);
            self.hold |= hold;
        } else {
            self.stop_before = Some(index);
            self.stop_lines = tagged;
            self.stop_hold = hold;
        }
    }

    /// The next job line to go out has reached a pending [`Self::insert_before`] index.
    fn check_stop(&mut self) {
        let next = self.next_job_line().unwrap_or(self.job.len());
        if self.stop_before.is_some_and(|i| next >= i) {
            self.stop_before = None;
            let lines = std::mem::take(&mut self.stop_lines);
            self.inserts.extend(lines);
            self.hold |= self.stop_hold;
        }
    }

    /// The inserted lines (pause sequence) have all been sent and acknowledged.
    pub fn inserts_done(&self) -> bool {
        self.inserts.is_empty() && self.stop_before.is_none() && !self.awaiting_ok
    }

    fn next_job_line(&self) -> Option<usize> {
        self.next.as_ref().map(|(i, _)| *i)
    }

    fn write_line(&mut self, text: &str, origin: Origin, numbered: bool, now_us: u64) {
        let (n, wire) = if numbered {
            let n = self.next_n;
            self.next_n += 1;
            (Some(n), numbered_line(n, text))
        } else {
            (None, text.to_string())
        };
        let mut bytes = wire.clone().into_bytes();
        bytes.push(b'\n');
        self.tx.write(&bytes, now_us);
        let sent = SentLine {
            n,
            wire,
            origin,
            t_us: now_us,
        };
        if origin != Origin::Realtime {
            self.in_flight = Some((origin, text.to_string()));
        }
        if n.is_some() {
            self.numbered.push(sent.clone());
            self.first_n += trim_log(&mut self.numbered) as i64;
        }
        self.sent_log.push(sent);
        trim_log(&mut self.sent_log);
    }

    /// Send the next line if the printer has cleared us to (the `ok` flow control).
    pub fn pump(&mut self, now_us: u64) {
        if !self.clear || self.aborted.is_some() {
            return;
        }
        let numbered = self.cfg.numbered;
        if !self.started {
            self.started = true;
            if self.cfg.reset_line && numbered {
                // `M110 N0`: the printer's last line number is now 0, the job starts at N1.
                self.next_n = 1;
                self.first_n = 1;
                self.write_line("M110 N0", Origin::Setup, false, now_us);
                self.clear = false;
                self.awaiting_ok = true;
                return;
            }
            self.first_n = self.next_n;
        }
        if let Some(n) = self.resend_from {
            let i = usize::try_from(n - self.first_n).ok();
            match i.and_then(|i| self.numbered.get(i).cloned()) {
                Some(line) => {
                    let mut bytes = line.wire.clone().into_bytes();
                    bytes.push(b'\n');
                    self.tx.write(&bytes, now_us);
                    self.resends += 1;
                    // `N<n> <command>*<checksum>`: the command is what a refusal is about.
                    let command = line
                        .wire
                        .split_once(' ')
                        .and_then(|(_, c)| c.rsplit_once('*'))
                        .map_or("", |(c, _)| c);
                    self.in_flight = Some((line.origin, command.to_string()));
                    let next = n + 1;
                    self.resend_from = if next < self.next_n { Some(next) } else { None };
                    self.sent_log.push(SentLine {
                        t_us: now_us,
                        ..line
                    });
                    trim_log(&mut self.sent_log);
                    self.clear = false;
                    self.awaiting_ok = true;
                    return;
                }
                None if n < self.first_n => {
                    // Older than the kept history: say so rather than skip lines.
                    self.aborted = Some(format!(
                        "the printer asked for line {n}, older than the {HISTORY_LINES} lines kept"
                    ));
                    self.resend_from = None;
                    return;
                }
                None => self.resend_from = None,
            }
        }
        if let Some((text, origin)) = self.inserts.pop_front() {
            self.write_line(&text, origin, numbered, now_us);
            self.clear = false;
            self.awaiting_ok = true;
            return;
        }
        self.check_stop();
        if !self.inserts.is_empty() {
            return self.pump(now_us);
        }
        if self.hold {
            return;
        }
        if let Some((i, text)) = self.next.take() {
            self.cursor = i + 1;
            self.write_line(&text, Origin::Job(i), numbered, now_us);
            self.clear = false;
            self.awaiting_ok = true;
            self.fill_next();
        } else {
            self.cursor = self.job.len();
        }
    }

    /// Write a realtime request at once, unnumbered, without waiting for `ok`.
    pub fn send_realtime(&mut self, text: &str, now_us: u64) {
        if self.cfg.realtime_ok {
            self.realtime_oks += 1;
        }
        self.write_line(text, Origin::Realtime, false, now_us);
    }

    /// Write raw bytes at once (control bytes).
    pub fn send_raw(&mut self, bytes: &[u8], now_us: u64) {
        self.tx.write(bytes, now_us);
    }

    /// Bytes the printer wrote at `now_us` go onto the return wire.
    pub fn printer_wrote(&mut self, bytes: &[u8], now_us: u64) {
        if !bytes.is_empty() {
            self.rx.write(bytes, now_us);
        }
    }

    /// Handle every printer line that has arrived by `now_us`; then send what flow control
    /// allows.
    pub fn receive_arrived(&mut self, now_us: u64) {
        while let Some(bytes) = self.rx.take_arrived(now_us) {
            for b in bytes {
                if b == b'\n' {
                    let text = String::from_utf8_lossy(&self.rx_partial)
                        .trim_end_matches('\r')
                        .to_string();
                    self.rx_partial.clear();
                    self.handle_line(text, now_us);
                } else {
                    self.rx_partial.push(b);
                }
            }
        }
        self.pump(now_us);
    }

    fn handle_line(&mut self, text: String, now_us: u64) {
        let lower = text.to_ascii_lowercase();
        if let Some(rest) = lower
            .strip_prefix("resend:")
            .or_else(|| lower.strip_prefix("rs "))
        {
            let digits: String = rest
                .trim()
                .trim_start_matches('n')
                .chars()
                .take_while(|c| c.is_ascii_digit() || *c == '-')
                .collect();
            if let Ok(n) = digits.parse::<i64>() {
                let count = match self.last_resend {
                    Some((m, k)) if m == n => k + 1,
                    _ => 1,
                };
                self.last_resend = Some((n, count));
                if count > MAX_RESENDS_OF_ONE_LINE {
                    let line = usize::try_from(n - self.first_n)
                        .ok()
                        .and_then(|i| self.numbered.get(i))
                        .map(|l| l.wire.clone())
                        .unwrap_or_default();
                    self.aborted = Some(format!(
                        "the printer asked for line {n} {count} times in a row; gave up \
                         (line: {line:?}, last error: {:?})",
                        self.received
                            .iter()
                            .rev()
                            .find(|r| r.text.starts_with("Error"))
                            .map(|r| r.text.clone())
                            .unwrap_or_default()
                    ));
                } else {
                    self.resend_from = Some(n);
                }
            }
        } else if lower.starts_with("echo:refused:") || lower.starts_with("echo:unknown command") {
            // About the line in flight (one at a time with `ok` flow control).
            if let Some((Origin::Job(index), line)) = &self.in_flight {
                let list = if lower.starts_with("echo:refused:") {
                    &mut self.refused
                } else {
                    &mut self.unknown
                };
                list.count += 1;
                if list.first.len() < REFUSALS_KEPT {
                    list.first.push(RefusedLine {
                        index: *index,
                        text: line.clone(),
                        reply: text.clone(),
                    });
                }
            }
        } else if lower.starts_with("ok") {
            self.oks += 1;
            if self.realtime_oks > 0 {
                // The answer to a realtime line (in whichever order the two oks come).
                self.realtime_oks -= 1;
            } else {
                self.clear = true;
                self.awaiting_ok = false;
            }
        }
        self.received.push(Received { t_us: now_us, text });
        trim_log(&mut self.received);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checksum_matches_printcore() {
        // printcore: reduce(xor, map(ord, "N1 G28")).
        let expect = "N1 G28".bytes().fold(0, |a, b| a ^ b);
        assert_eq!(checksum("N1 G28"), expect);
        assert_eq!(numbered_line(1, "G28"), format!("N1 G28*{expect}"));
    }

    #[test]
    fn strips_comments() {
        assert_eq!(strip_comment("G1 X1 ; move"), "G1 X1");
        assert_eq!(strip_comment(";LAYER_CHANGE"), "");
    }

    #[test]
    fn wire_timing_is_ten_bits_per_byte() {
        let mut w = Wire::new(LinkConfig::default().byte_ns());
        let t = w.write(&[0; 1_152], 0);
        // 1152 bytes at 11520 bytes/s = 100 ms.
        assert_eq!(t, 100_000);
        // A second chunk queues behind the first.
        let t2 = w.write(&[0; 10], 50_000);
        assert_eq!(t2, (1162 * 86_805u64).div_ceil(1000));
    }

    fn answer(h: &mut Host, now: u64, text: &str) -> u64 {
        while h.tx.take_arrived(u64::MAX).is_some() {}
        let t = h.rx.write(format!("{text}\n").as_bytes(), now);
        h.receive_arrived(t);
        t
    }

    #[test]
    fn ok_flow_control_and_resend() {
        let job = vec![
            "G28 ; home".into(),
            "".into(),
            ";c".into(),
            "G1 X1".into(),
            "G1 X2".into(),
        ];
        let mut h = Host::new(LinkConfig::default(), job);
        h.pump(0);
        assert_eq!(h.sent().len(), 1);
        assert_eq!(h.sent()[0].wire, "M110 N0");
        // Nothing more until ok.
        h.pump(10);
        assert_eq!(h.sent().len(), 1);
        let t = answer(&mut h, 1000, "ok");
        assert_eq!(h.sent().len(), 2);
        assert_eq!(h.sent()[1].wire, numbered_line(1, "G28"));
        assert_eq!(h.sent()[1].origin, Origin::Job(0));
        let t = answer(&mut h, t, "ok");
        assert_eq!(h.sent()[2].origin, Origin::Job(3));
        assert_eq!(h.sent()[2].n, Some(2));
        // The printer asks for line 2 again.
        let t = answer(&mut h, t, "Resend: 2");
        assert_eq!(h.sent().len(), 3);
        let t = answer(&mut h, t, "ok");
        assert_eq!(h.sent()[3].wire, numbered_line(2, "G1 X1"));
        assert_eq!(h.resends, 1);
        let t = answer(&mut h, t, "ok");
        assert_eq!(h.sent()[4].wire, numbered_line(3, "G1 X2"));
        assert!(!h.done());
        answer(&mut h, t, "ok");
        assert!(h.done());
        assert_eq!(h.origin_of(3), Some(Origin::Job(4)));
    }

    #[test]
    fn gives_up_on_a_resend_storm() {
        let mut h = Host::new(LinkConfig::default(), vec!["G1 X1".into(), "G1 X2".into()]);
        h.pump(0);
        let mut t = answer(&mut h, 0, "ok");
        for _ in 0..MAX_RESENDS_OF_ONE_LINE + 1 {
            t = answer(&mut h, t, "Error:checksum mismatch, Last Line: 0");
            t = answer(&mut h, t, "Resend: 1");
            t = answer(&mut h, t, "ok");
        }
        assert!(h.aborted.is_some());
        assert!(h.done());
        let n = h.sent().len();
        h.pump(t);
        assert_eq!(h.sent().len(), n, "nothing more is sent after giving up");
    }

    #[test]
    fn logs_stay_bounded_on_a_long_job() {
        let n = 5 * HISTORY_LINES;
        let job: Vec<String> = (0..n).map(|i| format!("G1 X{}", i % 100)).collect();
        let mut h = Host::new(LinkConfig::default(), job);
        h.pump(0);
        let mut t = 0;
        for _ in 0..=n {
            t = answer(&mut h, t, "ok");
        }
        assert!(h.done());
        assert_eq!(h.oks as usize, n + 1);
        for len in [h.sent().len(), h.received.len(), h.numbered.len()] {
            assert!((HISTORY_LINES..2 * HISTORY_LINES).contains(&len), "{len}");
        }
        // The newest lines are kept, with their numbers: a resend of a recent line works.
        assert_eq!(h.origin_of(n as i64), Some(Origin::Job(n - 1)));
        assert_eq!(h.origin_of(1), None);
        // Resend from the last-but-one line: it and the last go out again.
        let mut t = answer(&mut h, t, &format!("Resend: {}", n - 1));
        t = answer(&mut h, t, "ok");
        answer(&mut h, t, "ok");
        assert_eq!(h.resends, 2);
        assert!(h.aborted.is_none());
        // One older than the history: the host gives up and says why.
        answer(&mut h, t, "Resend: 2");
        assert!(h.aborted.as_deref().is_some_and(|a| a.contains("older")));
    }

    #[test]
    fn realtime_goes_out_without_waiting() {
        let mut h = Host::new(LinkConfig::default(), vec!["G1 X1".into()]);
        h.pump(0);
        h.send_realtime("M25", 5);
        assert_eq!(h.sent().len(), 2);
        assert_eq!(h.sent()[1].wire, "M25");
        assert_eq!(h.sent()[1].n, None);
    }

    #[test]
    fn insert_and_hold_before_a_line() {
        let job: Vec<String> = (0..5).map(|i| format!("G1 X{i}")).collect();
        let cfg = LinkConfig {
            reset_line: false,
            ..LinkConfig::default()
        };
        let mut h = Host::new(cfg, job);
        h.pump(0);
        h.insert_and_hold_before(2, vec!["M83".into(), "G1 E-2".into()]);
        let mut t = 0;
        for _ in 0..6 {
            t = answer(&mut h, t, "ok");
        }
        let origins: Vec<Origin> = h.sent().iter().map(|l| l.origin).collect();
        assert_eq!(
            origins,
            vec![
                Origin::Job(0),
                Origin::Job(1),
                Origin::Service(0),
                Origin::Service(1)
            ]
        );
        assert!(h.holding());
        assert!(h.inserts_done());
        h.release();
        h.pump(t);
        assert_eq!(h.sent().last().map(|l| l.origin), Some(Origin::Job(2)));
    }
}
