//! Host lines into the executive: each line the host side hands over is routed by the
//! intake's rules (docs/frontend.md, "Host rules") — discarded as a cancelled job's tail,
//! taken as a manual command while parked, queued for the job, spilled to the card, answered
//! without room (reports), or held until there is room (with `busy:` keep-alives while a pause
//! holds the queue) — and the commands it carries go to the part that owns them.

use super::intake::{Interpreted, LineOutcome, Route, TailLine};
use super::Printer;
use crate::gcode::{self, PauseSchedule};
use crate::gcode::{HeatCommand, MotionCommand, PauseCommand};
use crate::link::ReceivedLine;

impl Printer {
    /// Realtime requests the link picked out of the byte stream, in order.
    #[inline]
    pub(super) fn take_realtime(&mut self) {
        if self.host.has_realtime() {
            self.take_realtimes();
        }
    }

    fn take_realtimes(&mut self) {
        while let Some(rt) = self.host.take_realtime() {
            let now = self.now_us;
            self.request(rt, now);
        }
    }

    /// The next host line: the one waiting for room, else the link's next (only while the
    /// output ring can take its answer).
    fn next_line(&mut self) -> Option<ReceivedLine> {
        if self.intake.has_held_line() {
            if !self.host.room_for_answers() {
                return None;
            }
            self.host.answer_line_port();
            return self.intake.take_held_line();
        }
        self.host.pop_line()
    }

    /// Whether the card can take the parked intake's spill now.
    fn card_for_spill(&self) -> bool {
        self.sd_spill_ready()
    }

    /// Take lines from the link while there is room, and answer each. A line that needs no
    /// queue room (reports, messages) is answered even when the queue is full; one that needs
    /// room waits in the intake's held slot, with `busy:` keep-alives while a pause holds the
    /// queue.
    pub(super) fn process_lines(&mut self) {
        for _ in 0..64 {
            if self.pause.halted() {
                return;
            }
            if self.intake.cutting_arc() {
                if !self.intake.push_arc(self.pause.state()) {
                    if self.intake.host_kept_waiting(self.pause.state()) {
                        self.keep_alive();
                    }
                    return;
                }
                self.host.ok();
            }
            if self.intake.sync_owed() || self.sd_request_pending() {
                // M400 is waiting for the motion to end, or an SD command for the card: the
                // next line waits too.
                return;
            }
            let from_held = self.intake.has_held_line();
            if let Some(held) = self.intake.held_line() {
                // Known to need room: wait for it without parsing again.
                let port = self.intake.held_port().unwrap_or(self.host.reply_port());
                let pause = self.pause.state();
                let fits = if self.intake.is_manual(held, port, pause, || self.in_job()) {
                    !self.motion.service_full()
                } else {
                    self.intake.job_line_fits(pause)
                        || self
                            .intake
                            .intake_due(held, pause, self.card_for_spill(), self.now_us)
                            .is_some()
                };
                if !fits {
                    if self.intake.host_kept_waiting(pause) {
                        self.keep_alive();
                    }
                    return;
                }
            }
            if self.pause.state().cancelling() {
                // The cancel is still parking: lines wait (a move taken now would be dropped
                // with the planner when the cancel completes).
                if self.host.lines_waiting() > 0 || self.intake.has_held_line() {
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
            self.intake.note_reset(reset);
            let tail = self
                .intake
                .after_cancel(&line, reset, self.now_us, &mut self.host);
            if tail == TailLine::Discard {
                self.host.ok();
                continue;
            }
            let port = self.host.reply_port();
            let pause = self.pause.state();
            let manual = self.intake.is_manual(&line, port, pause, || self.in_job());
            let route = if manual {
                (!self.motion.service_full()).then_some(Route::Queue)
            } else if self.intake.job_line_fits(pause) {
                Some(Route::Queue)
            } else if from_held {
                let card = self.card_for_spill();
                self.intake.intake_due(&line, pause, card, self.now_us)
            } else {
                None
            };
            if route == Some(Route::Spill) {
                // A new job's first line behind spilled lines of the job before: the job
                // starts when it is fed back, in stream order (it carries the reset).
                let reset = self.intake.take_start_for_spill();
                let port = self.host.reply_port();
                self.intake
                    .spill_line(&line, reset, port, self.now_us, &mut self.host);
                continue;
            }
            if route.is_none() {
                // A report needs no room — unless it is a layer marker (`M73 L`,
                // `SET_PRINT_STATS_INFO CURRENT_LAYER=`, a marker comment): every marker is
                // part of the job stream and waits for room like a move.
                if answered_without_room(&line) && !self.intake.is_marker(&line) {
                    self.start_due_job();
                    self.answer_report(&line);
                    continue;
                }
                let port = self.host.reply_port();
                self.intake.hold_line(line, port, self.now_us);
                if self.intake.host_kept_waiting(self.pause.state()) {
                    // A pause holds the queue: keep the host from timing out.
                    self.keep_alive();
                }
                return;
            }
            let job_port = (!manual).then(|| self.host.reply_port());
            self.intake.took_line(line.number(), job_port, self.now_us);
            if !manual {
                self.start_due_job();
            }
            self.handle_line(&line, manual);
            self.feed_planner();
        }
    }

    /// The job start a line-number reset announced, when no line of the job before is left in
    /// the spill (else it waits for the next job line, which goes to the spill with the
    /// reset; docs/planner.md, "What a layer is").
    fn start_due_job(&mut self) {
        if self.intake.take_due_start() {
            self.job_start();
        }
    }

    /// Answer a report/message line while the queue is full (see
    /// [`super::intake::Intake::report_line`]).
    fn answer_report(&mut self, line: &ReceivedLine) {
        let cmd = self
            .intake
            .report_line(line, self.settings.cfg(), &mut self.host);
        let answered = match &cmd {
            Some(c) => self.execute(c),
            None => false,
        };
        if !answered {
            self.host.ok();
        }
    }

    /// Interpret a host or card line and carry out what it asks; `manual`: a console command
    /// (while parked, or the job's host's unnumbered line while its job runs).
    pub(super) fn handle_line(&mut self, line: &ReceivedLine, manual: bool) {
        let Interpreted {
            outcome,
            marks,
            modal_before,
            job_line,
            job_move,
        } = self.intake.interpret(
            line,
            manual,
            self.settings.cfg(),
            &self.heat,
            self.pause.state(),
            &mut self.host,
        );
        if job_line {
            // A job line after M1000 without the host's M110: the continuation has begun.
            self.job.continuation_begun();
        }
        for mark in &marks {
            let sd_offset = self.sd_line_offset();
            self.job
                .note_boundary(mark, line.number(), &modal_before, sd_offset);
        }
        if job_move {
            self.kept_job_superseded();
        }
        match outcome {
            LineOutcome::Refused | LineOutcome::ArcPending => {}
            LineOutcome::Done => self.host.ok(),
            LineOutcome::ManualMove(m) => {
                self.motion.push_service(m);
                self.host.ok();
            }
            LineOutcome::Execute(gcode::Command::Motion(MotionCommand::WaitMoves))
                if manual && self.pause.parked() =>
            {
                // A console M400 while parked waits for the manual moves, not the held job.
                // While the job runs a console M400 (printcore's `send_now`, manual since the
                // held job tells console lines from the job's) waits for every move queued
                // before it, as Marlin's: its `ok` says the job's moves have ended.
                self.intake.owe_manual_sync();
            }
            LineOutcome::Execute(cmd) => {
                if !self.execute(&cmd) {
                    self.host.ok();
                }
            }
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
            // The whole report family (M114 M115 M117 M118 M73 M110 M119 M155 M113 M31 M27,
            // SET_PRINT_STATS_INFO) and the other families' reports.
            G::Report(_)
            | G::Heat(HeatCommand::Report)
            | G::Motion(MotionCommand::FeedOverride(None))
            | G::Motion(MotionCommand::FlowOverride(None))
            | G::Pause(PauseCommand::Schedule(PauseSchedule::Report))
            | G::Tool(0)
            | G::Unknown(_) => true,
            // SD commands queue nothing (M24 is realtime); a listing while parked with a
            // full queue must not wait for the resume.
            G::Sd(_) => true,
            G::Pause(PauseCommand::Params(p)) => p.is_empty(),
            _ => false,
        },
    }
}

/// Spilled lines fed back per card service at most (the command queue bounds it first).
const SPILL_LINES_PER_SERVICE: usize = 64;

impl Printer {
    /// The parked intake's spill with the driver's card (from `service_card`): write what is
    /// staged, then feed spilled lines back, in order, while the queue has room for a host
    /// line. A spill that cannot be read back cancels the job (its lines are gone with the
    /// card; the cancel parks the head off the part).
    pub(super) fn service_spill<D: embedded_sdmmc::BlockDevice>(
        &mut self,
        card: &mut crate::storage::sd::Card<D>,
    ) where
        D::Error: core::fmt::Debug,
    {
        use super::intake::spill::Replay;
        if !self.sd_spill_ready() {
            return;
        }
        self.intake.service_spill(card, &mut self.host);
        for _ in 0..SPILL_LINES_PER_SERVICE {
            if self.intake.spilled() == 0 || !self.spill_line_room() {
                break;
            }
            match self.intake.next_spilled(card) {
                Replay::Line(mut line) => {
                    if line.take_reset() {
                        // The next job's first line: the job before has run to its end.
                        self.job_start();
                    }
                    // Its `ok` went out when it was taken: answered as a file line.
                    self.host.answer_file();
                    self.intake.touch(self.now_us);
                    self.handle_line(&line, false);
                    self.feed_planner();
                }
                Replay::Wait => break,
                Replay::Lost(n) => {
                    self.host.error(format_args!(
                        "SD read error: {n} kept job lines lost; cancelling"
                    ));
                    let now = self.now_us;
                    self.request(crate::motion::Realtime::Cancel, now);
                    return;
                }
            }
        }
        self.intake.spill_done(&mut self.host);
    }

    /// Whether a spilled line could be handled now: as a host line (queue room, nothing owed,
    /// no cancel parking).
    fn spill_line_room(&self) -> bool {
        !self.pause.halted()
            && !self.intake.cutting_arc()
            && !self.intake.sync_owed()
            && !self.pause.state().cancelling()
            && self.intake.line_room(self.pause.state())
    }
}
