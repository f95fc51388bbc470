//! What a run of the emulated board is given: the image, the host's script and port, the
//! board's outside (card, settings file, LSI, a driver plugged in backwards), faults, and the
//! clock model. Shared by the scripted run (`crate::scenario`) and `--serve` (`crate::serve`).

use crate::cycles::ClockModel;
use crate::fault::Fault;
use crate::flash::FlashTiming;
use std::path::PathBuf;

/// What to run.
#[derive(Clone, Debug)]
pub struct Options {
    /// The image (`firmware-f407.bin` or `-f429.bin`).
    pub image: PathBuf,
    /// Its ELF (symbols for the stack's bounds); optional.
    pub elf: Option<PathBuf>,
    /// The F429 (192 KiB of SRAM mapped).
    pub f429: bool,
    /// Lines sent before the job, each after the previous one is answered; `@reset` resets
    /// the board (NRST), `@wait <ms>` waits, `@until <text>` waits for a line containing it.
    pub commands: Vec<String>,
    /// The job (G-code lines).
    pub job: Vec<String>,
    /// Schedule a pause at the start of layer N (`M761 L<n>`, as `sim run --pause-at-layer`).
    pub pause_at_layer: Option<u32>,
    /// Resume this long after `//action:paused`, s.
    pub resume_after_s: f64,
    /// Request a layer pause (M601, realtime) this long after the job's first step, s.
    pub pause_request_after_s: Option<f64>,
    /// A fault to inject.
    pub fault: Option<Fault>,
    /// Inject it this long after the first job line was answered, s.
    pub fault_after_s: f64,
    /// LSI frequency, Hz.
    pub lsi_hz: u32,
    /// Flash times.
    pub flash_timing: FlashTiming,
    /// The settings sectors' file (read at start, written at the end).
    pub flash_file: Option<PathBuf>,
    /// The settings sectors' content when there is no file yet.
    pub flash_fill: Option<FlashFill>,
    /// The card in the slot (an image file).
    pub sd_image: Option<PathBuf>,
    /// A driver module plugged in backwards (0 = X .. 3 = E).
    pub reversed_driver: Option<usize>,
    /// Carriage start, mm from each switch (X, Y, Z).
    pub start_mm: [f32; 3],
    /// Give up after this much virtual time, s.
    pub max_virtual_s: f64,
    /// Keep running this long after the job, s (watch what follows).
    pub settle_s: f64,
    /// The clock model (`crate::cycles`).
    pub clock: ClockModel,
    /// The port the scripted host talks through.
    pub port: HostPort,
    /// The USB cable is plugged in (always when the host is on USB).
    pub usb_plugged: bool,
    /// Job lines keep their comments (slicer layer markers reach the printer).
    pub keep_comments: bool,
}

/// Which port the scripted host uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum HostPort {
    /// USART1, the TFT header, 115200 Bd.
    #[default]
    Tft,
    /// The USB CDC ACM port, through the emulated USB host (`crate::usbhost`).
    Usb,
}

/// What a foreign settings area holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FlashFill {
    /// Zeros (a sector another firmware left, or half erased).
    Zeros,
    /// Pseudo-random bytes (fixed seed).
    Random,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            image: PathBuf::new(),
            elf: None,
            f429: false,
            commands: Vec::new(),
            job: Vec::new(),
            pause_at_layer: None,
            resume_after_s: 1.0,
            pause_request_after_s: None,
            fault: None,
            fault_after_s: 0.5,
            lsi_hz: 32_000,
            flash_timing: FlashTiming::Typ,
            flash_file: None,
            flash_fill: None,
            sd_image: None,
            reversed_driver: None,
            start_mm: [60.0, 60.0, 10.0],
            max_virtual_s: 120.0,
            settle_s: 0.2,
            clock: ClockModel::Chip,
            port: HostPort::Tft,
            usb_plugged: false,
            keep_comments: false,
        }
    }
}
