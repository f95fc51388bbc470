//! Realtime requests on the link: the single control bytes and the command spellings that act
//! at once, ahead of the line FIFO.

use crate::gcode::Command;
use crate::gcode::PauseCommand;
use crate::motion::{PauseMode, Realtime};

/// Control byte: emergency stop (Ctrl-X, CAN).
pub const BYTE_EMERGENCY_STOP: u8 = 0x18;
/// Control byte: quick stop (Ctrl-Y, EM).
pub const BYTE_QUICK_STOP: u8 = 0x19;
/// Control byte: pause at the layer boundary (Ctrl-P, DLE).
pub const BYTE_PAUSE_LAYER: u8 = 0x10;
/// Control byte: pause now (Ctrl-N, SO).
pub const BYTE_PAUSE_NOW: u8 = 0x0E;
/// Control byte: resume (Ctrl-R, DC2).
pub const BYTE_RESUME: u8 = 0x12;
/// Control byte: cancel the job (Ctrl-C, ETX).
pub const BYTE_CANCEL: u8 = 0x03;
/// Control byte: break out of a heater wait (Ctrl-B, STX).
pub const BYTE_BREAK_WAIT: u8 = 0x02;

/// The realtime request of a single control byte, if it is one.
pub const fn control_byte(b: u8) -> Option<Realtime> {
    match b {
        BYTE_EMERGENCY_STOP => Some(Realtime::EmergencyStop),
        BYTE_QUICK_STOP => Some(Realtime::QuickStop),
        BYTE_PAUSE_LAYER => Some(Realtime::Pause(PauseMode::Layer)),
        BYTE_PAUSE_NOW => Some(Realtime::Pause(PauseMode::Now)),
        BYTE_RESUME => Some(Realtime::Resume),
        BYTE_CANCEL => Some(Realtime::Cancel),
        BYTE_BREAK_WAIT => Some(Realtime::BreakWait),
        _ => None,
    }
}

/// The realtime request a parsed command stands for, if any (the host-link spellings).
pub fn realtime_of(cmd: &Command) -> Option<Realtime> {
    match cmd {
        Command::Pause(PauseCommand::BreakWait) => Some(Realtime::BreakWait),
        Command::Pause(PauseCommand::EmergencyStop) => Some(Realtime::EmergencyStop),
        Command::Pause(PauseCommand::QuickStop) => Some(Realtime::QuickStop),
        Command::Pause(PauseCommand::Pause { mode, .. }) => Some(Realtime::Pause(*mode)),
        Command::Pause(PauseCommand::Resume { .. }) => Some(Realtime::Resume),
        Command::Pause(PauseCommand::Cancel) => Some(Realtime::Cancel),
        _ => None,
    }
}
