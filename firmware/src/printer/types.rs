//! The executive's public types: run state, commands, policies, execution records, status.

use crate::motion::{LayerMark, MoveRequest, PauseMode, StepPos};
use crate::planner::{BlockKind, RING_CAPACITY};
use crate::thermal::HeaterId;

/// Longest message line the executive formats.
pub const LINE_LEN: usize = 120;

/// Command queue capacity (commands after parsing; each ≈ 32 B): the most a policy lets wait.
pub const CMD_CAPACITY: usize = 32;

/// Run state, as reported by [`super::Printer::status`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Nothing queued, nothing moving.
    Idle,
    /// Executing the job.
    Printing,
    /// A pause was requested: speeding up / braking, then retract, lift and park.
    Pausing,
    /// Parked; held moves wait.
    Paused,
    /// Returning from the park position.
    Resuming,
    /// The job was cancelled (until the next command arrives).
    Cancelled,
    /// Emergency stop: nothing moves until a new `Printer` is made (reset).
    Halted,
}

/// A command after parsing and the machine's modal state: what the command queue holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// A job move.
    Move(MoveRequest),
    /// A layer boundary.
    Layer(LayerMark),
    /// G28: wait for motion to end, then move the named axes (bit i = axis i; X, Y, Z) to
    /// the home corner (axes' minimum). There are no endstops in the portable library: the
    /// position is trusted, as after a successful homing.
    Home {
        /// Axes to home, bit i = axis i.
        mask: u8,
    },
    /// M109/M190: wait until the heater has reached its target (M108 breaks the wait).
    WaitHeater(HeaterId),
    /// G92 and friends: wait for motion to end, then set the position in steps.
    SetPosition(StepPos),
    /// G4: wait for motion to end, then wait this long.
    Dwell {
        /// Dwell time, ms.
        ms: u32,
    },
    /// M400: wait for motion to end.
    Sync,
    /// M761 L/Z inside the job: schedule a pause.
    SchedulePause(Schedule),
    /// M0/M1 (without a time) and M600: stop once everything before this point has run,
    /// then retract, lift and park like any pause, and wait for a resume.
    PauseHere,
    /// M17/M18/M84: a request for the board's stepper drivers, passed on in job order
    /// (a disable waits until the motion before it has run).
    Steppers(StepperRequest),
    /// M1000's last step (after its heater waits and X/Y homing): wait for motion to end,
    /// then return to the kept job's boundary as a resume from a park (see `recovery.rs`).
    Recover,
    /// A job line's heater, fan, acceleration or cold-extrusion setting: it takes effect in
    /// job order, when it reaches the front of the queue — never while a pause holds the job
    /// (an end code's `M104 S0` that arrived while parked runs after the held layer).
    Setting(JobSetting),
}

/// A state command of the job (see [`Command::Setting`]): the G-code's own fields, checked
/// for what does not depend on when it runs (the tool, the fan index) when the line came.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JobSetting {
    /// M104/M109/M140/M190 (T0 or no T).
    Temperature {
        /// Which heater.
        heater: crate::gcode::Heater,
        /// M109/M190: wait for the target after setting it.
        wait: bool,
        /// `S`, °C.
        s: Option<f32>,
        /// `R`, °C.
        r: Option<f32>,
    },
    /// M106 `S` (None: full) / M107 (`Some(0.0)`), fan 0.
    Fan(Option<f32>),
    /// M204 with at least one value; NaN = not given (keeps [`Command`] at a move's size).
    Acceleration {
        /// `P`.
        print: f32,
        /// `R`.
        retract: f32,
        /// `T`.
        travel: f32,
        /// `S`.
        s: f32,
    },
    /// M302 with `S` or `P`.
    ColdExtrusion {
        /// `S`, °C.
        min_temp_c: Option<f32>,
        /// `P`.
        allow: Option<bool>,
    },
}

impl JobSetting {
    /// The setting a job line's command is, when it is one (`None`: the command acts when its
    /// line is taken — reports, settings, the pause's own commands, or a refusal to say).
    pub fn of(cmd: &crate::gcode::Command) -> Option<JobSetting> {
        use crate::gcode::{Command as G, HeatCommand as H, SettingsCommand as S};
        Some(match *cmd {
            G::Heat(H::SetTemperature {
                heater,
                wait,
                s,
                r,
                tool: None | Some(0),
            }) => JobSetting::Temperature { heater, wait, s, r },
            G::Heat(H::FanOn {
                speed,
                fan: None | Some(0),
            }) => JobSetting::Fan(speed),
            G::Heat(H::FanOff {
                fan: None | Some(0),
            }) => JobSetting::Fan(Some(0.0)),
            G::Settings(S::Acceleration {
                print,
                retract,
                travel,
                s,
            }) if print.is_some() || retract.is_some() || travel.is_some() || s.is_some() => {
                JobSetting::Acceleration {
                    print: print.unwrap_or(f32::NAN),
                    retract: retract.unwrap_or(f32::NAN),
                    travel: travel.unwrap_or(f32::NAN),
                    s: s.unwrap_or(f32::NAN),
                }
            }
            G::Heat(H::ColdExtrusion { min_temp_c, allow })
                if min_temp_c.is_some() || allow.is_some() =>
            {
                JobSetting::ColdExtrusion { min_temp_c, allow }
            }
            _ => return None,
        })
    }
}

/// A request for the board's stepper drivers (M17/M18/M84), taken with
/// [`super::Printer::take_stepper_request`]. The portable executive has no driver pins: the
/// board (or the sim) acts on these.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepperRequest {
    /// M17 `[X Y Z E]`: enable the drivers of these axes (bit i = axis i; no axis named = all).
    Enable {
        /// Axes, bit i = axis i.
        mask: u8,
    },
    /// M18/M84 `[X Y Z E]` without `S`: disable these axes' drivers (no axis named = all),
    /// issued once every move queued before it has been stepped.
    Disable {
        /// Axes, bit i = axis i.
        mask: u8,
    },
    /// M18/M84 `S<seconds>`: the idle time after which the board disables every driver
    /// (0 = never), as Marlin.
    IdleTimeout {
        /// Seconds.
        s: f32,
    },
}

/// A scheduled pause (M761).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Schedule {
    /// At the start of layer n (at the boundary before it).
    Layer(u32),
    /// At the first layer whose height is at or above this, µm.
    Z(i32),
}

/// What lines the host sends while paused mean.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PausedLines {
    /// Job lines: they keep queuing behind the barrier until the queue is full (safe with any
    /// host; manual moves wait for the resume).
    Queue,
    /// Manual commands: moves run at once in the service lane; the modal state is restored on
    /// resume (for hosts that stop streaming on `//action:paused`, like OctoPrint).
    Manual,
    /// Decided per line: once the host has numbered its lines (printcore, OctoPrint, Repetier
    /// and our sender number and checksum every job line), a numbered line while paused is a
    /// job line ([`PausedLines::Queue`]) and an unnumbered one is a manual command
    /// ([`PausedLines::Manual`]): printcore's `send_now` and OctoPrint's terminal and jog
    /// buttons while paused send without numbers. A host that never numbers gets `Queue`.
    /// See docs/frontend.md, "host rules".
    Auto,
}

/// Policy knobs: our firmware and conventional firmware on the same code.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Policy {
    /// Cut moves into `segment_len_mm` segments.
    pub segment: bool,
    /// A pause acts only after everything queued before it has executed (Marlin, Klipper).
    pub pause_at_tail: bool,
    /// Most planner blocks queued, the executing one included (≤ [`RING_CAPACITY`]).
    pub max_blocks: usize,
    /// Most commands waiting in the command queue (≤ [`CMD_CAPACITY`]).
    pub cmd_limit: usize,
    /// Plan a stop at every layer mark (lets a `layer` pause stop at any queued boundary; costs
    /// a standstill per mark). Off: a mark costs nothing, a pause stops at the first
    /// *reachable* one (see `Planner::can_stop_before`).
    pub stop_at_marks: bool,
    /// Meaning of host lines while paused.
    pub paused_lines: PausedLines,
}

impl Policy {
    /// Ours: segmentation, layer barrier, full ring.
    pub const FIRMWARE: Policy = Policy {
        segment: true,
        pause_at_tail: false,
        max_blocks: RING_CAPACITY,
        cmd_limit: CMD_CAPACITY,
        // A mark costs nothing (no standstill unless a pause needs one there).
        stop_at_marks: false,
        paused_lines: PausedLines::Auto,
    };
    /// Conventional firmware: no segmentation, pause at the tail, 16 moves queued in all
    /// (15 planner blocks including the executing one, as Marlin's 16-slot ring, plus 1
    /// command waiting), as measured in SPEC §1.
    pub const FIFO: Policy = Policy {
        segment: false,
        pause_at_tail: true,
        max_blocks: 15,
        cmd_limit: 1,
        stop_at_marks: false,
        paused_lines: PausedLines::Queue,
    };

    /// Split a total limit of queued moves into 1 waiting command + planner blocks.
    pub fn with_queue_limit(mut self, total: usize) -> Self {
        let total = total.clamp(2, RING_CAPACITY + 1);
        self.cmd_limit = 1;
        self.max_blocks = total - 1;
        self
    }
}

impl Default for Policy {
    fn default() -> Self {
        Self::FIRMWARE
    }
}

/// What happened, for the simulator's and the tests' execution record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Record {
    /// A block finished executing.
    Executed {
        /// Job sequence number.
        seq: u32,
        /// Segment index within the move.
        seg: u32,
        /// Segments of the move.
        segs: u32,
        /// Job, homing or service lane.
        kind: BlockKind,
        /// When its last step happened, µs.
        t_us: u64,
        /// Position after it, steps.
        pos: StepPos,
    },
    /// The head crossed a layer boundary (the first block of the layer started).
    Layer {
        /// Layer that started.
        layer: u32,
        /// When, µs.
        t_us: u64,
    },
    /// The state changed.
    State {
        /// New state.
        state: State,
        /// When, µs.
        t_us: u64,
    },
    /// A `layer` pause sped up the rest of the layer (the visible acknowledgement).
    SpeedUp {
        /// When, µs.
        t_us: u64,
    },
    /// A feed hold started braking from this speed.
    Brake {
        /// Speed when braking started, mm/s.
        v_mm_s: f32,
        /// Acceleration used by the executing block, mm/s².
        accel_mm_s2: f32,
        /// When, µs.
        t_us: u64,
    },
    /// A job move reached the planner with a nozzle too cold to extrude (and not heating):
    /// its E part was dropped, the rest of it planned (Marlin's "cold extrusion prevented").
    /// The move's extrusion is lost.
    ColdRefused {
        /// Job sequence number of the move.
        seq: u32,
        /// E steps not extruded.
        e_steps: i32,
        /// When, µs.
        t_us: u64,
    },
    /// The head stopped for a pause at this position.
    Stopped {
        /// Position, steps.
        pos: StepPos,
        /// Layer mark the barrier stood at (layer mode), if any.
        layer: Option<u32>,
        /// True when a block was interrupted mid-way (now mode).
        mid_block: bool,
        /// When, µs.
        t_us: u64,
    },
}

/// A snapshot for displays, the sim and the board.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Status {
    /// Run state.
    pub state: State,
    /// Position of the steppers, steps.
    pub position: StepPos,
    /// Current layer (last boundary crossed).
    pub layer: Option<u32>,
    /// Commands waiting + planner blocks + executing block.
    pub queue_depth: usize,
    /// Planner blocks queued.
    pub planner_blocks: usize,
    /// Commands waiting in the command queue.
    pub commands: usize,
    /// Where the head stopped for the current pause, steps.
    pub paused_at: Option<StepPos>,
    /// Mode of the current pause.
    pub pause_mode: Option<PauseMode>,
    /// Axes whose position is lost because their drivers were switched off (M18/M84) and not
    /// homed since: bit i = axis i (X, Y, Z). The pause does not park on a lost X/Y.
    pub position_lost: u8,
}
