//! The job's layers in the executive: one numbering for every report (docs/frontend.md,
//! "Numbering"). Layer n is the n-th layer the printer prints in the job, from 1 — the number
//! the slicers' previews show — whatever the source of the marks; the count restarts when a
//! job starts: the host resets its line numbers (`M110`, sent by OctoPrint and printcore at
//! every print), an SD file starts printing, or something extrudes after a job's end code (the
//! detector sees that by itself). `M27`, `M761 L<n>`, the pause's `echo:` messages and the
//! power-cut record all name this number.

use super::state::Pause;
use super::{Command, Printer, Schedule};
use crate::motion::{LayerMark, LayerSource};

impl Printer {
    /// A job starts here in the host's stream (the line after an `M110`) or the card's (an SD
    /// file starts): the layer count restarts, from the kept layer when M1000 continues a job
    /// after a power cut.
    pub(super) fn job_start(&mut self) {
        let first = self.job.continue_at.take().unwrap_or(1);
        self.layers.restart(first);
        if !self.marks_pending() {
            // Nothing of an earlier job is still to print: M27 has no layer until the first
            // mark of this job runs.
            self.layer = None;
        }
    }

    /// M1000 continues a kept job from the start of layer `layer`: the job start that follows
    /// (the host's `M110`, or the SD file's start) numbers from there.
    pub(super) fn continue_job_at(&mut self, layer: u32) {
        self.job.continue_at = Some(layer);
        self.layers.restart(layer);
    }

    /// Layer marks of this or an earlier job not yet executed.
    fn marks_pending(&self) -> bool {
        self.planner.first_mark().is_some()
            || self.cmds.iter().any(|c| matches!(c, Command::Layer(_)))
    }

    /// A layer mark was crossed by the head (hook in `exec.rs`): M27's layer. The end mark is
    /// no layer; crossing it ends the job, and a pause scheduled for a later layer of it will
    /// never come: it is cleared (and said), so it does not stop the next job.
    pub(super) fn layer_crossed(&mut self, mark: &LayerMark) {
        if mark.source != LayerSource::End {
            self.layer = Some(mark.layer);
            return;
        }
        // The job has ended: no layer is printing (the next job numbers from 1).
        self.layer = None;
        if let Some(s) = self.schedule.take() {
            match s {
                Schedule::Layer(n) => self.say(format_args!(
                    "pause schedule cleared: the job ended after layer {} (scheduled at layer {n})",
                    mark.layer.saturating_sub(1)
                )),
                Schedule::Z(z) => self.say(format_args!(
                    "pause schedule cleared: the job ended below Z{:.3}",
                    z as f32 / 1000.0
                )),
            }
        }
    }

    /// `M761 L<n>`: pause at the boundary before layer n (after the last extrusion of layer
    /// n−1), as a slicer's "pause at layer n" does. When layer n is already printing, the
    /// user asked for the layer in front of them: the pause is at the end of this layer
    /// (before layer n+1), the soonest boundary that keeps the layer whole, and the answer says
    /// so. A layer already printed is refused: there is no boundary left before it.
    pub(super) fn m761_layer(&mut self, n: u32) {
        if n == 0 {
            self.warn(format_args!("M761 L0: layers count from 1"));
            return;
        }
        let current = match self.pause {
            Pause::Run => self.layer.filter(|_| self.in_job()),
            _ => None,
        };
        match current {
            Some(c) if n < c => {
                self.warn(format_args!(
                    "M761 L{n}: layer {n} has been printed (printing layer {c})"
                ));
                return;
            }
            Some(c) if n == c => self.say(format_args!(
                "pause scheduled at layer {n}: layer {n} is printing, pausing at its end (before layer {})",
                n.saturating_add(1)
            )),
            _ => self.say(format_args!("pause scheduled at layer {n}")),
        }
        self.schedule = Some(Schedule::Layer(n));
        self.schedule_queued_marks();
    }
}
