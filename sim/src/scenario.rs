//! What defines one run: the policy, the pause mode, when the pause is requested, and the
//! machine, link and queue settings around them.

use crate::hostlink::LinkConfig;
use crate::port::FirmwareKnobs;
use firmware::config::MachineConfig;

/// How the printer and host handle a pause (see the crate docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Policy {
    /// Conventional firmware: no segmentation, the pause queued behind every buffered move
    /// (16 moves), park once the queue has drained.
    Fifo,
    /// The paper's host-side method on a FIFO firmware: moves pre-split by the host, the pause
    /// sequence appended by the host after the current layer.
    HostSplit,
    /// This project's firmware: segmentation in the planner, layer barrier, speed-up, feed hold.
    Firmware,
}

impl Policy {
    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Policy::Fifo => "fifo",
            Policy::HostSplit => "host-split",
            Policy::Firmware => "firmware",
        }
    }
}

/// Pause mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// Finish the current layer, stop at its end.
    Layer,
    /// Stop as soon as possible (feed hold).
    Now,
}

impl Mode {
    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Layer => "layer",
            Mode::Now => "now",
        }
    }
}

/// When the pause is requested.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PauseWhen {
    /// At this virtual time, µs.
    AtUs(u64),
    /// Scheduled before the job for the start of layer `n` (M761 L n for the firmware; a pause
    /// placed in the stream before layer `n` for the conventional policies).
    AtLayer(u32),
    /// While job line `line` executes, at `fraction` of its duration (the lab's "during the 3rd
    /// line").
    DuringLine {
        /// Job line index.
        line: usize,
        /// 0..1 of the line's execution time.
        fraction: f64,
    },
}

/// No limit on a run's virtual time (`sim run --max-hours` sets one): a quarter of the µs
/// clock's range, so sums of deadlines never overflow. A run still ends: when its job has, or
/// when it stalls ([`crate::engine::STALL_LIMIT_US`] without a step or a line sent).
pub const NO_TIME_LIMIT_US: u64 = u64::MAX / 4;

/// Everything that defines one run.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Policy.
    pub policy: Policy,
    /// Pause mode.
    pub mode: Mode,
    /// When to pause (`None`: print without pausing).
    pub pause: Option<PauseWhen>,
    /// Resume this long after the printer is parked, µs (`None`: stay paused, end the run).
    pub resume_after_us: Option<u64>,
    /// Machine configuration.
    pub machine: MachineConfig,
    /// Host link.
    pub link: LinkConfig,
    /// Moves the conventional policies buffer (paper: 16).
    pub queue_limit: usize,
    /// Planner segment length for the `firmware` policy, mm (`None`: the firmware default).
    pub segment_len_mm: Option<f32>,
    /// Host-split piece length, mm (paper: 0.1–0.2).
    pub split_mm: f64,
    /// Give up after this much virtual time, µs ([`NO_TIME_LIMIT_US`] by default: a run ends
    /// when its job does, or when it stalls — see [`crate::engine::STALL_LIMIT_US`]).
    pub max_time_us: u64,
    /// Also run the job with segmentation off to measure segmentation's print-time cost.
    pub measure_segmentation_cost: bool,
    /// Extrude cold, as `M302 P1` allows (default off: the cold-extrusion guard is on, as on
    /// the board; the built-in patterns of `lab` and `demo`, which model motion without
    /// heating, turn it on).
    pub allow_cold: bool,
    /// Keep the executed-block record of a run without a pause (`Outcome::run.rec.records`).
    /// A pause always keeps both runs' records (the metrics compare them); without one only
    /// callers that inspect the records need them (`sim run` does not: memory then stays
    /// flat with job length, see docs/sim.md).
    pub keep_records: bool,
}

impl Scenario {
    /// Defaults for a policy and mode: 115200 baud, queue 16, host pieces 0.2 mm.
    pub fn new(policy: Policy, mode: Mode) -> Self {
        Self {
            policy,
            mode,
            pause: None,
            resume_after_us: Some(10_000_000),
            machine: MachineConfig::ENDER3,
            link: LinkConfig::default(),
            queue_limit: 16,
            segment_len_mm: None,
            split_mm: 0.2,
            max_time_us: NO_TIME_LIMIT_US,
            measure_segmentation_cost: false,
            allow_cold: false,
            keep_records: true,
        }
    }

    /// The firmware knobs this policy sets.
    pub fn knobs(&self) -> FirmwareKnobs {
        match self.policy {
            Policy::Fifo | Policy::HostSplit => FirmwareKnobs {
                segment_len_mm: None,
                pause_at_tail: true,
                queue_limit: Some(self.queue_limit),
                speedup: Some(1.0),
                allow_cold: self.allow_cold,
            },
            Policy::Firmware => FirmwareKnobs {
                segment_len_mm: Some(
                    self.segment_len_mm
                        .unwrap_or(self.machine.pause.segment_len_mm),
                ),
                pause_at_tail: false,
                queue_limit: None,
                speedup: None,
                allow_cold: self.allow_cold,
            },
        }
    }
}
