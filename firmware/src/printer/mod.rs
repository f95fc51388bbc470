//! The executive every driver runs (the board's main loop and timer interrupt, the simulator,
//! the tests): host lines in, step events and host answers out, with the layer-aware pause in
//! between.
//!
//! Drivers call [`Printer::receive_on`] with host bytes, [`Printer::request`] for a pause
//! button, [`Printer::poll`] from the main loop, and pull step events with
//! [`Printer::next_step_ns`] / [`Printer::next_step`]. What happened is reported as
//! [`Record`]s ([`Printer::pop_record`]) and host-link lines ([`Printer::write_output_on`]).
//!
//! The executive is a set of parts, each the owner of its state behind a small interface
//! (docs/planner.md, "The executive's parts"):
//!
//! ```text
//!   host ──lines──► intake ──commands──► (Printer: feed, dispatch) ──► motion ──► step events
//!    ▲  answers      queued / held /        │ routes the parts' events      ▲
//!    │               refused, and why       ▼                               │ barrier, hold,
//!    └──────────── every part answers ── pause (state, schedule, park) ─────┘ service lane
//!                  through the host       heat (heaters, fan, guard), settings, job record,
//!                                         SD card, board
//! ```
//!
//! The `Printer` itself owns nothing but its parts, the clock and the policy; its files route:
//! `lines` (host lines to the intake and the parts that answer them), `run` (the command queue
//! into motion, heat and pause in job order, and the commands the parts carry out), `step`
//! (blocks to the step generator, the pause's progress and its events), `session` (hosts that
//! come and go), `layers` (the job's layer numbering), `store` (the driver's flash store).

/// The context a part is lent for one call (see [`Cx`]): built from the printer's own parts.
macro_rules! cx {
    ($p:ident) => {
        &mut $crate::printer::cx::Cx {
            now_us: $p.now_us,
            cfg: $p.settings.cfg(),
            host: &mut $p.host,
            records: &mut $p.records,
            motion: &mut $p.motion,
            heat: &mut $p.heat,
        }
    };
}

mod board;
mod commands;
mod cx;
mod drivers;
mod guards;
mod heat;
mod homing;
mod host;
mod init;
mod intake;
mod job;
mod layers;
mod lines;
mod motion;
mod pause;
mod records;
mod recovery;
mod run;
mod sd;
mod session;
mod settings;
mod step;
mod store;
mod types;

pub use board::{BoardStats, STEPPER_REQ_CAPACITY};
pub use drivers::{DriverRequest, DRIVER_REQ_CAPACITY};
pub use guards::{ExtrusionGuard, Refusal};
pub use host::DEFAULT_BUSY_US as BUSY_PERIOD_US;
pub use intake::spill::{SPILL_CHUNK, SPILL_FLUSH, SPILL_STAGE};
pub use intake::{CMD_CAPACITY, CMD_SLOTS, LAYER_PAUSE_IDLE_US, PARKED_EXTRA, PARKED_PACE_US};
pub use motion::service::ServiceMove;
pub use records::RECORD_CAPACITY;
pub use sd::{SD_CHUNK, SD_LINES_PER_SERVICE};
pub use store::ERASE_AHEAD_IDLE_US;
pub use types::{
    Command, JobSetting, PausedLines, Policy, Record, Schedule, State, Status, StepperRequest,
    LINE_LEN,
};

use crate::config::MachineConfig;
use crate::link::{HostLink, PortId};
use crate::machine::MachineState;
use crate::motion::Realtime;
use crate::planner::{Planner, PlannerPolicy, RING_CAPACITY};
use crate::stepgen::StepGen;
use crate::thermal::{HeaterId, Thermal};
use heat::Heat;
use host::Host;
use intake::Intake;
use motion::Motion;
use pause::{Pause, PauseCtl};
use records::Records;

/// The executive. See the module documentation.
pub struct Printer {
    policy: Policy,
    /// The executive's clock, µs (the latest time a driver gave).
    now_us: u64,
    /// Ports, answers, reports.
    host: Host,
    /// What is queued, held or refused.
    intake: Intake,
    /// Planner, step generator, service lane, homing.
    motion: Motion,
    /// The pause machine and its schedule.
    pause: PauseCtl,
    /// Heaters, fan, extrusion guard.
    heat: Heat,
    /// The execution record.
    records: Records,
    /// The configuration, factory settings and the store's requests.
    settings: settings::SettingsLink,
    /// The job's layers, boundaries and its power-cut record.
    job: job::JobLink,
    /// The SD card's job and the commands waiting for the card.
    sd: sd::SdLink,
    /// What the board is asked to do and tells.
    board: board::BoardLink,
}

impl Printer {
    /// A printer with `cfg`, the [`Policy::FIRMWARE`] policy, at position 0, time 0.
    pub fn new(cfg: MachineConfig) -> Self {
        Self::with_policy(cfg, Policy::FIRMWARE)
    }

    /// Change the policy (between jobs).
    pub fn set_policy(&mut self, policy: Policy) {
        self.policy = policy;
        self.motion.set_policy(PlannerPolicy {
            segment: policy.segment,
            max_blocks: policy.max_blocks.clamp(1, RING_CAPACITY),
            stop_at_marks: policy.stop_at_marks,
        });
        self.intake.set_policy(&policy);
        self.pause.set_at_tail(policy.pause_at_tail);
    }

    /// The policy.
    pub fn policy(&self) -> Policy {
        self.policy
    }

    /// The configuration.
    pub fn config(&self) -> &MachineConfig {
        self.settings.cfg()
    }

    /// Change the configuration (M204, M760, ... apply here).
    pub fn config_mut(&mut self) -> &mut MachineConfig {
        self.settings.cfg_mut()
    }

    /// The planner (read-only, for tests and displays).
    pub fn planner(&self) -> &Planner {
        self.motion.planner()
    }

    /// The step generator (read-only).
    pub fn stepgen(&self) -> &StepGen {
        self.motion.stepgen()
    }

    fn set_now(&mut self, now_us: u64) {
        if now_us > self.now_us {
            self.now_us = now_us;
        }
    }

    /// Now on the motion timeline: the clock, or the last step when motion runs ahead of it.
    fn t_us(&self) -> u64 {
        self.now_us.max(self.motion.last_step_us())
    }

    /// Take the oldest stepper-driver request (M17/M18/M84) for the board to act on. When the
    /// board does not take them, the oldest is dropped beyond [`STEPPER_REQ_CAPACITY`].
    pub fn take_stepper_request(&mut self) -> Option<StepperRequest> {
        self.board.take_stepper_request()
    }

    /// Take the oldest execution record.
    pub fn pop_record(&mut self) -> Option<Record> {
        self.records.pop()
    }

    /// Records lost because the driver did not take them in time.
    pub fn records_dropped(&self) -> u32 {
        self.records.dropped()
    }

    /// Write every pending host-link line of the USB port (`ok`, `echo:`, `//action:`,
    /// errors ...), each followed by `\n`. Same as [`Printer::write_output_on`] with
    /// [`PortId::Usb`].
    pub fn write_output<W: core::fmt::Write>(&mut self, w: &mut W) -> core::fmt::Result {
        self.write_output_on(PortId::Usb, w)
    }

    /// Write every pending host-link line of port `port`.
    pub fn write_output_on<W: core::fmt::Write>(
        &mut self,
        port: PortId,
        w: &mut W,
    ) -> core::fmt::Result {
        self.host.write_output(port, w)
    }

    /// Copy pending USB-port output bytes into `buf` (for a UART/USB driver); returns how many
    /// were written. Same as [`Printer::read_output_on`] with [`PortId::Usb`].
    pub fn read_output(&mut self, buf: &mut [u8]) -> usize {
        self.read_output_on(PortId::Usb, buf)
    }

    /// Copy pending output bytes of port `port` into `buf`; returns how many were written.
    pub fn read_output_on(&mut self, port: PortId, buf: &mut [u8]) -> usize {
        self.host.read_output(port, buf)
    }

    /// One port's host link (line numbers, counters), read-only.
    pub fn port(&self, port: PortId) -> &HostLink {
        self.host.port(port)
    }

    /// Whether single control bytes (Ctrl-X, Ctrl-C, …) are requests on `port` (by default on
    /// the USB port only: [`PortId::default_control_bytes`]).
    pub fn set_control_bytes(&mut self, port: PortId, on: bool) {
        self.host.set_control_bytes(port, on);
    }

    /// Host bytes in on the USB port: [`Printer::receive_on`] with [`PortId::Usb`].
    #[must_use = "bytes not taken must be offered again later (flow control)"]
    pub fn receive(&mut self, bytes: &[u8], now_us: u64) -> usize {
        self.receive_on(PortId::Usb, bytes, now_us)
    }

    /// Host bytes in on port `port`: realtime requests act at once; lines are taken, parsed,
    /// interpreted by the machine state and queued while the command queue has room (each
    /// answered `ok` when taken). Returns how many bytes were taken, from the front: the rest
    /// did not fit (the line FIFO is full because the command queue is) and must be offered
    /// again later — the driver leaves them unread (pty) or NAKs them (USB). A host that waits
    /// for `ok` never has more than its window outstanding, so nothing it sends is lost and its
    /// realtime lines are always within what is taken.
    #[must_use = "bytes not taken must be offered again later (flow control)"]
    pub fn receive_on(&mut self, port: PortId, bytes: &[u8], now_us: u64) -> usize {
        self.set_now(now_us);
        let mut taken = 0;
        loop {
            let n = self.host.receive(port, bytes.get(taken..).unwrap_or(&[]));
            taken += n;
            self.take_realtime();
            self.process_lines();
            // Each round takes at least one byte, or stops.
            if n == 0 || taken >= bytes.len() {
                break;
            }
        }
        self.update_state_record();
        taken
    }

    /// Room in the command queue under the policy's limit.
    pub fn command_room(&self) -> usize {
        self.intake.command_room()
    }

    /// Queue a command (what the front end does for every parsed line). Returns the command
    /// back when the queue is full (the host gets no `ok` until there is room) or the printer
    /// is halted. While paused with [`PausedLines::Manual`], moves run at once in the service
    /// lane instead.
    pub fn push_command(&mut self, cmd: Command, now_us: u64) -> Result<(), Command> {
        self.set_now(now_us);
        if self.pause.halted() {
            return Err(cmd);
        }
        if self.pause.parked() && self.policy.paused_lines == PausedLines::Manual {
            if let Command::Move(m) = cmd {
                let taken = self.motion.push_service(ServiceMove {
                    target: m.target,
                    feed_mm_s: m.feed_mm_s,
                });
                return if taken { Ok(()) } else { Err(cmd) };
            }
        }
        if self.intake.command_room() == 0 {
            return Err(cmd);
        }
        self.intake.forget_cancel();
        self.intake.took_line(None, None, self.now_us);
        self.intake.push(cmd);
        self.feed_planner();
        self.update_state_record();
        Ok(())
    }

    /// Main loop: move commands into the planner, run the pause state machine and dwell.
    pub fn poll(&mut self, now_us: u64) {
        self.set_now(now_us);
        self.take_realtime();
        if self.pause.halted() {
            return;
        }
        // Lines are taken only when one waits (or an arc is being cut): the idle tick costs
        // a compare instead of the line handler's frame.
        if self.intake.cutting_arc() || self.host.lines_waiting() > 0 || self.intake.has_held_line()
        {
            self.process_lines();
        }
        self.feed_planner();
        self.update_pause();
        self.feed_planner();
        if self.intake.sync_owed() {
            // An M400 waits for the motion to end with its `ok` owed; while parked, for the
            // machine's rest only (`intake/sync.rs`).
            let (parked, busy) = (self.pause.parked(), self.motion.service_busy());
            if self.intake.pay_sync_at_rest(parked, busy) {
                self.host.ok();
            } else {
                self.keep_alive();
            }
        }
        let state = self.state();
        let heat = &self.heat;
        self.host
            .report_tick(self.now_us, state, || heat.report(), || heat.heaters_off());
        self.update_state_record();
    }

    /// Work queued, planned or moving, or spilled lines still to run.
    fn has_work(&self) -> bool {
        !self.intake.is_empty() || !self.motion.idle() || self.intake.spilled() > 0
    }

    /// Whether the printer is in a job — the same notion for pause and cancel: work queued or
    /// moving, lines received before the request and not taken yet (a pause written in the
    /// same burst as the moves it should stop: the link sees it before the executive takes
    /// them, issue 31), or a host streaming one (a line taken or a move ended within
    /// [`LAYER_PAUSE_IDLE_US`]: between lines, or at a boundary the host drained with M400),
    /// and not a job just cancelled.
    fn in_job(&self) -> bool {
        self.has_work()
            || self.host.request_lines_ahead() > 0
            || self.intake.has_held_line()
            || (!self.intake.cancelled() && self.intake.recently_active(self.now_us))
    }

    /// Realtime request (pause button, sim, or parsed from the byte stream).
    pub fn request(&mut self, req: Realtime, now_us: u64) {
        self.set_now(now_us);
        if self.pause.halted() {
            self.host.say(format_args!("halted: reset required"));
            return;
        }
        self.retire_finished();
        match req {
            Realtime::Pause(mode) => {
                let (in_job, queued) = (self.in_job(), self.intake.len());
                self.pause.request_pause(mode, in_job, queued, cx!(self));
                if self.policy.pause_at_tail {
                    // The tail stop counts down from what is queued now.
                    self.feed_planner();
                }
            }
            Realtime::Resume => {
                // M24 starts a selected SD file when there is no pause to resume.
                if !self.sd_start_on_resume() {
                    let orphaned = self.intake.orphaned();
                    let ev = self.pause.request_resume(orphaned, cx!(self));
                    self.route(ev);
                }
            }
            Realtime::Cancel => {
                let sd = self.sd_cancel();
                let in_job = self.in_job();
                let ev = self.pause.request_cancel(in_job, cx!(self));
                self.route(ev);
                if sd {
                    // The host's stream was not the job: nothing of it is to be discarded.
                    self.intake.forget_cancel();
                }
            }
            Realtime::EmergencyStop => self.emergency_stop(),
            Realtime::QuickStop => self.quick_stop(),
            Realtime::BreakWait => {
                self.heat.thermal_mut().cancel_autotune();
                self.feed_planner_breaking(true);
            }
        }
        self.update_pause();
        self.update_state_record();
    }

    /// M112 or a fault: nothing moves until reset, heaters off, every port told.
    fn emergency_stop(&mut self) {
        if self.motion.abort_homing() {
            self.homing_aborted();
        }
        self.pause.halt();
        self.heat.thermal_mut().kill(self.now_us);
        self.motion.halt();
        self.intake.halt();
        // As Marlin's kill(): an error to every port, then no answer to anything until reset.
        self.host.halt();
    }

    /// M410: stop at once, everything queued in the planner dropped.
    fn quick_stop(&mut self) {
        if self.motion.abort_homing() {
            self.homing_aborted();
        }
        let d = self.motion.quick_stop();
        // A quick stop during a cancel's park ends the cancel there, by the cancel's own end
        // (the lines that waited during the park are the cancelled job's tail, not a new job:
        // found by the fuzzer, an `M109 S200` of the tail heated the nozzle again).
        let ev = self.pause.quick_stop(cx!(self));
        self.intake.quick_stop();
        self.route(ev);
        let pos = self.motion.position();
        self.intake.machine_at(&pos, self.settings.cfg());
        self.host.say(format_args!(
            "quick stop (M410): dropped {} blocks, {} uncut segments",
            d.blocks, d.segments
        ));
    }

    /// A G28 in progress was aborted (M112, M410): its command leaves the queue.
    fn homing_aborted(&mut self) {
        self.intake.drop_front_home();
        self.host.say(format_args!("homing aborted"));
    }

    /// The run state now.
    pub fn state(&self) -> State {
        match self.pause.state() {
            Pause::Halted => State::Halted,
            Pause::Stopping { .. } | Pause::Parking { .. } => State::Pausing,
            Pause::Parked { .. } => State::Paused,
            Pause::Returning { .. } => State::Resuming,
            Pause::Run => {
                if self.has_work() {
                    State::Printing
                } else if self.intake.cancelled() || self.sd_cancelled() {
                    State::Cancelled
                } else {
                    State::Idle
                }
            }
        }
    }

    fn update_state_record(&mut self) {
        let s = self.state();
        if self.records.state_changed(s) {
            let t_us = self.t_us();
            self.records.state(s, t_us);
        }
    }

    /// A snapshot of the printer.
    pub fn status(&self) -> Status {
        let held = self.pause.state().held();
        let exec = usize::from(self.motion.executing() || held.is_some_and(|h| h.block.is_some()));
        let planned = self.motion.planner().len();
        Status {
            state: self.state(),
            position: self.motion.position(),
            layer: self.job.layer(),
            queue_depth: self.intake.len() + planned + exec,
            planner_blocks: planned,
            commands: self.intake.len(),
            paused_at: held.map(|h| h.pos),
            pause_mode: self.pause.state().mode(),
            position_lost: self.motion.position_lost(),
        }
    }

    /// Heater sample in; duty 0..=1 out. Same as [`Printer::heater_sample`].
    pub fn thermal_sample(&mut self, id: HeaterId, measured_c: f32, now_us: u64) -> f32 {
        self.heater_sample(id, measured_c, now_us)
    }

    /// Heater sample in (°C, NaN = unreadable), duty 0..=1 out. A thermal fault halts the
    /// printer (reported as Marlin does).
    pub fn heater_sample(&mut self, id: HeaterId, measured_c: f32, now_us: u64) -> f32 {
        self.set_now(now_us);
        let (duty, fault) = self.heat.sample(id, measured_c, now_us, &mut self.host);
        if let Some(f) = fault {
            self.host.error(format_args!("{f}"));
            if !self.pause.halted() {
                self.emergency_stop();
            }
        }
        duty
    }

    /// The heaters (read-only).
    pub fn thermal(&self) -> &Thermal {
        self.heat.thermal()
    }

    /// The heaters (for the board's configuration).
    pub fn thermal_mut(&mut self) -> &mut Thermal {
        self.heat.thermal_mut()
    }

    /// Part-cooling fan PWM 0..=255 (M106/M107).
    pub fn fan_pwm(&self) -> u8 {
        self.heat.fan_pwm()
    }

    /// The machine's modal state (read-only).
    pub fn machine(&self) -> &MachineState {
        self.intake.machine()
    }

    /// Cold/long-extrusion settings (M302). Test and simulator drivers that model motion
    /// without heaters set `allow_cold`, as M302 P1 would.
    pub fn extrusion_guard(&self) -> &ExtrusionGuard {
        self.heat.guard()
    }

    /// Change the cold/long-extrusion settings.
    pub fn extrusion_guard_mut(&mut self) -> &mut ExtrusionGuard {
        self.heat.guard_mut()
    }

    /// Set a pause schedule now (M761 from the host). A matching layer mark already in the
    /// planner becomes the barrier at once.
    pub fn schedule_pause(&mut self, s: Option<Schedule>) {
        self.pause.set_schedule(s, cx!(self));
    }

    /// The current pause schedule (M761 report).
    pub fn scheduled_pause(&self) -> Option<Schedule> {
        self.pause.schedule()
    }

    /// What the job reports need of the printer now.
    fn job_view(&self) -> host::JobView {
        host::JobView {
            state: self.state(),
            layer: self.job.layer(),
            sd_progress: self.sd_progress(),
        }
    }

    /// A `busy:` keep-alive for the line waiting (paused-for-user wording while parked).
    fn keep_alive(&mut self) {
        let parked = self.pause.parked();
        self.host.keep_alive(self.now_us, parked);
    }
}
