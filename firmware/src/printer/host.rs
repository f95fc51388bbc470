//! The host side of the executive: lines from the link are parsed, interpreted by the machine
//! state, fed to the layer detector and queued as [`Command`]s; commands that are not motion
//! (temperatures, reports, M760/M761, ...) are answered here.

use super::state::Pause;
use super::{Command, PausedLines, Printer, LINE_LEN};
use crate::gcode::{self, PauseSchedule};
use crate::layer::MoveFacts;
use crate::link::{ReceivedLine, Response};

use crate::machine::Action;
use crate::printer::service::ServiceMove;
use crate::printer::{CMD_CAPACITY, CMD_SLOTS};
use core::fmt::Write as _;
use heapless::String;

/// Job lines a parked printer takes into RAM beyond the running queue limit
/// ([`CMD_CAPACITY`]), one per pace period, so that a host that keeps streaming one numbered
/// line per `ok` into a parked printer (printcore: it ignores `//action:paused`) keeps getting
/// `ok`s, and with each `ok` its priority queue (`send_now`: M602, M524, M105, jogs) gets out.
/// Beyond them the lines go to the SD card when one is mounted (`spill.rs`), for as long as
/// the pause lasts; without a card the intake ends here (docs/frontend.md, "Host rules").
pub const PARKED_EXTRA: usize = 96;

/// Pace of the parked intake: a job line that has waited this long while parked is taken
/// (and its `ok` sent). With a card to spill to the pace stays at this, so a console line
/// queued at any moment gets out within it; without one it grows by this much for every 32
/// lines taken, so the RAM slots last 32 × (1 + 2 + 3) s = 192 s of pause with `ok`s at most
/// 3 s apart.
pub const PARKED_PACE_US: u64 = 1_000_000;

/// Where the parked intake puts a job line it takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Intake {
    /// Into the command queue (within the running limit, or into the RAM extra slots).
    Queue,
    /// Into the spill on the SD card (`spill.rs`).
    Spill,
}

/// After a cancel, the host may still stream the rest of the job (printcore ignores
/// `//action:cancel`; lines were in flight): those lines are discarded (answered `ok`, never
/// executed) until the host starts anew — a numbered line whose number is not beyond `after`
/// (the host reset its line numbers with M110, as printcore and OctoPrint do at a job's start),
/// or any line after the host was silent for [`crate::printer::LAYER_PAUSE_IDLE_US`].
/// Unnumbered lines from a host that numbers its job (OctoPrint's cancel script, a console
/// command) are taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct AfterCancel {
    /// The last numbered line taken before the cancel.
    pub(super) after: Option<u32>,
    /// Lines discarded so far.
    pub(super) discarded: u32,
}

/// The host-line side of the executive (see docs/frontend.md, "Host rules").
#[derive(Clone, Debug, Default)]
pub(super) struct HostLines {
    /// A line taken from the link that waits for queue room (it needs room; lines that need
    /// none are answered at once, see [`answered_without_room`]).
    pub(super) held_line: Option<ReceivedLine>,
    /// The host has sent numbered lines (it numbers its job): with [`PausedLines::Auto`],
    /// unnumbered lines while paused are manual commands.
    pub(super) host_numbers: bool,
    /// Number of the last numbered line taken.
    pub(super) last_line_no: Option<u32>,
    /// The job was cancelled: the rest of the host's stream is discarded until it starts anew.
    pub(super) after_cancel: Option<AfterCancel>,
    /// An M400 waits for the motion to end: its `ok` is owed, and no further line is taken.
    pub(super) sync_ok_owed: bool,
    /// When the last `busy:` keep-alive went out, µs.
    pub(super) last_busy_us: u64,
    /// When `held_line` started to wait, µs (the parked intake's pace counts from it).
    pub(super) held_since_us: u64,
    /// The port `held_line` came from.
    pub(super) held_port: Option<crate::link::PortId>,
    /// The port of the last job line taken (whose host streams the job).
    pub(super) job_port: Option<crate::link::PortId>,
    /// The host reset its line numbers (`M110`): a job starts at its next job line taken —
    /// when that line goes to the spill behind lines of the job before, the reset goes with it
    /// and the job starts when it is fed back (`spill.rs`).
    pub(super) job_start_due: bool,
    /// The job's host went away while the job ran or was paused (`session.rs`): it cannot be
    /// resumed, only cancelled.
    pub(super) orphaned: bool,
}

impl Printer {
    /// Act on every realtime request the ports hold. The idle check stays inline in the main
    /// loop (an idle poll costs a compare, not a call: qemu-test's idle poll).
    #[inline]
    pub(super) fn take_realtime(&mut self) {
        if self.link.has_realtime() {
            self.take_realtimes();
        }
    }

    fn take_realtimes(&mut self) {
        while let Some(rt) = self.link.take_realtime() {
            let now = self.now_us;
            self.request(rt, now);
        }
    }

    fn queued_moves(&self) -> usize {
        self.cmds
            .iter()
            .filter(|c| !matches!(c, Command::Layer(_)))
            .count()
    }

    /// Command slots kept free while a pause is on its way (stopping, parking): the line the
    /// host has in flight when the printer announces `//action:paused` always fits, so its
    /// `ok` follows the announcement and the host can send its resume next (docs/frontend.md,
    /// "host rules").
    fn reserved_lines(&self) -> usize {
        usize::from(matches!(
            self.pause,
            Pause::Stopping { .. } | Pause::Parking { .. }
        ))
    }

    /// Room for one more host line: the policy's limit on waiting commands (layer marks do not
    /// count) less the pause's reserve, and physical room for a mark plus a command.
    pub(super) fn line_room(&self) -> bool {
        let reserve = self.reserved_lines();
        self.queued_moves() + reserve < self.policy.cmd_limit.clamp(1, CMD_CAPACITY)
            && self.cmds.len() + 2 + reserve <= CMD_CAPACITY
    }

    /// Commands queued beyond the running limit (lines the parked intake took).
    fn parked_excess(&self) -> usize {
        self.queued_moves()
            .saturating_sub(self.policy.cmd_limit.clamp(1, CMD_CAPACITY))
    }

    /// Whether a job line may go straight into the queue: room under the limit, and no
    /// spilled line ahead of it.
    fn job_line_fits(&self) -> bool {
        self.line_room() && self.spill.pending() == 0
    }

    /// Whether the job line waiting in `held_line` is due for the paced intake, and where it
    /// goes: parked (or, after the resume, while what the intake took still runs), and it has
    /// waited the pace ([`PARKED_PACE_US`]; longer as the RAM slots fill when no card can
    /// take the spill). Then it is taken and answered `ok`, and the host's next line (its
    /// priority line, or its next job line, which waits the next pace) follows.
    fn intake_due(&self, line: &ReceivedLine) -> Option<Intake> {
        let backlog = self.parked_excess() > 0 || self.spill.pending() > 0;
        let on = match self.pause {
            // A job whose host went away takes no new session's lines behind it.
            Pause::Parked { .. } => !self.lines.orphaned,
            Pause::Run => backlog,
            _ => false,
        };
        if !on {
            return None;
        }
        let pace_us = if self.spill_possible() {
            PARKED_PACE_US
        } else {
            PARKED_PACE_US * (1 + (self.parked_excess() / 32) as u64)
        };
        if self.now_us.saturating_sub(self.lines.held_since_us) < pace_us {
            return None;
        }
        if self.spill.pending() == 0 && self.cmds.len() + 2 <= CMD_SLOTS {
            return Some(Intake::Queue);
        }
        self.spill_room(line).then_some(Intake::Spill)
    }

    /// Whether a host line waiting for room should get `busy:` keep-alives: while a pause
    /// holds the queue, and while the lines the parked intake took run after the resume.
    fn host_kept_waiting(&self) -> bool {
        !matches!(self.pause, Pause::Run) || self.parked_excess() > 0 || self.spill.pending() > 0
    }

    /// Whether a host line taken now is a manual command (while parked, see [`PausedLines`]).
    fn is_manual(&self, line: &ReceivedLine) -> bool {
        matches!(self.pause, Pause::Parked { .. })
            && match self.policy.paused_lines {
                PausedLines::Queue => false,
                PausedLines::Manual => true,
                PausedLines::Auto => self.lines.host_numbers && line.number().is_none(),
            }
    }

    /// The next host line: the one waiting for room, else the link's next (only while the
    /// output ring can take its answer).
    fn next_line(&mut self) -> Option<ReceivedLine> {
        if self.lines.held_line.is_some() {
            if self.link.line_output_free() < crate::link::OUT_RESERVE {
                return None;
            }
            self.link.answer_line_port();
            return self.lines.held_line.take();
        }
        self.link.pop_line()
    }

    /// Take lines from the link while there is room, and answer each. A line that needs no
    /// queue room (reports, messages) is answered even when the queue is full; one that needs
    /// room waits in `held_line`, with `busy:` keep-alives while a pause holds the queue.
    pub(super) fn process_lines(&mut self) {
        for _ in 0..64 {
            if self.is_halted() {
                return;
            }
            if self.arc.is_some() {
                self.push_arc();
                if self.arc.is_some() {
                    if self.host_kept_waiting() {
                        self.keep_alive();
                    }
                    return;
                }
                self.link.respond(Response::Ok);
            }
            if self.lines.sync_ok_owed || self.sd_request_pending() {
                // M400 is waiting for the motion to end, or an SD command for the card: the
                // next line waits too.
                return;
            }
            let from_held = self.lines.held_line.is_some();
            if let Some(held) = &self.lines.held_line {
                // Known to need room: wait for it without parsing again.
                let fits = if self.is_manual(held) {
                    !self.service.is_full()
                } else {
                    self.job_line_fits() || self.intake_due(held).is_some()
                };
                if !fits {
                    if self.host_kept_waiting() {
                        self.keep_alive();
                    }
                    return;
                }
            }
            if self.pause.cancelling() {
                // The cancel is still parking: lines wait (a move taken now would be dropped
                // with the planner when the cancel completes).
                if self.link.lines_waiting() > 0 || self.lines.held_line.is_some() {
                    self.keep_alive();
                }
                return;
            }
            let Some(mut line) = self.next_line() else {
                return;
            };
            // The host reset its line numbers before this line: a job starts with the next
            // job line.
            let reset = line.take_reset();
            self.lines.job_start_due |= reset;
            if self.discard_after_cancel(&line, reset) {
                self.link.respond(Response::Ok);
                continue;
            }
            let manual = self.is_manual(&line);
            let route = if manual {
                (!self.service.is_full()).then_some(Intake::Queue)
            } else if self.job_line_fits() {
                Some(Intake::Queue)
            } else if from_held {
                self.intake_due(&line)
            } else {
                None
            };
            if route == Some(Intake::Spill) {
                // A new job's first line behind spilled lines of the job before: the job
                // starts when it is fed back, in stream order (it carries the reset).
                let reset = core::mem::take(&mut self.lines.job_start_due);
                self.spill_line(&line, reset);
                continue;
            }
            if route.is_none() {
                // A report needs no room — unless it is a layer marker (`M73 L`,
                // `SET_PRINT_STATS_INFO CURRENT_LAYER=`, a marker comment): every marker is part
                // of the job stream and waits for room like a move.
                if answered_without_room(&line) && !self.is_marker(&line) {
                    self.start_due_job();
                    self.answer_report(&line);
                    continue;
                }
                self.lines.held_line = Some(line);
                self.lines.held_since_us = self.now_us;
                self.lines.held_port = Some(self.link.reply_port());
                if self.host_kept_waiting() {
                    // A pause holds the queue: keep the host from timing out.
                    self.keep_alive();
                }
                return;
            }
            if line.number().is_some() {
                self.lines.host_numbers = true;
                self.lines.last_line_no = line.number();
            }
            if !manual {
                self.lines.job_port = Some(self.link.reply_port());
            }
            self.last_activity_us = self.now_us;
            if manual {
                self.swap_manual_machine();
                self.handle_line(&line, true);
                self.swap_manual_machine();
            } else {
                self.start_due_job();
                self.handle_line(&line, false);
            }
            self.feed_planner();
        }
    }

    /// The job start a line-number reset announced, when no line of the job before is left in
    /// the spill (else it waits for the next job line, which goes to the spill with the
    /// reset; docs/planner.md, "What a layer is").
    fn start_due_job(&mut self) {
        if self.lines.job_start_due && self.spill.pending() == 0 {
            self.lines.job_start_due = false;
            self.job_start();
        }
    }

    /// Swap the job's modal state with the manual one of the parked pause (if any): manual
    /// lines are interpreted between two swaps.
    fn swap_manual_machine(&mut self) {
        if let Pause::Parked {
            manual: Some(m), ..
        } = &mut self.pause
        {
            core::mem::swap(&mut self.machine, m);
        }
    }

    /// Whether `line` is the rest of a cancelled job (see [`AfterCancel`]): then it is
    /// counted and must be answered `ok` without being executed. Ends the discarding when the
    /// host has started anew.
    fn discard_after_cancel(&mut self, line: &ReceivedLine, reset: bool) -> bool {
        let Some(mut a) = self.lines.after_cancel else {
            return false;
        };
        let silent_us = self.now_us.saturating_sub(self.last_activity_us);
        let fresh = silent_us >= crate::printer::LAYER_PAUSE_IDLE_US
            || (reset && line.number().is_some())
            || match (line.number(), a.after) {
                // Numbers restarted (M110): a new job.
                (Some(n), Some(after)) => n <= after,
                (Some(_), None) => false,
                // A host that numbers its job sends its own commands unnumbered.
                (None, _) => self.lines.host_numbers,
            };
        self.last_activity_us = self.now_us;
        if fresh {
            if line.number().is_some() || silent_us >= crate::printer::LAYER_PAUSE_IDLE_US {
                if a.discarded > 0 {
                    self.say(format_args!(
                        "cancelled: {} lines of the cancelled job discarded",
                        a.discarded
                    ));
                }
                self.lines.after_cancel = None;
            }
            return false;
        }
        if a.discarded == 0 {
            self.say(format_args!(
                "cancelled: discarding the rest of the job until the host starts anew"
            ));
        }
        a.discarded = a.discarded.saturating_add(1);
        self.lines.after_cancel = Some(a);
        true
    }

    /// Whether a line carries a layer marker of any family (it must enter the queue).
    fn is_marker(&self, line: &ReceivedLine) -> bool {
        line.parse().is_ok_and(|l| self.layers.is_marker(&l))
    }

    /// Answer a report/message line while the queue is full. It is the next line of the stream
    /// (every line before it was taken), it queues nothing and changes nothing a later job line
    /// is interpreted in; the layer detector still sees it, in order (it carries no marker:
    /// see `is_marker`).
    fn answer_report(&mut self, line: &ReceivedLine) {
        match line.parse() {
            Ok(parsed) => {
                let here = MoveFacts::of(&self.machine, &self.machine, &self.cfg);
                let mark = self.layers.feed(&parsed, here);
                debug_assert!(mark.is_none(), "a marker line answered without room");
                let answered = match &parsed.command {
                    Some(cmd) => self.executive(cmd),
                    None => false,
                };
                if !answered {
                    self.link.respond(Response::Ok);
                }
            }
            Err(e) => {
                self.warn(format_args!("{e}"));
                self.link.respond(Response::Ok);
            }
        }
    }

    fn push_arc(&mut self) {
        while self.arc.is_some() {
            if !self.line_room() {
                return;
            }
            match self.arc.as_mut().and_then(|a| a.next()) {
                Some(m) => {
                    let _ = self.cmds.push_back(Command::Move(m));
                }
                None => self.arc = None,
            }
        }
    }

    /// A refused line: `echo:refused: <why>`, never `Error:` (OctoPrint cancels the print on
    /// any `Error:` that is not about line numbers or checksums). The line changed nothing:
    /// the machine's state is as before it. See the response table in docs/frontend.md.
    pub(super) fn warn(&mut self, args: core::fmt::Arguments) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = t.write_str("refused: ");
        let _ = t.write_fmt(args);
        self.link.respond(Response::Echo(&t));
    }

    /// Words of a command that reads none, taken as Marlin takes them:
    /// `echo:ignored P: not used by this command` (not `refused:`: the line is executed).
    fn note_ignored(&mut self, letters: u32) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = t.write_str("ignored");
        for (n, c) in (b'A'..=b'Z').enumerate() {
            if letters & (1 << n) != 0 {
                let _ = t.write_char(' ');
                let _ = t.write_char(char::from(c));
            }
        }
        let _ = t.write_str(": not used by this command");
        self.link.respond(Response::Echo(&t));
    }

    pub(super) fn handle_line(&mut self, line: &ReceivedLine, manual: bool) {
        let parsed = match line.parse() {
            Ok(l) => l,
            Err(e) => {
                self.warn(format_args!("{e}"));
                self.link.respond(Response::Ok);
                return;
            }
        };
        if parsed.ignored != 0 {
            self.note_ignored(parsed.ignored);
        }
        let modal_before = self.machine;
        let saved = self.machine;
        let action = match &parsed.command {
            Some(cmd) => match self.machine.apply(cmd, &self.cfg) {
                Ok(a) => a,
                Err(e) => {
                    self.warn(format_args!("{e}"));
                    self.link.respond(Response::Ok);
                    return;
                }
            },
            None => Action::None,
        };
        if let Err(r) = self.check_action(&action, &saved) {
            // Refused (cold or over-long extrusion): as if the line had not come.
            self.machine = saved;
            self.warn(format_args!("{r}"));
            self.link.respond(Response::Ok);
            return;
        }
        if !manual {
            // A job line after M1000 without the host's M110: the continuation has begun.
            self.job.continue_at = None;
            let facts = MoveFacts::of(&saved, &self.machine, &self.cfg);
            if let Some(mark) = self.layers.feed(&parsed, facts) {
                let _ = self.cmds.push_back(Command::Layer(mark));
                self.note_boundary(&mark, line.number(), &modal_before);
            }
            // M400 after a layer's marker comments: the boundary is here (a host that drains
            // the queue at a boundary, then pauses, stops at this layer, not the next).
            if matches!(parsed.command, Some(gcode::Command::WaitMoves)) {
                if let Some(mark) = self.layers.finish() {
                    let _ = self.cmds.push_back(Command::Layer(mark));
                    self.note_boundary(&mark, line.number(), &modal_before);
                }
            }
        }
        let mut answered = false;
        match action {
            Action::None => {}
            Action::Move(m) => {
                if manual {
                    let _ = self.service.push_back(ServiceMove {
                        target: m.target,
                        feed_mm_s: m.feed_mm_s,
                    });
                } else {
                    self.kept_job_superseded();
                    let _ = self.cmds.push_back(Command::Move(m));
                }
            }
            Action::Arc(a) => {
                if manual {
                    self.warn(format_args!("arcs are not taken while paused"));
                } else {
                    self.arc = Some(a);
                    self.push_arc();
                    if self.arc.is_some() {
                        return; // `ok` once the whole arc is queued
                    }
                }
            }
            Action::Home(flags) => {
                if manual {
                    self.warn(format_args!("homing is not allowed while paused"));
                } else {
                    let mut mask = 0u8;
                    for (i, on) in flags.0.iter().enumerate() {
                        if *on {
                            mask |= 1 << i;
                        }
                    }
                    let _ = self.cmds.push_back(Command::Home { mask });
                }
            }
            Action::Dwell { ms } => {
                if !manual {
                    let _ = self.cmds.push_back(Command::Dwell { ms });
                }
            }
            Action::Executive => {
                if let Some(cmd) = &parsed.command {
                    answered = self.executive(cmd);
                }
            }
        }
        if !answered {
            self.link.respond(Response::Ok);
        }
    }
}

/// Lines the executive answers without command-queue room, even while a pause holds a full
/// queue: reports and messages, which queue nothing and change no state a later job line is
/// interpreted in (and lines that do not parse: answered, nothing queued). Realtime lines
/// (M24/M25/M108/M112/M410/M524/M601/M602) never wait: the link acts on them as they arrive.
pub(super) fn answered_without_room(line: &ReceivedLine) -> bool {
    use gcode::Command as G;
    match line.parse() {
        Err(_) => true,
        Ok(gcode::Line { command: None, .. }) => false,
        Ok(gcode::Line {
            command: Some(c), ..
        }) => match c {
            G::ReportTemperatures
            | G::ReportPosition
            | G::FirmwareInfo
            | G::Message(_)
            | G::Echo(_)
            | G::Progress(_)
            | G::Report(_)
            | G::PrintStatsInfo { .. }
            | G::FeedOverride(None)
            | G::FlowOverride(None)
            | G::SchedulePause(PauseSchedule::Report)
            | G::SetLineNumber(_)
            | G::Tool(0)
            | G::Unknown(_) => true,
            // SD commands queue nothing (M24 is realtime); a listing while parked with a
            // full queue must not wait for the resume.
            G::Sd(_) => true,
            G::PauseParams(p) => p.is_empty(),
            _ => false,
        },
    }
}
