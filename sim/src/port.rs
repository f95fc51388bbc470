//! The seam between the simulator and the firmware executive: what the sim needs from
//! `firmware::printer::Printer`, as a small trait. The sim's event loop, host model and recorder
//! are written against this trait only; [`crate::exec`] implements it for the real executive.
//! Nothing here plans motion or decides a pause: that is the firmware's job.

use firmware::motion::{Realtime, StepPos};
use firmware::planner::BlockKind;
/// The executive's run state and its step events, as the firmware defines them.
pub use firmware::printer::State;
pub use firmware::stepgen::StepEvent;

/// Which lane a step belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Lane {
    /// A move of the job (or, for host-split, any G-code line the host sent).
    Job,
    /// The firmware's own pause/resume moves (retract, lift, park, return, un-retract).
    Service,
}

/// Identity of the block a step belongs to: the job command and the planner segment of it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BlockTag {
    /// The command's job sequence number (`MoveRequest::seq`).
    pub seq: u32,
    /// Segment index within the command (0 when not segmented).
    pub segment: u32,
    /// Job or service lane.
    pub lane: Lane,
}

impl BlockTag {
    /// The block `ev` belongs to (homing moves are job moves to the sim: the job commanded
    /// them).
    pub fn of(ev: &StepEvent) -> Self {
        BlockTag {
            seq: ev.seq,
            segment: ev.seg,
            lane: match ev.kind {
                BlockKind::Service => Lane::Service,
                BlockKind::Job | BlockKind::Homing => Lane::Job,
            },
        }
    }
}

/// Whether two step events are the same motion: time, axes and directions (not the block).
pub fn same_motion(a: &StepEvent, b: &StepEvent) -> bool {
    a.t_ns == b.t_ns && a.axis_mask == b.axis_mask && a.dir_mask == b.dir_mask
}

/// What the sim reads of the executive's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExecStatus {
    /// Run state.
    pub state: State,
    /// Position in steps (where the stepper is now).
    pub pos_steps: StepPos,
    /// Current layer, when known.
    pub layer: Option<u32>,
    /// Moves queued (command queue + planner).
    pub queue_depth: usize,
}

/// How a policy configures the one firmware (see `sim run --policy`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FirmwareKnobs {
    /// Cut moves into segments no longer than this (mm); `None` = no segmentation.
    pub segment_len_mm: Option<f32>,
    /// Queue a pause request at the tail, behind every buffered move (conventional firmware).
    pub pause_at_tail: bool,
    /// Most moves queued at once (command queue + planner), `None` = the firmware's capacity.
    pub queue_limit: Option<usize>,
    /// Speed-up factor after a `layer` request (1.0 = off); `None` = the firmware default.
    pub speedup: Option<f32>,
    /// Extrude below the minimum hotend temperature, as `M302 P1` allows (off: the printer's
    /// cold-extrusion guard, as on the board).
    pub allow_cold: bool,
}

/// What the simulator drives. Implemented for the real executive in [`crate::exec`].
pub trait Executive {
    /// Host bytes arrived at `now_us` (realtime requests are handled at once by the firmware).
    /// Returns how many were taken, from the front; the rest must be offered again later
    /// (flow control: they stay on the wire).
    fn receive(&mut self, bytes: &[u8], now_us: u64) -> usize;
    /// A realtime request raised at `now_us` outside the serial link (pause button).
    fn request(&mut self, req: Realtime, now_us: u64);
    /// Let the firmware's main loop run at `now_us`.
    fn poll(&mut self, now_us: u64);
    /// Time of the next step event, if the step generator has one ready.
    fn next_step_us(&mut self, now_us: u64) -> Option<u64>;
    /// Take the next step event (the one [`Self::next_step_us`] announced).
    fn pop_step(&mut self, now_us: u64) -> Option<StepEvent>;
    /// Host-link output written since the last call.
    fn take_output(&mut self, out: &mut String);
    /// Current state.
    fn status(&self) -> ExecStatus;
    /// The sequence number the firmware will give the next job move, when it tells (used to map
    /// executed blocks back to the host line that produced them).
    fn next_seq(&self) -> Option<u32> {
        None
    }
    /// Feed a temperature sample (°C) for heater `bed` (false = hotend); returns the heater
    /// duty 0..=1 the firmware asks for. Executives without thermal control return 0.
    fn thermal(&mut self, bed: bool, measured_c: f32, now_us: u64) -> f32;
    /// Job moves whose extrusion was dropped when they reached the planner (a nozzle too
    /// cold), from the execution record: each is a lost move, whatever the step comparison
    /// says of its X/Y/Z.
    fn cold_refused(&self) -> usize {
        0
    }
}
