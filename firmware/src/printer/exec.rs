//! The step side of the executive: planned blocks go to the step generator (job blocks, or
//! the service lane while a pause holds the job), finished blocks are recorded, and the layer
//! marks they cross are reported.

use super::state::{Pause, Stop};
use super::{service, Printer, Record};

use crate::planner::{BlockKind, PlannedBlock, RING_CAPACITY};
use crate::stepgen::StepEvent;
use crate::thermal::HeaterId;

impl Printer {
    /// Time of the next step event, ns (loads the next block when the current one is done).
    /// Always inlined, with [`Printer::next_step`]: the per-event path is a few compares and
    /// additions (the block loading is out of line), and whether the compiler inlines it must
    /// not depend on how many callers the binary has (the emulated-core budget, issue 16).
    #[inline(always)]
    pub fn next_step_ns(&mut self) -> Option<u64> {
        // The common case, an event of the loaded block, without the loop.
        if let Some(t) = self.stepgen.peek_time_ns() {
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
            if let Some(t) = self.stepgen.peek_time_ns() {
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
        let ev = self.stepgen.next_event();
        if ev.is_some() && self.stepgen.block_finished() {
            // Record the block at once so the record follows its last step.
            self.advance_block();
        }
        ev
    }

    pub(super) fn retire_finished(&mut self) {
        if self.stepgen.block_finished() {
            if let Some(e) = self.stepgen.unload() {
                let b = e.planned.block;
                if b.kind != BlockKind::Service {
                    self.planner.exec_done();
                }
                let t_us = crate::stepgen::div_small(self.stepgen.last_time_ns(), 1000).0;
                self.last_activity_us = self.last_activity_us.max(t_us);
                let pos = self.stepgen.position();
                self.record(Record::Executed {
                    seq: b.seq,
                    seg: b.seg,
                    segs: b.segs,
                    kind: b.kind,
                    t_us,
                    pos,
                });
                if b.kind == BlockKind::Homing
                    && matches!(
                        self.pause,
                        Pause::Stopping {
                            how: Stop::Hold { after_homing: true },
                            ..
                        }
                    )
                {
                    self.begin_hold();
                }
            }
        }
    }

    /// Retire a finished block and load the next one. False when nothing can be loaded.
    #[cold]
    #[inline(never)]
    pub(super) fn advance_block(&mut self) -> bool {
        if self.is_halted() {
            return false;
        }
        self.retire_finished();
        if self.stepgen.current().is_some() {
            return false; // held mid-block
        }
        if let Some(pb) = self.next_block() {
            self.load_block(pb);
            return true;
        }
        self.update_pause();
        if self.stepgen.current().is_some() {
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
    pub(super) fn load_block(&mut self, pb: PlannedBlock) {
        let now = self.now_ns();
        self.stepgen.load(pb, now);
        self.feed_planner();
    }

    pub(super) fn job_block(&mut self) -> Option<PlannedBlock> {
        let pb = self.planner.pop()?;
        self.planner.refill();
        // The layer started when its first block starts on the motion timeline, which runs
        // ahead of or behind the caller's clock (a block entered at speed continues from the
        // last step however late the poll that loads it).
        // (Worked out only for a block with a mark: this runs for every block.)
        let mut start_us = None;
        while let Some(m) = self.planner.take_mark_before(pb.block.id) {
            self.layer_crossed(&m);
            let t_us = *start_us.get_or_insert_with(|| {
                crate::stepgen::div_small(self.stepgen.start_ns(&pb, self.now_ns()), 1000).0
            });
            self.record(Record::Layer {
                layer: m.layer,
                t_us,
            });
        }
        Some(pb)
    }

    pub(super) fn next_block(&mut self) -> Option<PlannedBlock> {
        match &mut self.pause {
            Pause::Run => self.job_block(),
            Pause::Stopping { how, .. } => {
                if !how.brakes()
                    || matches!(how, Stop::Hold { after_homing: true })
                    || (self.stepgen.is_braking() && self.stepgen.exit_speed_mm_s() > 0.0)
                {
                    // Layer and tail stops run to their barrier; a feed hold brakes through
                    // the next blocks while it still has speed (or waits for a homing move).
                    self.job_block()
                } else {
                    None
                }
            }
            Pause::Parking { .. } | Pause::Parked { .. } | Pause::Returning { .. } => {
                if self.job_clear_waits() {
                    return None; // the paused-job record is cleared before the head returns
                }
                if let Pause::Returning { reheat, .. } = &mut self.pause {
                    if *reheat {
                        if !self.thermal.reached(HeaterId::Hotend) {
                            return None;
                        }
                        *reheat = false;
                    }
                }
                while let Some(m) = self.service.pop_front() {
                    let from = self.stepgen.position();
                    if let Some(pb) = service::block(&self.cfg, from, m) {
                        return Some(pb);
                    }
                }
                None
            }
            Pause::Halted => None,
        }
    }
}
