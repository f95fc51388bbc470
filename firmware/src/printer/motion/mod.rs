//! Motion, as the executive owns it: the planner ring (job blocks and layer marks, the pause's
//! barrier), the step generator (the executing block, the feed hold), the service lane (park,
//! return, manual moves while paused: planned one at a time, never touching held job blocks),
//! homing on the endstops ([`homing`]), a G4 dwell, and which axes' positions are lost
//! (drivers switched off). The other parts ask for motion through this interface; the step
//! events come out of [`Motion::peek_time_ns`] / [`Motion::next_event`] (the step interrupt's
//! path: a few compares and additions).

pub(super) mod homing;
pub mod service;

use homing::HomingState;
use service::{ServiceMove, SERVICE_CAPACITY};

use crate::config::MachineConfig;
use crate::motion::{LayerMark, MoveRequest, StepPos};
use crate::planner::{Barrier, Block, BlockKind, PlannedBlock, Planner, PlannerPolicy};
use crate::stepgen::{ExecBlock, StepEvent, StepGen};
use heapless::Deque;

/// A finished block, as the execution record reports it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Retired {
    /// The block.
    pub(super) block: Block,
    /// When its last step happened, µs.
    pub(super) t_us: u64,
    /// Position after it, steps.
    pub(super) pos: StepPos,
}

/// How a feed hold began: the speed it brakes from and the block's acceleration.
#[derive(Clone, Copy, Debug)]
pub(super) struct Brake {
    /// Speed when braking started, mm/s.
    pub(super) v_mm_s: f32,
    /// Acceleration of the executing block, mm/s².
    pub(super) accel_mm_s2: f32,
}

/// Where the head stopped for a pause: the block interrupted mid-way (a feed hold), if any.
#[derive(Clone, Copy, Debug)]
pub(super) struct Stop {
    /// The interrupted block, to be finished on resume.
    pub(super) block: Option<ExecBlock>,
    /// Where the head stopped, steps.
    pub(super) pos: StepPos,
}

/// What a cancel or quick stop dropped from the planner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Dropped {
    /// Planned blocks (the held one included).
    pub(super) blocks: u32,
    /// Segments of moves not yet cut.
    pub(super) segments: u32,
    /// Layer marks.
    pub(super) marks: u32,
}

/// The motion part (see the module documentation).
#[derive(Clone, Debug)]
pub(super) struct Motion {
    planner: Planner,
    stepgen: StepGen,
    service: Deque<ServiceMove, SERVICE_CAPACITY>,
    homing: HomingState,
    /// Axes (bit i = X, Y, Z) whose drivers were switched off since they were last homed.
    position_lost: u8,
    /// A G4 at the front of the queue waits until this time, µs.
    dwell_until_us: Option<u64>,
}

impl Motion {
    pub(super) const fn new() -> Self {
        Self {
            planner: Planner::new(),
            stepgen: StepGen::new(),
            service: Deque::new(),
            homing: HomingState::new(),
            position_lost: 0,
            dwell_until_us: None,
        }
    }

    /// The planner's policy (segmentation, ring depth, stops at marks).
    pub(super) fn set_policy(&mut self, p: PlannerPolicy) {
        self.planner.policy = p;
    }

    /// The planner, read-only (queries: marks, barrier, depth).
    pub(super) fn planner(&self) -> &Planner {
        &self.planner
    }

    /// The step generator, read-only.
    pub(super) fn stepgen(&self) -> &StepGen {
        &self.stepgen
    }

    // ---- state ----

    /// Nothing planned and nothing executing.
    pub(super) fn idle(&self) -> bool {
        self.planner.is_empty() && self.stepgen.current().is_none()
    }

    /// Where the steppers are, steps.
    pub(super) fn position(&self) -> StepPos {
        self.stepgen.position()
    }

    /// Set the position of the planner and the steppers (G92, homing, settings; idle only).
    pub(super) fn set_position(&mut self, pos: StepPos) {
        self.planner.set_position(pos);
        self.stepgen.set_position(pos);
    }

    /// Set only the planner's position (M1000: job moves start at the kept boundary while the
    /// head is parked elsewhere; the return's service moves bring it there).
    pub(super) fn set_planner_position(&mut self, pos: StepPos) {
        self.planner.set_position(pos);
    }

    /// Set only the steppers' position (the pause's logical E after the return).
    pub(super) fn set_stepper_position(&mut self, pos: StepPos) {
        self.stepgen.set_position(pos);
    }

    /// When the last step happened (or the last block started), µs.
    pub(super) fn last_step_us(&self) -> u64 {
        crate::stepgen::div_small(self.stepgen.last_time_ns(), 1000).0
    }

    // ---- the step interrupt's path ----

    /// Time of the loaded block's next step event, ns.
    #[inline(always)]
    pub(super) fn peek_time_ns(&mut self) -> Option<u64> {
        self.stepgen.peek_time_ns()
    }

    /// The loaded block's next step event.
    #[inline(always)]
    pub(super) fn next_event(&mut self) -> Option<StepEvent> {
        self.stepgen.next_event()
    }

    /// The loaded block has taken all its steps.
    #[inline(always)]
    pub(super) fn block_finished(&self) -> bool {
        self.stepgen.block_finished()
    }

    /// A block is loaded (executing, braking, or held mid-way).
    pub(super) fn executing(&self) -> bool {
        self.stepgen.current().is_some()
    }

    /// The loaded block is a homing move that has steps left.
    pub(super) fn homing_move_running(&self) -> bool {
        self.stepgen
            .current()
            .is_some_and(|e| e.planned.block.kind == BlockKind::Homing && !e.finished())
    }

    /// Unload a finished block; job and homing blocks leave the planner's ring.
    pub(super) fn retire(&mut self) -> Option<Retired> {
        if !self.stepgen.block_finished() {
            return None;
        }
        let e = self.stepgen.unload()?;
        let block = e.planned.block;
        if block.kind != BlockKind::Service {
            self.planner.exec_done();
        }
        Some(Retired {
            block,
            t_us: self.last_step_us(),
            pos: self.stepgen.position(),
        })
    }

    /// The next planned job block (the planner refills its cut segments behind it).
    pub(super) fn pop_job_block(&mut self) -> Option<PlannedBlock> {
        let pb = self.planner.pop()?;
        self.planner.refill();
        Some(pb)
    }

    /// A layer mark queued before block `id`, in order.
    pub(super) fn take_mark_before(&mut self, id: u32) -> Option<LayerMark> {
        self.planner.take_mark_before(id)
    }

    /// When `pb`, loaded at `now_ns`, starts on the motion timeline, µs.
    pub(super) fn start_us(&self, pb: &PlannedBlock, now_ns: u64) -> u64 {
        crate::stepgen::div_small(self.stepgen.start_ns(pb, now_ns), 1000).0
    }

    /// Hand a block to the step generator.
    pub(super) fn load(&mut self, pb: PlannedBlock, now_ns: u64) {
        self.stepgen.load(pb, now_ns);
    }

    /// The next service move's block, from where the head is (moves without a step are
    /// skipped).
    pub(super) fn pop_service_block(&mut self, cfg: &MachineConfig) -> Option<PlannedBlock> {
        while let Some(m) = self.service.pop_front() {
            if let Some(pb) = service::block(cfg, self.stepgen.position(), m) {
                return Some(pb);
            }
        }
        None
    }

    // ---- the job into the planner ----

    /// The planner takes a move now.
    pub(super) fn can_accept(&self) -> bool {
        self.planner.can_accept()
    }

    /// Room for more blocks, and whether cut segments wait to enter it.
    pub(super) fn room(&self) -> usize {
        self.planner.room()
    }

    /// Segments of a move not yet in the ring.
    pub(super) fn has_pending(&self) -> bool {
        self.planner.has_pending()
    }

    /// Cut segments into the ring as room frees.
    pub(super) fn refill(&mut self) {
        self.planner.refill();
    }

    /// Where the planned motion ends.
    pub(super) fn end_position(&self) -> StepPos {
        self.planner.end_position()
    }

    /// Plan a move of `kind`.
    pub(super) fn push_move(&mut self, cfg: &MachineConfig, req: &MoveRequest, kind: BlockKind) {
        let _ = self.planner.push_move(cfg, req, kind);
    }

    /// The last move's E part was dropped: see [`Planner::skip_e`].
    pub(super) fn skip_e(&mut self, e_steps: i32) {
        self.planner.skip_e(e_steps);
    }

    /// Queue a layer mark: `Ok(true)` when it became the pause's barrier.
    pub(super) fn push_mark(&mut self, mark: LayerMark) -> Result<bool, ()> {
        self.planner.push_mark(mark).map_err(|_| ())
    }

    /// G4 at the front of the queue: whether its time (from when motion ended) is over.
    pub(super) fn dwell_over(&mut self, now_us: u64, ms: u32, broken: bool) -> bool {
        let until = *self
            .dwell_until_us
            .get_or_insert(now_us + u64::from(ms) * 1000);
        if now_us < until && !broken {
            return false;
        }
        self.dwell_until_us = None;
        true
    }

    // ---- the pause's requests ----

    /// The pause's barrier: before the first layer mark the head can still stop at; its mark.
    pub(super) fn barrier_at_reachable_mark(&mut self) -> Option<LayerMark> {
        let (id, m) = self.planner.first_reachable_mark()?;
        self.planner.set_barrier(id);
        Some(m)
    }

    /// The barrier at the next mark that enters the planner.
    pub(super) fn barrier_at_next_mark(&mut self) {
        self.planner.set_barrier_next_mark();
    }

    /// The barrier after everything planned (M0/M600, the conventional tail stop).
    pub(super) fn barrier_here(&mut self) {
        let id = self.planner.next_id();
        self.planner.set_barrier(id);
    }

    /// The barrier before the last layer mark queued (a schedule met as the mark entered).
    pub(super) fn barrier_at_last_mark(&mut self) {
        if let Some((id, _)) = self.planner.marks().last() {
            self.planner.set_barrier(id);
        }
    }

    /// The barrier before the first queued mark that `hit` accepts and the head can still stop
    /// at; its mark.
    pub(super) fn barrier_at_mark_where(
        &mut self,
        hit: impl Fn(&LayerMark) -> bool,
    ) -> Option<LayerMark> {
        let (id, m) = self
            .planner
            .marks()
            .find(|(id, m)| hit(m) && self.planner.can_stop_before(*id))?;
        self.planner.set_barrier(id);
        Some(m)
    }

    /// No barrier any more (a withdrawn layer pause).
    pub(super) fn clear_barrier(&mut self) {
        self.planner.clear_barrier();
    }

    /// Speed up the rest of the layer before the barrier (the pause's acknowledgement).
    pub(super) fn speed_up(&mut self) {
        self.planner.speed_up();
    }

    /// Feed hold: brake from the executing block on.
    pub(super) fn hold(&mut self, now_ns: u64) -> Brake {
        let v_mm_s = self.stepgen.hold(now_ns);
        let accel_mm_s2 = self
            .stepgen
            .current()
            .map_or(0.0, |e| e.planned.block.accel_mm_s2);
        Brake {
            v_mm_s,
            accel_mm_s2,
        }
    }

    /// Whether a feed hold has stopped: no step left in the loaded block (held mid-way), or
    /// between blocks with nothing to brake through. A brake that ends exactly at the last
    /// queued point may leave a rounding-sized exit speed with no block after it: the head is
    /// at the end of the queued motion, and that is the stop.
    pub(super) fn hold_stopped(&self) -> bool {
        self.stepgen.is_stopped()
            && (self.stepgen.current().is_some()
                || self.stepgen.exit_speed_mm_s() <= 0.0
                || self.planner.is_empty()
                || self.planner.at_barrier())
    }

    /// A feed hold still has speed to brake through the next blocks.
    pub(super) fn braking_on(&self) -> bool {
        self.stepgen.is_braking() && self.stepgen.exit_speed_mm_s() > 0.0
    }

    /// Whether a barrier stop has stopped: nothing executing, and the barrier reached.
    pub(super) fn at_barrier(&self) -> bool {
        self.stepgen.current().is_none() && self.planner.at_barrier()
    }

    /// The barrier waits for a mark that has not entered the planner yet.
    pub(super) fn barrier_waits_for_mark(&self) -> bool {
        self.planner.barrier() == Barrier::NextMark
    }

    /// The first layer mark queued in the planner.
    pub(super) fn first_mark(&self) -> Option<LayerMark> {
        self.planner.first_mark().map(|(_, m)| m)
    }

    /// The head has stopped for a pause: take what it left (the block held mid-way).
    pub(super) fn take_stop(&mut self) -> Stop {
        let block = self.stepgen.unload();
        self.stepgen.end_hold();
        Stop {
            block,
            pos: self.stepgen.position(),
        }
    }

    /// Release the held job: the interrupted block (if any) continues from standstill, the
    /// planner's barrier goes.
    pub(super) fn release(&mut self, block: Option<ExecBlock>, now_ns: u64) {
        let rem = block.map(|e| {
            let b = e.planned.block;
            (e.remaining_mm(), b.accel_mm_s2, b.base_v2)
        });
        let exit = self.planner.release(rem);
        if let Some(mut e) = block {
            e.planned.block.nominal_v2 = e.planned.block.base_v2;
            self.stepgen.restore(e);
            self.stepgen.resume_held(exit, now_ns);
        }
    }

    /// Drop the planned job (a cancel); the head stays where it is.
    pub(super) fn drop_job(&mut self) -> Dropped {
        let pos = self.stepgen.position();
        let (blocks, segments, marks) = self.planner.clear(pos);
        Dropped {
            blocks: blocks as u32,
            segments,
            marks: marks as u32,
        }
    }

    /// The job is over (a cancel completed): nothing planned, the ring empty.
    pub(super) fn reset_planner(&mut self) {
        let pos = self.stepgen.position();
        self.planner.clear(pos);
        self.planner.exec_done();
    }

    /// M410: stop at once, everything planned dropped.
    pub(super) fn quick_stop(&mut self) -> Dropped {
        self.homing.abort();
        let _ = self.stepgen.unload();
        self.stepgen.end_hold();
        let d = self.drop_job();
        self.planner.exec_done();
        self.service.clear();
        d
    }

    /// M112 / a fault: nothing moves any more.
    pub(super) fn halt(&mut self) {
        self.homing.abort();
        let _ = self.stepgen.unload();
        let pos = self.stepgen.position();
        self.planner.clear(pos);
        self.service.clear();
    }

    // ---- the service lane ----

    /// Queue a service move; false when the lane is full.
    pub(super) fn push_service(&mut self, m: ServiceMove) -> bool {
        self.service.push_back(m).is_ok()
    }

    /// Forget the service moves not yet started.
    pub(super) fn clear_service(&mut self) {
        self.service.clear();
    }

    /// The lane is full (a manual move waits).
    pub(super) fn service_full(&self) -> bool {
        self.service.is_full()
    }

    /// Service moves queued or the head still moving.
    pub(super) fn service_busy(&self) -> bool {
        !self.service.is_empty() || self.stepgen.current().is_some()
    }

    // ---- positions lost and found ----

    /// Axes whose position is lost (their drivers were off), bit i = axis i.
    pub(super) fn position_lost(&self) -> u8 {
        self.position_lost
    }

    /// The drivers of `mask` were switched off: returns the axes newly lost.
    pub(super) fn lose_position(&mut self, mask: u8) -> u8 {
        let new = mask & 0b111 & !self.position_lost;
        self.position_lost |= new;
        new
    }
}
