//! Homing (G28) as a portable state machine: which move to make next, and what a finished move
//! means. The executive (or a test driver) runs each [`HomingMove`] through the planner, with
//! the endstop watched during the approaches, and reports how it ended; this module decides
//! the sequence, as Marlin's `G28` / `homeaxis()` does:
//!
//! 1. **Z raised first** when X or Y is homed ([`HomingConfig::z_raise_mm`], Marlin's
//!    `Z_CLEARANCE_FOR_HOMING`, formerly `Z_HOMING_HEIGHT`), so the nozzle clears the bed and
//!    its clips; relative, since Z may not be known.
//! 2. Each axis in the order X, Y, Z: a **fast approach** towards the switch at the homing feed
//!    (Marlin's `HOMING_FEEDRATE_MM_M`), at most 1.5 × the axis's travel; a **bump** back by
//!    [`HomingConfig::bump_mm`] (`HOMING_BUMP_MM`); a **slow second approach** at the feed
//!    divided by [`HomingConfig::bump_divisor`] (`HOMING_BUMP_DIVISOR`), at most twice the
//!    bump. Where the slow approach triggers is the axis's minimum.
//! 3. Every named axis is homed, always: an axis believed to be at its minimum is moved all
//!    the same (the belief is what homing checks).
//!
//! A fast or slow approach that ends without the switch triggering fails the homing with a
//! clear [`HomingError`]; so does a switch still pressed after the bump. [`Homing::abort`]
//! (M112, kill, quick stop) ends it at once.
//!
//! The switches are read through [`Endstops`]; [`PinEndstops`] reads three embedded-hal
//! [`InputPin`]s, the simulator and the tests implement the trait with a switch at a known
//! position.
//!
//! Values of [`HomingConfig::ENDER3`] from Marlin's Ender-3 example configuration
//! (`config/examples/Creality/Ender-3/CrealityV427/Configuration.h` and `Configuration_adv.h`
//! of MarlinFirmware/Configurations, commit 25e9ab2318): `HOMING_FEEDRATE_MM_M
//! { (20*60), (20*60), (4*60) }`, `HOMING_BUMP_MM { 5, 5, 2 }`, `HOMING_BUMP_DIVISOR
//! { 2, 2, 4 }`; `Z_CLEARANCE_FOR_HOMING` is left off there, 4 mm is the value its comment
//! suggests (`//#define Z_CLEARANCE_FOR_HOMING  4`).

use crate::config::MachineConfig;
use crate::motion::Axis;
use core::fmt;
use embedded_hal::digital::InputPin;

#[cfg(test)]
mod tests;

/// Reads the minimum endstops of X, Y and Z.
pub trait Endstops {
    /// The switch of `axis` is pressed (`false` for E and for a switch that cannot be read).
    fn triggered(&mut self, axis: Axis) -> bool;
}

/// Three endstop switches on GPIO inputs.
pub struct PinEndstops<X, Y, Z> {
    /// X minimum switch.
    pub x: X,
    /// Y minimum switch.
    pub y: Y,
    /// Z minimum switch.
    pub z: Z,
    /// Bit i (X, Y, Z) set: that switch reads high when pressed (Marlin's Ender-3 example
    /// configurations: `X_MIN_ENDSTOP_HIT_STATE HIGH`, with `ENDSTOPPULLUPS`;
    /// `MachineConfig::endstop_hit_high_mask`).
    pub pressed_high: u8,
}

impl<X: InputPin, Y: InputPin, Z: InputPin> Endstops for PinEndstops<X, Y, Z> {
    fn triggered(&mut self, axis: Axis) -> bool {
        let level = match axis {
            Axis::X => self.x.is_high().ok(),
            Axis::Y => self.y.is_high().ok(),
            Axis::Z => self.z.is_high().ok(),
            Axis::E => return false,
        };
        let pressed_high = self.pressed_high & (1 << axis.index()) != 0;
        // An unreadable pin counts as pressed: homing then stops instead of driving on.
        level.is_none_or(|high| high == pressed_high)
    }
}

/// Homing speeds and distances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingConfig {
    /// Approach feed per axis (X Y Z), mm/s.
    pub feed_mm_s: [f32; 3],
    /// Distance backed off after the first touch, per axis, mm.
    pub bump_mm: [f32; 3],
    /// The second approach runs at `feed_mm_s / bump_divisor`.
    pub bump_divisor: [f32; 3],
    /// Z raised (relative) before X or Y is homed, mm; 0 = off.
    pub z_raise_mm: f32,
}

impl HomingConfig {
    /// Marlin's Ender-3 values (see the module documentation for the source).
    pub const ENDER3: HomingConfig = HomingConfig {
        feed_mm_s: [20.0, 20.0, 4.0],
        bump_mm: [5.0, 5.0, 2.0],
        bump_divisor: [2.0, 2.0, 4.0],
        z_raise_mm: 4.0,
    };
}

impl Default for HomingConfig {
    fn default() -> Self {
        Self::ENDER3
    }
}

/// One move of the homing sequence, relative to where the axis is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomingMove {
    /// The axis that moves (only one at a time).
    pub axis: Axis,
    /// Signed distance, mm (negative = towards the minimum switch).
    pub distance_mm: f32,
    /// Feed, mm/s.
    pub feed_mm_s: f32,
    /// Stop the move when the axis's switch triggers (approaches); otherwise run it whole.
    pub stop_at_switch: bool,
}

/// How a [`HomingMove`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveEnd {
    /// It ran its whole distance; `switch` = the axis's switch is pressed now.
    Completed {
        /// The switch state at the end.
        switch: bool,
    },
    /// The switch triggered and the move stopped there.
    Triggered,
}

/// Why homing failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HomingError {
    /// An approach ran its whole distance without the switch triggering (switch unplugged or
    /// broken, axis blocked): the axis is not homed.
    SwitchNotHit {
        /// The axis.
        axis: Axis,
        /// How far it travelled looking for the switch, mm.
        searched_mm: f32,
    },
    /// The switch was still pressed after backing off by the bump distance.
    SwitchStuck {
        /// The axis.
        axis: Axis,
    },
    /// Aborted (M112, kill, quick stop).
    Aborted,
}

impl fmt::Display for HomingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::SwitchNotHit { axis, searched_mm } => write!(
                f,
                "Homing Failed: {} endstop not hit within {searched_mm:.0} mm",
                axis.letter()
            ),
            Self::SwitchStuck { axis } => write!(
                f,
                "Homing Failed: {} endstop still pressed after the bump",
                axis.letter()
            ),
            Self::Aborted => f.write_str("Homing aborted"),
        }
    }
}

/// What the driver of the sequence does next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Next {
    /// Run this move, then call [`Homing::finished`].
    Move(HomingMove),
    /// The axis reached its switch on the slow approach: its position is now its minimum
    /// (`min_mm`). Call [`Homing::next_step`] again.
    Homed(Axis),
    /// Every named axis is homed.
    Done,
    /// Homing failed; the axes homed before the failure stay homed.
    Failed(HomingError),
}

/// Where the sequence is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    /// Raise Z before X/Y.
    RaiseZ,
    /// First approach of the axis at `order[k]`.
    Fast(usize),
    /// Back off.
    Bump(usize),
    /// Second, slow approach.
    Slow(usize),
    /// The axis at `order[k]` is homed; report it, then go on with `k + 1`.
    Homed(usize),
    /// A move is running; `then` decides on its end.
    Running(Step),
    Done,
    Failed(HomingError),
}

/// The phase a running move belongs to.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Step {
    RaiseZ,
    Fast(usize),
    Bump(usize),
    Slow(usize),
}

/// The homing sequence for one G28. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Homing {
    order: [Axis; 3],
    count: usize,
    cfg: HomingConfig,
    /// Fast-approach distance per axis (1.5 × travel), mm.
    search_mm: [f32; 3],
    phase: Phase,
}

impl Homing {
    /// Home the axes named in `mask` (bit 0 X, 1 Y, 2 Z; none named = all three).
    pub fn new(mask: u8, cfg: &HomingConfig, machine: &MachineConfig) -> Self {
        let mask = if mask & 0b111 == 0 { 0b111 } else { mask };
        let mut order = [Axis::X; 3];
        let mut count = 0;
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            if mask & (1 << axis.index()) != 0 {
                order[count] = axis;
                count += 1;
            }
        }
        let mut search_mm = [0.0f32; 3];
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let a = machine.axis(axis);
            let travel = a.max_mm - a.min_mm;
            search_mm[axis.index()] = if travel.is_finite() && travel > 0.0 {
                1.5 * travel
            } else {
                0.0
            };
        }
        let xy = mask & 0b011 != 0;
        Homing {
            order,
            count,
            cfg: *cfg,
            search_mm,
            phase: if xy && cfg.z_raise_mm > 0.0 {
                Phase::RaiseZ
            } else {
                Phase::Fast(0)
            },
        }
    }

    /// The axes homed in order.
    pub fn axes(&self) -> &[Axis] {
        &self.order[..self.count]
    }

    /// What to do now. A move in progress stays in progress: [`Next::Move`] is returned once
    /// per move, and later calls before [`Homing::finished`] return the same move again.
    pub fn next_step(&mut self) -> Next {
        let (step, mv) = match self.phase {
            Phase::Done => return Next::Done,
            Phase::Failed(e) => return Next::Failed(e),
            Phase::Homed(k) => {
                self.phase = Phase::Fast(k + 1);
                return Next::Homed(self.order[k]);
            }
            Phase::Running(step) => (step, self.move_of(step)),
            Phase::RaiseZ => (Step::RaiseZ, self.move_of(Step::RaiseZ)),
            Phase::Fast(k) if k >= self.count => {
                self.phase = Phase::Done;
                return Next::Done;
            }
            Phase::Fast(k) => (Step::Fast(k), self.move_of(Step::Fast(k))),
            Phase::Bump(k) => (Step::Bump(k), self.move_of(Step::Bump(k))),
            Phase::Slow(k) => (Step::Slow(k), self.move_of(Step::Slow(k))),
        };
        self.phase = Phase::Running(step);
        Next::Move(mv)
    }

    fn move_of(&self, step: Step) -> HomingMove {
        let c = &self.cfg;
        match step {
            Step::RaiseZ => HomingMove {
                axis: Axis::Z,
                distance_mm: c.z_raise_mm,
                feed_mm_s: c.feed_mm_s[Axis::Z.index()],
                stop_at_switch: false,
            },
            Step::Fast(k) => {
                let i = self.order[k].index();
                HomingMove {
                    axis: self.order[k],
                    distance_mm: -self.search_mm[i],
                    feed_mm_s: c.feed_mm_s[i],
                    stop_at_switch: true,
                }
            }
            Step::Bump(k) => {
                let i = self.order[k].index();
                HomingMove {
                    axis: self.order[k],
                    distance_mm: c.bump_mm[i],
                    feed_mm_s: c.feed_mm_s[i],
                    stop_at_switch: false,
                }
            }
            Step::Slow(k) => {
                let i = self.order[k].index();
                let div = if c.bump_divisor[i] >= 1.0 {
                    c.bump_divisor[i]
                } else {
                    1.0
                };
                HomingMove {
                    axis: self.order[k],
                    distance_mm: -2.0 * c.bump_mm[i],
                    feed_mm_s: c.feed_mm_s[i] / div,
                    stop_at_switch: true,
                }
            }
        }
    }

    /// The running move ended this way.
    pub fn finished(&mut self, end: MoveEnd) {
        let Phase::Running(step) = self.phase else {
            return;
        };
        self.phase = match (step, end) {
            (Step::RaiseZ, _) => Phase::Fast(0),
            (Step::Fast(k), MoveEnd::Triggered) => {
                if self.cfg.bump_mm[self.order[k].index()] > 0.0 {
                    Phase::Bump(k)
                } else {
                    Phase::Homed(k)
                }
            }
            (Step::Bump(k), MoveEnd::Completed { switch: false }) => Phase::Slow(k),
            (Step::Bump(k), _) => Phase::Failed(HomingError::SwitchStuck {
                axis: self.order[k],
            }),
            (Step::Slow(k), MoveEnd::Triggered) => Phase::Homed(k),
            (Step::Fast(k) | Step::Slow(k), MoveEnd::Completed { .. }) => {
                let mv = self.move_of(step);
                Phase::Failed(HomingError::SwitchNotHit {
                    axis: self.order[k],
                    searched_mm: -mv.distance_mm,
                })
            }
        };
    }

    /// Stop homing now (M112, kill, quick stop); [`Homing::next_step`] then reports the failure.
    pub fn abort(&mut self) {
        if !matches!(self.phase, Phase::Done) {
            self.phase = Phase::Failed(HomingError::Aborted);
        }
    }

    /// A move is running.
    pub fn is_moving(&self) -> bool {
        matches!(self.phase, Phase::Running(_))
    }

    /// The running move, if any.
    pub fn current(&self) -> Option<HomingMove> {
        match self.phase {
            Phase::Running(step) => Some(self.move_of(step)),
            _ => None,
        }
    }
}

/// Marlin's M119 report of `endstops`: `Reporting endstop status` then `x_min: open` or
/// `x_min: TRIGGERED` for X, Y and Z, one line each (written without line ends; the caller
/// sends each of the four strings as a line).
pub fn m119_lines(endstops: &mut impl Endstops) -> [&'static str; 4] {
    let mut state = |axis, open, hit| {
        if endstops.triggered(axis) {
            hit
        } else {
            open
        }
    };
    [
        "Reporting endstop status",
        state(Axis::X, "x_min: open", "x_min: TRIGGERED"),
        state(Axis::Y, "y_min: open", "y_min: TRIGGERED"),
        state(Axis::Z, "z_min: open", "z_min: TRIGGERED"),
    ]
}
