//! Comparing the run with the pause (A) against its reference (B) as they run, so memory stays
//! flat with job length: the executed blocks are taken from each recorder as they complete
//! ([`crate::recorder::Recorder::take_complete`]) and compared as two collapsed key sequences
//! ([`Compare`]); what the pause figures need of B (where a line ends) is kept only for the few
//! lines around the pause ([`LineEnds`]). `crate::run` advances A and B in turns so neither runs
//! far ahead of the other, and keeps A's records from the request to the resume (the window
//! [`crate::metrics::compute`] reads).

use crate::engine::Engine;
use crate::hostlink::Origin;
use crate::port::{Executive, Lane};
use crate::recorder::SegRecord;
use firmware::motion::StepPos;
use std::collections::{BTreeMap, HashMap, VecDeque};

/// A job block: (job line, segment).
pub type Key = (usize, u32);

/// Key of a homing move (`G28`): the firmware gives homing blocks no sequence number
/// ([`HOMING_SEQ`]), so they are compared as homing moves in order, not as whatever job line the
/// sequence map holds last when the record is read (which depends on when that is: a streamed
/// comparison read them at other moments in the run with the pause than in its reference, and
/// counted one move lost and another duplicated).
pub const HOMING_LINE: usize = usize::MAX;

/// The sequence number the firmware gives homing blocks (`printer/homing.rs`).
pub const HOMING_SEQ: u32 = u32::MAX;

/// The job block a record executed, or `None` for service moves and host-inserted lines.
pub fn key_of<E: Executive>(e: &Engine<E>, r: &SegRecord) -> Option<Key> {
    if r.tag.lane == Lane::Service {
        return None;
    }
    if r.tag.seq == HOMING_SEQ {
        return Some((HOMING_LINE, r.tag.segment));
    }
    match e.origin_of_seq(r.tag.seq) {
        Some(Origin::Job(line)) => Some((line, r.tag.segment)),
        Some(_) => None,
        // Unknown numbering: keep it as a job block keyed by its sequence number.
        None => Some((HOMING_LINE - 1 - r.tag.seq as usize, r.tag.segment)),
    }
}

/// Which run a key comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The run with the pause.
    A,
    /// The reference.
    B,
}

/// The executed job blocks of A against B, fed in order: each side's keys collapsed (a block
/// interrupted by the pause and finished after it, with service moves between, counts once),
/// then paired up. Memory: the keys one side is ahead of the other, plus the blocks that
/// differ.
#[derive(Clone, Debug, Default)]
pub struct Compare {
    pend_a: VecDeque<Key>,
    pend_b: VecDeque<Key>,
    last_a: Option<Key>,
    last_b: Option<Key>,
    out_of_order: bool,
    /// Per block: executions in B minus executions in A (only non-zero entries).
    count: HashMap<Key, i64>,
    /// Collapsed keys fed from A.
    pub fed_a: u64,
    /// Collapsed keys fed from B.
    pub fed_b: u64,
}

/// What [`Compare`] found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Comparison {
    /// The executed job segments equal the reference's, in order.
    pub in_order: bool,
    /// Segments never executed.
    pub lost_segments: usize,
    /// Segments executed more than once.
    pub duplicated_segments: usize,
    /// Job lines with a segment never executed.
    pub lost_moves: usize,
    /// Job lines with a segment executed more than once.
    pub duplicated_moves: usize,
}

impl Compare {
    /// Feed the next key of one side.
    pub fn push(&mut self, side: Side, key: Option<Key>) {
        let Some(k) = key else { return };
        let (last, pend, fed) = match side {
            Side::A => (&mut self.last_a, &mut self.pend_a, &mut self.fed_a),
            Side::B => (&mut self.last_b, &mut self.pend_b, &mut self.fed_b),
        };
        if *last == Some(k) {
            return;
        }
        *last = Some(k);
        pend.push_back(k);
        *fed += 1;
        while !self.pend_a.is_empty() && !self.pend_b.is_empty() {
            let (Some(a), Some(b)) = (self.pend_a.pop_front(), self.pend_b.pop_front()) else {
                break;
            };
            if a != b {
                self.out_of_order = true;
                self.add(b, 1);
                self.add(a, -1);
            }
        }
    }

    fn add(&mut self, k: Key, d: i64) {
        let c = self.count.entry(k).or_default();
        *c += d;
        if *c == 0 {
            self.count.remove(&k);
        }
    }

    /// Keys waiting for the other side (for tests of the memory bound).
    pub fn pending(&self) -> usize {
        self.pend_a.len() + self.pend_b.len()
    }

    /// Both sides fed completely: the result.
    pub fn finish(mut self) -> Comparison {
        let rest_a: Vec<Key> = self.pend_a.drain(..).collect();
        let rest_b: Vec<Key> = self.pend_b.drain(..).collect();
        if !rest_a.is_empty() || !rest_b.is_empty() {
            self.out_of_order = true;
        }
        for k in rest_a {
            self.add(k, -1);
        }
        for k in rest_b {
            self.add(k, 1);
        }
        let mut c = Comparison {
            in_order: !self.out_of_order,
            ..Comparison::default()
        };
        let mut lost_lines = std::collections::BTreeSet::new();
        let mut dup_lines = std::collections::BTreeSet::new();
        for (k, n) in &self.count {
            if *n > 0 {
                c.lost_segments += *n as usize;
                lost_lines.insert(k.0);
            } else if *n < 0 {
                c.duplicated_segments += (-*n) as usize;
                dup_lines.insert(k.0);
            }
        }
        c.lost_moves = lost_lines.len();
        c.duplicated_moves = dup_lines.len();
        c
    }
}

/// Where each job line ends in the reference (the end of its last executed block), kept for
/// lines from `floor` on (and up to `ceil` once set): the lines around the pause.
#[derive(Clone, Debug, Default)]
pub struct LineEnds {
    ends: BTreeMap<usize, StepPos>,
    floor: usize,
    ceil: Option<usize>,
}

impl LineEnds {
    /// Note a record of the reference.
    pub fn note(&mut self, key: Option<Key>, r: &SegRecord) {
        if let Some((line, _)) = key {
            if line >= self.floor && self.ceil.is_none_or(|c| line <= c) {
                self.ends.insert(line, r.end);
            }
        }
    }

    /// Forget lines below `floor` (they can no longer be asked for).
    pub fn raise_floor(&mut self, floor: usize) {
        if floor > self.floor {
            self.floor = floor;
            self.ends = self.ends.split_off(&floor);
        }
    }

    /// Keep nothing above `ceil` from now on.
    pub fn set_ceil(&mut self, ceil: usize) {
        self.ceil = Some(ceil);
        if let Some(above) = ceil.checked_add(1) {
            let _ = self.ends.split_off(&above);
        }
    }

    /// Where line `line` ends in the reference, if known.
    pub fn get(&self, line: usize) -> Option<&StepPos> {
        self.ends.get(&line)
    }

    /// Lines held (for tests of the memory bound).
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// True when no line is held.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }
}

/// Take the complete records of one run (all with `all`, at its end) into the comparison (and,
/// for B, the line ends). Returns the smallest job line still in the recorder's window.
pub fn feed<E: Executive>(
    e: &mut Engine<E>,
    side: Side,
    all: bool,
    cmp: &mut Compare,
    ends: &mut LineEnds,
) {
    let recs = e.rec.take_complete(all);
    for r in &recs {
        let k = key_of(e, r);
        cmp.push(side, k);
        if side == Side::B {
            ends.note(k, r);
        }
    }
    if e.rec.stream {
        // Origins of blocks no longer recorded are never asked for again (homing blocks carry
        // no job number: `SeqMap::forget_before` ignores theirs).
        if let Some(seq) = e
            .rec
            .records
            .iter()
            .filter(|r| r.tag.lane == Lane::Job)
            .map(|r| r.tag.seq)
            .min()
        {
            e.seqs.forget_before(seq);
        } else if let Some(r) = recs.iter().rev().find(|r| r.tag.lane == Lane::Job) {
            e.seqs.forget_before(r.tag.seq);
        }
    }
}

/// The smallest job line in a run's recorder window (`None` when it holds no job block).
pub fn window_floor<E: Executive>(e: &Engine<E>) -> Option<usize> {
    e.rec
        .records
        .iter()
        .filter_map(|r| key_of(e, r))
        .map(|k| k.0)
        .min()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(cmp: &mut Compare, side: Side, keys: &[Option<Key>]) {
        for k in keys {
            cmp.push(side, *k);
        }
    }

    #[test]
    fn equal_runs_compare_in_order_with_little_pending() {
        let mut c = Compare::default();
        for i in 0..10_000usize {
            c.push(Side::A, Some((i, 0)));
            c.push(Side::A, None);
            c.push(Side::B, Some((i, 0)));
            assert!(c.pending() <= 1);
        }
        assert_eq!(
            c.finish(),
            Comparison {
                in_order: true,
                ..Comparison::default()
            }
        );
    }

    #[test]
    fn interrupted_block_counts_once_lost_and_duplicated_are_counted() {
        let mut c = Compare::default();
        // A: block (2,0) interrupted by service moves and finished after them.
        run(
            &mut c,
            Side::A,
            &[
                Some((1, 0)),
                Some((2, 0)),
                None,
                None,
                Some((2, 0)),
                Some((3, 0)),
            ],
        );
        run(&mut c, Side::B, &[Some((1, 0)), Some((2, 0)), Some((3, 0))]);
        assert!(c.finish().in_order);

        let mut c = Compare::default();
        run(
            &mut c,
            Side::A,
            &[Some((1, 0)), Some((3, 0)), Some((3, 1)), Some((3, 1))],
        );
        run(
            &mut c,
            Side::B,
            &[Some((1, 0)), Some((2, 0)), Some((3, 0)), Some((3, 1))],
        );
        let r = c.finish();
        assert!(!r.in_order);
        assert_eq!((r.lost_segments, r.lost_moves), (1, 1));
        // (3,1) twice in a row collapses: the repeat is not a second execution.
        assert_eq!(r.duplicated_segments, 0);
    }
}
