//! G-code: a streaming, allocation-free parser of one line into a typed [`Command`], and the
//! symmetrical emitter ([`Command`] implements [`core::fmt::Display`]).
//!
//! One line in, one [`Line`] out: the command (if any) and the comment text (if any), which
//! [`crate::layer`] reads for slicer layer markers. Line numbers (`N…`) and checksums (`*…`) are
//! the host link's business ([`crate::link`]) and are stripped before a line reaches this parser.
//!
//! Grammar (case-insensitive letters, spaces between words optional):
//! - a command word: `G`, `M` or `T` with a whole number (`G1`, `G01`, `M104`, `T0`; a subcode
//!   such as `M862.3` makes an [`Command::Unknown`]), or a Klipper-style extended command name
//!   (`SET_PRINT_STATS_INFO CURRENT_LAYER=3`; any other name is [`Command::Unknown`]);
//! - parameter words: a letter and a decimal number (`X-1.5`, `E.03321`, `F7800`), no exponent
//!   (`X1E5` is X=1, E=5), magnitude at most [`MAX_ABS_VALUE`] and, unless zero, at least
//!   [`MIN_ABS_VALUE`]; some letters are flags that may stand alone (`G28 X Y`);
//! - comments: `;` to the end of the line, and `( … )` anywhere between words;
//! - text commands (M117, M118): the rest of the line up to `;`, cut to [`TEXT_CAP`] bytes.
//!
//! Every G/M code without a meaning here parses to [`Command::Unknown`] (the executive answers
//! `echo:Unknown command`, like Marlin). Syntax errors — a letter without a number where one is
//! required, a letter the command does not take, the same letter twice, `nan`, `inf`, numbers
//! out of range, bytes that are not G-code — are a [`ParseError`] with a static message.
//!
//! ```
//! use firmware::gcode::{parse_line, Command};
//! let line = parse_line(b"G1 X10.5 Y-3 E.25 F1800 ; perimeter").unwrap();
//! let Some(Command::Move { rapid: false, axes, feed }) = line.command else { panic!() };
//! assert_eq!(axes.0, [Some(10.5), Some(-3.0), None, Some(0.25)]);
//! assert_eq!(feed, Some(1800.0));
//! assert_eq!(line.comment, Some(&b" perimeter"[..]));
//! // The emitter writes what the parser reads.
//! assert_eq!(
//!     format!("{}", line.command.unwrap()),
//!     "G1 X10.5 Y-3 E0.25 F1800"
//! );
//! assert!(parse_line(b"G1 Xnan").is_err());
//! ```

mod emit;
mod number;
// Settings M-codes (M92 M201 M203 M205 M206 M851 M906 M500-M503): parse and emit.
mod settings;
pub use settings::{Advanced, SettingsCommand};
// Report M-codes hosts expect (M155 M113 M31 M27): parse and emit.
mod report;
pub use report::{ReportCommand, MAX_REPORT_PERIOD_S};
// Stepper-driver M-codes (M122 M350 M569; M906 is a settings command): parse and emit.
mod driver;
pub use driver::DriverCommand;
// SD-card M-codes (M20 M21 M22 M23 M26 M27 S/C M32): parse and emit.
mod sd;
pub use sd::{SdCommand, MAX_SD_REPORT_S};
// Power-cut resume (M1000, M1000 C): parse and emit.
mod recovery;
pub use recovery::RecoveryCommand;

use crate::motion::{Axis, AXES};
use core::fmt;

pub use emit::write_command;
use number::Num;
pub use number::{MAX_ABS_VALUE, MAX_NUMBER_LEN, MAX_SIG_DIGITS, MIN_ABS_VALUE};

/// Capacity in bytes of the text of M117/M118 and of an [`Command::Unknown`] command's text.
/// Longer text is a [`ParseError`] (never truncated). 96 bytes fit every LCD message and the
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
}

impl PauseParams {
    /// True when no parameter is given (M760 alone: report).
    pub fn is_empty(&self) -> bool {
        *self == PauseParams::default()
    }
}

/// M761: when to pause.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PauseSchedule {
    /// `M761`: report the scheduled pause.
    Report,
    /// `M761 L<n>`: pause at the start of layer n (as counted by [`crate::layer`], 0-based).
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

/// One parsed line: a command and/or a comment.
#[derive(Clone, Debug, PartialEq)]
pub struct Line<'a> {
    /// The command, or `None` for an empty or comment-only line.
    pub command: Option<Command>,
    /// The text after `;` (without the `;`, trailing whitespace removed), or else the text of
    /// the first `( … )` comment. Raw bytes: slicers write comments in any encoding.
    pub comment: Option<&'a [u8]>,
}

/// What went wrong in a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParseErrorKind {
    /// A letter that needs a number has none (`G1 X`, `G1 Xnan`, `G1 Xinf`).
    MissingNumber,
    /// A number with more than [`MAX_SIG_DIGITS`] significant digits.
    TooManyDigits,
    /// A number longer than [`MAX_NUMBER_LEN`] characters.
    NumberTooLong,
    /// A number beyond ±[`MAX_ABS_VALUE`], a non-zero number smaller than [`MIN_ABS_VALUE`], or
    /// beyond its parameter's range.
    OutOfRange,
    /// A number where only a whole number makes sense has a fraction.
    NotWhole,
    /// A negative number where only non-negative ones make sense.
    Negative,
    /// Malformed number text.
    BadNumber,
    /// A parameter letter the command does not take.
    UnexpectedLetter,
    /// The same parameter letter twice.
    DuplicateLetter,
    /// A byte that is not part of G-code (control characters, punctuation, non-ASCII outside
    /// comments and text).
    BadByte,
    /// The line does not start with a G, M or T command.
    NoCommand,
    /// A command code beyond 65535 or a malformed subcode.
    BadCode,
    /// A `(` comment without `)`.
    UnclosedComment,
    /// Text longer than [`TEXT_CAP`] (no longer produced: display text is cut instead).
    TextTooLong,
    /// Text that is not valid UTF-8 or has control characters.
    BadText,
    /// A parameter value is not valid for this command (e.g. `M761` with two schedules).
    BadValue,
    /// An extended command parameter that is not `KEY=value`.
    BadExtendedParam,
}

impl ParseErrorKind {
    /// A short, static, human-readable description.
    pub const fn message(self) -> &'static str {
        match self {
            Self::MissingNumber => "letter without a number",
            Self::TooManyDigits => "number has too many digits",
            Self::NumberTooLong => "number is too long",
            Self::OutOfRange => "number out of range",
            Self::NotWhole => "expected a whole number",
            Self::Negative => "expected a non-negative number",
            Self::BadNumber => "malformed number",
            Self::UnexpectedLetter => "parameter not accepted by this command",
            Self::DuplicateLetter => "parameter given twice",
            Self::BadByte => "unexpected character",
            Self::NoCommand => "line does not start with a G, M or T command",
            Self::BadCode => "malformed command code",
            Self::UnclosedComment => "unclosed ( comment",
            Self::TextTooLong => "text too long",
            Self::BadText => "text has invalid characters",
            Self::BadValue => "invalid parameter value",
            Self::BadExtendedParam => "malformed KEY=value parameter",
        }
    }
}

/// A syntax error in a line: what and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// What went wrong.
    pub kind: ParseErrorKind,
    /// Byte offset in the line where it was found.
    pub at: usize,
}

impl ParseError {
    /// The static message of the error kind.
    pub const fn message(&self) -> &'static str {
        self.kind.message()
    }
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (column {})", self.kind.message(), self.at + 1)
    }
}

/// Most distinct parameter letters one line may carry (known commands take at most 8; more is
/// an [`ParseErrorKind::UnexpectedLetter`], or text for an unknown command).
const MAX_WORDS: usize = 16;

/// A parameter word: letter index 0..26 and its number, if any.
#[derive(Clone, Copy, Debug, Default)]
struct Word {
    num: Option<Num>,
    letter: u8,
    at: u16,
}

/// The parameter words of one command.
struct Words<'a> {
    line: &'a [u8],
    mask: u32,
    /// Index into `words` of each letter present (valid where `mask` has the bit).
    slot: [u8; 26],
    /// Filled lazily (no per-line initialisation of every slot).
    words: heapless::Vec<Word, MAX_WORDS>,
    /// Position of the first repeated letter, reported by `check` after the per-word errors.
    dup: Option<usize>,
}

impl<'a> Words<'a> {
    fn new(line: &'a [u8]) -> Self {
        Words {
            line,
            mask: 0,
            slot: [0; 26],
            words: heapless::Vec::new(),
            dup: None,
        }
    }
}

/// Bit of a letter in a letter mask.
const fn bit(c: u8) -> u32 {
    1 << (c - b'A')
}

/// Letter mask of a set of upper-case letters.
const fn mask(s: &[u8]) -> u32 {
    let mut m = 0;
    let mut i = 0;
    while i < s.len() {
        m |= bit(s[i]);
        i += 1;
    }
    m
}

impl<'a> Words<'a> {
    fn find(&self, c: u8) -> Option<&Word> {
        if self.mask & bit(c) == 0 {
            return None;
        }
        let i = self.slot.get(usize::from(c - b'A'))?;
        self.words.get(usize::from(*i))
    }

    /// Check the letters: only `allowed`; letters outside `flags` need a number.
    fn check(&self, allowed: &[u8], flags: &[u8]) -> Result<(), ParseError> {
        let allowed_m = mask(allowed);
        let flags_m = mask(flags);
        for w in self.words.iter() {
            let b = 1u32 << w.letter;
            if allowed_m & b == 0 {
                return Err(err(ParseErrorKind::UnexpectedLetter, usize::from(w.at)));
            }
            if w.num.is_none() && flags_m & b == 0 {
                return Err(err(ParseErrorKind::MissingNumber, usize::from(w.at) + 1));
            }
        }
        match self.dup {
            Some(at) => Err(err(ParseErrorKind::DuplicateLetter, at)),
            None => Ok(()),
        }
    }

    fn f32(&self, c: u8) -> Result<Option<f32>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => n
                .to_f32(self.line)
                .map(Some)
                .map_err(|k| err(k, usize::from(*at) + 1)),
            _ => Ok(None),
        }
    }

    fn u32(&self, c: u8) -> Result<Option<u32>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => n
                .to_u32()
                .map(Some)
                .map_err(|k| err(k, usize::from(*at) + 1)),
            _ => Ok(None),
        }
    }

    fn u8(&self, c: u8) -> Result<Option<u8>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => n
                .to_u8()
                .map(Some)
                .map_err(|k| err(k, usize::from(*at) + 1)),
            _ => Ok(None),
        }
    }

    fn i32(&self, c: u8) -> Result<Option<i32>, ParseError> {
        match self.find(c) {
            Some(Word {
                num: Some(n), at, ..
            }) => {
                let at = usize::from(*at) + 1;
                let v = n.to_i64().map_err(|k| err(k, at))?;
                i32::try_from(v)
                    .map(Some)
                    .map_err(|_| err(ParseErrorKind::OutOfRange, at))
            }
            _ => Ok(None),
        }
    }

    fn has(&self, c: u8) -> bool {
        self.mask & bit(c) != 0
    }

    fn axes(&self) -> Result<AxisWords, ParseError> {
        Ok(AxisWords([
            self.f32(b'X')?,
            self.f32(b'Y')?,
            self.f32(b'Z')?,
            self.f32(b'E')?,
        ]))
    }

    fn flags(&self) -> AxisFlags {
        AxisFlags([
            self.has(b'X'),
            self.has(b'Y'),
            self.has(b'Z'),
            self.has(b'E'),
        ])
    }

    /// A flag that must be 0/1 when it has a number (`S1`, `U1`); absent = false.
    fn bool01(&self, c: u8) -> Result<bool, ParseError> {
        match self.find(c) {
            None => Ok(false),
            Some(Word { num: None, .. }) => Ok(true),
            Some(Word {
                num: Some(n), at, ..
            }) => match n.to_u32() {
                Ok(0) => Ok(false),
                Ok(1) => Ok(true),
                _ => Err(err(ParseErrorKind::BadValue, usize::from(*at) + 1)),
            },
        }
    }
}

const fn err(kind: ParseErrorKind, at: usize) -> ParseError {
    ParseError { kind, at }
}

fn is_space(c: u8) -> bool {
    c == b' ' || c == b'\t'
}

/// Remove trailing spaces, tabs, CR and LF.
fn trim_end(s: &[u8]) -> &[u8] {
    let mut end = s.len();
    while end > 0 && matches!(s.get(end - 1), Some(b' ' | b'\t' | b'\r' | b'\n')) {
        end -= 1;
    }
    s.get(..end).unwrap_or(s)
}

/// Split off the `;` comment: (code part, comment text).
fn split_comment(line: &[u8]) -> (&[u8], Option<&[u8]>) {
    match line.iter().position(|&c| c == b';') {
        Some(p) => (
            line.get(..p).unwrap_or(line),
            Some(trim_end(line.get(p + 1..).unwrap_or(&[]))),
        ),
        None => (line, None),
    }
}

/// Parse one line (without line number and checksum; a trailing CR/LF is ignored).
///
/// Returns the command (if any) and the comment text. Never panics, never allocates.
pub fn parse_line(line: &[u8]) -> Result<Line<'_>, ParseError> {
    // One pass: the `;` comment is found where the words end (text commands and unknown
    // commands look for it themselves).
    let mut i = 0;
    while line.get(i).copied().is_some_and(is_space) {
        i += 1;
    }
    let mut paren_comment: Option<&[u8]> = None;
    // Leading ( comments.
    while line.get(i) == Some(&b'(') {
        let (c, next) = paren(line, i)?;
        paren_comment = paren_comment.or(Some(c));
        i = next;
        while line.get(i).copied().is_some_and(is_space) {
            i += 1;
        }
    }
    let first = match line.get(i) {
        None | Some(b'\r' | b'\n') => {
            return Ok(Line {
                command: None,
                comment: paren_comment,
            })
        }
        Some(b';') => {
            return Ok(Line {
                command: None,
                comment: Some(trim_end(line.get(i + 1..).unwrap_or(&[]))),
            })
        }
        Some(&c) => c,
    };
    let second = line.get(i + 1).copied().filter(|c| *c != b';');
    let upper = first.to_ascii_uppercase();
    let gmt = matches!(upper, b'G' | b'M' | b'T');
    let (command, semi) = if gmt && second.is_none_or(|c| c.is_ascii_digit() || is_space(c)) {
        parse_classic(line, i, &mut paren_comment)?
    } else if (first.is_ascii_alphabetic() || first == b'_')
        && second.is_some_and(|c| c.is_ascii_alphabetic() || c == b'_')
    {
        let (code, semi) = split_comment(line);
        (parse_extended(code, i)?, semi)
    } else {
        return Err(err(ParseErrorKind::NoCommand, i));
    };
    Ok(Line {
        command: Some(command),
        comment: semi.or(paren_comment),
    })
}

/// A `( … )` comment starting at `i`: (content, position after `)`). A `;` before the `)`
/// leaves it unclosed.
fn paren(code: &[u8], i: usize) -> Result<(&[u8], usize), ParseError> {
    let rest = code.get(i + 1..).unwrap_or(&[]);
    match rest.iter().position(|&c| c == b')' || c == b';') {
        Some(p) if rest.get(p) == Some(&b')') => Ok((rest.get(..p).unwrap_or(&[]), i + 2 + p)),
        _ => Err(err(ParseErrorKind::UnclosedComment, i)),
    }
}

/// Parse `G`/`M`/`T` + code and its words.
/// Returns the command and the `;` comment text.
fn parse_classic<'a>(
    line: &'a [u8],
    start: usize,
    paren_comment: &mut Option<&'a [u8]>,
) -> Result<(Command, Option<&'a [u8]>), ParseError> {
    let code = line;
    let letter = code.get(start).map_or(b'G', u8::to_ascii_uppercase);
    // The code number: digits, optional `.digits` subcode.
    let mut i = start + 1;
    let mut num: u32 = 0;
    let mut nd = 0;
    while let Some(&c) = code.get(i) {
        if !c.is_ascii_digit() {
            break;
        }
        num = num * 10 + u32::from(c - b'0');
        nd += 1;
        if num > u32::from(u16::MAX) || nd > 6 {
            return Err(err(ParseErrorKind::BadCode, start));
        }
        i += 1;
    }
    if nd == 0 {
        return Err(err(ParseErrorKind::MissingNumber, start + 1));
    }
    let mut sub = false;
    if code.get(i) == Some(&b'.') {
        i += 1;
        let s = i;
        while code.get(i).is_some_and(u8::is_ascii_digit) {
            i += 1;
        }
        if i == s || i - s > 3 {
            return Err(err(ParseErrorKind::BadCode, start));
        }
        sub = true;
    }
    // After the code: end, space, a `(`, or (for parameter words) a letter.
    let code_end = i;
    let cmd_code = (letter, num as u16);
    if !sub {
        if let (b'M', n) = cmd_code {
            if sd::is_name_code(n) {
                let (code, semi) = split_comment(line);
                let text = parse_text(code, code_end)?;
                return Ok((Command::Sd(sd::build_name(n, text, code_end)?), semi));
            }
        }
        if let (b'M', 117 | 118) = cmd_code {
            let (code, semi) = split_comment(line);
            let text = parse_text(code, code_end)?;
            let c = if num == 117 {
                Command::Message(text)
            } else {
                Command::Echo(text)
            };
            return Ok((c, semi));
        }
    }
    if sub {
        // Subcodes (`M862.3`) are never known; their arguments are free text.
        let (code, semi) = split_comment(line);
        return Ok((unknown(code, start)?, semi));
    }
    let mut words = Words::new(line);
    let semi_at = match scan_words(line, code_end, paren_comment, &mut words) {
        Ok(at) => at,
        Err(e) => {
            // Unknown commands are never executed: their arguments are kept as text.
            let (code, semi) = split_comment(line);
            return match build_known(cmd_code, &Words::new(line)) {
                None => Ok((unknown(code, start)?, semi)),
                Some(_) => Err(e),
            };
        }
    };
    let semi = semi_at.map(|p| trim_end(line.get(p + 1..).unwrap_or(&[])));
    let c = match build_known(cmd_code, &words) {
        Some(r) => r?,
        None => {
            let code = line.get(..semi_at.unwrap_or(line.len())).unwrap_or(line);
            unknown(code, start)?
        }
    };
    Ok((c, semi))
}

/// The text argument of M117/M118: after the code and one run of spaces, to the end (the `;`
/// comment is already split off), trailing whitespace removed.
fn parse_text(code: &[u8], mut i: usize) -> Result<Text, ParseError> {
    match code.get(i) {
        None => return Ok(Text::new()),
        Some(&c) if is_space(c) => {}
        Some(_) => return Err(err(ParseErrorKind::BadByte, i)),
    }
    while code.get(i).copied().is_some_and(is_space) {
        i += 1;
    }
    let raw = trim_end(code.get(i..).unwrap_or(&[]));
    to_text(raw, i)
}

/// Text that is only displayed or echoed: cut to [`TEXT_CAP`] bytes (at a character boundary)
/// rather than refused, so a long `M117` or `EXCLUDE_OBJECT_DEFINE` line never stops a job.
fn to_text(raw: &[u8], at: usize) -> Result<Text, ParseError> {
    let cut = raw.len() > TEXT_CAP;
    // Cut, then trim again: a cut inside a run of blanks must not leave them at the end (the
    // text would not read back the same from the emitter; found by fuzzing).
    let head = trim_end(raw.get(..TEXT_CAP).unwrap_or(raw));
    let s = match core::str::from_utf8(head) {
        Ok(s) => s,
        // A character cut in two at the cap: drop its first bytes.
        Err(e) if cut && e.error_len().is_none() => {
            core::str::from_utf8(trim_end(head.get(..e.valid_up_to()).unwrap_or(&[])))
                .map_err(|_| err(ParseErrorKind::BadText, at))?
        }
        Err(e) => return Err(err(ParseErrorKind::BadText, at + e.valid_up_to())),
    };
    if let Some(p) = s.chars().position(char::is_control) {
        return Err(err(ParseErrorKind::BadText, at + p));
    }
    let mut t = Text::new();
    t.push_str(s)
        .map_err(|_| err(ParseErrorKind::TextTooLong, at + TEXT_CAP))?;
    Ok(t)
}

/// The command text for [`Command::Unknown`]: from the command word to the end, trimmed.
fn unknown(code: &[u8], start: usize) -> Result<Command, ParseError> {
    let raw = trim_end(code.get(start..).unwrap_or(&[]));
    Ok(Command::Unknown(to_text(raw, start)?))
}

/// Scan parameter words from `i` to the end of `code`.
fn scan_words<'a>(
    code: &'a [u8],
    mut i: usize,
    paren_comment: &mut Option<&'a [u8]>,
    w: &mut Words<'a>,
) -> Result<Option<usize>, ParseError> {
    while let Some(&c) = code.get(i) {
        if c == b';' {
            return Ok(Some(i));
        }
        if is_space(c) || c == b'\r' || c == b'\n' {
            i += 1;
            continue;
        }
        if c == b'(' {
            let (text, next) = paren(code, i)?;
            *paren_comment = paren_comment.or(Some(text));
            i = next;
            continue;
        }
        if !c.is_ascii_alphabetic() {
            return Err(err(ParseErrorKind::BadByte, i));
        }
        let up = c.to_ascii_uppercase();
        let b = bit(up);
        let dup = w.mask & b != 0;
        if dup {
            w.dup = w.dup.or(Some(i));
        }
        let num = number::lex(code, i + 1).map_err(|k| err(k, i + 1))?;
        let (num, next) = match num {
            Some((n, next)) => (Some(n), next),
            None => (None, i + 1),
        };
        // A number must be followed by a separator or the next letter.
        if let Some(&after) = code.get(next) {
            if !(after.is_ascii_alphabetic()
                || is_space(after)
                || after == b'('
                || after == b';'
                || after == b'\r'
                || after == b'\n')
            {
                return Err(err(ParseErrorKind::BadByte, next));
            }
        }
        if !dup {
            let idx = w.words.len() as u8;
            w.words
                .push(Word {
                    letter: up - b'A',
                    num,
                    at: i.min(usize::from(u16::MAX)) as u16,
                })
                .map_err(|_| err(ParseErrorKind::UnexpectedLetter, i))?;
            if let Some(s) = w.slot.get_mut(usize::from(up - b'A')) {
                *s = idx;
            }
        }
        w.mask |= b;
        i = next;
    }
    Ok(None)
}

/// Build a known command from its code and words; `None` = unknown code.
fn build_known(code: (u8, u16), w: &Words<'_>) -> Option<Result<Command, ParseError>> {
    let r = (|| -> Result<Option<Command>, ParseError> {
        let none = || -> Result<(), ParseError> { w.check(b"", b"") };
        let c = match code {
            (b'G', n @ (0 | 1)) => {
                w.check(b"XYZEF", b"")?;
                Command::Move {
                    rapid: n == 0,
                    axes: w.axes()?,
                    feed: w.f32(b'F')?,
                }
            }
            (b'G', n @ (2 | 3)) => {
                w.check(b"XYZEFIJR", b"")?;
                Command::Arc {
                    clockwise: n == 2,
                    axes: w.axes()?,
                    i: w.f32(b'I')?,
                    j: w.f32(b'J')?,
                    r: w.f32(b'R')?,
                    feed: w.f32(b'F')?,
                }
            }
            (b'G', 4) => {
                w.check(b"PS", b"")?;
                Command::Dwell {
                    ms: w.f32(b'P')?,
                    s: w.f32(b'S')?,
                }
            }
            (b'G', 10) => {
                none()?;
                Command::Retract
            }
            (b'G', 11) => {
                none()?;
                Command::Recover
            }
            (b'G', 20) => {
                none()?;
                Command::Inches
            }
            (b'G', 21) => {
                none()?;
                Command::Millimetres
            }
            (b'G', 28) => {
                w.check(b"XYZ", b"XYZ")?;
                // Values are accepted (Marlin ignores them) but must be numbers.
                w.axes()?;
                Command::Home(w.flags())
            }
            (b'G', 90) => {
                none()?;
                Command::Absolute
            }
            (b'G', 91) => {
                none()?;
                Command::Relative
            }
            (b'G', 92) => {
                w.check(b"XYZE", b"")?;
                Command::SetPosition(w.axes()?)
            }
            (b'M', n @ (0 | 1)) => {
                w.check(b"PS", b"")?;
                Command::Stop {
                    optional: n == 1,
                    ms: w.f32(b'P')?,
                    s: w.f32(b'S')?,
                }
            }
            (b'M', 17) => {
                w.check(b"XYZE", b"XYZE")?;
                Command::EnableSteppers(w.flags())
            }
            (b'M', n @ (18 | 84)) => {
                w.check(b"XYZES", b"XYZE")?;
                Command::DisableSteppers {
                    m18: n == 18,
                    axes: w.flags(),
                    s: w.f32(b'S')?,
                }
            }
            (b'M', n @ (24 | 602)) => {
                none()?;
                Command::Resume { m602: n == 602 }
            }
            (b'M', n @ (25 | 601)) => {
                w.check(b"S", b"")?;
                Command::Pause {
                    m601: n == 601,
                    now: w.bool01(b'S')?,
                }
            }
            (b'M', 82) => {
                none()?;
                Command::AbsoluteE
            }
            (b'M', 83) => {
                none()?;
                Command::RelativeE
            }
            (b'M', n @ (104 | 109 | 140 | 190)) => {
                let hotend = matches!(n, 104 | 109);
                let wait = matches!(n, 109 | 190);
                match (hotend, wait) {
                    (true, true) => w.check(b"SRT", b"")?,
                    (true, false) => w.check(b"ST", b"")?,
                    (false, true) => w.check(b"SR", b"")?,
                    (false, false) => w.check(b"S", b"")?,
                }
                Command::SetTemperature {
                    heater: if hotend { Heater::Hotend } else { Heater::Bed },
                    wait,
                    s: w.f32(b'S')?,
                    r: w.f32(b'R')?,
                    tool: w.u8(b'T')?,
                }
            }
            (b'M', 105) => {
                // Marlin takes T and R; both are ignored (one hotend, one bed).
                w.check(b"TR", b"TR")?;
                Command::ReportTemperatures
            }
            (b'M', 106) => {
                w.check(b"SP", b"")?;
                let speed = w.f32(b'S')?;
                if speed.is_some_and(|s| !(0.0..=255.0).contains(&s)) {
                    return Err(err(ParseErrorKind::OutOfRange, 0));
                }
                Command::FanOn {
                    speed,
                    fan: w.u8(b'P')?,
                }
            }
            (b'M', 107) => {
                w.check(b"P", b"")?;
                Command::FanOff { fan: w.u8(b'P')? }
            }
            (b'M', 108) => {
                none()?;
                Command::BreakWait
            }
            (b'M', 110) => {
                w.check(b"N", b"")?;
                // printcore opens a session with `N-1 M110` / `M110 N-1` (Marlin accepts it):
                // -1 is "before line 0", kept as u32::MAX so the next expected line wraps to 0.
                let n = match w.u32(b'N') {
                    Ok(n) => n,
                    Err(e) if w.i32(b'N') == Ok(Some(-1)) => {
                        let _ = e;
                        Some(u32::MAX)
                    }
                    Err(e) => return Err(e),
                };
                Command::SetLineNumber(n)
            }
            (b'M', 112) => {
                none()?;
                Command::EmergencyStop
            }
            (b'M', 114) => {
                // Marlin's D (detail), E (stepper E), R (real) are accepted and ignored.
                w.check(b"DER", b"DER")?;
                Command::ReportPosition
            }
            (b'M', 115) => {
                none()?;
                Command::FirmwareInfo
            }
            (b'M', 73) => {
                w.check(b"PRQSCL", b"")?;
                Command::Progress(Progress {
                    percent: w.f32(b'P')?,
                    remaining_min: w.f32(b'R')?,
                    silent_percent: w.f32(b'Q')?,
                    silent_remaining_min: w.f32(b'S')?,
                    change_min: w.f32(b'C')?,
                    layer: w.u32(b'L')?,
                })
            }
            (b'M', 204) => {
                w.check(b"PRTS", b"")?;
                Command::SetAcceleration {
                    print: w.f32(b'P')?,
                    retract: w.f32(b'R')?,
                    travel: w.f32(b'T')?,
                    s: w.f32(b'S')?,
                }
            }
            (b'M', 220) => {
                w.check(b"S", b"")?;
                Command::FeedOverride(w.f32(b'S')?)
            }
            (b'M', 221) => {
                w.check(b"S", b"")?;
                Command::FlowOverride(w.f32(b'S')?)
            }
            (b'M', 400) => {
                none()?;
                Command::WaitMoves
            }
            (b'M', 410) => {
                none()?;
                Command::QuickStop
            }
            (b'M', 524) => {
                none()?;
                Command::Cancel
            }
            (b'M', 600) => {
                w.check(b"XYZELUB", b"")?;
                Command::FilamentChange(FilamentChange {
                    axes: w.axes()?,
                    load_mm: w.f32(b'L')?,
                    unload_mm: w.f32(b'U')?,
                    beeps: w.u32(b'B')?,
                })
            }
            (b'M', n @ (301 | 304)) => {
                w.check(b"PID", b"")?;
                Command::SetPid {
                    heater: if n == 301 {
                        Heater::Hotend
                    } else {
                        Heater::Bed
                    },
                    p: w.f32(b'P')?,
                    i: w.f32(b'I')?,
                    d: w.f32(b'D')?,
                }
            }
            (b'M', 303) => {
                w.check(b"ESCU", b"")?;
                Command::Autotune {
                    heater_index: w.i32(b'E')?,
                    target_c: w.f32(b'S')?,
                    cycles: w.u32(b'C')?,
                    use_result: w.bool01(b'U')?,
                }
            }
            (b'M', 760) => {
                w.check(b"RZXYFSVL", b"")?;
                Command::PauseParams(PauseParams {
                    retract_mm: w.f32(b'R')?,
                    lift_z_mm: w.f32(b'Z')?,
                    park_x_mm: w.f32(b'X')?,
                    park_y_mm: w.f32(b'Y')?,
                    park_feed_mm_min: w.f32(b'F')?,
                    speedup_factor: w.f32(b'S')?,
                    max_volumetric_mm3_s: w.f32(b'V')?,
                    segment_len_mm: w.f32(b'L')?,
                })
            }
            (b'M', 761) => {
                w.check(b"LZC", b"C")?;
                if w.words.len() > 1 {
                    return Err(err(ParseErrorKind::BadValue, 0));
                }
                let s = if w.has(b'C') {
                    if w.find(b'C').is_some_and(|c| c.num.is_some()) {
                        return Err(err(ParseErrorKind::BadValue, 0));
                    }
                    PauseSchedule::Clear
                } else if let Some(l) = w.u32(b'L')? {
                    PauseSchedule::Layer(l)
                } else if let Some(z) = w.f32(b'Z')? {
                    PauseSchedule::Z(z)
                } else {
                    PauseSchedule::Report
                };
                Command::SchedulePause(s)
            }
            (b'M', 302) => {
                w.check(b"SP", b"")?;
                let allow = match w.find(b'P') {
                    None => None,
                    Some(_) => Some(w.bool01(b'P')?),
                };
                Command::ColdExtrusion {
                    min_temp_c: w.f32(b'S')?,
                    allow,
                }
            }
            (b'M', 119) => {
                none()?;
                Command::ReportEndstops
            }
            (b'M', n) if settings::is_settings_code(n) => Command::Settings(settings::build(n, w)?),
            (b'M', n) if sd::is_sd_code(n, w) => Command::Sd(sd::build(n, w)?),
            (b'M', n) if report::is_report_code(n) => Command::Report(report::build(n, w)?),
            (b'M', n) if driver::is_driver_code(n) => Command::Driver(driver::build(n, w)?),
            (b'M', n) if recovery::is_recovery_code(n) => Command::Recovery(recovery::build(w)?),
            (b'T', n) => {
                none()?;
                match u8::try_from(n) {
                    Ok(t) => Command::Tool(t),
                    Err(_) => return Err(err(ParseErrorKind::OutOfRange, 0)),
                }
            }
            _ => return Ok(None),
        };
        Ok(Some(c))
    })();
    match r {
        Ok(Some(c)) => Some(Ok(c)),
        Ok(None) => None,
        Err(e) => Some(Err(e)),
    }
}

/// Klipper-style extended command: `NAME [KEY=value ...]`.
fn parse_extended(code: &[u8], start: usize) -> Result<Command, ParseError> {
    let mut i = start;
    while code
        .get(i)
        .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
    {
        i += 1;
    }
    let name = code.get(start..i).unwrap_or(&[]);
    match code.get(i) {
        None => {}
        Some(&c) if is_space(c) => {}
        Some(_) => return Err(err(ParseErrorKind::BadByte, i)),
    }
    if !name.eq_ignore_ascii_case(b"SET_PRINT_STATS_INFO") {
        // Arguments of unknown extended commands are free text (Klipper passes them on).
        return unknown(code, start);
    }
    let mut current_layer = None;
    let mut total_layer = None;
    loop {
        while code.get(i).copied().is_some_and(is_space) {
            i += 1;
        }
        if i >= code.len() {
            break;
        }
        let ks = i;
        while code
            .get(i)
            .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
        {
            i += 1;
        }
        let key = code.get(ks..i).unwrap_or(&[]);
        if code.get(i) != Some(&b'=') || key.is_empty() {
            return Err(err(ParseErrorKind::BadExtendedParam, ks));
        }
        i += 1;
        let vs = i;
        let Some((n, next)) = number::lex(code, i).map_err(|k| err(k, vs))? else {
            return Err(err(ParseErrorKind::MissingNumber, vs));
        };
        if code.get(next).is_some_and(|c| !is_space(*c)) {
            return Err(err(ParseErrorKind::BadByte, next));
        }
        let v = n.to_u32().map_err(|k| err(k, vs))?;
        let slot = if key.eq_ignore_ascii_case(b"CURRENT_LAYER") {
            &mut current_layer
        } else if key.eq_ignore_ascii_case(b"TOTAL_LAYER") {
            &mut total_layer
        } else {
            return Err(err(ParseErrorKind::UnexpectedLetter, ks));
        };
        if slot.is_some() {
            return Err(err(ParseErrorKind::DuplicateLetter, ks));
        }
        *slot = Some(v);
        i = next;
    }
    Ok(Command::PrintStatsInfo {
        current_layer,
        total_layer,
    })
}

#[cfg(test)]
mod tests;
