//! Lookahead: the backward and forward passes over the planned part of the ring (in v²),
//! bounded by grbl's planned pointer, and the exit speed allowed at its end (0 at the barrier,
//! or what the uncut remainder of the pending move allows).

use super::{fmin, Barrier, Planner};

impl Planner {
    /// Number of ring blocks before the barrier (the part of the ring that is planned).
    pub(super) fn plan_len(&self) -> usize {
        match self.barrier {
            Barrier::At(id) => {
                let mut k = 0;
                while k < self.len && (self.ring[self.idx(k)].id.wrapping_sub(id) as i32) < 0 {
                    k += 1;
                }
                k
            }
            _ => self.len,
        }
    }

    /// Exit speed² allowed at the end of the planned part of the ring.
    pub(super) fn tail_exit_v2(&self, end: usize) -> f32 {
        if end < self.len {
            return 0.0;
        }
        if let Barrier::At(id) = self.barrier {
            if (self.next_id.wrapping_sub(id) as i32) >= 0 {
                return 0.0;
            }
        }
        match self.pending {
            Some(p) => {
                let rem = (p.n - p.next) as f32 * p.seg_len_mm;
                let v = if self.fast {
                    p.fast_mm_s
                } else {
                    p.kin.nominal_mm_s
                };
                let nom = v * v;
                let j = if p.next == 0 {
                    p.first_junction_v2
                } else {
                    f32::INFINITY
                };
                fmin(fmin(nom, j), 2.0 * p.kin.accel_mm_s2 * rem)
            }
            None => 0.0,
        }
    }

    /// Lookahead: backward then forward pass from the planned pointer to the end of the
    /// planned part of the ring. The head block's entry is fixed.
    pub(super) fn recalculate(&mut self) {
        let end = self.plan_len();
        if end == 0 {
            self.planned = 0;
            return;
        }
        if self.planned >= end {
            self.planned = end - 1;
        }
        let mut next_entry = self.tail_exit_v2(end);
        let mut k = end;
        while k > self.planned + 1 {
            k -= 1;
            let i = self.idx(k);
            let b = &mut self.ring[i];
            let v = fmin(b.entry_max_v2, next_entry + 2.0 * b.accel_mm_s2 * b.len_mm);
            b.entry_v2 = v;
            next_entry = v;
        }
        let mut k = self.planned;
        while k + 1 < end {
            let cur = &self.ring[self.idx(k)];
            let (cur_entry_v2, cur_reach_v2) = (cur.entry_v2, 2.0 * cur.accel_mm_s2 * cur.len_mm);
            let ni = self.idx(k + 1);
            let nxt = &mut self.ring[ni];
            if cur_entry_v2 < nxt.entry_v2 {
                let v = cur_entry_v2 + cur_reach_v2;
                if v < nxt.entry_v2 {
                    nxt.entry_v2 = v;
                    self.planned = k + 1;
                }
            }
            if nxt.entry_v2 >= nxt.entry_max_v2 {
                self.planned = k + 1;
            }
            k += 1;
        }
    }

    /// Replan the whole planned part of the ring from the head, ignoring the planned pointer
    /// (done after the speed or the barrier changed; O(ring)). Public so tests can check that
    /// the incremental plan equals the full one.
    pub fn replan_all(&mut self) {
        self.planned = 0;
        self.recalculate();
    }
}
