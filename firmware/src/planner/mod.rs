//! The planner: a fixed-capacity ring buffer of motion blocks with motion-queue segmentation,
//! lookahead, layer marks and the pause barrier.
//!
//! * **Segmentation**: a [`MoveRequest`] is held as the *pending* move and cut lazily, as room
//!   frees in the ring, into segments no longer than `segment_len_mm`. Segments of one move join
//!   at full speed. The uncut remainder of the pending move is collinear, so it counts as known
//!   lookahead: the last queued segment may leave at `√(2·a·remainder)` instead of 0, and a
//!   small ring still reaches full speed on a long move.
//! * **Lookahead**: junction deviation corner speeds, trapezoidal profiles, a backward and a
//!   forward pass over the ring in `v²`, bounded by grbl's *planned pointer* (blocks whose entry
//!   speed can no longer rise are never revisited). The first block of the ring always has a
//!   fixed entry speed (the exit of the executing block), so the plan is always one the head can
//!   follow, and it always ends at standstill within the queued distance.
//! * **Layer marks** sit between blocks ([`LayerMark`] queued with the id of the block that
//!   follows). A mark costs nothing: the plan runs through it at full speed (helical and vase
//!   prints have one per turn and no corner there). A `layer` pause places the barrier at the
//!   *first reachable* mark ([`Planner::first_reachable_mark`]): the first one the head can
//!   still brake to from its current speed over the queued blocks; a mark inside the braking
//!   distance is passed and the pause takes the following one.
//! * **Barrier**: a block id the plan may not pass. Blocks at and behind it stay queued,
//!   unplanned and untouched until [`Planner::release`].

mod barrier;
mod kin;
mod lookahead;

pub use kin::{
    cap_for_segments, fmax, fmin, hold_entry_v2, junction_v2, kinematics, sped_up_mm_s, sqrtf, Kin,
    HOLD_SLACK_MM,
};

use crate::config::MachineConfig;
use crate::motion::{LayerMark, MoveRequest, StepPos, AXES};
use heapless::Deque;

/// Ring capacity in blocks. RAM: `RING_CAPACITY × size_of::<Block>()` (64 × 72 B ≈ 4.6 KiB on
/// the MCU). With 0.2 mm segments a long straight move needs no more than a few blocks thanks
/// to the pending-move lookahead; the depth matters for runs of short moves (curves), where 64
/// blocks of ≥ 0.2 mm give ≥ 12.8 mm of lookahead: enough to stop from 113 mm/s at 500 mm/s².
pub const RING_CAPACITY: usize = 64;

/// Layer marks that can wait in the queue at once (each is 20 B).
pub const MARK_CAPACITY: usize = 16;

/// What produced a block.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BlockKind {
    /// A segment of a job move.
    #[default]
    Job,
    /// A homing move (G28): a pause waits until it has finished.
    Homing,
    /// A move of the pause/resume service lane or a manual move while paused.
    Service,
}

/// One planned segment of a move.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Block {
    /// Planner-wide block number, strictly increasing.
    pub id: u32,
    /// Job sequence number of the move this segment belongs to.
    pub seq: u32,
    /// Index of this segment within its move (0-based).
    pub seg: u32,
    /// Number of segments of the move.
    pub segs: u32,
    /// What produced the block.
    pub kind: BlockKind,
    /// Signed steps per axis.
    pub delta: [i32; AXES],
    /// Path length, mm.
    pub len_mm: f32,
    /// Acceleration, mm/s².
    pub accel_mm_s2: f32,
    /// Nominal speed², mm²/s² (sped up after a `layer` pause request).
    pub nominal_v2: f32,
    /// Nominal speed² without the speed-up.
    pub base_v2: f32,
    /// Nominal speed² with the speed-up.
    pub fast_v2: f32,
    /// Corner limit at the entry of this block (∞ inside one move, 0 at a layer mark).
    pub junction_v2: f32,
    /// Highest entry speed²: min(junction, previous nominal, own nominal).
    pub entry_max_v2: f32,
    /// Planned entry speed².
    pub entry_v2: f32,
}

/// A block handed to the step generator with its planned entry and exit speeds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlannedBlock {
    /// The block.
    pub block: Block,
    /// Entry speed², mm²/s².
    pub entry_v2: f32,
    /// Exit speed², mm²/s².
    pub exit_v2: f32,
}

/// Why the planner did not take an entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanError {
    /// A move is still being cut into segments: try again after [`Planner::refill`].
    Busy,
    /// The mark queue is full.
    Full,
}

/// Where the plan must stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Barrier {
    /// No barrier.
    None,
    /// At the next layer mark to be queued.
    NextMark,
    /// Before the block with this id.
    At(u32),
}

/// Runtime policy knobs: the same planner models conventional firmware.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannerPolicy {
    /// Cut moves into segments (`false`: one block per move, as Marlin/Klipper).
    pub segment: bool,
    /// Highest number of blocks queued, the executing one included (≤ [`RING_CAPACITY`]).
    pub max_blocks: usize,
    /// Plan a stop at every layer mark (a standstill per mark, whether a pause needs it or
    /// not). Off by default: a pause stops at the first mark it can still reach
    /// ([`Planner::first_reachable_mark`]).
    pub stop_at_marks: bool,
}

impl Default for PlannerPolicy {
    fn default() -> Self {
        Self {
            segment: true,
            max_blocks: RING_CAPACITY,
            stop_at_marks: false,
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Pending {
    seq: u32,
    kind: BlockKind,
    n: u32,
    next: u32,
    /// Position after segment `next - 1`: `from + floor((to - from) · next / n)` per axis,
    /// tracked incrementally (quotient and remainder) so cutting a segment needs no 64-bit
    /// division (a library call of ~100 instructions on a Cortex-M).
    cur: [i64; AXES],
    /// `(to - from) · next mod n` per axis.
    cur_rem: [u32; AXES],
    /// `(to - from).div_euclid(n)` per axis: whole steps added per segment.
    step_q: [i64; AXES],
    /// `(to - from).rem_euclid(n)` per axis.
    step_r: [u32; AXES],
    kin: Kin,
    seg_len_mm: f32,
    first_junction_v2: f32,
    fast_mm_s: f32,
}

#[derive(Clone, Copy, Debug)]
struct QueuedMark {
    id: u32,
    mark: LayerMark,
}

/// The planner ring buffer. See the module documentation.
#[derive(Clone, Debug)]
pub struct Planner {
    ring: [Block; RING_CAPACITY],
    head: usize,
    len: usize,
    planned: usize,
    marks: Deque<QueuedMark, MARK_CAPACITY>,
    pending: Option<Pending>,
    /// Position at the end of everything queued (pending move included).
    end_pos: StepPos,
    prev_unit: [f32; AXES],
    /// Acceleration of the last queued move, mm/s² (for [`hold_entry_v2`]).
    prev_accel_mm_s2: f32,
    prev_nominal_v2: f32,
    have_prev: bool,
    stop_next: bool,
    next_id: u32,
    barrier: Barrier,
    fast: bool,
    executing: bool,
    head_entry_v2: f32,
    /// Policy knobs.
    pub policy: PlannerPolicy,
}

impl Default for Planner {
    fn default() -> Self {
        Self::new()
    }
}

impl Planner {
    /// An empty planner at position 0.
    pub const fn new() -> Self {
        const B: Block = Block {
            id: 0,
            seq: 0,
            seg: 0,
            segs: 0,
            kind: BlockKind::Job,
            delta: [0; AXES],
            len_mm: 0.0,
            accel_mm_s2: 0.0,
            nominal_v2: 0.0,
            base_v2: 0.0,
            fast_v2: 0.0,
            junction_v2: 0.0,
            entry_max_v2: 0.0,
            entry_v2: 0.0,
        };
        Self {
            ring: [B; RING_CAPACITY],
            head: 0,
            len: 0,
            planned: 0,
            marks: Deque::new(),
            pending: None,
            end_pos: [0; AXES],
            prev_unit: [0.0; AXES],
            prev_accel_mm_s2: 0.0,
            prev_nominal_v2: 0.0,
            have_prev: false,
            stop_next: false,
            next_id: 0,
            barrier: Barrier::None,
            fast: false,
            executing: false,
            head_entry_v2: 0.0,
            policy: PlannerPolicy {
                segment: true,
                max_blocks: RING_CAPACITY,
                stop_at_marks: false,
            },
        }
    }

    fn idx(&self, k: usize) -> usize {
        (self.head + k) % RING_CAPACITY
    }

    /// Blocks in the ring (the executing block is not in the ring).
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing is queued (ring empty and no pending move).
    pub fn is_empty(&self) -> bool {
        self.len == 0 && self.pending.is_none()
    }

    /// True while a move is still being cut into segments.
    pub fn has_pending(&self) -> bool {
        self.pending.is_some()
    }

    /// Segments of the pending move not yet in the ring.
    pub fn pending_segments(&self) -> u32 {
        self.pending.map_or(0, |p| p.n - p.next)
    }

    /// Position at the end of everything queued.
    pub fn end_position(&self) -> StepPos {
        self.end_pos
    }

    /// The current barrier.
    pub fn barrier(&self) -> Barrier {
        self.barrier
    }

    /// Id the next queued block will get.
    pub fn next_id(&self) -> u32 {
        self.next_id
    }

    /// Block at offset `k` from the head of the ring.
    pub fn get(&self, k: usize) -> Option<&Block> {
        (k < self.len).then(|| &self.ring[self.idx(k)])
    }

    fn limit(&self) -> usize {
        self.policy.max_blocks.clamp(1, RING_CAPACITY)
    }

    /// Free block slots under the current limit (the executing block counts).
    pub fn room(&self) -> usize {
        self.limit()
            .saturating_sub(self.len + usize::from(self.executing))
    }

    /// True when a new move can be accepted at once: no pending move and room for a block.
    pub fn can_accept(&self) -> bool {
        self.pending.is_none() && self.room() > 0
    }

    /// Set the position (G92, homing) when nothing is queued. Returns false if motion is queued.
    pub fn set_position(&mut self, pos: StepPos) -> bool {
        if !self.is_empty() {
            return false;
        }
        self.end_pos = pos;
        self.have_prev = false;
        true
    }

    /// Queue a move; it is cut into segments as room frees ([`Planner::refill`] is called
    /// here once). A move without steps is dropped (`Ok(false)`).
    pub fn push_move(
        &mut self,
        cfg: &MachineConfig,
        req: &MoveRequest,
        kind: BlockKind,
    ) -> Result<bool, PlanError> {
        if self.pending.is_some() {
            return Err(PlanError::Busy);
        }
        let mut delta = [0i32; AXES];
        for (i, d) in delta.iter_mut().enumerate() {
            *d = req.target[i].wrapping_sub(self.end_pos[i]);
        }
        let Some(kin) = kinematics(cfg, &delta, req.feed_mm_s) else {
            return Ok(false);
        };
        let seg = cfg.pause.segment_len_mm;
        let n = if self.policy.segment && kind == BlockKind::Job && seg > 0.0 && kin.len_mm > seg {
            let n = libm::ceilf(kin.len_mm / seg);
            if n >= 1.0e6 {
                1_000_000
            } else {
                n as u32
            }
        } else {
            1
        };
        let mut junction = if self.have_prev {
            let a = kin.accel_mm_s2;
            fmin(
                junction_v2(&self.prev_unit, &kin.unit, cfg.junction_deviation_mm, a),
                hold_entry_v2(self.prev_accel_mm_s2, a),
            )
        } else {
            0.0
        };
        if self.stop_next {
            junction = 0.0;
            self.stop_next = false;
        }
        let mut cur = [0i64; AXES];
        let mut step_q = [0i64; AXES];
        let mut step_r = [0u32; AXES];
        let mut max_seg_steps = [0u32; AXES];
        for i in 0..AXES {
            let d = i64::from(req.target[i]) - i64::from(self.end_pos[i]);
            cur[i] = i64::from(self.end_pos[i]);
            step_q[i] = d.div_euclid(i64::from(n));
            // In 0..n, n ≤ 1e6.
            step_r[i] = d.rem_euclid(i64::from(n)) as u32;
            // ⌈|d|/n⌉ ≤ |d| < 2³².
            max_seg_steps[i] = d.unsigned_abs().div_ceil(u64::from(n)) as u32;
        }
        let kin = cap_for_segments(cfg, kin, &max_seg_steps, n);
        self.pending = Some(Pending {
            seq: req.seq,
            kind,
            n,
            next: 0,
            cur,
            cur_rem: [0; AXES],
            step_q,
            step_r,
            kin,
            seg_len_mm: kin.len_mm / n as f32,
            first_junction_v2: junction,
            fast_mm_s: sped_up_mm_s(
                &kin,
                cfg.pause.speedup_factor,
                cfg.pause.max_volumetric_mm3_s,
                cfg.filament_diameter_mm,
            ),
        });
        self.end_pos = req.target;
        self.prev_unit = kin.unit;
        self.prev_accel_mm_s2 = kin.accel_mm_s2;
        self.have_prev = true;
        self.refill();
        Ok(true)
    }

    /// The last move's E part was not planned (a cold nozzle): the planned position takes
    /// `e_steps` as if it had been, so the next move feeds only its own filament (Marlin's
    /// `position.e = target.e` in `Planner::_populate_block`). The steppers' E count keeps
    /// what really moved.
    pub fn skip_e(&mut self, e_steps: i32) {
        self.end_pos[crate::motion::Axis::E.index()] = e_steps;
    }

    /// Queue a layer mark before the next block. Becomes the barrier if one is waiting for
    /// the next mark (returns `Ok(true)` then). A mark right after another one, with no block
    /// between them (a layer without motion), stands at the same place: it replaces the
    /// earlier one, so marks never pile up where no block can ever consume them (issue 24's
    /// executive find: 50 layer markers in a row filled the marks, and the next one waited for
    /// room that only a block behind it could make — every later line waited for ever).
    pub fn push_mark(&mut self, mark: LayerMark) -> Result<bool, PlanError> {
        if self.pending.is_some() {
            return Err(PlanError::Busy);
        }
        let id = self.next_id;
        if let Some(last) = self.marks.back_mut().filter(|m| m.id == id) {
            last.mark = mark;
            if self.barrier == Barrier::NextMark {
                self.set_barrier(id);
                return Ok(true);
            }
            return Ok(false);
        }
        if self.marks.is_full() {
            return Err(PlanError::Full);
        }
        // Cannot fail: checked is_full above.
        let _ = self.marks.push_back(QueuedMark { id, mark });
        if self.policy.stop_at_marks {
            self.stop_next = true;
        }
        if self.barrier == Barrier::NextMark {
            self.set_barrier(id);
            return Ok(true);
        }
        Ok(false)
    }

    /// Cut more segments of the pending move into the ring, then replan. Returns the number of
    /// blocks added.
    pub fn refill(&mut self) -> usize {
        let mut added = 0;
        let Some(mut p) = self.pending else {
            return 0;
        };
        while p.next < p.n {
            if self.room() == 0 {
                break;
            }
            let j = p.next + 1;
            let mut delta = [0i32; AXES];
            for (i, d) in delta.iter_mut().enumerate() {
                // to = from + floor(d · j / n), from the previous segment's end by adding
                // floor(d / n) and carrying the remainder (exact, same as dividing).
                let mut to = p.cur[i] + p.step_q[i];
                let r = p.cur_rem[i] + p.step_r[i];
                p.cur_rem[i] = if r >= p.n {
                    to += 1;
                    r - p.n
                } else {
                    r
                };
                *d = (to as i32).wrapping_sub(p.cur[i] as i32);
                p.cur[i] = to;
            }
            let base = p.kin.nominal_mm_s;
            let fast = p.fast_mm_s;
            let base_v2 = base * base;
            let fast_v2 = fast * fast;
            let nominal_v2 = if self.fast { fast_v2 } else { base_v2 };
            let junction = if p.next == 0 {
                p.first_junction_v2
            } else {
                f32::INFINITY
            };
            let prev_nom = if self.len > 0 {
                self.ring[self.idx(self.len - 1)].nominal_v2
            } else {
                self.prev_nominal_v2
            };
            let b = Block {
                id: self.next_id,
                seq: p.seq,
                seg: p.next,
                segs: p.n,
                kind: p.kind,
                delta,
                len_mm: p.seg_len_mm,
                accel_mm_s2: p.kin.accel_mm_s2,
                nominal_v2,
                base_v2,
                fast_v2,
                junction_v2: junction,
                entry_max_v2: fmin(fmin(junction, prev_nom), nominal_v2),
                entry_v2: if self.len == 0 && self.executing {
                    self.head_entry_v2
                } else {
                    0.0
                },
            };
            let slot = self.idx(self.len);
            self.ring[slot] = b;
            self.len += 1;
            self.next_id = self.next_id.wrapping_add(1);
            self.prev_nominal_v2 = nominal_v2;
            p.next = j;
            added += 1;
        }
        self.pending = if p.next >= p.n { None } else { Some(p) };
        if added > 0 {
            self.recalculate();
        }
        added
    }

    /// Take the head block for execution with its entry and exit speeds, unless the barrier
    /// is reached or the ring is empty. The planner counts it as executing until
    /// [`Planner::exec_done`].
    pub fn pop(&mut self) -> Option<PlannedBlock> {
        if self.len == 0 || self.plan_len() == 0 {
            return None;
        }
        let b = self.ring[self.head];
        let exit = if self.plan_len() > 1 {
            self.ring[self.idx(1)].entry_v2
        } else {
            self.tail_exit_v2(1)
        };
        self.head = (self.head + 1) % RING_CAPACITY;
        self.len -= 1;
        self.planned = self.planned.saturating_sub(1);
        self.executing = true;
        self.head_entry_v2 = exit;
        // The new head's entry is now fixed to `exit`.
        if self.len > 0 {
            let h = self.head;
            self.ring[h].entry_v2 = exit;
        }
        Some(PlannedBlock {
            block: b,
            entry_v2: b.entry_v2,
            exit_v2: exit,
        })
    }

    /// The executing block has finished (or was dropped).
    pub fn exec_done(&mut self) {
        self.executing = false;
        self.head_entry_v2 = 0.0;
    }

    /// Layer marks at or before block `id` (crossed when that block starts), oldest first.
    pub fn take_mark_before(&mut self, id: u32) -> Option<LayerMark> {
        if let Some(m) = self.marks.front() {
            if (id.wrapping_sub(m.id) as i32) >= 0 {
                return self.marks.pop_front().map(|m| m.mark);
            }
        }
        None
    }

    /// The first queued layer mark that the head has not crossed: (block id, mark).
    pub fn first_mark(&self) -> Option<(u32, LayerMark)> {
        self.marks.front().map(|m| (m.id, m.mark))
    }

    /// Queued marks, oldest first: (block id, mark).
    pub fn marks(&self) -> impl Iterator<Item = (u32, LayerMark)> + '_ {
        self.marks.iter().map(|m| (m.id, m.mark))
    }

    /// Drop everything queued (cancel, quick stop). Returns (blocks dropped, pending segments
    /// dropped, marks dropped). The end position becomes `pos`.
    pub fn clear(&mut self, pos: StepPos) -> (usize, u32, usize) {
        let r = (self.len, self.pending_segments(), self.marks.len());
        self.len = 0;
        self.planned = 0;
        self.pending = None;
        self.marks.clear();
        self.barrier = Barrier::None;
        self.fast = false;
        self.stop_next = false;
        self.have_prev = false;
        self.end_pos = pos;
        r
    }
}
