//! `board-emu`: runs the unmodified SKR 2 image on the emulated board and writes a JSON report
//! (`docs/board-emu.md`; `scripts/board-emu.sh` builds the image and calls this).
use anyhow::{Context, Result};
use board_emu::cycles::ClockModel;
use board_emu::fault::Fault;
use board_emu::flash::FlashTiming;
use board_emu::scenario::{self, FlashFill, HostPort, Options};
use clap::Parser;
use std::path::PathBuf;

/// Boots the image, sends M115, the commands and the job over USART1 one line per `ok`.
#[derive(Parser)]
#[command(name = "board-emu")]
struct Args {
    /// The image as flashed (`firmware-f407.bin`).
    #[arg(long)]
    image: PathBuf,
    /// Its ELF, for the stack's bounds (the high-water mark).
    #[arg(long)]
    elf: Option<PathBuf>,
    /// The image is the F429 build (maps its 192 KiB of SRAM).
    #[arg(long)]
    f429: bool,
    /// G-code job sent over USART1.
    #[arg(long)]
    job: Option<PathBuf>,
    /// A command sent before the job (repeatable; `@reset` resets the board, `@wait MS`).
    #[arg(long = "cmd")]
    commands: Vec<String>,
    /// Schedule a pause at the start of layer N (`M761 L<n>`, as `sim run --pause-at-layer`).
    #[arg(long)]
    pause_at_layer: Option<u32>,
    /// Request a layer pause (M601, realtime) this long after the job's first step, s.
    #[arg(long)]
    pause_request_after: Option<f64>,
    /// Resume this long after the printer parked, s.
    #[arg(long, default_value_t = 1.0)]
    resume_after: f64,
    /// Inject a fault while the job moves.
    #[arg(long, value_enum)]
    fault: Option<Fault>,
    /// Inject it this long after the job's first line was answered, s.
    #[arg(long, default_value_t = 0.5)]
    fault_after: f64,
    /// LSI frequency, Hz (datasheet: 17000 min, 32000 typ, 47000 max).
    #[arg(long, default_value_t = 32_000)]
    lsi_hz: u32,
    /// Flash erase/program times.
    #[arg(long, value_enum, default_value = "typ")]
    flash_timing: FlashTiming,
    /// The settings sectors as a file (kept across runs).
    #[arg(long)]
    flash: Option<PathBuf>,
    /// Fill a fresh settings area with foreign data.
    #[arg(long, value_enum)]
    flash_fill: Option<FlashFill>,
    /// A card image in the micro-SD slot.
    #[arg(long)]
    sd_image: Option<PathBuf>,
    /// A driver module plugged in backwards: 0 X, 1 Y, 2 Z, 3 E.
    #[arg(long)]
    reversed_driver: Option<usize>,
    /// Where the carriage starts, mm from each switch: X,Y,Z.
    #[arg(long, value_delimiter = ',', default_values_t = [60.0f32, 60.0, 10.0])]
    start_mm: Vec<f32>,
    /// Give up after this much virtual time, s.
    #[arg(long, default_value_t = 120.0)]
    max_virtual_s: f64,
    /// Keep running this long after the job, s.
    #[arg(long, default_value_t = 0.2)]
    settle: f64,
    /// The clock model: `chip` (instruction timings, flash wait states through the ART
    /// accelerator, exception cycles) or `ideal` (one instruction a cycle).
    #[arg(long, value_enum, default_value = "chip")]
    clock: ClockModel,
    /// The port the scripted host uses: `tft` (USART1) or `usb` (the CDC ACM port, through
    /// the emulated USB host).
    #[arg(long, value_enum, default_value = "tft")]
    port: HostPort,
    /// Plug the USB cable in even when the host uses the TFT port.
    #[arg(long)]
    usb_plugged: bool,
    /// Send the job's comments (slicer layer markers) instead of stripping them.
    #[arg(long)]
    keep_comments: bool,
    /// Serve the board on two pseudo-terminals (USB CDC and the TFT UART, announced first on
    /// stdout as `usb: PATH` and `tft: PATH`), paced to the wall clock, until SIGINT/SIGTERM;
    /// then write the report. `--job`, `--cmd` and the pause options do not apply.
    #[arg(long)]
    serve: bool,
    /// Write the report here (else stdout).
    #[arg(long)]
    json: Option<PathBuf>,
}

fn main() -> Result<()> {
    let a = Args::parse();
    let job = match &a.job {
        Some(p) => std::fs::read_to_string(p)
            .with_context(|| format!("reading {}", p.display()))?
            .lines()
            .map(str::to_string)
            .collect(),
        None => Vec::new(),
    };
    anyhow::ensure!(
        a.start_mm.len() == 3 && a.start_mm.iter().all(|v| v.is_finite() && *v >= 0.0),
        "--start-mm takes three distances, mm, not negative"
    );
    anyhow::ensure!(
        a.lsi_hz > 0 && a.max_virtual_s.is_finite() && a.max_virtual_s > 0.0,
        "--lsi-hz and --max-virtual-s must be positive"
    );
    let o = Options {
        image: a.image,
        elf: a.elf,
        f429: a.f429,
        commands: a.commands,
        job,
        pause_at_layer: a.pause_at_layer,
        resume_after_s: a.resume_after,
        pause_request_after_s: a.pause_request_after.filter(|s| s.is_finite() && *s >= 0.0),
        fault: a.fault,
        fault_after_s: a.fault_after,
        lsi_hz: a.lsi_hz,
        flash_timing: a.flash_timing,
        flash_file: a.flash,
        flash_fill: a.flash_fill,
        sd_image: a.sd_image,
        reversed_driver: a.reversed_driver,
        max_virtual_s: a.max_virtual_s.min(3600.0),
        settle_s: a.settle.clamp(0.0, 600.0),
        clock: a.clock,
        start_mm: [a.start_mm[0], a.start_mm[1], a.start_mm[2]],
        port: a.port,
        usb_plugged: a.usb_plugged,
        keep_comments: a.keep_comments,
    };
    let r = if a.serve {
        board_emu::serve::serve(&o, |usb, tft| {
            println!("usb: {}", usb.display());
            println!("tft: {}", tft.display());
            let _ = std::io::Write::flush(&mut std::io::stdout());
            eprintln!(
                "board-emu: the emulated SKR 2 (F407 image) on {} (USB CDC) and {} (TFT UART), \
                 paced to the wall clock; Ctrl-C ends it",
                usb.display(),
                tft.display()
            );
        })?
    } else {
        scenario::run(&o)?
    };
    let text = serde_json::to_string_pretty(&r)?;
    match &a.json {
        Some(p) => std::fs::write(p, text).with_context(|| format!("writing {}", p.display()))?,
        None => println!("{text}"),
    }
    Ok(())
}
