//! The pause machine's state as one type: each variant carries the data that exists only in
//! it, so impossible combinations (a deferred resume while printing, a held block while
//! stopping, a cancel and a withdrawal at once...) cannot be written.
//!
//! ```text
//! Run ──pause/cancel──► Stopping{how, mode, then} ──head stopped──► Parking{held, then}
//!   ▲                      │ then = Continue: release, back to Run      │ then = Cancel
//!   │                      ▼                                            ▼
//!   └──── Returning{held, then} ◄──resume── Parked{held}             Run (cancelled)
//! any ──M112──► Halted
//! ```

use crate::motion::{PauseMode, StepPos};
use crate::stepgen::ExecBlock;

/// Where the pause machine is.
#[derive(Clone, Copy, Debug)]
pub(in crate::printer) enum Pause {
    /// Printing or idle: no pause.
    Run,
    /// A pause (or a cancel) on its way: the head moves until it has stopped.
    Stopping {
        /// How it stops.
        how: Stop,
        /// The mode it reports (what was asked; a conventional tail stop runs to its barrier
        /// whatever was asked).
        mode: PauseMode,
        /// What happens once it has stopped.
        then: AfterStop,
    },
    /// Retract, lift and park in the service lane.
    Parking {
        /// The held job.
        held: Held,
        /// What happens once parked.
        then: AfterPark,
    },
    /// Parked; the held job waits.
    Parked {
        /// The held job.
        held: Held,
    },
    /// Returning to the held position: XY, Z, un-retract, then the held job is released.
    Returning {
        /// The held job.
        held: Held,
        /// Waiting for the nozzle to be hot again (the pause idle timeout cooled it).
        reheat: bool,
        /// What happens once back.
        then: AfterReturn,
    },
    /// Emergency stop: nothing moves until reset.
    Halted,
}

/// How a stopping pause stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::printer) enum Stop {
    /// At the layer barrier in the planner (layer pause, scheduled pause, M0/M600); `layer`
    /// is the mark the barrier stands at, once known.
    Barrier {
        /// The barrier's layer mark.
        layer: Option<u32>,
    },
    /// Feed hold: brake now. `after_homing`: a homing move is running; the brake starts when
    /// it has finished.
    Hold {
        /// Waiting for a homing move to finish before braking.
        after_homing: bool,
    },
    /// Conventional firmware ([`crate::printer::Policy::pause_at_tail`]): after everything
    /// queued at the request. `countdown`: commands still to enter the planner before the
    /// barrier is set at the planner's tail.
    Tail {
        /// Commands left before the tail barrier is set.
        countdown: Option<usize>,
    },
}

impl Stop {
    /// Whether this stop brakes the motion (a feed hold). A tail stop never does, whatever
    /// mode was asked for: it runs everything queued before it to its barrier, as a
    /// conventional firmware's pause does.
    pub(in crate::printer) fn brakes(self) -> bool {
        matches!(self, Stop::Hold { .. })
    }
}

/// What a stopping pause does once the head has stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::printer) enum AfterStop {
    /// Park (the pause).
    Park,
    /// The pause was withdrawn during a feed hold: continue from where it stopped.
    Continue,
    /// A cancel: drop the job, park, then back to [`Pause::Run`].
    Cancel,
}

/// What a parking pause does once parked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::printer) enum AfterPark {
    /// Stay parked (announce `//action:paused`).
    Wait,
    /// A resume came while parking: return at once.
    Resume,
    /// A cancel: finish it (the job is already dropped).
    Cancel,
}

/// What a returning pause does once back at the held position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::printer) enum AfterReturn {
    /// Release the held job.
    Print,
    /// A pause came while returning: release, then pause again.
    Pause(PauseMode),
    /// A cancel came while returning: finish it where the head is.
    Cancel,
}

/// The job held by a pause: where it stopped and what it left.
#[derive(Clone, Copy, Debug)]
pub(in crate::printer) struct Held {
    /// The block interrupted mid-way (feed hold), to be finished on resume.
    pub(in crate::printer) block: Option<ExecBlock>,
    /// Where the head stopped, steps.
    pub(in crate::printer) pos: StepPos,
    /// E retracted by the park, steps (given back by the return).
    pub(in crate::printer) retracted_steps: i32,
    /// The pause's mode (reported).
    pub(in crate::printer) mode: PauseMode,
    /// The layer the held job starts with when the head stopped at a layer boundary (the
    /// barrier's mark); `None` after a stop inside a layer (feed hold, a conventional
    /// firmware's tail stop). What a host that connects to the parked printer is told.
    pub(in crate::printer) before_layer: Option<u32>,
}

impl Pause {
    /// The held job, from the stop to the release.
    pub(in crate::printer) fn held(&self) -> Option<&Held> {
        match self {
            Pause::Parking { held, .. }
            | Pause::Parked { held }
            | Pause::Returning { held, .. } => Some(held),
            _ => None,
        }
    }

    /// The held job, mutable.
    pub(super) fn held_mut(&mut self) -> Option<&mut Held> {
        match self {
            Pause::Parking { held, .. }
            | Pause::Parked { held }
            | Pause::Returning { held, .. } => Some(held),
            _ => None,
        }
    }

    /// The current pause's mode, if a pause is in progress.
    pub(in crate::printer) fn mode(&self) -> Option<PauseMode> {
        match self {
            Pause::Stopping { mode, .. } => Some(*mode),
            _ => self.held().map(|h| h.mode),
        }
    }

    /// A cancel is on its way (it completes when the head has stopped and parked).
    pub(in crate::printer) fn cancelling(&self) -> bool {
        matches!(
            self,
            Pause::Stopping {
                then: AfterStop::Cancel,
                ..
            } | Pause::Parking {
                then: AfterPark::Cancel,
                ..
            } | Pause::Returning {
                then: AfterReturn::Cancel,
                ..
            }
        )
    }

    /// The layer a parked or stopping printer's held job starts with: the barrier's mark, or
    /// `None` for a stop inside a layer.
    pub(in crate::printer) fn before_layer(&self) -> Option<u32> {
        match self {
            Pause::Stopping {
                how: Stop::Barrier { layer },
                ..
            } => *layer,
            p => p.held().and_then(|h| h.before_layer),
        }
    }
}
