//! M1000, power-cut resume: the job a layer pause kept in flash ([`crate::storage::PausedJob`],
//! see `job.rs`) continues after the power came back, as Marlin's `M1000` continues its
//! power-loss recovery, but from the exact boundary the pause stopped at.
//!
//! At power-up the kept job is announced (`//action:notification Paused job kept: ...`). Then:
//!
//! * `M1000 C` discards it (the record is cleared in flash).
//! * `M1000` (only while idle) answers `echo:power-cut resume: layer L at Z<mm>: send the job
//!   from host line N (M110 N<N-1> first)` and then `ok`, and queues, in this order:
//!   1. the position of Z and E set to the saved park position without moving (**Z is trusted**,
//!      as Prusa's recovery does: the lead screws hold Z while the power is off; X and Y are
//!      homed below, so only Z and E are taken on trust);
//!   2. the saved hotend and bed targets and fan, waiting for both heaters (M190/M109);
//!   3. G28 X Y (homing X and Y only: homing Z would drag the nozzle over the print);
//!   4. the resume of a park: XY back to the boundary, then Z down to it, then the pause's
//!      retract given back, at which point `//action:resumed` is sent and the job continues
//!      with the modal state it had at the boundary (G90/G91, M82/M83, G20/G21, G10, feed,
//!      M220/M221, G92 offsets, logical E, the exact commanded position).
//!
//!   The modal state is restored when M1000 is taken, so the host's lines from N on, which
//!   queue behind these steps, are interpreted exactly as in the uninterrupted job. The record
//!   is cleared before the head leaves the park position (as for any resume), so a second
//!   power cut during or after the return offers nothing stale.
//!
//! A job move queued while a record is kept and no M1000 is under way starts another job:
//! the record is discarded then (with an `echo:`), so a stale job is never offered again.

use super::state::{Held, Pause};
use super::{job::JobRequest, steps, Command, Printer, CMD_CAPACITY};
use crate::gcode::RecoveryCommand;
use crate::machine::MachineState;
use crate::motion::{Axis, PauseMode};
use crate::storage::JobSource;
use crate::thermal::HeaterId;

/// Commands M1000 queues (position, two heater waits, homing, the return).
const RECOVERY_COMMANDS: usize = 5;

impl Printer {
    /// The record kept at power-up and not yet resumed or discarded.
    pub fn kept_job(&self) -> Option<&crate::storage::PausedJob> {
        self.job.kept.as_ref()
    }

    /// M1000 / M1000 C (the `ok` is sent by the caller).
    pub(super) fn recovery_command(&mut self, c: &RecoveryCommand) {
        match c {
            RecoveryCommand::Discard => {
                if self.job.recovering {
                    self.say(format_args!("refused: M1000 C: the resume is under way"));
                } else if self.job.kept.take().is_some() {
                    self.forget_kept_job();
                    self.say(format_args!("power-cut resume: kept job discarded"));
                } else {
                    self.say(format_args!("refused: M1000 C: no paused job kept"));
                }
            }
            RecoveryCommand::Resume => self.m1000(),
        }
    }

    /// Clear the record in flash (driver's store) and forget that one was saved.
    fn forget_kept_job(&mut self) {
        self.job.saved = false;
        self.job.request = Some(JobRequest::Clear);
    }

    fn m1000(&mut self) {
        let Some(j) = self.job.kept.clone() else {
            self.say(format_args!(
                "refused: M1000: no paused job kept (nothing to resume)"
            ));
            return;
        };
        if self.job.recovering || !matches!(self.pause, Pause::Run) || self.has_work() {
            self.say(format_args!(
                "refused: M1000: only while idle (the resume is under way or a job runs)"
            ));
            return;
        }
        let line = match j.source {
            JobSource::Host { line } => line,
            JobSource::Sd { .. } => {
                self.say(format_args!(
                    "refused: M1000: the kept job is an SD file and this firmware has no SD printing (M1000 C discards it)"
                ));
                return;
            }
        };
        if CMD_CAPACITY - self.cmds.len() < RECOVERY_COMMANDS {
            self.say(format_args!(
                "refused: M1000: command queue full, send it again"
            ));
            return;
        }
        let machine = match MachineState::from_modal(&j.modal, &self.cfg) {
            Ok(m) => m,
            Err(e) => {
                self.say(format_args!(
                    "refused: M1000: the kept state does not fit this machine ({e}); M1000 C discards it"
                ));
                return;
            }
        };
        for (id, t) in [(HeaterId::Hotend, j.hotend_c), (HeaterId::Bed, j.bed_c)] {
            if let Err(e) = self.thermal.set_target(id, t) {
                self.say(format_args!("refused: M1000: {e}"));
                return;
            }
        }
        self.fan_pwm = j.fan_pwm;
        // Host lines from N on are interpreted from the boundary, in the job's modes.
        self.machine = machine;
        let mut pos = self.stepgen.position();
        for ax in [Axis::Z, Axis::E] {
            pos[ax.index()] = j.park_steps[ax.index()];
        }
        let _ = self.cmds.push_back(Command::SetPosition(pos));
        for (id, t) in [(HeaterId::Bed, j.bed_c), (HeaterId::Hotend, j.hotend_c)] {
            if t > 0.0 {
                let _ = self.cmds.push_back(Command::WaitHeater(id));
            }
        }
        let _ = self.cmds.push_back(Command::Home { mask: 0b011 });
        let _ = self.cmds.push_back(Command::Recover);
        self.job.recovering = true;
        self.say(format_args!(
            "power-cut resume: layer {} at Z{:.3}: send the job from host line {line} (M110 N{} first)",
            j.layer,
            j.boundary_z_um as f32 / 1000.0,
            line.saturating_sub(1)
        ));
    }

    /// M1000's last step, at the front of the queue with the motion idle (X/Y homed): the
    /// printer is parked at the saved park position with the boundary held, and resumes.
    pub(super) fn recover_now(&mut self) {
        self.job.recovering = false;
        let Some(j) = self.job.kept.take() else {
            return;
        };
        // Job moves start at the boundary; the head returns there first (service lane).
        self.planner.set_position(j.boundary_steps);
        self.pause = Pause::Parked {
            held: Held {
                block: None,
                pos: j.boundary_steps,
                retracted_steps: steps(&self.cfg, Axis::E, j.retract_mm),
                mode: PauseMode::Layer,
            },
            manual: None,
        };
        // The resume clears the record before the head leaves (`on_job_continues`).
        self.job.saved = true;
        self.start_resume();
        self.update_state_record();
    }

    /// A job move is queued (hook in `host.rs`): while a kept record waits and no M1000 is
    /// under way, this is another job, and the record is discarded.
    pub(super) fn kept_job_superseded(&mut self) {
        if self.job.kept.is_some() && !self.job.recovering {
            self.job.kept = None;
            self.forget_kept_job();
            self.say(format_args!(
                "power-cut resume: kept job discarded (a new job moves the head)"
            ));
        }
    }
}
