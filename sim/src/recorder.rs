//! The executor's record: the tool position (X, Y, Z, E in steps) over time, built from the
//! firmware's step events, and the executed blocks in order.
//!
//! Every run of consecutive steps with the same [`BlockTag`] becomes one [`SegRecord`] with its
//! start and end time and position. A segment interrupted by a pause and finished after the
//! resume therefore appears twice, with the service moves in between; the metrics treat the two
//! parts as one execution.

use crate::port::{BlockTag, ExecStatus, Lane, State, StepEvent};
use firmware::motion::StepPos;

/// One executed block (or the part of one executed between two other blocks).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegRecord {
    /// Which block.
    pub tag: BlockTag,
    /// Time of the first step, µs.
    pub t_start_us: u64,
    /// Time of the last step, µs.
    pub t_end_us: u64,
    /// Position before the first step.
    pub start: StepPos,
    /// Position after the last step.
    pub end: StepPos,
    /// Steps taken (all axes).
    pub steps: u32,
}

/// A change of the executive's run state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateChange {
    /// When the sim saw it, µs.
    pub t_us: u64,
    /// The new state.
    pub state: State,
    /// Position then.
    pub pos: StepPos,
}

/// Records step events into positions and executed blocks.
#[derive(Clone, Debug, Default)]
pub struct Recorder {
    /// Position now, steps.
    pub pos: StepPos,
    /// Executed blocks in order (only when `keep_records`).
    pub records: Vec<SegRecord>,
    /// Run-state changes in order.
    pub states: Vec<StateChange>,
    /// Steps seen.
    pub steps: u64,
    /// Time of the last step, µs.
    pub last_step_us: u64,
    /// Keep [`SegRecord`]s (off for pure speed runs).
    pub keep_records: bool,
    /// Records are consumed as they complete ([`Recorder::take_complete`] removes them):
    /// `records` then holds only what has not been taken yet (see `crate::stream`).
    pub stream: bool,
    /// Records taken so far by [`Recorder::take_complete`].
    pub taken: usize,
    cur: Option<BlockTag>,
}

impl Recorder {
    /// A recorder that keeps every executed block.
    pub fn new() -> Self {
        Self {
            keep_records: true,
            ..Self::default()
        }
    }

    /// Take one step event. Returns true when it starts a new block.
    #[inline]
    pub fn on_step(&mut self, ev: &StepEvent) -> bool {
        let tag = BlockTag::of(ev);
        let new_block = self.cur != Some(tag);
        if new_block {
            self.cur = Some(tag);
            if self.keep_records {
                self.records.push(SegRecord {
                    tag,
                    t_start_us: ev.t_us,
                    t_end_us: ev.t_us,
                    start: self.pos,
                    end: self.pos,
                    steps: 0,
                });
            }
        }
        let mut n = 0;
        for (i, p) in self.pos.iter_mut().enumerate() {
            if ev.axis_mask & (1 << i) != 0 {
                *p += if ev.dir_mask & (1 << i) != 0 { 1 } else { -1 };
                n += 1;
            }
        }
        self.steps += n;
        self.last_step_us = ev.t_us;
        if self.keep_records {
            if let Some(r) = self.records.last_mut() {
                r.end = self.pos;
                r.t_end_us = ev.t_us;
                r.steps += n as u32;
            }
        }
        new_block
    }

    /// The records complete and not taken yet (every one but the last, which may still grow;
    /// with `all`, the last too): removed from `records` when streaming, else only counted.
    pub fn take_complete(&mut self, all: bool) -> Vec<SegRecord> {
        let first = if self.stream { 0 } else { self.taken };
        let end = if all {
            self.records.len()
        } else {
            self.records.len().saturating_sub(1)
        };
        if end <= first {
            return Vec::new();
        }
        self.taken += end - first;
        if self.stream {
            self.records.drain(..end).collect()
        } else {
            self.records[first..end].to_vec()
        }
    }

    /// Note the executive's status at `t_us`; records a [`StateChange`] when the state changed.
    pub fn on_status(&mut self, st: &ExecStatus, t_us: u64) {
        if self.states.last().map(|s| s.state) != Some(st.state) {
            self.states.push(StateChange {
                t_us,
                state: st.state,
                pos: self.pos,
            });
        }
    }

    /// Time of the first change into `state` at or after `from_us`.
    pub fn first_state_after(&self, state: State, from_us: u64) -> Option<u64> {
        self.states
            .iter()
            .find(|s| s.state == state && s.t_us >= from_us)
            .map(|s| s.t_us)
    }
}

/// Millimetres per step of each axis, for turning records into lengths.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// mm per step, indexed by axis.
    pub mm_per_step: [f64; 4],
}

impl Scale {
    /// From a machine configuration.
    pub fn from_config(cfg: &firmware::config::MachineConfig) -> Self {
        let mut mm_per_step = [0.0; 4];
        for (m, a) in mm_per_step.iter_mut().zip(cfg.axes.iter()) {
            *m = 1.0 / f64::from(a.steps_per_mm);
        }
        Self { mm_per_step }
    }

    /// Position in mm.
    pub fn mm(&self, p: &StepPos) -> [f64; 4] {
        let mut out = [0.0; 4];
        for i in 0..4 {
            out[i] = f64::from(p[i]) * self.mm_per_step[i];
        }
        out
    }

    /// Straight XYZ distance between two positions, mm.
    pub fn xyz_dist_mm(&self, a: &StepPos, b: &StepPos) -> f64 {
        let mut s = 0.0;
        for i in 0..3 {
            let d = f64::from(b[i] - a[i]) * self.mm_per_step[i];
            s += d * d;
        }
        s.sqrt()
    }

    /// E difference `b - a`, mm of filament.
    pub fn e_mm(&self, a: &StepPos, b: &StepPos) -> f64 {
        f64::from(b[3] - a[3]) * self.mm_per_step[3]
    }
}

/// True for records of the job (as opposed to pause/resume service moves), given how to
/// classify a job-lane sequence number (host-split marks its own inserted lines as service).
pub fn is_job(tag: &BlockTag, service_seq: &dyn Fn(u32) -> bool) -> bool {
    tag.lane == Lane::Job && !service_seq(tag.seq)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ev(t: u64, axis: u8, dir: i8, seq: u32) -> StepEvent {
        StepEvent {
            t_us: t,
            t_ns: t * 1000,
            axis_mask: 1 << axis,
            dir_mask: if dir > 0 { 1 << axis } else { 0 },
            seq,
            seg: 0,
            kind: firmware::planner::BlockKind::Job,
        }
    }

    #[test]
    fn records_blocks_and_positions() {
        let mut r = Recorder::new();
        assert!(r.on_step(&ev(10, 0, 1, 1)));
        assert!(!r.on_step(&ev(20, 0, 1, 1)));
        assert!(r.on_step(&ev(30, 1, -1, 2)));
        assert_eq!(r.pos, [2, -1, 0, 0]);
        assert_eq!(r.records.len(), 2);
        assert_eq!(r.records[0].start, [0, 0, 0, 0]);
        assert_eq!(r.records[0].end, [2, 0, 0, 0]);
        assert_eq!(r.records[0].t_end_us, 20);
        assert_eq!(r.records[1].steps, 1);
        // Bits above the four axes are ignored.
        r.on_step(&ev(40, 6, 1, 2));
        assert_eq!(r.pos, [2, -1, 0, 0]);
    }

    #[test]
    fn scale_lengths() {
        let s = Scale::from_config(&firmware::config::MachineConfig::ENDER3);
        let d = s.xyz_dist_mm(&[0, 0, 0, 0], &[240, 320, 0, 93]);
        assert!((d - 5.0).abs() < 1e-9);
        assert!((s.e_mm(&[0, 0, 0, 0], &[0, 0, 0, 93]) - 1.0).abs() < 1e-9);
    }
}
