//! One run of the emulated board: power on, the host sends `M115`, the commands and the job
//! over USART1 one line per `ok`, faults are injected, and the report is made from the pins,
//! the UART and the chip's state.

use crate::adc::{BED, HOTEND};
use crate::axes::Axes;
use crate::board::{Board, Stall};
use crate::cpu::{Emulator, RunEnd};
use crate::cycles::{Clock, ClockModel};
use crate::fault::{Fault, BAD_RETURN};
use crate::flash::{Flash, FlashTiming, STORE_LEN};
use crate::host::Host;
use crate::iwdg::Iwdg;
use crate::nvic::{exc, irq};
use crate::rcc::ResetKind;
use crate::report::{self, Report, RunFacts};
use crate::sdio::Sdio;
use crate::time::{cyc_from_ms, s_from_cyc, Cyc};
use crate::usbhost::UsbHost;
use crate::tmc::{Drivers, Seating};
use anyhow::{Context, Result};
use firmware::config::MachineConfig;
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

/// The stack's bounds from the ELF (`_stack_end` .. `_stack_start`, cortex-m-rt's symbols).
fn stack_bounds(elf: &std::path::Path) -> Result<(u32, u32)> {
    use object::{Object, ObjectSymbol};
    let data = std::fs::read(elf).with_context(|| format!("reading {}", elf.display()))?;
    let file = object::File::parse(&*data)?;
    let sym = |n: &str| {
        file.symbols()
            .find(|s| s.name() == Ok(n))
            .map(|s| s.address() as u32)
    };
    Ok((
        sym("_stack_end").context("no _stack_end in the ELF")?,
        sym("_stack_start").context("no _stack_start in the ELF")?,
    ))
}

fn initial_store(o: &Options) -> Result<Vec<u8>> {
    if let Some(f) = &o.flash_file {
        if f.exists() {
            let d = std::fs::read(f)?;
            anyhow::ensure!(
                d.len() == STORE_LEN,
                "{} is not {} bytes",
                f.display(),
                STORE_LEN
            );
            return Ok(d);
        }
    }
    Ok(match o.flash_fill {
        None => vec![0xFF; STORE_LEN],
        Some(FlashFill::Zeros) => vec![0; STORE_LEN],
        Some(FlashFill::Random) => {
            let mut x: u32 = 0x2545_F491;
            (0..STORE_LEN)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    x as u8
                })
                .collect()
        }
    })
}

/// Paint pattern for the stack.
const PAINT: u32 = 0xC5C5_C5C5;

/// Runs `o` and reports.
pub fn run(o: &Options) -> Result<Report> {
    let wall0 = std::time::Instant::now();
    let image =
        std::fs::read(&o.image).with_context(|| format!("reading {}", o.image.display()))?;
    let mut flash = Flash::new(o.flash_timing);
    flash.store = initial_store(o)?;
    let mut seating = [Seating::Correct; 4];
    if let Some(i) = o.reversed_driver {
        seating[i.min(3)] = Seating::Reversed;
    }
    let card = match &o.sd_image {
        Some(p) => Some(std::fs::read(p).with_context(|| format!("reading {}", p.display()))?),
        None => None,
    };
    let cfg = MachineConfig::ENDER3;
    let axes = Axes::new(&cfg, o.start_mm);
    let mut board = Board::new(
        flash,
        Iwdg::new(o.lsi_hz),
        Drivers::new(seating),
        axes,
        Sdio::with_card(card),
    );
    board.clock = Clock::new(o.clock);
    if o.usb_plugged || o.port == HostPort::Usb {
        board.usb = UsbHost::new(true);
    }
    if o.port == HostPort::Usb {
        // The host program holds the port from the start: DTR once enumerated.
        board.usb.set_open(0, true);
    }
    let mut emu = Emulator::new(board, image, o.f429)?;
    let stack = match &o.elf {
        Some(e) => Some(stack_bounds(e)?),
        None => None,
    };
    if let Some((lo, hi)) = stack {
        emu.paint(lo, hi, PAINT)?;
    }

    let mut host = Host::new();
    host.keep_comments = o.keep_comments;
    // M115 goes last: its ~700-byte reply stalled the TFT port of main's image for good
    // (docs/board-emu.md, "Found by the emulated board"), so nothing could follow it.
    let mut script: std::collections::VecDeque<String> = o.commands.iter().cloned().collect();
    let mut job_sent = false;
    let mut r = Reaction::default();
    let until = (o.max_virtual_s * 168e6) as Cyc;
    let end = loop {
        let end = emu.run_until(until, |emu| {
            poll(&mut host, emu, o.port);
            react(emu, &mut host, o, &mut r);
            // A pause waits for its resume before the job counts as done.
            let pausing = o.pause_at_layer.is_some() && job_sent && !r.resumed;
            !pausing && host.idle()
        })?;
        if end != RunEnd::Condition {
            break end;
        }
        let now = emu.now();
        // Everything sent so far is answered: the next step of the script.
        if let Some(cmd) = script.pop_front() {
            if cmd == "@reset" {
                emu.power_on(ResetKind::Pin)?;
            } else if let Some(usb) = usb_command(&cmd) {
                let b = emu.board_mut();
                match usb {
                    UsbCommand::Plug(p) => b.usb.set_plugged(now, p),
                    UsbCommand::Open(p) => b.usb.set_open(now, p),
                }
            } else if let Some(text) = cmd.strip_prefix("@until ") {
                let text = text.trim().to_string();
                let from = host.received.len();
                emu.run_until(until, |emu| {
                    poll(&mut host, emu, o.port);
                    react(emu, &mut host, o, &mut r);
                    host.received[from..].iter().any(|(_, l)| l.contains(&text))
                })?;
            } else if let Some(ms) = cmd.strip_prefix("@wait ") {
                let ms: u64 = ms.trim().parse().unwrap_or(0);
                let t = now + cyc_from_ms(ms);
                emu.run_until(t.min(until), |emu| {
                    poll(&mut host, emu, o.port);
                    react(emu, &mut host, o, &mut r);
                    false
                })?;
            } else {
                host.send_lines([cmd.as_str()]);
            }
            continue;
        }
        if !job_sent {
            job_sent = true;
            r.oks_before_job = host.oks;
            r.job_started = true;
            if let Some(n) = o.pause_at_layer {
                host.send_lines([format!("M761 L{n}").as_str()]);
            }
            host.send_lines(o.job.iter().map(String::as_str));
            host.send_lines(["M400"]);
            continue;
        }
        host.send_lines(["M115"]);
        // Wait for the reply line (its `ok` may never come), then settle.
        let limit = emu.now() + cyc_from_ms(2_000);
        emu.run_until(limit.min(until), |emu| {
            poll(&mut host, emu, o.port);
            host.idle() || host.find("FIRMWARE_NAME").is_some()
        })?;
        // Done: watch a little longer (what the board does after the job or the fault).
        let t = emu.now() + (o.settle_s * 168e6) as Cyc;
        break run_plain(&mut emu, &mut host, o.port, t)?;
    };
    let _ = end;
    if std::env::var_os("BOARD_EMU_DEBUG").is_some() {
        let now = emu.now();
        let b = emu.board_mut();
        let e = usize::from(exc::IRQ0 + irq::USART1);
        eprintln!(
            "host queued {} idle {} usart host_tx {} rx log {}",
            host.queued(),
            host.idle(),
            b.usart1.host_tx.len(),
            b.usart1.tx_log.len()
        );
        eprintln!(
            "usart1 cr1 {:#x} sr {:#x} irq {} nvic en {} pend {} act {} prio {:#x} stack {:?} last tx {:?}",
            b.usart1.read(0x0C, now),
            b.usart1.read(0x00, now),
            b.usart1.irq(),
            b.nvic.enabled[e],
            b.nvic.pending[e],
            b.nvic.active[e],
            b.nvic.prio[e],
            b.nvic.stack,
            b.usart1.tx_log.last().map(|(t, c)| (s_from_cyc(*t), *c as char))
        );
    }
    if std::env::var_os("BOARD_EMU_DEBUG").is_some() {
        let b = emu.board();
        eprintln!(
            "ccr1 {:?}",
            &b.tim5.ccr1_writes[..b.tim5.ccr1_writes.len().min(8)]
        );
        eprintln!(
            "rises X {:?}",
            &b.axes.axis[0].rises[..b.axes.axis[0].rises.len().min(8)]
        );
    }
    if let Some(p) = &emu.profile {
        let mut v: Vec<_> = p.iter().collect();
        v.sort_by_key(|(_, n)| std::cmp::Reverse(**n));
        for (pc, n) in v.iter().take(15) {
            eprintln!("profile: {pc:#010x} {n}");
        }
    }
    if let Some(f) = &o.flash_file {
        std::fs::write(f, &emu.board().flash.store)
            .with_context(|| format!("writing {}", f.display()))?;
    }
    Ok(report::make(
        &emu,
        &host,
        &RunFacts {
            start_mm: o.start_mm,
            lsi_hz: o.lsi_hz,
            parked: r.parked,
            injected: r.injected,
            stack,
            wall_s: wall0.elapsed().as_secs_f64(),
            usb_plugged: o.usb_plugged || o.port == HostPort::Usb,
        },
    ))
}

/// A USB command of the script: `@unplug`, `@plug`, `@close` (the program closes the port:
/// DTR dropped), `@open`.
enum UsbCommand {
    Plug(bool),
    Open(bool),
}

fn usb_command(cmd: &str) -> Option<UsbCommand> {
    Some(match cmd.trim() {
        "@unplug" => UsbCommand::Plug(false),
        "@plug" => UsbCommand::Plug(true),
        "@close" => UsbCommand::Open(false),
        "@open" => UsbCommand::Open(true),
        _ => return None,
    })
}

/// The host reads and writes its port.
pub fn poll(host: &mut Host, emu: &mut Emulator, port: HostPort) {
    let now = emu.now();
    let b = emu.board_mut();
    match port {
        HostPort::Tft => host.poll(&mut b.usart1, now),
        HostPort::Usb => host.poll(&mut b.usb, now),
    }
}

/// Runs to `t` while the host keeps talking.
fn run_plain(emu: &mut Emulator, host: &mut Host, port: HostPort, t: Cyc) -> Result<RunEnd> {
    emu.run_until(t, |emu| {
        poll(host, emu, port);
        false
    })
}

/// Drives a job with a pause and faults: the parts of [`run`] that react to the printer.
pub fn react(emu: &mut Emulator, host: &mut Host, o: &Options, r: &mut Reaction) {
    let now = emu.now();
    // Resume after the park.
    if r.parked.is_none() {
        if let Some((t, _)) = host.find("//action:paused") {
            r.parked = Some(*t);
            emu.board_mut().axes.mark("parked", *t);
        }
    }
    if let (Some(tp), false) = (r.parked, r.resumed) {
        if s_from_cyc(now.saturating_sub(tp)) >= o.resume_after_s {
            host.send_now("M24");
            r.resumed = true;
            emu.board_mut().axes.mark("resume", now);
        }
    }
    // Inject the fault once the job has moved for a while.
    let Some(f) = o.fault else { return };
    if r.injected.is_some() || !r.job_started {
        return;
    }
    let Some(t0) = r.job_first_ok else {
        if host.oks >= r.oks_before_job + 2 {
            r.job_first_ok = Some(now);
        }
        return;
    };
    if s_from_cyc(now - t0) < o.fault_after_s {
        return;
    }
    let b = emu.board_mut();
    match f {
        Fault::MotionStall | Fault::ExecutorStall => {
            b.stall = f.stall().map(|duration| Stall {
                after: now,
                duration,
            });
            r.injected = Some(now);
        }
        Fault::UnexpectedIrq => {
            b.nvic.systick.load = 167_999;
            b.nvic.systick.write_ctrl(now, 0b111);
            b.notes.push(format!(
                "SysTick armed (1 ms, TICKINT) at t = {:.4} s",
                s_from_cyc(now)
            ));
            r.injected = Some(now);
        }
        Fault::HardFault => {
            // Wait until the step interrupt is the active handler, then corrupt its frame.
            if b.nvic.stack.last() != Some(&(exc::IRQ0 + irq::TIM5)) {
                return;
            }
            // The stacked return address: word 6 of the frame the entry pushed.
            let ret_slot = b.frame_sp.last().map(|sp| sp + 24);
            if let Some(slot) = ret_slot {
                let old = emu.peek32(slot);
                emu.poke32(slot, BAD_RETURN);
                emu.board_mut().notes.push(format!(
                    "HardFault injected: TIM5 frame's return address {old:#010x} -> {BAD_RETURN:#010x} at t = {:.4} s",
                    s_from_cyc(now)
                ));
                r.injected = Some(now);
            }
        }
    }
}

/// What [`react`] keeps between calls.
#[derive(Clone, Debug, Default)]
pub struct Reaction {
    /// `//action:paused` seen at.
    pub parked: Option<Cyc>,
    /// M24 sent.
    pub resumed: bool,
    /// The job's lines were queued.
    pub job_started: bool,
    /// `ok`s before the job's lines.
    pub oks_before_job: u64,
    /// The job's first line answered.
    pub job_first_ok: Option<Cyc>,
    /// The fault went in at.
    pub injected: Option<Cyc>,
}

/// Heaters' and drivers' state.
pub fn outputs(b: &Board) -> ([bool; 2], [bool; 4]) {
    (
        [b.heaters.powered(HOTEND), b.heaters.powered(BED)],
        b.drivers_enabled(),
    )
}
