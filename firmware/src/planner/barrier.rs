//! The pause side of the planner: the barrier (where the plan must stop), the speed-up of the
//! rest of the layer, and the release of held blocks on resume.

use super::{Barrier, Planner};
use crate::motion::LayerMark;

/// Speed² counted as standstill, mm²/s² (0.03 mm/s).
const STOP_EPS_V2: f32 = 1.0e-3;

impl Planner {
    /// Place the barrier before block `id` and replan to stop there.
    pub fn set_barrier(&mut self, id: u32) {
        self.barrier = Barrier::At(id);
        if self.fast {
            // The speed-up ends at the barrier: later blocks keep their speed.
            self.fast = false;
        }
        self.replan_all();
    }

    /// True when the plan can still stop before block `id`: braking from the head's fixed entry
    /// speed (the exit of the executing block) over the queued blocks before `id` reaches
    /// standstill there. A boundary nearer than the braking distance is not reachable (the
    /// pause takes the following one); one behind the ring's end always is (the plan always
    /// ends at standstill within the queued distance).
    pub fn can_stop_before(&self, id: u32) -> bool {
        let mut end = 0;
        while end < self.len && (self.ring[self.idx(end)].id.wrapping_sub(id) as i32) < 0 {
            end += 1;
        }
        if end == 0 {
            // Between the executing block and the ring: only if that block stops at its end.
            let exit = if self.len > 0 {
                self.ring[self.head].entry_v2
            } else {
                self.head_entry_v2
            };
            return !self.executing || exit <= STOP_EPS_V2;
        }
        if !self.executing {
            // Nothing moving: the whole ring can still be planned from standstill.
            return true;
        }
        let mut v2 = 0.0f32;
        for k in (1..end).rev() {
            let b = &self.ring[self.idx(k)];
            v2 = super::fmin(b.entry_max_v2, v2 + 2.0 * b.accel_mm_s2 * b.len_mm);
        }
        let h = &self.ring[self.head];
        let head_max_v2 = v2 + 2.0 * h.accel_mm_s2 * h.len_mm;
        h.entry_v2 <= head_max_v2 * (1.0 + 1.0e-4) + STOP_EPS_V2
    }

    /// The first queued layer mark the plan can still stop at ([`Planner::can_stop_before`]):
    /// the *first reachable boundary*. `None` when every queued mark is too close.
    pub fn first_reachable_mark(&self) -> Option<(u32, LayerMark)> {
        self.marks().find(|(id, _)| self.can_stop_before(*id))
    }

    /// Place the barrier at the next layer mark that will be queued.
    pub fn set_barrier_next_mark(&mut self) {
        self.barrier = Barrier::NextMark;
    }

    /// Speed up every planned block before the barrier (and, with the barrier still waiting
    /// for its mark, every block queued until then) to its `fast` speed, and replan.
    pub fn speed_up(&mut self) {
        let end = self.plan_len();
        if self.barrier == Barrier::NextMark || self.barrier == Barrier::None {
            self.fast = true;
        }
        let prev_nom = self.set_nominals(end, true);
        if end == self.len && self.len > 0 {
            self.prev_nominal_v2 = prev_nom;
        }
        self.replan_all();
    }

    /// Withdraw the barrier and the speed-up while moving (a pause request taken back before
    /// it stopped): the head's entry stays fixed, the rest is replanned.
    pub fn clear_barrier(&mut self) {
        self.barrier = Barrier::None;
        self.fast = false;
        let prev_nom = self.set_nominals(self.len, false);
        if self.len > 0 {
            self.prev_nominal_v2 = prev_nom;
        }
        self.replan_all();
    }

    /// True when the plan stands at the barrier: the next block to execute is the barrier's.
    pub fn at_barrier(&self) -> bool {
        match self.barrier {
            Barrier::At(id) => {
                let head_id = if self.len > 0 {
                    self.ring[self.head].id
                } else {
                    self.next_id
                };
                (head_id.wrapping_sub(id) as i32) >= 0
            }
            _ => false,
        }
    }

    /// Remove the barrier and the speed-up and replan from the held state. `exec_rem` is the
    /// unexecuted part of a block held mid-way by a feed hold: (remaining mm, accel mm/s²,
    /// nominal²). Returns the exit speed² for that held block (the new head's entry).
    pub fn release(&mut self, exec_rem: Option<(f32, f32, f32)>) -> f32 {
        self.barrier = Barrier::None;
        self.fast = false;
        let prev_nom = self.set_nominals(self.len, false);
        if self.len > 0 {
            self.prev_nominal_v2 = prev_nom;
            // Head entry: from standstill, or reachable from the held remainder.
            let h = self.head;
            let max = match exec_rem {
                Some((rem, a, nom)) => {
                    let b = &self.ring[h];
                    b.junction_v2.min(nom).min(b.nominal_v2).min(2.0 * a * rem)
                }
                None => 0.0,
            };
            // Plan the ring with a temporarily free head, then fix it.
            let end = self.plan_len();
            let mut next_entry = self.tail_exit_v2(end);
            let mut k = end;
            while k > 0 {
                k -= 1;
                let i = self.idx(k);
                let b = &mut self.ring[i];
                let cap = if k == 0 { max } else { b.entry_max_v2 };
                let v = cap.min(next_entry + 2.0 * b.accel_mm_s2 * b.len_mm);
                b.entry_v2 = v;
                next_entry = v;
            }
            self.planned = 0;
            self.recalculate();
            self.ring[h].entry_v2
        } else {
            self.prev_nominal_v2 = 0.0;
            0.0
        }
    }

    /// Give the first `end` queued blocks their fast (speed-up) or base nominal speed and
    /// recompute their entry limits from it (the head's entry stays fixed). Returns the last
    /// block's nominal speed² (infinity when `end` is 0).
    fn set_nominals(&mut self, end: usize, fast: bool) -> f32 {
        let mut prev_nom = f32::INFINITY;
        for k in 0..end {
            let i = self.idx(k);
            let b = &mut self.ring[i];
            b.nominal_v2 = if fast { b.fast_v2 } else { b.base_v2 };
            if k > 0 {
                b.entry_max_v2 = b.junction_v2.min(prev_nom).min(b.nominal_v2);
            }
            prev_nom = b.nominal_v2;
        }
        prev_nom
    }
}
