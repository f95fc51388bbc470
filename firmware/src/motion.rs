//! Types that cross the seam between the front end (host link, G-code, machine state) and the
//! motion side (planner, pause, step generator). Keeping them in one small module lets both
//! sides be written and tested on their own.

/// Number of motion axes: X, Y, Z and the extruder E (E is an axis like any other).
pub const AXES: usize = 4;

/// A machine position in whole motor steps, indexed by [`Axis`]. Positions are integers so the
/// host, the simulator and the MCU agree to the step.
pub type StepPos = [i32; AXES];

/// One motion axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axis {
    /// Carriage left/right.
    X = 0,
    /// Bed (Ender-3 class) or carriage front/back.
    Y = 1,
    /// Vertical.
    Z = 2,
    /// Extruder filament feed.
    E = 3,
}

impl Axis {
    /// All axes in index order.
    pub const ALL: [Axis; AXES] = [Axis::X, Axis::Y, Axis::Z, Axis::E];

    /// Index into a [`StepPos`] or per-axis array.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The G-code letter of the axis.
    pub const fn letter(self) -> char {
        match self {
            Axis::X => 'X',
            Axis::Y => 'Y',
            Axis::Z => 'Z',
            Axis::E => 'E',
        }
    }
}

/// A straight move handed from the machine state to the planner: an absolute target in steps and
/// the requested tool speed with the feed override (M220) already applied. The flow override
/// (M221) is already applied to the E target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MoveRequest {
    /// Absolute target in steps.
    pub target: StepPos,
    /// Requested speed along the path in mm/s (XYZ length; E alone for extruder-only moves).
    pub feed_mm_s: f32,
    /// Job sequence number of the command that produced this move: strictly increasing over a
    /// job, so the execution record can prove each move ran exactly once and in order.
    pub seq: u32,
}

/// Where a layer change was detected, so reports can say why a boundary exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayerSource {
    /// A slicer comment (`;LAYER_CHANGE`, `;LAYER:n`, `; layer n`, ideaMaker, ...).
    Comment,
    /// A command (`M73 L`, `SET_PRINT_STATS_INFO CURRENT_LAYER=`).
    Command,
    /// No marker in the file: the extrusion height changed (see [`crate::layer`]: Z rose or
    /// dropped before the next extruding move, or a helix rose by a layer height).
    ZRise,
    /// The end of printing: the first end-code command (heater off, motors off) after the
    /// last extrusion, so a pause in the last layer stops before the end code.
    End,
    /// The host compiler's own marker for layer-free (helical) prints: one per turn.
    Turn,
}

/// A layer boundary as an entry in the command stream: everything queued before it belongs to
/// the previous layer. The planner keeps these in its queue so a pause can stop exactly here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayerMark {
    /// Number of the layer that starts here: the n-th layer printed in the job, from 1
    /// (docs/planner.md, "What a layer is").
    pub layer: u32,
    /// Height of the new layer in micrometres, when known.
    pub z_um: Option<i32>,
    /// What produced the mark.
    pub source: LayerSource,
}

/// How a pause request acts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PauseMode {
    /// Finish the current layer (sped up), stop at the first layer boundary after the executing
    /// block, then retract, lift and park.
    Layer,
    /// Feed hold: brake at once at the configured deceleration, then retract, lift and park.
    Now,
}

/// Requests that bypass the command queue: picked straight out of the byte stream (or raised by
/// the board's pause button) so they act even when every buffer is full.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Realtime {
    /// Pause at the next layer boundary (M25 / M601 by default).
    Pause(PauseMode),
    /// Resume a paused print (M24 / M602).
    Resume,
    /// Cancel the job: held moves are dropped on purpose and reported.
    Cancel,
    /// M112: heaters and motors off, state kept until reset.
    EmergencyStop,
    /// M410: stop all motion now and discard queued moves (position stays known).
    QuickStop,
    /// M108: break out of a heater wait or a wait for the user.
    BreakWait,
}

/// Round half away from zero to an `i32`, or `None` outside its range (and for NaN). Exact:
/// for |x| < 2^31 the truncation and the fraction `x - trunc(x)` are exact in `f64`; the same
/// result as `libm::round`, without its bit twiddling (property-tested).
pub(crate) fn round_i32(x: f64) -> Option<i32> {
    if !(x > f64::from(i32::MIN) - 0.5 && x < f64::from(i32::MAX) + 0.5) {
        return None;
    }
    // In range: the casts cannot saturate.
    let t = x as i64;
    let frac = x - t as f64;
    let r = if frac >= 0.5 {
        t + 1
    } else if frac <= -0.5 {
        t - 1
    } else {
        t
    };
    i32::try_from(r).ok()
}
