//! Host-link responses, formatted the way Marlin writes them so Pronterface/printcore,
//! OctoPrint and Repetier-Host understand them. Every [`Response`] implements
//! [`core::fmt::Display`] (one or more lines, without the final line end).

use crate::motion::{StepPos, AXES};
use core::fmt;

/// Firmware name reported by M115.
pub const FIRMWARE_NAME: &str = "LayerPause";
/// Firmware version reported by M115.
pub const FIRMWARE_VERSION: &str = env!("CARGO_PKG_VERSION");
/// Host protocol version reported by M115 (Marlin's).
pub const PROTOCOL_VERSION: &str = "1.0";

/// Capabilities reported by M115 (`Cap:<name>:<0|1>`): only what this firmware really does.
pub const CAPABILITIES: &[(&str, bool)] = &[
    ("SERIAL_XON_XOFF", false),
    ("BINARY_FILE_TRANSFER", false),
    ("EEPROM", false),
    ("VOLUMETRIC", false),
    ("AUTOREPORT_TEMP", true),
    ("AUTOREPORT_POS", false),
    ("PROGRESS", true),
    ("PRINT_JOB", true),
    ("AUTOLEVEL", false),
    ("Z_PROBE", false),
    ("LEVELING_DATA", false),
    ("SOFTWARE_POWER", false),
    ("TOGGLE_LIGHTS", false),
    ("CASE_LIGHT_BRIGHTNESS", false),
    ("EMERGENCY_PARSER", true),
    ("HOST_ACTION_COMMANDS", true),
    ("PROMPT_SUPPORT", false),
    ("SDCARD", true),
    ("AUTOREPORT_SD_STATUS", true),
    ("THERMAL_PROTECTION", true),
    ("MOTION_MODES", false),
    ("ARCS", true),
    ("BABYSTEPPING", false),
    ("CHAMBER_TEMPERATURE", false),
    ("EXTENDED_M20", true),
    // Firmware-specific: M760 pause parameters, M761 scheduled pause, layer-boundary pause.
    ("PAUSE_AT_LAYER", true),
];

/// An OctoPrint host action (`//action:<name>`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HostAction {
    /// `//action:pause`: the printer asks the host to pause its stream.
    Pause,
    /// `//action:paused`: the printer has paused (parked).
    Paused,
    /// `//action:resume`: the printer asks the host to resume.
    Resume,
    /// `//action:resumed`: the printer has resumed.
    Resumed,
    /// `//action:cancel`: the printer asks the host to cancel the job.
    Cancel,
    /// `//action:notification <text>`: a message for the user.
    Notification,
}

impl HostAction {
    /// The action name after `//action:`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Pause => "pause",
            Self::Paused => "paused",
            Self::Resume => "resume",
            Self::Resumed => "resumed",
            Self::Cancel => "cancel",
            Self::Notification => "notification",
        }
    }
}

/// M105 temperature report: `T:<cur> /<target> B:<cur> /<target> @:<0-127> B@:<0-127>`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TempReport {
    /// Hotend temperature, °C.
    pub hotend_c: f32,
    /// Hotend target, °C.
    pub hotend_target_c: f32,
    /// Bed temperature and target, °C, if the machine has a heated bed.
    pub bed_c: Option<(f32, f32)>,
    /// Hotend heater duty 0..=1 (reported as `@:` 0..127 like Marlin).
    pub hotend_duty: f32,
    /// Bed heater duty 0..=1 (`B@:`).
    pub bed_duty: f32,
}

/// M114 position report: logical mm, then `Count` in steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PositionReport {
    /// Logical position X Y Z E, mm (after G92).
    pub logical_mm: [f64; AXES],
    /// Machine position in steps X Y Z (E is not counted, as in Marlin).
    pub steps: StepPos,
}

/// One response to the host. [`core::fmt::Display`] writes it as Marlin does (lines separated
/// by `\n`, no final line end).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Response<'a> {
    /// `ok`: the line was accepted.
    Ok,
    /// `Resend: <n>`: send again from line n.
    Resend(u32),
    /// `Error:<text>`.
    Error(&'a str),
    /// `Error:<text>, Last Line: <n>` (line-number and checksum errors, as Marlin writes them).
    LineError(&'a str, u32),
    /// `echo:<text>`.
    Echo(&'a str),
    /// `<text>` as it is: Marlin's SD-card messages (`Begin file list`, `File opened: …`,
    /// `SD printing byte …`, `Done printing file`) carry no `echo:` prefix.
    Plain(&'a str),
    /// `echo:Unknown command: "<text>"`.
    UnknownCommand(&'a str),
    /// `busy: processing` (keep-alive during long waits, about every 2 s).
    Busy,
    /// `busy: paused for user` (Marlin's keep-alive while it waits for the user, e.g. paused
    /// with the host's line held).
    BusyPaused,
    /// `//action:<name>` or `//action:notification <text>`.
    Action(HostAction, &'a str),
    /// `ok T:.. /.. B:.. /.. @:.. B@:..` (M105), or without `ok` (`with_ok` false) as the
    /// periodic report during M109/M190.
    Temperatures {
        /// The values.
        report: TempReport,
        /// Prefix `ok ` (the M105 answer is its own `ok`).
        with_ok: bool,
    },
    /// `X:.. Y:.. Z:.. E:.. Count X:.. Y:.. Z:..` (M114; send `ok` after it).
    Position(PositionReport),
    /// The M115 report: `FIRMWARE_NAME:… PROTOCOL_VERSION:…` and one `Cap:` line per entry of
    /// [`CAPABILITIES`] (send `ok` after it).
    FirmwareInfo,
}

fn duty127(d: f32) -> u32 {
    let d = if d.is_nan() { 0.0 } else { d.clamp(0.0, 1.0) };
    (d * 127.0 + 0.5) as u32
}

impl fmt::Display for Response<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Response::Ok => f.write_str("ok"),
            Response::Resend(n) => write!(f, "Resend: {n}"),
            Response::Error(t) => write!(f, "Error:{t}"),
            Response::LineError(t, n) => write!(f, "Error:{t}, Last Line: {n}"),
            Response::Echo(t) => write!(f, "echo:{t}"),
            Response::Plain(t) => f.write_str(t),
            Response::UnknownCommand(t) => write!(f, "echo:Unknown command: \"{t}\""),
            Response::Busy => f.write_str("busy: processing"),
            Response::BusyPaused => f.write_str("busy: paused for user"),
            Response::Action(HostAction::Notification, t) => {
                write!(f, "//action:notification {t}")
            }
            Response::Action(a, _) => write!(f, "//action:{}", a.name()),
            Response::Temperatures { report: r, with_ok } => {
                if *with_ok {
                    f.write_str("ok ")?;
                }
                write!(f, "T:{:.1} /{:.1}", r.hotend_c, r.hotend_target_c)?;
                if let Some((c, t)) = r.bed_c {
                    write!(f, " B:{c:.1} /{t:.1}")?;
                }
                write!(f, " @:{}", duty127(r.hotend_duty))?;
                if r.bed_c.is_some() {
                    write!(f, " B@:{}", duty127(r.bed_duty))?;
                }
                Ok(())
            }
            Response::Position(p) => {
                let l = &p.logical_mm;
                write!(
                    f,
                    "X:{:.2} Y:{:.2} Z:{:.2} E:{:.2} Count X:{} Y:{} Z:{}",
                    l[0], l[1], l[2], l[3], p.steps[0], p.steps[1], p.steps[2]
                )
            }
            Response::FirmwareInfo => {
                write!(
                    f,
                    "FIRMWARE_NAME:{FIRMWARE_NAME} {FIRMWARE_VERSION} SOURCE_CODE_URL:local \
                     PROTOCOL_VERSION:{PROTOCOL_VERSION} MACHINE_TYPE:Ender-3 EXTRUDER_COUNT:1"
                )?;
                for (name, on) in CAPABILITIES {
                    write!(f, "\nCap:{name}:{}", u8::from(*on))?;
                }
                Ok(())
            }
        }
    }
}
