//! The model's steps in emission order, with emission thinning: runs of short straight strings
//! merged on the fly, keeping their volume and time.

use crate::design::model::{Step, Str};
use glam::DVec3;

/// Emission thinning: merges runs of contiguous straight strings until each merged string is
/// at least `min_len_mm` long. The merged string keeps the run's volume (cross-section =
/// volume ÷ chord) and its time (speed = chord ÷ Σ time).
pub fn thin(steps: &[Step], min_len_mm: f64) -> Vec<Step> {
    Emission::new(steps, Some(min_len_mm))
        .map(|item| match item {
            Item::Str(s, _) => Step::String(s),
            Item::Ref(s, _) => Step::String(*s),
            Item::Step(s) => s.clone(),
        })
        .collect()
}

/// A run of short strings being merged (the first one by reference: no copy per string).
struct Acc<'a> {
    first: &'a Str,
    end: DVec3,
    volume: f64,
    time: f64,
    len: f64,
    n: usize,
}

impl<'a> Acc<'a> {
    fn new(st: &'a Str) -> Self {
        let l = st.len_mm();
        Acc {
            first: st,
            end: st.end,
            volume: st.cross_mm2 * l,
            time: l / st.speed_mm_s,
            len: l,
            n: 1,
        }
    }

    /// The merged string (or the run's only one) and its length (`Str::len_mm` of it,
    /// computed once).
    fn finish(self) -> Item<'a> {
        if self.n == 1 {
            return Item::Ref(self.first, self.len);
        }
        let start = self.first.start;
        let chord = start.distance(self.end);
        if chord <= 1e-9 || self.time <= 0.0 {
            return Item::Ref(self.first, self.first.len_mm());
        }
        Item::Str(
            Str::line(start, self.end, self.volume / chord, chord / self.time),
            chord,
        )
    }
}

/// One step as written: a merged string with its length, a string of the model with its
/// length, or any other step of the model.
pub(super) enum Item<'a> {
    Str(Str, f64),
    Ref(&'a Str, f64),
    Step(&'a Step),
}

/// The model's steps in emission order, thinned on the fly when `min_len_mm` is given.
pub(super) struct Emission<'a> {
    steps: std::slice::Iter<'a, Step>,
    min_len_mm: Option<f64>,
    acc: Option<Acc<'a>>,
    /// A step that ended a run, given out after the run's merged string.
    held: Option<&'a Step>,
    /// Strings of the model consumed so far.
    pub(super) consumed_strings: usize,
}

impl<'a> Emission<'a> {
    pub(super) fn new(steps: &'a [Step], min_len_mm: Option<f64>) -> Self {
        Emission {
            steps: steps.iter(),
            min_len_mm,
            acc: None,
            held: None,
            consumed_strings: 0,
        }
    }
}

impl<'a> Emission<'a> {
    /// The model's steps not given out yet (after the step just given out, when no merged
    /// run is pending).
    pub(super) fn rest(&self) -> &'a [Step] {
        self.steps.as_slice()
    }
}

impl<'a> Iterator for Emission<'a> {
    type Item = Item<'a>;

    fn next(&mut self) -> Option<Item<'a>> {
        if let Some(h) = self.held.take() {
            return Some(Item::Step(h));
        }
        loop {
            let Some(step) = self.steps.next() else {
                return self.acc.take().map(Acc::finish);
            };
            if let Step::String(_) = step {
                self.consumed_strings += 1;
            }
            let min = match (step, self.min_len_mm) {
                (Step::String(st), Some(min)) if st.arc.is_none() => min,
                _ => {
                    // Any other step ends a run.
                    return match self.acc.take() {
                        Some(a) => {
                            self.held = Some(step);
                            Some(a.finish())
                        }
                        None => Some(Item::Step(step)),
                    };
                }
            };
            let Step::String(st) = step else {
                continue;
            };
            if let Some(a) = &mut self.acc {
                if a.len < min && a.end.distance_squared(st.start) < 1e-12 {
                    let l = st.len_mm();
                    a.end = st.end;
                    a.volume += st.cross_mm2 * l;
                    a.time += l / st.speed_mm_s;
                    a.len += l;
                    a.n += 1;
                    continue;
                }
            }
            let done = self.acc.replace(Acc::new(st));
            if let Some(a) = done {
                return Some(a.finish());
            }
        }
    }
}
