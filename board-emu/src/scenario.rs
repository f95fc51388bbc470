//! One scripted run of the emulated board: power on, the host sends the commands and the job
//! one line per `ok` over USART1 or the USB CDC port, then `M115`; a pause is resumed, faults
//! are injected, and the report is made from the pins, the ports and the chip's state.

use crate::adc::{BED, HOTEND};
use crate::board::Board;
use crate::cpu::{Emulator, RunEnd};
use crate::fault;
use crate::host::Host;
use crate::nvic::{exc, irq};
pub use crate::options::{FlashFill, HostPort, Options};
use crate::rcc::ResetKind;
use crate::report::{self, Report, RunFacts};
use crate::setup;
use crate::time::{cyc_from_ms, s_from_cyc, Cyc};
use anyhow::Result;

/// Runs `o` and reports.
pub fn run(o: &Options) -> Result<Report> {
    let wall0 = std::time::Instant::now();
    let (mut emu, stack) = setup::build(o)?;
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
            let pause = o.pause_at_layer.is_some() || o.pause_request_after_s.is_some();
            let pausing = pause && job_sent && !r.resumed;
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
            r.job_sent_at = Some(emu.now());
            r.oks_before_job = host.oks;
            r.job_started = true;
            if let Some(n) = o.pause_at_layer {
                host.send_lines([format!("M761 L{n}").as_str()]);
            }
            host.send_lines(o.job.iter().map(String::as_str));
            host.send_lines(["M400"]);
            continue;
        }
        // A job's M400 answered while parked is paid at rest (the host could not send the
        // resume otherwise: firmware/src/printer/intake/sync.rs); after the resume one more
        // waits for the held job's moves to end.
        if r.resumed && !r.synced_after_resume {
            r.synced_after_resume = true;
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
    setup::finish(&emu, o)?;
    Ok(report::make(
        &emu,
        &host.received,
        &RunFacts {
            start_mm: o.start_mm,
            lsi_hz: o.lsi_hz,
            parked: r.parked,
            requested: r.requested,
            first_job_step: r.first_job_step,
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
        let new = host.received.get(r.lines_seen..).unwrap_or(&[]);
        r.lines_seen = host.received.len();
        if let Some((t, _)) = new.iter().find(|(_, l)| l.contains("//action:paused")) {
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
    // A layer pause requested (M601, realtime) this long after the job's first step.
    if let (Some(after), Some(sent), None) = (o.pause_request_after_s, r.job_sent_at, r.requested) {
        let first = emu
            .board()
            .axes
            .axis
            .iter()
            .filter_map(|a| a.rises.iter().map(|(t, _)| *t).find(|t| *t >= sent))
            .min();
        if first.is_some_and(|t| s_from_cyc(now.saturating_sub(t)) >= after) {
            host.send_now("M601");
            r.requested = Some(now);
            r.first_job_step = first;
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
    if s_from_cyc(now - t0) >= o.fault_after_s && fault::inject(emu, f) {
        r.injected = Some(now);
    }
}

/// What [`react`] keeps between calls.
#[derive(Clone, Debug, Default)]
pub struct Reaction {
    /// `//action:paused` seen at.
    pub parked: Option<Cyc>,
    /// M24 sent.
    pub resumed: bool,
    /// The M400 after the resume sent.
    pub synced_after_resume: bool,
    /// The job's lines were queued.
    pub job_started: bool,
    /// `ok`s before the job's lines.
    pub oks_before_job: u64,
    /// The job's first line answered.
    pub job_first_ok: Option<Cyc>,
    /// The fault went in at.
    pub injected: Option<Cyc>,
    /// When the job's lines were queued.
    pub job_sent_at: Option<Cyc>,
    /// The job's first step.
    pub first_job_step: Option<Cyc>,
    /// M601 sent at (`Options::pause_request_after_s`).
    pub requested: Option<Cyc>,
    /// Lines of the host looked at for `//action:paused`.
    pub lines_seen: usize,
}

/// Heaters' and drivers' state.
pub fn outputs(b: &Board) -> ([bool; 2], [bool; 4]) {
    (
        [b.heaters.powered(HOTEND), b.heaters.powered(BED)],
        b.drivers_enabled(),
    )
}
