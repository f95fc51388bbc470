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
//! For a job kept from the SD card (`SD file PATH byte N`), M1000 does the same by itself: it
//! opens the file first (mounting the card after power-up) and checks that it has the kept
//! size and that the kept offset starts a line in it, then answers `File opened: …`, `File
//! selected`, `echo:power-cut resume: layer L at Z<mm>: SD file PATH byte N continues` and
//! `ok`, queues the same four steps, and feeds the file from the offset behind them, as
//! `M26 S<N>` + `M24` would. No card, no such file, or a file that changed (another size, or
//! the offset inside a line) is refused with an `echo:` and nothing is heated, homed or
//! started; the record stays for another try or `M1000 C`.
//!
//! A job move queued while a record is kept and no M1000 is under way starts another job:
//! the record is discarded then (with an `echo:`), so a stale job is never offered again.

use super::intake::CMD_CAPACITY;
use super::job::{PlaceText, Where};
use super::motion::homing::steps_at;
use super::pause::Held;
use super::sd::ReopenError;
use super::{Command, Printer, LINE_LEN};
use crate::gcode::RecoveryCommand;
use crate::link::{PortId, Response};
use crate::machine::{MachineError, MachineState};
use crate::motion::{Axis, PauseMode};
use crate::storage::sd::Card;
use crate::storage::{JobSource, PausedJob};
use crate::thermal::{HeaterId, ThermalError};
use core::fmt::Write as _;
use embedded_sdmmc::BlockDevice;

/// Commands M1000 queues (position, two heater waits, homing, the return).
const RECOVERY_COMMANDS: usize = 5;

/// Why M1000 does not resume (the text after `refused: M1000: `).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Refusal {
    NothingKept,
    Busy,
    QueueFull,
    DoesNotFit(MachineError),
    Heater(ThermalError),
    NoCardSlot,
    File(ReopenError),
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Refusal::NothingKept => f.write_str("no paused job kept (nothing to resume)"),
            Refusal::Busy => f.write_str("only while idle (the resume is under way or a job runs)"),
            Refusal::QueueFull => f.write_str("command queue full, send it again"),
            Refusal::DoesNotFit(e) => write!(
                f,
                "the kept state does not fit this machine ({e}); M1000 C discards it"
            ),
            Refusal::Heater(e) => write!(f, "{e}"),
            Refusal::NoCardSlot => f.write_str(
                "the kept job is an SD file and there is no card slot (M1000 C discards it)",
            ),
            Refusal::File(e) => {
                write!(f, "kept SD file: {e} (M1000 C discards the kept job)")
            }
        }
    }
}

impl Printer {
    /// The record kept at power-up and not yet resumed or discarded.
    pub fn kept_job(&self) -> Option<&crate::storage::PausedJob> {
        self.job.kept()
    }

    /// M1000 / M1000 C. Returns true when the `ok` is owed: M1000 of an SD job answers once
    /// the card has (see [`Printer::resume_sd_job`]).
    pub(super) fn recovery_command(&mut self, c: &RecoveryCommand) -> bool {
        match c {
            RecoveryCommand::Discard => {
                if self.job.recovering() {
                    self.host
                        .say(format_args!("refused: M1000 C: the resume is under way"));
                } else if self.job.kept().is_some() {
                    self.job.forget_kept();
                    self.host
                        .say(format_args!("power-cut resume: kept job discarded"));
                } else {
                    self.host
                        .say(format_args!("refused: M1000 C: no paused job kept"));
                }
                false
            }
            RecoveryCommand::Resume => self.m1000(),
        }
    }

    fn m1000(&mut self) -> bool {
        let planned = match self.job.kept().cloned() {
            Some(j) => self.recovery_plan(&j).map(|m| (j, m)),
            None => Err(Refusal::NothingKept),
        };
        let refusal = match planned {
            Ok((j, machine)) => match &j.source {
                JobSource::Host { line } => match self.begin_recovery(&j, machine) {
                    Ok(()) => {
                        self.host.say(format_args!(
                            "power-cut resume: layer {} at Z{:.3}: send the job from host line {line} (M110 N{} first)",
                            j.layer,
                            j.boundary_z_um as f32 / 1000.0,
                            line.saturating_sub(1)
                        ));
                        return false;
                    }
                    Err(r) => r,
                },
                JobSource::Sd { .. } if self.card_attached() => {
                    // The card answers first (`resume_sd_job`); the `ok` waits for it.
                    self.request_card_resume();
                    return true;
                }
                JobSource::Sd { .. } => Refusal::NoCardSlot,
            },
            Err(r) => r,
        };
        self.host.say(format_args!("refused: M1000: {refusal}"));
        false
    }

    /// What M1000 checks before it changes anything: idle, queue room, the state fits.
    fn recovery_plan(&self, j: &PausedJob) -> Result<MachineState, Refusal> {
        if self.job.recovering() || !self.pause.running() || self.has_work() || self.sd_printing() {
            return Err(Refusal::Busy);
        }
        if CMD_CAPACITY.saturating_sub(self.intake.len()) < RECOVERY_COMMANDS {
            return Err(Refusal::QueueFull);
        }
        MachineState::from_modal(&j.modal, self.settings.cfg()).map_err(Refusal::DoesNotFit)
    }

    /// Set the kept heater targets and fan, the modal state of the boundary, and queue the
    /// recovery's steps (see the module documentation).
    fn begin_recovery(&mut self, j: &PausedJob, machine: MachineState) -> Result<(), Refusal> {
        for (id, t) in [(HeaterId::Hotend, j.hotend_c), (HeaterId::Bed, j.bed_c)] {
            self.heat
                .thermal_mut()
                .set_target(id, t)
                .map_err(Refusal::Heater)?;
        }
        self.heat.restore_fan(j.fan_pwm);
        // Job lines from the boundary on are interpreted in the job's modes.
        self.intake.restore_machine(machine);
        let mut pos = self.motion.position();
        for ax in [Axis::Z, Axis::E] {
            pos[ax.index()] = j.park_steps[ax.index()];
        }
        self.intake.push(Command::SetPosition(pos));
        for (id, t) in [(HeaterId::Bed, j.bed_c), (HeaterId::Hotend, j.hotend_c)] {
            if t > 0.0 {
                self.intake.push(Command::WaitHeater(id));
            }
        }
        self.intake.push(Command::Home { mask: 0b011 });
        self.intake.push(Command::Recover);
        self.job.set_recovering(true);
        // The continued job's layers number from the kept one on.
        self.continue_job_at(j.layer);
        Ok(())
    }

    /// M1000 of a kept SD job, with the card (from `service_card`): open the file at the kept
    /// offset, and only if it is there, begin the recovery and feed the file behind it. The
    /// `ok` owed to `port` goes last.
    pub(super) fn resume_sd_job<D: BlockDevice>(&mut self, card: &mut Card<D>, port: Option<PortId>)
    where
        D::Error: core::fmt::Debug,
    {
        let refusal = match self.job.kept().cloned() {
            None => Some(Refusal::NothingKept),
            Some(j) => match (self.recovery_plan(&j), &j.source) {
                (Err(r), _) => Some(r),
                (Ok(_), JobSource::Host { .. }) => Some(Refusal::NothingKept),
                (Ok(machine), JobSource::Sd { path, offset, size }) => {
                    match self.sd_select_at(card, port, path, *offset, *size) {
                        Err(e) => Some(Refusal::File(e)),
                        Ok(()) => match self.begin_recovery(&j, machine) {
                            Err(r) => {
                                self.sd_unselect(card);
                                Some(r)
                            }
                            Ok(()) => {
                                let mut t = PlaceText::new();
                                let _ = write!(
                                    t,
                                    "power-cut resume: layer {} at Z{:.3}: {} continues",
                                    j.layer,
                                    j.boundary_z_um as f32 / 1000.0,
                                    Where(&j.source)
                                );
                                self.answer_to(port, Response::Echo(&t));
                                self.sd_start_on_resume();
                                None
                            }
                        },
                    }
                }
            },
        };
        if let Some(r) = refusal {
            let mut t: heapless::String<LINE_LEN> = heapless::String::new();
            let _ = write!(t, "refused: M1000: {r}");
            self.answer_to(port, Response::Echo(&t));
        }
        self.answer_to(port, Response::Ok);
    }

    /// M1000's last step, at the front of the queue with the motion idle (X/Y homed): the
    /// printer is parked at the saved park position with the boundary held, and resumes.
    pub(super) fn recover_now(&mut self) {
        self.job.set_recovering(false);
        let Some(j) = self.job.take_kept() else {
            return;
        };
        // Job moves start at the boundary; the head returns there first (service lane).
        self.motion.set_planner_position(j.boundary_steps);
        let held = Held {
            block: None,
            pos: j.boundary_steps,
            retracted_steps: steps_at(self.settings.cfg(), Axis::E, j.retract_mm),
            mode: PauseMode::Layer,
            before_layer: Some(j.layer),
        };
        // The resume clears the record before the head leaves (`on_job_continues`).
        self.job.resumed_from_kept();
        let ev = self.pause.resume_kept(held, cx!(self));
        self.route(ev);
        self.update_state_record();
    }

    /// A job move is queued (hook in `lines.rs`): while a kept record waits and no M1000 is
    /// under way, this is another job, and the record is discarded.
    pub(super) fn kept_job_superseded(&mut self) {
        if self.job.superseded() {
            self.host.say(format_args!(
                "power-cut resume: kept job discarded (a new job moves the head)"
            ));
        }
    }
}
