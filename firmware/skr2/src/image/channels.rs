//! What the tasks say to each other. The executive (`firmware::printer::Printer`) has one
//! owner, the motion task; every other task talks to it only through these (embassy-sync's
//! pipes, channels and signals, each behind a critical-section mutex), as embassy's examples
//! wire their tasks:
//!
//! | from → to | what | carrier |
//! |---|---|---|
//! | USB / TFT task → motion | host bytes, in order | [`USB_IN`], [`TFT_IN`] (a full pipe holds the host back: the USB endpoint NAKs, the UART's own buffer fills) |
//! | motion → USB / TFT task | the executive's answers | [`USB_OUT`], [`TFT_OUT`] |
//! | USB task → motion | a host session opened or closed (DTR, USB reset, unplug) | [`SESSIONS`] |
//! | heater task → motion | the thermistors' latest temperatures | [`TEMPS`] |
//! | motion → heater task | heater duties, fans, halted | [`HEAT`] |
//! | motion → card task | bring the card up (M21, power-up, a lost card) | `board::sd`'s own signal (the card's driver and its task live there) |

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::pipe::Pipe;
use embassy_sync::signal::Signal;
use firmware::link::PortId;

/// Host bytes buffered per port on their way in: a USB packet's worth four times over, 22 ms
/// of the TFT line at 115200 Bd.
pub const IN_PIPE: usize = 256;
/// Host-link bytes buffered per port on their way out.
pub const OUT_PIPE: usize = 1024;

pub static USB_IN: Pipe<CriticalSectionRawMutex, IN_PIPE> = Pipe::new();
pub static TFT_IN: Pipe<CriticalSectionRawMutex, IN_PIPE> = Pipe::new();
pub static USB_OUT: Pipe<CriticalSectionRawMutex, OUT_PIPE> = Pipe::new();
pub static TFT_OUT: Pipe<CriticalSectionRawMutex, OUT_PIPE> = Pipe::new();

/// A host session's start (true) or end on a port.
pub static SESSIONS: Channel<CriticalSectionRawMutex, (PortId, bool), 4> = Channel::new();

/// The thermistors' temperatures, °C (faults as ±∞, which the thermal control understands),
/// and when they were read, µs.
#[derive(Clone, Copy)]
pub struct Temps {
    pub hotend_c: f32,
    pub bed_c: f32,
    pub t_us: u64,
}

pub static TEMPS: Signal<CriticalSectionRawMutex, Temps> = Signal::new();

/// What the heater task drives: the duties the thermal control asks for (0–1), the fans, and
/// whether the printer is halted (heaters off whatever the duties).
#[derive(Clone, Copy)]
pub struct HeatOut {
    pub hotend_duty: f32,
    pub bed_duty: f32,
    pub hotend_fan_on: bool,
    pub part_fan_pwm: u8,
    pub halted: bool,
}

pub static HEAT: Signal<CriticalSectionRawMutex, HeatOut> = Signal::new();
