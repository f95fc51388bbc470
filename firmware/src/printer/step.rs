//! Blocks to the step generator, and the pause's progress: job blocks (or, while a pause holds
//! the job, the service lane's) are loaded as the executing one finishes; finished blocks are
//! recorded with the layer marks they cross; the pause machine advances and its events go to
//! the parts they concern.

use super::intake::LAYER_PAUSE_IDLE_US;
use super::pause::{Events, PauseEvent};
use super::{Printer, Record};
use crate::link::HostAction;
use crate::motion::PauseMode;
use crate::planner::{BlockKind, PlannedBlock, RING_CAPACITY};
use crate::stepgen::StepEvent;

impl Printer {
    /// Time of the next step event, ns (loads the next block when the current one is done).
    /// Always inlined, with [`Printer::next_step`]: the per-event path is a few compares and
    /// additions (the block loading is out of line), and whether the compiler inlines it must
    /// not depend on how many callers the binary has (the emulated-core budget, issue 16).
    #[inline(always)]
    pub fn next_step_ns(&mut self) -> Option<u64> {
        // The common case, an event of the loaded block, without the loop.
        if let Some(t) = self.motion.peek_time_ns() {
            return Some(t);
        }
        self.next_step_ns_load()
    }

    /// [`Printer::next_step_ns`] when the loaded block has no event left: out of line, so the
    /// per-event path stays small (it runs once per block).
    #[cold]
    #[inline(never)]
    fn next_step_ns_load(&mut self) -> Option<u64> {
        for _ in 0..(RING_CAPACITY + 8) {
            if let Some(t) = self.motion.peek_time_ns() {
                return Some(t);
            }
            if !self.advance_block() {
                return None;
            }
        }
        None
    }

    /// Time of the next step event, µs.
    pub fn next_step_us(&mut self) -> Option<u64> {
        self.next_step_ns()
            .map(|t| crate::stepgen::div_small(t, 1000).0)
    }

    /// Take the next step event (the one [`Printer::next_step_ns`] announced). The driver
    /// calls this when its clock reaches the event's time.
    #[inline(always)]
    pub fn next_step(&mut self) -> Option<StepEvent> {
        self.next_step_ns()?;
        let ev = self.motion.next_event();
        if ev.is_some() && self.motion.block_finished() {
            // Record the block at once so the record follows its last step.
            self.advance_block();
        }
        ev
    }

    /// Record a finished block (a homing move's end lets a feed hold that waited for it brake).
    pub(super) fn retire_finished(&mut self) {
        let Some(r) = self.motion.retire() else {
            return;
        };
        let b = r.block;
        self.intake.active(r.t_us);
        self.records.push(Record::Executed {
            seq: b.seq,
            seg: b.seg,
            segs: b.segs,
            kind: b.kind,
            t_us: r.t_us,
            pos: r.pos,
        });
        if b.kind == BlockKind::Homing {
            self.pause.homing_move_done(cx!(self));
        }
    }

    /// Retire a finished block and load the next one. False when nothing can be loaded.
    #[cold]
    #[inline(never)]
    fn advance_block(&mut self) -> bool {
        if self.pause.halted() {
            return false;
        }
        self.retire_finished();
        if self.motion.executing() {
            return false; // held mid-block
        }
        if let Some(pb) = self.next_block() {
            self.load_block(pb);
            return true;
        }
        self.update_pause();
        if self.motion.executing() {
            return true;
        }
        if let Some(pb) = self.next_block() {
            self.load_block(pb);
            return true;
        }
        false
    }

    /// Hand a block to the step generator, then refill the planner from the command queue.
    /// Only after the load: commands that wait for the motion to end (G4, M400, G28, M18) must
    /// not see an idle machine while a popped block is on its way to the step generator.
    fn load_block(&mut self, pb: PlannedBlock) {
        let now = self.now_us.saturating_mul(1000);
        self.motion.load(pb, now);
        self.feed_planner();
    }

    /// The next job block, and the layer marks it crosses.
    fn job_block(&mut self) -> Option<PlannedBlock> {
        let pb = self.motion.pop_job_block()?;
        // The layer started when its first block starts on the motion timeline, which runs
        // ahead of or behind the caller's clock (a block entered at speed continues from the
        // last step however late the poll that loads it).
        // (Worked out only for a block with a mark: this runs for every block.)
        let mut start_us = None;
        while let Some(m) = self.motion.take_mark_before(pb.block.id) {
            self.job.layer_crossed(&m);
            self.pause.layer_crossed(&m, &mut self.host);
            let now_ns = self.now_us.saturating_mul(1000);
            let t_us = *start_us.get_or_insert_with(|| self.motion.start_us(&pb, now_ns));
            self.records.push(Record::Layer {
                layer: m.layer,
                t_us,
            });
        }
        Some(pb)
    }

    /// The next block to execute: the job's, or the service lane's while a pause holds it.
    fn next_block(&mut self) -> Option<PlannedBlock> {
        match self.pause.lane(&self.motion)? {
            false => self.job_block(),
            true => {
                if self.job.clear_waits(self.pause.state()) {
                    return None; // the paused-job record is cleared before the head returns
                }
                if !self.pause.service_lane_ready(&self.heat) {
                    return None;
                }
                self.motion.pop_service_block(self.settings.cfg())
            }
        }
    }

    /// Advance the pause machine (stop → park → parked, return → release) and route what it
    /// asks of the other parts.
    #[inline]
    pub(super) fn update_pause(&mut self) {
        self.retire_finished();
        // Printing, parked or halted: nothing to advance (the main loop's common case, without
        // the frame of the rest).
        if self.pause.moving_on() {
            self.advance_pause();
        }
    }

    #[inline(never)]
    fn advance_pause(&mut self) {
        // A layer pause whose job ended before any boundary stops at its end.
        if self.pause.waits_for_a_mark(&self.motion)
            && self.intake.is_empty()
            && self.intake.idle_us(self.now_us) >= LAYER_PAUSE_IDLE_US
        {
            let mark = self.intake.finish_layer();
            self.pause.stop_at_job_end(mark, cx!(self));
        }
        let ev = self.pause.update(cx!(self));
        self.route(ev);
    }

    /// A cancel switches both heaters and the fan off, as Marlin's abort does
    /// (`thermalManager.disable_all_heaters()`, `zero_fan_speeds()`): nothing is left hot when
    /// the job is gone. A host line taken after the cancel may heat again; the cancelled
    /// job's tail may not (`intake/cancel.rs`).
    fn cool_down_after_cancel(&mut self) {
        use crate::thermal::HeaterId;
        for id in [HeaterId::Hotend, HeaterId::Bed] {
            // Setting 0 °C is never refused (it is below every limit).
            let _ = self.heat.set_target(id, 0.0);
        }
        self.heat.set_fan(Some(0.0));
        self.heat.thermal_mut().cancel_autotune();
    }

    /// What the pause asked of the other parts, in order.
    #[inline]
    pub(super) fn route(&mut self, events: Events) {
        if !events.is_empty() {
            self.route_events(events);
        }
    }

    #[inline(never)]
    fn route_events(&mut self, events: Events) {
        for ev in events {
            match ev {
                PauseEvent::JobDropped(d) => {
                    let (cmds, spilled) = self.intake.drop_job();
                    self.cool_down_after_cancel();
                    super::intake::Intake::say_spill_dropped(spilled, &mut self.host);
                    self.pay_sync_ok();
                    self.host.action(HostAction::Cancel);
                    self.host.say(format_args!(
                        "cancelled: dropped {} commands, {} blocks, {} uncut segments, {} layer marks",
                        cmds, d.blocks, d.segments, d.marks
                    ));
                }
                PauseEvent::CancelDone => {
                    self.on_job_continues();
                    self.intake.cancel_done(self.now_us);
                    let pos = self.motion.position();
                    self.intake.machine_at(&pos, self.settings.cfg());
                }
                PauseEvent::Parked { mode, resume } => {
                    let here = self.motion.position();
                    self.intake.parked(&here, self.settings.cfg());
                    if mode == PauseMode::Layer {
                        self.on_parked();
                    }
                    if resume {
                        let ev = self.pause.resume_deferred(cx!(self));
                        self.route(ev);
                    }
                }
                PauseEvent::ResumeStarted => {
                    self.intake.unparked();
                    self.on_job_continues();
                }
                PauseEvent::Released { resumed, repause } => {
                    self.feed_planner();
                    // A schedule that came due while this pause was in progress stops at its
                    // boundary.
                    self.pause.schedule_queued_marks(cx!(self));
                    if resumed {
                        self.host.action(HostAction::Resumed);
                    }
                    if let Some(m) = repause {
                        // Back in a job: the held lines are queued.
                        let queued = self.intake.len();
                        self.pause.request_pause(m, true, queued, cx!(self));
                    }
                }
            }
        }
    }
}
