//! The emergency scan: `M112`, `M108` and `M410` (and their control bytes) seen in bytes the
//! link has not taken yet, as Marlin's emergency parser sees them as they arrive
//! (`EmergencyParser::update`, called for every byte entering the receive ring).
//!
//! Flow control keeps bytes the executive has no room for with the driver (the pty, the USB
//! endpoint, the driver's hold buffer), and [`super::HostLink::receive`] is offered them again
//! and again until it takes them. The scan reads on through what is offered, up to
//! [`SCAN_WINDOW`] bytes past the last byte taken, without taking it: every byte is scanned
//! exactly once, in order, before it is taken (the link keeps how far it has scanned past the
//! taken point; the driver's contract is to offer the bytes it did not take again, first).
//!
//! A line is judged by the scan when it is at most [`SCAN_LINE`] bytes long (every spelling of
//! the three, numbered and checksummed, is far shorter): it is checked exactly as the link
//! checks it when it takes it (the same assembler and classifier), so a line with a wrong
//! checksum does not act (unlike Marlin's parser, which ignores checksums and acts on `M1125`).
//! A numbered line acts once: the same line resent after a `Resend:` does not act again.
//!
//! Each line end and each control byte is an *event*, counted alike by the scan and by the
//! link's taking path; the events the scan judged are queued in [`Scan::decided`], and when the
//! taking path reaches one it does not act on it again (it still answers the line: line
//! number, `ok`). Lines the scan did not judge (longer ones) act when they are taken, as before.

use super::assemble::Assembler;
use super::classify::{classify, Verdict};
use crate::motion::Realtime;
use heapless::{Deque, Vec};

/// How far past the last byte taken the scan reads, bytes (it fits the scan's `u16`): the bound on how much a host may
/// have written ahead of its `ok`s and still have an `M112` act at once (docs/frontend.md,
/// "M112 finds its way in"). What a driver holds is the other bound: the scan sees only the
/// bytes it is offered.
pub const SCAN_WINDOW: usize = 4096;
const _: () = assert!(SCAN_WINDOW <= u16::MAX as usize);

/// Longest line the scan judges, bytes (line number, command, checksum, a short comment):
/// `N2147483647 M410*123` is 20.
pub const SCAN_LINE: usize = 48;

/// Events judged ahead and not yet taken. Beyond this many the scan waits (a host writing
/// more than four emergency lines ahead of its `ok`s).
const DECIDED_CAP: usize = 4;

/// Numbered emergency lines remembered as acted (a host resends a few lines at most).
const ACTED_KEPT: usize = 4;

/// The requests the scan acts on ahead of the taking path (Marlin's emergency parser's set).
pub(super) const fn is_emergency(rt: Realtime) -> bool {
    matches!(
        rt,
        Realtime::EmergencyStop | Realtime::QuickStop | Realtime::BreakWait
    )
}

/// What the scan found at an event that it judges.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Judged {
    /// Act on this request now (the line's number, if it has one).
    Act(Realtime, Option<u32>),
    /// An emergency line seen before (resent after a `Resend:`): no second action.
    Again,
}

/// The scan's state for one port.
#[derive(Clone, Debug)]
pub(super) struct Scan {
    /// Bytes past the taken point already scanned (offered in an earlier call; at most
    /// [`SCAN_WINDOW`]).
    pub(super) ahead: u16,
    /// The first of those bytes, to notice a driver that offers other bytes than the ones it
    /// did not get taken (then the scan starts again from the taken point); `None` when the
    /// last offer ended at the taken point.
    pub(super) first: Option<u8>,
    /// The line being scanned (the bytes the assembler would get).
    line: Vec<u8, SCAN_LINE>,
    /// The line is longer than [`SCAN_LINE`]: not judged here.
    long: bool,
    /// Events scanned so far (wrapping).
    pub(super) events: u32,
    /// Events the scan judged that the taking path has not reached yet.
    pub(super) decided: Deque<u32, DECIDED_CAP>,
    /// The last numbered emergency lines acted on, (line number, request), newest last: a
    /// resend of any of them does not act again.
    acted: Deque<(u32, Realtime), ACTED_KEPT>,
}

impl Scan {
    pub(super) const fn new() -> Self {
        Scan {
            ahead: 0,
            first: None,
            line: Vec::new(),
            long: false,
            events: 0,
            decided: Deque::new(),
            acted: Deque::new(),
        }
    }

    /// Start again from the taken point, where `taken_events` events have been taken and a
    /// line may be under way whose head the scan no longer has (it is not judged here).
    pub(super) fn restart(&mut self, taken_events: u32, mid_line: bool) {
        self.ahead = 0;
        self.line.clear();
        self.long = mid_line;
        self.events = taken_events;
        self.decided.clear();
    }

    /// Whether the scan can record one more judged event.
    pub(super) fn has_room(&self) -> bool {
        !self.decided.is_full()
    }

    /// Record event `e` as judged (room was checked).
    pub(super) fn decide(&mut self, e: u32) {
        let _ = self.decided.push_back(e);
    }

    /// Whether the taking path's event `e` was judged by the scan (and forget it).
    pub(super) fn take_decided(&mut self, e: u32) -> bool {
        if self.decided.front() == Some(&e) {
            self.decided.pop_front();
            true
        } else {
            false
        }
    }

    /// A byte of a line (not a line end, not a control byte).
    pub(super) fn push(&mut self, b: u8) {
        if self.line.push(b).is_err() {
            self.long = true;
        }
    }

    /// The line ended: what the scan judges it to be, if it is an emergency line it can judge.
    /// The line is kept until [`Scan::end_line`], so a judgement without room can be retried.
    pub(super) fn judge_line(&mut self) -> Option<Judged> {
        if self.long || !might_be_emergency(&self.line) {
            return None;
        }
        let mut asm = Assembler::new();
        for &b in &self.line {
            asm.push(b);
        }
        match classify(&asm.line()) {
            Verdict::SetLineNumber(_) => {
                // A new numbering: a line number seen before may come again.
                self.acted.clear();
                None
            }
            Verdict::Realtime(number, rt) if is_emergency(rt) => match number {
                Some(n) if self.acted.iter().any(|a| *a == (n, rt)) => Some(Judged::Again),
                _ => Some(Judged::Act(rt, number)),
            },
            _ => None,
        }
    }

    /// The judged line acted: remember its number (a resend of it does not act again).
    pub(super) fn acted(&mut self, rt: Realtime, number: Option<u32>) {
        if let Some(n) = number {
            if self.acted.is_full() {
                self.acted.pop_front();
            }
            let _ = self.acted.push_back((n, rt));
        }
    }

    /// The line end is scanned: the next line starts.
    pub(super) fn end_line(&mut self) {
        self.line.clear();
        self.long = false;
        self.events = self.events.wrapping_add(1);
    }

    /// A control byte is scanned.
    pub(super) fn end_control(&mut self) {
        self.events = self.events.wrapping_add(1);
    }
}

/// A cheap filter before the line is checked: it holds `M108`, `M112`, `M410` or `M110` (case
/// as the parser takes it).
fn might_be_emergency(line: &[u8]) -> bool {
    line.windows(4).any(|w| {
        matches!(w.first(), Some(b'M' | b'm'))
            && matches!(w.get(1..), Some(b"108" | b"112" | b"410" | b"110"))
    })
}
