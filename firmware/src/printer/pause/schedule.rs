//! The pause schedule (M761): a pause at the boundary before layer n, or at the first layer
//! at or above a height. A matching mark becomes the barrier as it enters the planner; one
//! already queued becomes it at once; a pause in progress meets it when it stops there.

use super::state::{AfterStop, Pause, Stop};
use super::PauseCtl;
use crate::gcode::PauseSchedule;
use crate::motion::{LayerMark, LayerSource, PauseMode};
use crate::printer::cx::Cx;
use crate::printer::host::Host;
use crate::printer::types::Schedule;

impl PauseCtl {
    /// The current schedule.
    pub(in crate::printer) fn schedule(&self) -> Option<Schedule> {
        self.schedule
    }

    /// Whether the schedule asks to stop before `mark`.
    pub(super) fn schedule_hit(&self, mark: &LayerMark) -> bool {
        hits(self.schedule, mark)
    }

    fn stop_before(&mut self, layer: u32, cx: &mut Cx) {
        self.schedule = None;
        self.state = Pause::Stopping {
            how: Stop::Barrier { layer: Some(layer) },
            mode: PauseMode::Layer,
            then: AfterStop::Park,
        };
        cx.host.say(format_args!(
            "scheduled pause: stopping before layer {layer}"
        ));
    }

    /// A layer mark entered the planner: a matching schedule becomes the barrier. While a pause
    /// is already in progress the schedule waits: it is met by that pause if it stops at a
    /// matching boundary, or looked for again among the queued marks when the job resumes.
    pub(in crate::printer) fn mark_queued(
        &mut self,
        mark: LayerMark,
        became_barrier: bool,
        cx: &mut Cx,
    ) {
        if became_barrier {
            self.barrier_at(mark.layer);
        }
        if self.schedule_hit(&mark) && matches!(self.state, Pause::Run) {
            cx.motion.barrier_at_last_mark();
            self.stop_before(mark.layer, cx);
        }
    }

    /// Apply the schedule to the layer marks already queued in the planner (a matching mark
    /// too close to brake for gives way to the next reachable one, which matches too).
    pub(in crate::printer) fn schedule_queued_marks(&mut self, cx: &mut Cx) {
        if self.schedule.is_none() || !matches!(self.state, Pause::Run) {
            return;
        }
        let s = self.schedule;
        if let Some(m) = cx.motion.barrier_at_mark_where(|m| hits(s, m)) {
            self.stop_before(m.layer, cx);
        }
    }

    /// Set a schedule (M761 from the host, the driver's API).
    pub(in crate::printer) fn set_schedule(&mut self, s: Option<Schedule>, cx: &mut Cx) {
        self.schedule = s;
        self.schedule_queued_marks(cx);
    }

    /// A schedule in the job's stream reached the front of the queue.
    pub(in crate::printer) fn schedule_from_job(&mut self, s: Schedule, host: &mut Host) {
        self.schedule = Some(s);
        host.say(format_args!("pause scheduled: {:?}", s));
    }

    /// The head crossed `mark`. The end mark ends the job: a pause scheduled for a later layer
    /// will never come, so it is cleared (and said), and does not stop the next job.
    pub(in crate::printer) fn layer_crossed(&mut self, mark: &LayerMark, host: &mut Host) {
        if mark.source != LayerSource::End {
            return;
        }
        if let Some(s) = self.schedule.take() {
            match s {
                Schedule::Layer(n) => host.say(format_args!(
                    "pause schedule cleared: the job ended after layer {} (scheduled at layer {n})",
                    mark.layer.saturating_sub(1)
                )),
                Schedule::Z(z) => host.say(format_args!(
                    "pause schedule cleared: the job ended below Z{:.3}",
                    z as f32 / 1000.0
                )),
            }
        }
    }

    /// M761: report, clear, or schedule at a layer or height. `printing`: the layer printing
    /// now, when a job runs — `M761 L<n>` for a layer already printing pauses at its end
    /// (before layer n+1), the soonest boundary that keeps the layer whole; a layer already
    /// printed is refused (no boundary is left before it).
    pub(in crate::printer) fn m761(
        &mut self,
        s: &PauseSchedule,
        printing: Option<u32>,
        cx: &mut Cx,
    ) {
        match *s {
            PauseSchedule::Report => match self.schedule {
                Some(Schedule::Layer(n)) => {
                    cx.host.say(format_args!("pause scheduled at layer {n}"))
                }
                Some(Schedule::Z(z)) => cx
                    .host
                    .say(format_args!("pause scheduled at Z{:.3}", z as f32 / 1000.0)),
                None => cx.host.say(format_args!("no pause scheduled")),
            },
            PauseSchedule::Clear => {
                self.schedule = None;
                cx.host.say(format_args!("pause schedule cleared"));
            }
            PauseSchedule::Layer(n) => {
                if n == 0 {
                    cx.host.warn(format_args!("M761 L0: layers count from 1"));
                    return;
                }
                let current = printing.filter(|_| matches!(self.state, Pause::Run));
                match current {
                    Some(c) if n < c => {
                        cx.host.warn(format_args!(
                            "M761 L{n}: layer {n} has been printed (printing layer {c})"
                        ));
                        return;
                    }
                    Some(c) if n == c => cx.host.say(format_args!(
                        "pause scheduled at layer {n}: layer {n} is printing, pausing at its end (before layer {})",
                        n.saturating_add(1)
                    )),
                    _ => cx.host.say(format_args!("pause scheduled at layer {n}")),
                }
                self.set_schedule(Some(Schedule::Layer(n)), cx);
            }
            PauseSchedule::Z(z) => {
                let um = libm::roundf(z * 1000.0);
                let um = if um.is_finite() {
                    um.clamp(i32::MIN as f32, i32::MAX as f32) as i32
                } else {
                    0
                };
                cx.host.say(format_args!("pause scheduled at Z{z:.3}"));
                self.set_schedule(Some(Schedule::Z(um)), cx);
            }
        }
    }
}

/// Whether schedule `s` asks to stop before `mark`.
fn hits(s: Option<Schedule>, mark: &LayerMark) -> bool {
    match s {
        Some(Schedule::Layer(n)) => mark.layer >= n,
        Some(Schedule::Z(z)) => mark.z_um.is_some_and(|mz| mz >= z),
        None => false,
    }
}
