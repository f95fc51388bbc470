//! The typed command a line parses to ([`Command`]) and the value types its variants carry.

use super::{DriverCommand, RecoveryCommand, ReportCommand, SdCommand, SettingsCommand};
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

/// A heater addressed by a temperature or PID command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Heater {
    /// The hotend (M104/M109/M301).
    Hotend,
    /// The bed (M140/M190/M304).
    Bed,
}

/// M760 parameters: the pause behaviour (see [`crate::config::PauseConfig`]); `None` = keep.
/// All `None` means "report the current values".
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PauseParams {
    /// `R`: retract length, mm.
    pub retract_mm: Option<f32>,
    /// `Z`: Z lift, mm.
    pub lift_z_mm: Option<f32>,
    /// `X`: park X, mm.
    pub park_x_mm: Option<f32>,
    /// `Y`: park Y, mm.
    pub park_y_mm: Option<f32>,
    /// `F`: park travel feed, mm/min (as written; divide by 60 for mm/s).
    pub park_feed_mm_min: Option<f32>,
    /// `S`: speed-up factor for the rest of the layer after a pause request.
    pub speedup_factor: Option<f32>,
    /// `V`: maximum volumetric flow, mm³/s.
    pub max_volumetric_mm3_s: Option<f32>,
    /// `L`: planner segment length, mm.
    pub segment_len_mm: Option<f32>,
    /// `T`: seconds parked before the nozzle heater goes off (0 = never; see
    /// [`crate::thermal::IdleConfig`]).
    pub nozzle_timeout_s: Option<f32>,
}

impl PauseParams {
    /// True when no parameter is given (M760 alone: report).
    pub fn is_empty(&self) -> bool {
        *self == PauseParams::default()
    }

    /// The M760 that sets the pause values `c` (every word given; the park feed in mm/min, as
    /// written) and `nozzle_timeout_s` (`T`, kept apart: it is the heaters' setting, not
    /// saved with the pause values).
    pub fn from_config(c: &crate::config::PauseConfig, nozzle_timeout_s: Option<f32>) -> Self {
        PauseParams {
            retract_mm: Some(c.retract_mm),
            lift_z_mm: Some(c.lift_z_mm),
            park_x_mm: Some(c.park_x_mm),
            park_y_mm: Some(c.park_y_mm),
            park_feed_mm_min: Some(c.park_feed_mm_s * 60.0),
            speedup_factor: Some(c.speedup_factor),
            max_volumetric_mm3_s: Some(c.max_volumetric_mm3_s),
            segment_len_mm: Some(c.segment_len_mm),
            nozzle_timeout_s,
        }
    }
}

/// M761: when to pause.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PauseSchedule {
    /// `M761`: report the scheduled pause.
    Report,
    /// `M761 L<n>`: pause at the start of layer n (the n-th layer printed in the job, from 1, as
    /// [`crate::layer`] counts: docs/planner.md, "What a layer is").
    Layer(u32),
    /// `M761 Z<mm>`: pause at the first layer at or above this height.
    Z(f32),
    /// `M761 C`: clear the schedule.
    Clear,
}

/// M73 progress parameters (Marlin, Prusa and Orca spellings); `None` = not given.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Progress {
    /// `P`: percent done (normal mode).
    pub percent: Option<f32>,
    /// `R`: minutes remaining (normal mode).
    pub remaining_min: Option<f32>,
    /// `Q`: percent done (silent mode, Prusa).
    pub silent_percent: Option<f32>,
    /// `S`: minutes remaining (silent mode, Prusa).
    pub silent_remaining_min: Option<f32>,
    /// `C`: minutes to the next colour change (Prusa).
    pub change_min: Option<f32>,
    /// `L`: current layer (Orca, Bambu): a layer marker for [`crate::layer`].
    pub layer: Option<u32>,
}

/// M600 filament change parameters (Marlin spelling); `None` = use the default.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FilamentChange {
    /// `X`, `Y`, `Z` change position and `E` retract length, mm.
    pub axes: AxisWords,
    /// `L`: load length, mm.
    pub load_mm: Option<f32>,
    /// `U`: unload length, mm.
    pub unload_mm: Option<f32>,
    /// `B`: number of beeps.
    pub beeps: Option<u32>,
}

/// A parsed command. Codes in the doc of each variant; letter parameters as in Marlin.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `G0` (rapid = true) / `G1`: straight move; `F` is mm/min in the current units.
    Move {
        /// G0 rather than G1 (the firmware treats both alike).
        rapid: bool,
        /// Target (absolute or relative per the modal state).
        axes: AxisWords,
        /// `F`: feed rate, units/min.
        feed: Option<f32>,
    },
    /// `G2` (clockwise) / `G3`: arc in the XY plane with centre offset `I J` or radius `R`.
    Arc {
        /// G2 rather than G3.
        clockwise: bool,
        /// End point X Y, helical Z, extrusion E.
        axes: AxisWords,
        /// `I`: centre X offset from the start point.
        i: Option<f32>,
        /// `J`: centre Y offset from the start point.
        j: Option<f32>,
        /// `R`: radius (instead of I/J); negative picks the larger arc.
        r: Option<f32>,
        /// `P`: complete extra circles before the arc (Marlin's `ARC_P_CIRCLES`), 0 when not
        /// given, at most [`crate::gcode::ARC_MAX_CIRCLES`].
        circles: u8,
        /// `F`: feed rate, units/min.
        feed: Option<f32>,
    },
    /// `G4 P<ms>` / `G4 S<s>`: dwell.
    Dwell {
        /// `P`: milliseconds.
        ms: Option<f32>,
        /// `S`: seconds.
        s: Option<f32>,
    },
    /// `G10`: firmware retract.
    Retract,
    /// `G11`: firmware recover (un-retract).
    Recover,
    /// `G20`: units are inches.
    Inches,
    /// `G21`: units are millimetres.
    Millimetres,
    /// `G28 [X] [Y] [Z]`: home the named axes (none named = all); values after the letters are
    /// accepted and ignored, as Marlin does.
    Home(AxisFlags),
    /// `G90`: absolute positioning (E too, until M83).
    Absolute,
    /// `G91`: relative positioning (E too, until M82).
    Relative,
    /// `G92`: set the logical position of the given axes.
    SetPosition(AxisWords),
    /// `M0` / `M1` (optional = true): stop and wait for the user, or `P` ms / `S` s.
    Stop {
        /// M1 rather than M0.
        optional: bool,
        /// `P`: milliseconds.
        ms: Option<f32>,
        /// `S`: seconds.
        s: Option<f32>,
    },
    /// `M17 [X Y Z E]`: enable steppers.
    EnableSteppers(AxisFlags),
    /// `M18` / `M84 [X Y Z E] [S<s>]`: disable steppers (or set the idle timeout with S).
    DisableSteppers {
        /// Written as M18 rather than M84.
        m18: bool,
        /// Axes named.
        axes: AxisFlags,
        /// `S`: idle timeout, seconds.
        s: Option<f32>,
    },
    /// `M24` / `M602`: resume. Also a realtime request on the host link.
    Resume {
        /// Written as M602 rather than M24.
        m602: bool,
    },
    /// `M25` / `M601 [S1]`: pause at the layer boundary, or at once with `S1`. Also a realtime
    /// request on the host link.
    Pause {
        /// Written as M601 rather than M25.
        m601: bool,
        /// `S1`: pause now (feed hold) rather than at the layer boundary.
        now: bool,
    },
    /// `M82`: absolute extrusion.
    AbsoluteE,
    /// `M83`: relative extrusion.
    RelativeE,
    /// `M104`/`M109` (hotend) and `M140`/`M190` (bed): set a target, optionally waiting.
    SetTemperature {
        /// Which heater.
        heater: Heater,
        /// M109/M190 rather than M104/M140.
        wait: bool,
        /// `S`: target °C (M109/M190: wait only while heating).
        s: Option<f32>,
        /// `R`: target °C, wait while heating or cooling (M109/M190).
        r: Option<f32>,
        /// `T`: tool index (hotend only).
        tool: Option<u8>,
    },
    /// `M105 [T]`: report temperatures.
    ReportTemperatures,
    /// `M106 [S<0-255>] [P<fan>]`: fan on.
    FanOn {
        /// `S`: speed 0..=255 (default 255).
        speed: Option<f32>,
        /// `P`: fan index.
        fan: Option<u8>,
    },
    /// `M107 [P<fan>]`: fan off.
    FanOff {
        /// `P`: fan index.
        fan: Option<u8>,
    },
    /// `M108`: break out of a heater wait. Also a realtime request on the host link.
    BreakWait,
    /// `M110 [N<n>]`: set the current line number (handled by [`crate::link`]).
    SetLineNumber(Option<u32>),
    /// `M112`: emergency stop. Also a realtime request on the host link.
    EmergencyStop,
    /// `M114`: report the position.
    ReportPosition,
    /// `M115`: report firmware name and capabilities.
    FirmwareInfo,
    /// `M117 <text>`: show a message.
    Message(Text),
    /// `M118 <text>`: echo text to the host.
    Echo(Text),
    /// `M73`: print progress; `L` is a layer marker.
    Progress(Progress),
    /// `M204 [P] [R] [T] [S]`: accelerations, mm/s² (print, retract, travel, both).
    SetAcceleration {
        /// `P`: printing moves.
        print: Option<f32>,
        /// `R`: retract/prime moves.
        retract: Option<f32>,
        /// `T`: travel moves.
        travel: Option<f32>,
        /// `S`: printing and travel (legacy).
        s: Option<f32>,
    },
    /// `M220 [S<percent>]`: feed rate override (no S: report).
    FeedOverride(Option<f32>),
    /// `M221 [S<percent>] [T]`: flow override (no S: report).
    FlowOverride(Option<f32>),
    /// `M400`: wait until all moves are done.
    WaitMoves,
    /// `M410`: quick stop. Also a realtime request on the host link.
    QuickStop,
    /// `M524`: cancel the job. Also a realtime request on the host link.
    Cancel,
    /// `M600`: filament change.
    FilamentChange(FilamentChange),
    /// `M301` (hotend) / `M304` (bed) `[P] [I] [D]`: set PID gains (none given: report).
    SetPid {
        /// Which heater.
        heater: Heater,
        /// `P`: proportional gain.
        p: Option<f32>,
        /// `I`: integral gain (Marlin units).
        i: Option<f32>,
        /// `D`: derivative gain (Marlin units).
        d: Option<f32>,
    },
    /// `M303 [E<-1|0>] [S<°C>] [C<cycles>] [U<0|1>]`: PID autotune (E-1 = bed).
    Autotune {
        /// `E`: heater index, -1 = bed, 0 = hotend.
        heater_index: Option<i32>,
        /// `S`: target temperature °C.
        target_c: Option<f32>,
        /// `C`: number of cycles.
        cycles: Option<u32>,
        /// `U1`: use the result.
        use_result: bool,
    },
    /// `M760`: set (or with no parameter report) the pause parameters. Firmware-specific.
    PauseParams(PauseParams),
    /// `M761`: schedule a pause at a layer or height, clear, or report. Firmware-specific.
    SchedulePause(PauseSchedule),
    // --- machine safety and homing (helper `safety`) ---
    /// `M302 [S<°C>] [P<0|1>]`: cold-extrusion protection as in Marlin: `S` sets the lowest
    /// hotend temperature at which E may move, `P1` allows cold extrusion, `P0` forbids it
    /// again; with neither, report.
    ColdExtrusion {
        /// `S`: minimum extrusion temperature, °C.
        min_temp_c: Option<f32>,
        /// `P`: allow cold extrusion (`P1`) or not (`P0`).
        allow: Option<bool>,
    },
    /// `M119`: report the endstop states.
    ReportEndstops,
    // --- end of the `safety` block ---
    /// `T<n>`: select a tool.
    Tool(u8),
    /// Klipper's `SET_PRINT_STATS_INFO [CURRENT_LAYER=<n>] [TOTAL_LAYER=<n>]`; CURRENT_LAYER is a
    /// layer marker for [`crate::layer`].
    PrintStatsInfo {
        /// `CURRENT_LAYER=`.
        current_layer: Option<u32>,
        /// `TOTAL_LAYER=`.
        total_layer: Option<u32>,
    },
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
