//! The executive every driver runs (the board's main loop and timer interrupt, the simulator,
//! the tests): command queue, planner, step generator and the pause state machine.
//!
//! Drivers call [`Printer::receive`] with host bytes, [`Printer::request`] for a pause button,
//! [`Printer::poll`] from the main loop, and pull step events with
//! [`Printer::next_step_ns`] / [`Printer::next_step`]. What happened is reported as
//! [`Record`]s ([`Printer::pop_record`]) and host-link lines ([`Printer::write_output`]).
//!
//! Pause state machine (see `docs/planner.md` for the edge-case table):
//!
//! ```text
//! Printing ─Pause(layer)─► Stopping: barrier at the next layer mark, rest of layer sped up
//! Printing ─Pause(now)───► Stopping: feed hold (brake at the block's acceleration)
//! Stopping ─stopped──────► Parking: retract, lift, park (service lane) ─► Paused
//! Paused ───Resume───────► Returning: XY, then Z, then un-retract ─► release held ─► Printing
//! ```
//!
//! Modules, one job each: `state` (the pause machine's state type), `pause` (requests: pause,
//! resume, cancel, stops), `park` (stop detection, park, return, release), `queue` (commands
//! into the planner, schedules, keep-alives), `exec` (blocks to the step generator, records),
//! `host` (host lines and the rules for them), `commands` (command handlers), `service` (the
//! service lane), `settings` (M92.. M503), `types` (public types).

mod autotune;
// Building a `Printer`, in place if need be (`init.rs`).
mod init;
// What the board reports (reversed drivers, its measurements for M115).
mod board;
pub use board::BoardStats;
mod commands;
mod exec;
mod guards;
mod homing;
mod host;
// The job's layer numbering: job starts, M27's layer, M761 L.
mod layers;
mod park;
mod pause;
mod queue;
mod state;
mod types;

pub use guards::{ExtrusionGuard, Refusal};
use host::{AfterCancel, HostLines};
pub use host::{PARKED_EXTRA, PARKED_PACE_US};
use state::Pause;

pub use types::{Command, PausedLines, Policy, Record, Schedule, State, Status, StepperRequest};
mod service;
// Settings M-codes and the flash store's requests (M500/M501).
// The paused-job record (power-cut resume).
mod job;
// M1000: resume the kept job after a power cut.
mod recovery;
mod settings;
pub use settings::ERASE_AHEAD_IDLE_US;
// Stepper drivers: M569/M350/M122 and the board's TMC2209 results.
mod drivers;
pub use drivers::{DriverRequest, DRIVER_REQ_CAPACITY};
// Reports hosts expect (temperatures during heater waits, M155, M113, M73, M31, M27).
mod report;
// SD-card printing: the SD M-codes and the card as a job source.
mod sd;
pub use sd::{SD_CHUNK, SD_LINES_PER_SERVICE};
// The parked intake's spill to the SD card.
mod spill;
// Host sessions that end and begin (USB DTR, the sim's pty).
mod session;
pub use spill::{SPILL_CHUNK, SPILL_FLUSH, SPILL_STAGE};

pub use service::ServiceMove;

use crate::config::MachineConfig;
use crate::layer::LayerDetector;
use crate::link::{HostAction, HostLink, HostPorts, PortId, Response};
use crate::machine::{ArcMoves, MachineState};
use crate::motion::{Axis, Realtime};
use crate::planner::{Planner, PlannerPolicy, RING_CAPACITY};
use crate::stepgen::StepGen;
use crate::thermal::{HeaterId, Thermal, ThermalConfig};
use core::fmt::Write as _;
use heapless::{Deque, String};

/// Command queue capacity (commands after parsing; each ≈ 32 B).
pub const CMD_CAPACITY: usize = 32;
/// Physical slots of the command queue: [`CMD_CAPACITY`] for the running job plus the parked
/// intake ([`PARKED_EXTRA`], host.rs: job lines a parked printer takes, paced, so that a
/// one-line-per-`ok` host that streams on still gets `ok`s for its priority lines).
pub const CMD_SLOTS: usize = CMD_CAPACITY + PARKED_EXTRA;
/// Stepper-driver requests kept until the board takes them.
pub const STEPPER_REQ_CAPACITY: usize = 4;
/// Execution records kept until the driver takes them.
pub const RECORD_CAPACITY: usize = 256;
/// Longest message line the executive formats.
pub const LINE_LEN: usize = 120;
/// Keep-alive period during heater waits (`busy: processing`), µs.
pub const BUSY_PERIOD_US: u64 = 2_000_000;
/// A `layer` pause waiting for a boundary treats the end of the known job as the boundary once
/// the printer has had nothing to do for this long (job ended before any layer boundary).
pub const LAYER_PAUSE_IDLE_US: u64 = 2_000_000;

/// The executive. See the module documentation.
pub struct Printer {
    cfg: MachineConfig,
    policy: Policy,
    planner: Planner,
    stepgen: StepGen,
    cmds: Deque<Command, CMD_SLOTS>,
    service: Deque<ServiceMove, { service::SERVICE_CAPACITY }>,
    /// The pause machine: every pause, cancel and halt state with its data.
    pause: Pause,
    /// The host-line side: lines waiting for room, numbering, discarding after a cancel, the
    /// `ok` an M400 owes, keep-alives.
    lines: HostLines,
    schedule: Option<Schedule>,
    layer: Option<u32>,
    /// A G4 at the front of the queue waits until this time, µs.
    dwell_until_us: Option<u64>,
    /// M108 is breaking the heater wait or dwell at the front of the queue (during one feed).
    break_wait: bool,
    now_us: u64,
    /// When a host line was last taken or a block last ended, µs ("in a job").
    last_activity_us: u64,
    last_state: State,
    records: Deque<Record, RECORD_CAPACITY>,
    stepper_reqs: Deque<StepperRequest, STEPPER_REQ_CAPACITY>,
    driver_reqs: Deque<drivers::DriverRequest, { drivers::DRIVER_REQ_CAPACITY }>,
    records_dropped: u32,
    link: HostPorts,
    /// The job's modal state (manual lines while parked use the copy in `Pause::Parked`).
    machine: MachineState,
    layers: LayerDetector,
    arc: Option<ArcMoves>,
    thermal: Thermal,
    fan_pwm: u8,
    /// Axes (bit i = X, Y, Z) whose drivers were switched off since they were last homed.
    position_lost: u8,
    /// Cold/long-extrusion protection (M302).
    guard: ExtrusionGuard,
    /// Homing with endstops (None: this machine's G28 moves to the minimum, no switches).
    homing_cfg: Option<crate::homing::HomingConfig>,
    /// The G28 in progress.
    homing: Option<crate::homing::Homing>,
    /// Endstop switch states as the driver reported them, bit i = axis i pressed.
    endstops: u8,
    /// The driver still has step events of the executive queued or running (a board whose step
    /// interrupt runs events ahead; see `homing.rs`): homing waits for them.
    steps_in_flight: bool,
    /// Axes homed on their switches (see `homing.rs`).
    homed: homing::HomedAxes,
    /// Factory settings and a pending M500/M501 (see `settings.rs`).
    settings: settings::SettingsLink,
    reports: report::Reports,
    /// Boundaries of the host stream and the paused-job record's requests (see `job.rs`).
    job: job::JobLink,
    /// The SD card's job and the commands waiting for the card (see `sd.rs`).
    sd: sd::SdLink,
    /// The board's measurements (see `board.rs`).
    board: board::BoardLink,
    /// Job lines of a parked printer kept on the card (see `spill.rs`).
    spill: spill::Spill,
}

fn steps(cfg: &MachineConfig, axis: Axis, mm: f32) -> i32 {
    let v = libm::roundf(mm * cfg.axis(axis).steps_per_mm);
    if v.is_finite() {
        v.clamp(i32::MIN as f32, i32::MAX as f32) as i32
    } else {
        0
    }
}

impl Printer {
    /// A printer with `cfg`, the [`Policy::FIRMWARE`] policy, at position 0, time 0.
    pub fn new(cfg: MachineConfig) -> Self {
        Self::with_policy(cfg, Policy::FIRMWARE)
    }

    /// Change the policy (between jobs).
    pub fn set_policy(&mut self, policy: Policy) {
        self.policy = policy;
        self.planner.policy = PlannerPolicy {
            segment: policy.segment,
            max_blocks: policy.max_blocks.clamp(1, RING_CAPACITY),
            stop_at_marks: policy.stop_at_marks,
        };
    }

    /// The policy.
    pub fn policy(&self) -> Policy {
        self.policy
    }

    /// The configuration.
    pub fn config(&self) -> &MachineConfig {
        &self.cfg
    }

    /// Change the configuration (M204, M760, ... apply here).
    pub fn config_mut(&mut self) -> &mut MachineConfig {
        &mut self.cfg
    }

    /// The planner (read-only, for tests and displays).
    pub fn planner(&self) -> &Planner {
        &self.planner
    }

    /// The step generator (read-only).
    pub fn stepgen(&self) -> &StepGen {
        &self.stepgen
    }

    fn now_ns(&self) -> u64 {
        self.now_us.saturating_mul(1000)
    }

    fn set_now(&mut self, now_us: u64) {
        if now_us > self.now_us {
            self.now_us = now_us;
        }
    }

    fn t_us(&self) -> u64 {
        self.now_us
            .max(crate::stepgen::div_small(self.stepgen.last_time_ns(), 1000).0)
    }

    fn record(&mut self, r: Record) {
        if self.records.is_full() {
            let _ = self.records.pop_front();
            self.records_dropped = self.records_dropped.saturating_add(1);
        }
        let _ = self.records.push_back(r);
    }

    /// Take the oldest stepper-driver request (M17/M18/M84) for the board to act on. When the
    /// board does not take them, the oldest is dropped beyond [`STEPPER_REQ_CAPACITY`].
    pub fn take_stepper_request(&mut self) -> Option<StepperRequest> {
        self.stepper_reqs.pop_front()
    }

    fn push_stepper_request(&mut self, r: StepperRequest) {
        if self.stepper_reqs.is_full() {
            let _ = self.stepper_reqs.pop_front();
        }
        let _ = self.stepper_reqs.push_back(r);
    }

    /// Take the oldest execution record.
    pub fn pop_record(&mut self) -> Option<Record> {
        self.records.pop_front()
    }

    /// Records lost because the driver did not take them in time.
    pub fn records_dropped(&self) -> u32 {
        self.records_dropped
    }

    /// An `echo:` line to the port that asked (see [`HostPorts::respond`]).
    fn say(&mut self, args: core::fmt::Arguments) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = t.write_fmt(args);
        self.link.respond(Response::Echo(&t));
    }

    /// An `echo:` line to every port (a notification, not an answer: pause state changes).
    fn notice(&mut self, args: core::fmt::Arguments) {
        let mut t: String<LINE_LEN> = String::new();
        let _ = t.write_fmt(args);
        self.link.notify(Response::Echo(&t));
    }

    /// A host action, to every port.
    fn action(&mut self, a: HostAction) {
        self.link.notify(Response::Action(a, ""));
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
        self.link.write_output(port, w)
    }

    /// Copy pending USB-port output bytes into `buf` (for a UART/USB driver); returns how many
    /// were written. Same as [`Printer::read_output_on`] with [`PortId::Usb`].
    pub fn read_output(&mut self, buf: &mut [u8]) -> usize {
        self.read_output_on(PortId::Usb, buf)
    }

    /// Copy pending output bytes of port `port` into `buf`; returns how many were written.
    pub fn read_output_on(&mut self, port: PortId, buf: &mut [u8]) -> usize {
        self.link.read_output(port, buf)
    }

    /// One port's host link (line numbers, counters), read-only.
    pub fn port(&self, port: PortId) -> &HostLink {
        self.link.port(port)
    }

    /// Whether single control bytes (Ctrl-X, Ctrl-C, …) are requests on `port` (by default on
    /// the USB port only: [`PortId::default_control_bytes`]).
    pub fn set_control_bytes(&mut self, port: PortId, on: bool) {
        self.link.set_control_bytes(port, on);
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
            let n = self.link.receive(port, bytes.get(taken..).unwrap_or(&[]));
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
        self.policy
            .cmd_limit
            .clamp(1, CMD_CAPACITY)
            .saturating_sub(self.cmds.len())
    }

    /// Queue a command (what the front end does for every parsed line). Returns the command
    /// back when the queue is full (the host gets no `ok` until there is room) or the printer
    /// is halted. While paused with [`PausedLines::Manual`], moves run at once in the service
    /// lane instead.
    pub fn push_command(&mut self, cmd: Command, now_us: u64) -> Result<(), Command> {
        self.set_now(now_us);
        if self.is_halted() {
            return Err(cmd);
        }
        if matches!(self.pause, Pause::Parked { .. })
            && self.policy.paused_lines == PausedLines::Manual
        {
            if let Command::Move(m) = cmd {
                return self
                    .service
                    .push_back(ServiceMove {
                        target: m.target,
                        feed_mm_s: m.feed_mm_s,
                    })
                    .map_err(|_| cmd);
            }
        }
        if self.command_room() == 0 {
            return Err(cmd);
        }
        self.lines.after_cancel = None;
        self.last_activity_us = self.now_us;
        self.cmds.push_back(cmd)?;
        self.feed_planner();
        self.update_state_record();
        Ok(())
    }

    /// Main loop: move commands into the planner, run the pause state machine and dwell.
    pub fn poll(&mut self, now_us: u64) {
        self.set_now(now_us);
        self.take_realtime();
        if self.is_halted() {
            return;
        }
        // Lines are taken only when one waits (or an arc is being cut): the idle tick costs
        // a compare instead of the line handler's frame.
        if self.arc.is_some() || self.link.lines_waiting() > 0 || self.lines.held_line.is_some() {
            self.process_lines();
        }
        self.feed_planner();
        self.retire_finished();
        self.update_pause();
        self.feed_planner();
        if self.lines.sync_ok_owed {
            // An M400 waits for the motion (maybe through a pause) with its `ok` owed.
            self.keep_alive();
        }
        self.report_tick();
        self.update_state_record();
    }

    fn has_work(&self) -> bool {
        !self.cmds.is_empty()
            || !self.planner.is_empty()
            || self.stepgen.current().is_some()
            || self.spill.pending() > 0
    }

    /// Realtime request (pause button, sim, or parsed from the byte stream).
    pub fn request(&mut self, req: Realtime, now_us: u64) {
        self.set_now(now_us);
        if self.is_halted() {
            self.say(format_args!("halted: reset required"));
            return;
        }
        self.retire_finished();
        match req {
            Realtime::Pause(mode) => self.request_pause(mode),
            Realtime::Resume => {
                // M24 starts a selected SD file when there is no pause to resume.
                if !self.sd_start_on_resume() {
                    self.request_resume()
                }
            }
            Realtime::Cancel => {
                let sd = self.sd_cancel();
                self.request_cancel();
                if sd {
                    // The host's stream was not the job: nothing of it is to be discarded.
                    self.lines.after_cancel = None;
                }
            }
            Realtime::EmergencyStop => self.emergency_stop(),
            Realtime::QuickStop => self.quick_stop(),
            Realtime::BreakWait => {
                self.break_wait = true;
                self.thermal.cancel_autotune();
                self.feed_planner();
                self.break_wait = false;
            }
        }
        self.update_pause();
        self.update_state_record();
    }

    /// The run state now.
    pub fn state(&self) -> State {
        match self.pause {
            Pause::Halted => State::Halted,
            Pause::Stopping { .. } | Pause::Parking { .. } => State::Pausing,
            Pause::Parked { .. } => State::Paused,
            Pause::Returning { .. } => State::Resuming,
            Pause::Run => {
                if self.has_work() {
                    State::Printing
                } else if self.lines.after_cancel.is_some() || self.sd_cancelled() {
                    State::Cancelled
                } else {
                    State::Idle
                }
            }
        }
    }

    /// Emergency-stopped (nothing moves until reset).
    fn is_halted(&self) -> bool {
        matches!(self.pause, Pause::Halted)
    }

    fn update_state_record(&mut self) {
        let s = self.state();
        if s != self.last_state {
            self.last_state = s;
            let t_us = self.t_us();
            self.record(Record::State { state: s, t_us });
        }
    }

    /// A snapshot of the printer.
    pub fn status(&self) -> Status {
        let held = self.pause.held();
        let exec = usize::from(
            self.stepgen.current().is_some() || held.is_some_and(|h| h.block.is_some()),
        );
        Status {
            state: self.state(),
            position: self.stepgen.position(),
            layer: self.layer,
            queue_depth: self.cmds.len() + self.planner.len() + exec,
            planner_blocks: self.planner.len(),
            commands: self.cmds.len(),
            paused_at: held.map(|h| h.pos),
            pause_mode: self.pause.mode(),
            position_lost: self.position_lost,
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
        let had_fault = self.thermal.fault().is_some();
        let tune = self.thermal.autotune_status(id);
        let was_lowered = self.thermal.idle_lowered();
        let duty = self.thermal.update(id, measured_c, now_us);
        self.report_autotune(id, tune);
        if !was_lowered && self.thermal.idle_lowered() {
            let s = self.thermal.idle_config().map_or(0, |i| i.timeout_s);
            self.notice(format_args!(
                "pause: nozzle heater off after {s} s parked (M760 T); the resume heats it \
                 again and waits before the head moves"
            ));
        }
        if !had_fault {
            if let Some(f) = self.thermal.fault() {
                let mut t: String<LINE_LEN> = String::new();
                let _ = write!(t, "{f}");
                self.link.notify(Response::Error(&t));
                if !self.is_halted() {
                    self.emergency_stop();
                }
            }
        }
        duty
    }

    /// The heaters (read-only).
    pub fn thermal(&self) -> &Thermal {
        &self.thermal
    }

    /// The heaters (for the board's configuration).
    pub fn thermal_mut(&mut self) -> &mut Thermal {
        &mut self.thermal
    }

    /// Part-cooling fan PWM 0..=255 (M106/M107).
    pub fn fan_pwm(&self) -> u8 {
        self.fan_pwm
    }

    /// The machine's modal state (read-only).
    pub fn machine(&self) -> &MachineState {
        &self.machine
    }
}
