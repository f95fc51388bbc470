//! Step generator: turns the executing block into per-axis step events with timestamps.
//!
//! Bresenham over the axis with the most steps (the *major* axis), with the trapezoid integrated
//! in closed form: the time of every [`SLICE_STEPS`]-th major step is computed exactly from the
//! profile (one `sqrtf`), and the steps between two such points are spread evenly (integer
//! nanosecond arithmetic). After a start from standstill the slices grow 1, 2, 4, 8 steps, so
//! the first steps (√t spacing) are timed exactly. The per-event work is a handful of integer additions per axis; the
//! square root is amortised over a slice. The MCU timer interrupt and the simulator both pull
//! events with [`StepGen::next_event`].
//!
//! Braking mid-block (feed hold): [`StepGen::hold`] replaces the profile from the current step
//! by a deceleration at the block's acceleration; blocks loaded while braking continue the
//! deceleration. When the speed reaches zero inside a block, that block stays loaded, with its
//! Bresenham state, as a *held* block: [`StepGen::resume_held`] continues it from exactly that
//! step.

use crate::motion::{StepPos, AXES};
use crate::planner::{fmax, fmin, sqrtf, Block, BlockKind, PlannedBlock};

/// Major-axis steps per slice (one exact profile time per slice).
pub const SLICE_STEPS: u32 = 8;

/// One step event: the axes in `axis_mask` take one step at `t_us`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepEvent {
    /// Time of the step, µs since the printer's time origin.
    pub t_us: u64,
    /// Time of the step, ns (the same instant, finer).
    pub t_ns: u64,
    /// Bit `i` set: axis `i` (X=0, Y=1, Z=2, E=3) steps.
    pub axis_mask: u8,
    /// Bit `i` set: axis `i` moves in the positive direction.
    pub dir_mask: u8,
    /// Job sequence number of the block the step belongs to.
    pub seq: u32,
    /// Segment index of that block within its move.
    pub seg: u32,
    /// What produced the block (job, homing, service lane).
    pub kind: BlockKind,
}

/// A trapezoidal speed profile over a distance interval of a block.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Profile {
    /// Start distance within the block, mm.
    pub s0: f32,
    /// End distance within the block, mm.
    pub s_end: f32,
    /// Speed at `s0`, mm/s.
    pub v0: f32,
    /// Cruise (peak) speed, mm/s.
    pub vc: f32,
    /// Speed at `s_end`, mm/s.
    pub v1: f32,
    /// Acceleration and deceleration, mm/s².
    pub a: f32,
    /// Length of the acceleration ramp, mm.
    pub d_acc: f32,
    /// Length of the deceleration ramp, mm.
    pub d_dec: f32,
}

impl Profile {
    /// The fastest trapezoid from `v0` to `v1` over `s0..s_end` with cruise at most `vmax`.
    pub fn new(s0: f32, s_end: f32, v0: f32, vmax: f32, v1: f32, a: f32) -> Self {
        let d = fmax(s_end - s0, 0.0);
        let a = if a > 0.0 { a } else { 1.0 };
        let mut vc = fmax(fmax(vmax, v0), v1);
        let mut d_acc = (vc * vc - v0 * v0) / (2.0 * a);
        let mut d_dec = (vc * vc - v1 * v1) / (2.0 * a);
        if d_acc + d_dec > d {
            let vc2 = (2.0 * a * d + v0 * v0 + v1 * v1) * 0.5;
            vc = fmax(fmax(sqrtf(vc2), v0), v1);
            d_acc = ((vc * vc - v0 * v0) / (2.0 * a)).clamp(0.0, d);
            d_dec = d - d_acc;
        }
        Profile {
            s0,
            s_end,
            v0,
            // Only a profile that never moves gets a stand-in cruise speed (for the time
            // formulas); a slow block keeps its own: a floor above it would run an axis beyond
            // its limit (issue 16: `G1 X1 E91335` ran E at 1e-3 mm/s × 91335 = 91 mm/s).
            vc: if vc > 0.0 { vc } else { 1.0e-3 },
            v1,
            a,
            d_acc,
            d_dec,
        }
    }

    /// A pure deceleration from `v0` at `s0`: ends at `s_end` or where the speed reaches 0.
    pub fn brake(s0: f32, s_end: f32, v0: f32, a: f32) -> Self {
        let a = if a > 0.0 { a } else { 1.0 };
        let stop = s0 + v0 * v0 / (2.0 * a);
        let end = fmin(stop, s_end);
        let v1_2 = fmax(v0 * v0 - 2.0 * a * (end - s0), 0.0);
        let v1 = if stop <= s_end { 0.0 } else { sqrtf(v1_2) };
        Profile {
            s0,
            s_end: end,
            v0,
            vc: fmax(v0, 1.0e-3),
            v1,
            a,
            d_acc: 0.0,
            d_dec: end - s0,
        }
    }

    /// Seconds from `s0` to distance `s` along the profile.
    pub fn time_at(&self, s: f32) -> f32 {
        let x = (s - self.s0).clamp(0.0, self.s_end - self.s0);
        let d = self.s_end - self.s0;
        let t_acc = (self.vc - self.v0) / self.a;
        let cruise = d - self.d_acc - self.d_dec;
        if x <= self.d_acc {
            (sqrtf(self.v0 * self.v0 + 2.0 * self.a * x) - self.v0) / self.a
        } else if x <= self.d_acc + cruise {
            t_acc + (x - self.d_acc) / self.vc
        } else {
            let y = x - self.d_acc - cruise;
            let r = fmax(self.vc * self.vc - 2.0 * self.a * y, 0.0);
            t_acc + fmax(cruise, 0.0) / self.vc + (self.vc - sqrtf(r)) / self.a
        }
    }

    /// Speed at distance `s`, mm/s.
    pub fn speed_at(&self, s: f32) -> f32 {
        let x = (s - self.s0).clamp(0.0, self.s_end - self.s0);
        let d = self.s_end - self.s0;
        if x <= self.d_acc {
            sqrtf(self.v0 * self.v0 + 2.0 * self.a * x)
        } else if x <= d - self.d_dec {
            self.vc
        } else {
            let y = x - (d - self.d_dec);
            sqrtf(fmax(self.vc * self.vc - 2.0 * self.a * y, 0.0))
        }
    }
}

/// The state of a block being stepped (also what a feed hold keeps).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExecBlock {
    /// The block and its planned speeds.
    pub planned: PlannedBlock,
    /// Major-axis steps of the block.
    pub n: u32,
    /// Major-axis steps taken.
    pub done: u32,
    /// Stop after this many major steps (`n`, or the brake point).
    pub stop_at: u32,
    abs: [u32; AXES],
    acc: [u32; AXES],
    prof_step: u32,
    dir_mask: u8,
    prof: Profile,
    t_prof_ns: u64,
    slice_end: u32,
    slice_m: u32,
    slice_dt_ns: u64,
    slice_rem: u32,
    slice_acc: u32,
}

impl ExecBlock {
    fn s_of(&self, k: u32) -> f32 {
        if self.n == 0 {
            return 0.0;
        }
        self.planned.block.len_mm * (k as f32 / self.n as f32)
    }

    /// Distance left in the block, mm.
    pub fn remaining_mm(&self) -> f32 {
        self.planned.block.len_mm - self.s_of(self.done)
    }

    /// True when every step of the block has been taken.
    pub fn finished(&self) -> bool {
        self.done >= self.n
    }
}

/// The step generator. See the module documentation.
#[derive(Clone, Debug, Default)]
pub struct StepGen {
    exec: Option<ExecBlock>,
    pos: StepPos,
    t_last_ns: u64,
    v_end: f32,
    braking: bool,
}

fn secs_to_ns(t: f32) -> u64 {
    if t.is_finite() && t > 0.0 {
        let ns = t * 1.0e9;
        // Below 2³² the 32-bit conversion (one VCVT on the MCU) truncates to the same integer
        // as the 64-bit one (a library call there).
        if ns < 4_294_967_296.0 {
            u64::from(ns as u32)
        } else {
            ns as u64
        }
    } else {
        0
    }
}

/// Quotient and remainder of `n / d` (`d ≥ 1`), exact, with 32-bit divisions only when
/// `d < 2¹⁶` (three hardware UDIVs on a Cortex-M instead of the ~100-instruction 64-bit
/// division routine); other divisors use the plain 64-bit division.
#[inline]
pub fn div_small(n: u64, d: u32) -> (u64, u32) {
    let d = d.max(1);
    if n >> 32 == 0 {
        let n = n as u32;
        return (u64::from(n / d), n % d);
    }
    if d >= 1 << 16 {
        return (n / u64::from(d), (n % u64::from(d)) as u32);
    }
    // Long division in 32/16-bit digits: every partial dividend is r·2¹⁶ + digit < 2³².
    let hi = (n >> 32) as u32;
    let (q_hi, r) = (hi / d, hi % d);
    let mid = (r << 16) | ((n >> 16) as u32 & 0xFFFF);
    let (q_mid, r) = (mid / d, mid % d);
    let lo = (r << 16) | (n as u32 & 0xFFFF);
    let (q_lo, r) = (lo / d, lo % d);
    (
        (u64::from(q_hi) << 32) + (u64::from(q_mid) << 16) + u64::from(q_lo),
        r,
    )
}

impl StepGen {
    /// An idle step generator at position 0, time 0.
    pub const fn new() -> Self {
        Self {
            exec: None,
            pos: [0; AXES],
            t_last_ns: 0,
            v_end: 0.0,
            braking: false,
        }
    }

    /// Position after the last emitted step.
    pub fn position(&self) -> StepPos {
        self.pos
    }

    /// Set the position (G92, homing, the pause's E bookkeeping). Only when idle.
    pub fn set_position(&mut self, pos: StepPos) {
        self.pos = pos;
    }

    /// Time of the last emitted step (or block start), ns.
    pub fn last_time_ns(&self) -> u64 {
        self.t_last_ns
    }

    /// The loaded block, if any.
    pub fn current(&self) -> Option<&ExecBlock> {
        self.exec.as_ref()
    }

    /// True while braking for a feed hold.
    pub fn is_braking(&self) -> bool {
        self.braking
    }

    /// True when no block is loaded or the loaded one will take no more steps (finished, or
    /// held by a feed hold).
    pub fn is_stopped(&self) -> bool {
        self.exec.is_none_or(|e| e.done >= e.stop_at)
    }

    /// True when the loaded block has taken all its steps.
    pub fn block_finished(&self) -> bool {
        self.exec.is_some_and(|e| e.finished())
    }

    /// Speed at the end of the last loaded profile, mm/s.
    pub fn exit_speed_mm_s(&self) -> f32 {
        self.v_end
    }

    /// Remove the finished (or held) block and return it.
    pub fn unload(&mut self) -> Option<ExecBlock> {
        self.exec.take()
    }

    /// Put back a held block (after the pause's service moves returned to its position).
    pub fn restore(&mut self, mut e: ExecBlock) {
        // Keep the slice inside the stop (the per-event path relies on it).
        e.slice_end = e.slice_end.min(e.stop_at);
        self.exec = Some(e);
    }

    /// When `pb`, loaded at `now_ns`, starts: at the last step of the previous block when it is
    /// entered at speed (the motion is continuous, whatever the caller's clock says), or no
    /// earlier than `now_ns` when the machine stood still in between. [`Self::load`] uses it.
    pub fn start_ns(&self, pb: &PlannedBlock, now_ns: u64) -> u64 {
        let at_speed = if self.braking {
            self.v_end > 0.0
        } else {
            pb.entry_v2 > 0.0
        };
        if at_speed {
            self.t_last_ns
        } else {
            self.t_last_ns.max(now_ns)
        }
    }

    /// Load the next block; it starts at the end of the previous one, or at `now_ns` when the
    /// machine stood still in between. While braking, the block continues the deceleration.
    pub fn load(&mut self, pb: PlannedBlock, now_ns: u64) {
        let b: &Block = &pb.block;
        let mut abs = [0u32; AXES];
        let mut dir = 0u8;
        let mut n = 0u32;
        for (i, (a, d)) in abs.iter_mut().zip(b.delta.iter()).enumerate() {
            *a = d.unsigned_abs();
            if *d > 0 {
                dir |= 1 << i;
            }
            n = n.max(*a);
        }
        let len = b.len_mm;
        let a = b.accel_mm_s2;
        let v0 = if self.braking {
            self.v_end
        } else {
            sqrtf(fmax(pb.entry_v2, 0.0))
        };
        let prof = if self.braking {
            Profile::brake(0.0, len, v0, a)
        } else {
            Profile::new(
                0.0,
                len,
                v0,
                sqrtf(fmax(b.nominal_v2, 0.0)),
                sqrtf(fmax(pb.exit_v2, 0.0)),
                a,
            )
        };
        let start = self.start_ns(&pb, now_ns);
        let mut e = ExecBlock {
            planned: pb,
            n,
            done: 0,
            stop_at: n,
            abs,
            acc: [n / 2; AXES],
            prof_step: 0,
            dir_mask: dir,
            prof,
            t_prof_ns: start,
            slice_end: 0,
            slice_m: 0,
            slice_dt_ns: 0,
            slice_rem: 0,
            slice_acc: 0,
        };
        if self.braking && prof.v1 <= 0.0 {
            e.stop_at = Self::stop_index(&e, prof.s_end);
        }
        self.v_end = prof.v1;
        self.t_last_ns = start;
        self.exec = Some(e);
    }

    fn stop_index(e: &ExecBlock, s_stop: f32) -> u32 {
        let len = e.planned.block.len_mm;
        if len <= 0.0 {
            return e.n;
        }
        let k = libm::floorf(s_stop / len * e.n as f32);
        let k = if k >= e.n as f32 {
            e.n
        } else {
            fmax(k, 0.0) as u32
        };
        k.max(e.done).min(e.n)
    }

    /// Feed hold: from the current step, decelerate at the block's acceleration. Returns the
    /// speed (mm/s) the brake started from. Blocks loaded later continue the deceleration until
    /// [`StepGen::resume_held`] or [`StepGen::end_hold`].
    pub fn hold(&mut self, now_ns: u64) -> f32 {
        self.braking = true;
        let Some(e) = self.exec.as_mut() else {
            self.v_end = 0.0;
            return 0.0;
        };
        if e.done >= e.stop_at {
            // Between blocks: the next block continues from the exit speed.
            return self.v_end;
        }
        let s_h = e.s_of(e.done);
        let v_h = e.prof.speed_at(s_h);
        let len = e.planned.block.len_mm;
        let prof = Profile::brake(s_h, len, v_h, e.planned.block.accel_mm_s2);
        e.prof = prof;
        e.prof_step = e.done;
        e.t_prof_ns = self.t_last_ns.max(now_ns);
        e.slice_end = e.done;
        if prof.v1 <= 0.0 {
            e.stop_at = Self::stop_index(e, prof.s_end);
        }
        self.t_last_ns = e.t_prof_ns;
        self.v_end = prof.v1;
        v_h
    }

    /// End braking mode without a held block (the brake ended exactly at a block end).
    pub fn end_hold(&mut self) {
        self.braking = false;
        self.v_end = 0.0;
    }

    /// Continue a held block from standstill at `now_ns`, leaving it at `exit_v2`.
    pub fn resume_held(&mut self, exit_v2: f32, now_ns: u64) {
        self.braking = false;
        if let Some(e) = self.exec.as_mut() {
            let s = e.s_of(e.done);
            let b = e.planned.block;
            let v1 = sqrtf(fmax(exit_v2, 0.0));
            e.prof = Profile::new(
                s,
                b.len_mm,
                0.0,
                sqrtf(fmax(b.nominal_v2, 0.0)),
                v1,
                b.accel_mm_s2,
            );
            e.stop_at = e.n;
            e.prof_step = e.done;
            e.t_prof_ns = self.t_last_ns.max(now_ns);
            e.slice_end = e.done;
            self.t_last_ns = e.t_prof_ns;
            self.v_end = v1;
        } else {
            self.v_end = 0.0;
        }
    }

    /// Time of the next step event, µs, if a step is due in the loaded block.
    #[inline(always)]
    pub fn peek_time_ns(&mut self) -> Option<u64> {
        let e = slice_ready(&mut self.exec, self.t_last_ns)?;
        let mut t = self.t_last_ns + e.slice_dt_ns;
        if e.slice_acc + e.slice_rem >= e.slice_m {
            t += 1;
        }
        Some(t)
    }

    /// Once per slice (up to 8 steps): out of line, so the per-event path stays small.
    #[inline(never)]
    fn prepare_slice(e: &mut ExecBlock, t_last_ns: u64) {
        // Slices grow 1, 2, 4, 8 steps after a profile starts, so the first steps after a
        // standstill get exact times (√t spacing) and later ones cost one sqrt per 8 steps.
        let len = if e.prof.v0 <= 0.0 {
            e.done.saturating_sub(e.prof_step).clamp(1, SLICE_STEPS)
        } else {
            SLICE_STEPS
        };
        let k1 = (e.done + len).min(e.stop_at);
        let t1 = e.t_prof_ns + secs_to_ns(e.prof.time_at(e.s_of(k1)));
        let t1 = t1.max(t_last_ns);
        // At most SLICE_STEPS.
        let m = (k1 - e.done).max(1);
        let span = t1 - t_last_ns;
        e.slice_end = k1;
        e.slice_m = m;
        // m ≤ SLICE_STEPS.
        let (dt, rem) = div_small(span, m);
        e.slice_dt_ns = dt;
        e.slice_rem = rem;
        e.slice_acc = 0;
    }

    /// The next step event of the loaded block, or `None` when it has none left (finished or
    /// held): then unload/load the next block.
    #[inline(always)]
    pub fn next_event(&mut self) -> Option<StepEvent> {
        let e = slice_ready(&mut self.exec, self.t_last_ns)?;
        let mut t = self.t_last_ns + e.slice_dt_ns;
        e.slice_acc += e.slice_rem;
        if e.slice_acc >= e.slice_m {
            e.slice_acc -= e.slice_m;
            t += 1;
        }
        self.t_last_ns = t;
        e.done += 1;
        let mut mask = 0u8;
        for i in 0..AXES {
            // acc < n and abs ≤ n ≤ 2³¹: the sum fits in u32.
            e.acc[i] += e.abs[i];
            if e.acc[i] >= e.n {
                e.acc[i] -= e.n;
                mask |= 1 << i;
                // +1 for a positive direction, −1 otherwise, without a branch.
                let up = i32::from((e.dir_mask >> i) & 1);
                self.pos[i] = self.pos[i].wrapping_add(2 * up - 1);
            }
        }
        Some(StepEvent {
            t_us: div_small(t, 1000).0,
            t_ns: t,
            axis_mask: mask,
            dir_mask: e.dir_mask,
            seq: e.planned.block.seq,
            seg: e.planned.block.seg,
            kind: e.planned.block.kind,
        })
    }
}

/// The loaded block with a slice ready for its next step — the next slice is prepared when the
/// current one is used up —, or `None` when the block has no step left: the set-up shared by
/// [`StepGen::peek_time_ns`] and [`StepGen::next_event`] (a function of the field, so the caller
/// keeps its other fields).
#[inline(always)]
fn slice_ready(exec: &mut Option<ExecBlock>, t_last_ns: u64) -> Option<&mut ExecBlock> {
    let e = exec.as_mut()?;
    // `slice_end <= stop_at` always (a slice never runs past the stop, and every change of
    // `stop_at` restarts the slice at `done`): inside a slice, one compare suffices.
    if e.done >= e.slice_end {
        if e.done >= e.stop_at {
            return None;
        }
        StepGen::prepare_slice(e, t_last_ns);
    }
    Some(e)
}
