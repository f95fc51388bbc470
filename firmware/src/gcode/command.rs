//! The typed command a line parses to ([`Command`]) and the value types its variants carry.

use super::{
    DriverCommand, HeatCommand, MotionCommand, PauseCommand, RecoveryCommand, ReportCommand,
    SdCommand, SettingsCommand,
};
use crate::motion::{Axis, AXES};

/// Capacity in bytes of the text of M117/M118 and of an [`Command::Unknown`] command's text.
/// Longer text is a [`ParseError`](super::ParseError) (never truncated). 96 bytes fit every LCD message and the
/// longest line the host link accepts ([`crate::link::LINE_CAP`]) minus the command word.
pub const TEXT_CAP: usize = 96;

/// Fixed-capacity text of a command ([`TEXT_CAP`] bytes).
pub type Text = heapless::String<TEXT_CAP>;

/// Axis words of a command (X, Y, Z, E), indexed by [`Axis::index`]; `None` = not given.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AxisWords(pub [Option<f32>; AXES]);

impl AxisWords {
    /// The word of one axis.
    pub fn get(&self, axis: Axis) -> Option<f32> {
        self.0[axis.index()]
    }

    /// True when no axis word is given.
    pub fn is_empty(&self) -> bool {
        self.0.iter().all(Option::is_none)
    }
}

/// Axis flags of a command (`G28 X Y`, `M84 E`), indexed by [`Axis::index`]; all false = none
/// given (the command then means every axis).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AxisFlags(pub [bool; AXES]);

impl AxisFlags {
    /// True when no flag is given.
    pub fn is_empty(&self) -> bool {
        !self.0.iter().any(|f| *f)
    }

    /// True if the axis is named, or no axis is named at all (which means "all").
    pub fn includes(&self, axis: Axis) -> bool {
        self.is_empty() || self.0[axis.index()]
    }
}

/// A parsed command. Codes in the doc of each variant; letter parameters as in Marlin.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Motion: moves, arcs, dwell, homing, positioning and units, overrides, M400 (see
    /// [`MotionCommand`]).
    Motion(MotionCommand),
    /// Heat: targets and waits, the temperature report, fan, PID, autotune, M302 (see
    /// [`HeatCommand`]).
    Heat(HeatCommand),
    /// Pause: pause, resume, stop, cancel, emergency and quick stop, M108, M600, M760, M761
    /// (see [`PauseCommand`]).
    Pause(PauseCommand),
    /// `T<n>`: select a tool.
    Tool(u8),
    /// Settings: M92, M201, M203, M205, M206, M851, M906 and M500–M503 (see [`SettingsCommand`]).
    Settings(SettingsCommand),
    /// Reports: M155, M113, M31 and M27 (see [`ReportCommand`]).
    Report(ReportCommand),
    /// Stepper drivers: M569, M350 and M122 (see [`DriverCommand`]).
    Driver(DriverCommand),
    /// SD card: M20, M21, M22, M23, M26, M27 S/C and M32 (see [`SdCommand`]).
    Sd(SdCommand),
    /// Power-cut resume: M1000, M1000 C (see [`RecoveryCommand`]).
    Recovery(RecoveryCommand),
    /// Any other G/M code or extended command: its text (comment stripped), for
    /// `echo:Unknown command: "<text>"`.
    Unknown(Text),
}
