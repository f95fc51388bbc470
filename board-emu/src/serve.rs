//! `--serve`: the emulated board as a printer on the desk. Its time is paced to the wall
//! clock; the USB CDC port and the TFT UART are each a pseudo-terminal a real host program
//! (OctoPrint, Pronterface/printcore, a terminal) opens, announced first on stdout as
//! `usb: /dev/pts/N` and `tft: /dev/pts/M`. SIGINT or SIGTERM ends the run: the settings
//! file is kept and the JSON report written.
//!
//! * USB: the pseudo-terminal is the serial port the kernel's `cdc-acm` driver would make of
//!   the board. A program opening it is the port opened (the emulated host sends
//!   SET_LINE_CODING and raises DTR: a session starts on the image's USB port), closing it
//!   drops DTR — told after [`OPEN_SETTLE`] as `sim serve` does, so that what the image says
//!   first to a new session comes after the program's serial library emptied its input.
//!   Bytes the program writes go out as bulk OUT packets while the device takes them (the
//!   device's NAKs leave them in the pseudo-terminal: flow control); what the device sends
//!   is written to it.
//! * TFT: bytes both ways at the UART's pace, no session (a UART has no DTR).
//!
//! Pacing: virtual time follows the wall clock from the start; while the emulator keeps up it
//! sleeps between slices (waking for host bytes); when it falls behind it runs flat out, and a
//! lag over [`MAX_LAG`] is given up (virtual time does not race to catch up), counted in the
//! report (`serve.lag_max_s`, `serve.virtual_per_wall`).

use crate::cpu::{Emulator, RunEnd};
use crate::fault;
use crate::options::Options;
use crate::report::{self, Report, RunFacts, ServeReport};
use crate::setup;
use crate::time::{cyc_from_ms, s_from_cyc, Cyc, CPU_HZ};
use anyhow::{Context, Result};
use sim::serve::pty::{hung_up, install_signals, open_pty, wait_readable, STOP};
use std::os::fd::{AsFd, OwnedFd};
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// How long a program holds the USB device before DTR is raised (`sim serve`'s value and
/// reason: pyserial's `open()` empties the input right after opening).
pub const OPEN_SETTLE: Duration = Duration::from_millis(100);
/// Most virtual time the emulator may lag behind the wall clock before the lag is dropped.
pub const MAX_LAG: Duration = Duration::from_millis(500);
/// Longest emulator slice between two looks at the terminals (virtual).
const SLICE: Cyc = cyc_from_ms(10);
/// Bytes kept waiting in the USB host's send queue (more stay in the pseudo-terminal).
const USB_QUEUE: usize = 512;
/// Bytes kept waiting on the UART line (more stay in the pseudo-terminal).
const UART_QUEUE: usize = 64;
/// Received bytes kept in the models' logs before the forwarded ones are dropped.
const LOG_KEEP: usize = 1 << 20;

/// One pseudo-terminal: its master end, what waits to be written to it, lines seen.
struct Term {
    master: OwnedFd,
    path: PathBuf,
    pending: Vec<u8>,
    /// Bytes of the model's receive log already taken.
    cursor: usize,
    open: bool,
    opening_since: Option<Instant>,
    partial: Vec<u8>,
    lines: std::collections::VecDeque<String>,
    /// When the image first said `//action:paused` here.
    paused_at: Option<Cyc>,
}

impl Term {
    fn open() -> Result<Self> {
        let (master, slave, path) = open_pty()?;
        // Not kept: the master then tells whether a program holds the device.
        drop(slave);
        Ok(Term {
            master,
            path,
            pending: Vec::new(),
            cursor: 0,
            open: false,
            opening_since: None,
            partial: Vec::new(),
            lines: Default::default(),
            paused_at: None,
        })
    }

    /// Whether a program holds the device, settled for [`OPEN_SETTLE`] on opening.
    fn held(&mut self) -> bool {
        let open = !hung_up(self.master.as_fd());
        if !open {
            self.opening_since = None;
            return false;
        }
        if self.open {
            return true;
        }
        let since = *self.opening_since.get_or_insert_with(Instant::now);
        since.elapsed() >= OPEN_SETTLE
    }

    /// Up to `max` bytes the program wrote.
    fn read(&mut self, max: usize) -> Result<Vec<u8>> {
        let mut buf = vec![0u8; max];
        match nix::unistd::read(self.master.as_fd(), &mut buf) {
            Ok(n) => {
                buf.truncate(n);
                Ok(buf)
            }
            Err(nix::errno::Errno::EAGAIN | nix::errno::Errno::EIO) => Ok(Vec::new()),
            Err(e) => Err(e).context("reading the pseudo-terminal"),
        }
    }

    /// New bytes from the device: noted as lines, written as far as the terminal takes them.
    fn give(&mut self, log: &[(Cyc, u8)]) -> Result<()> {
        let new = log.get(self.cursor..).unwrap_or(&[]);
        self.cursor = log.len();
        for &(t, b) in new {
            if b == b'\n' {
                let l = String::from_utf8_lossy(&self.partial)
                    .trim_end()
                    .to_string();
                if l == "//action:paused" && self.paused_at.is_none() {
                    self.paused_at = Some(t);
                }
                self.partial.clear();
                if self.lines.len() >= 10_000 {
                    self.lines.pop_front();
                }
                self.lines.push_back(l);
            } else if self.partial.len() < 4096 {
                self.partial.push(b);
            }
            self.pending.push(b);
        }
        if self.pending.is_empty() {
            return Ok(());
        }
        match nix::unistd::write(&self.master, &self.pending) {
            Ok(n) => {
                self.pending.drain(..n);
            }
            // Nobody holds it: the bytes go nowhere, as on a wire nobody listens to.
            Err(nix::errno::Errno::EIO) => self.pending.clear(),
            Err(nix::errno::Errno::EAGAIN) => {}
            Err(e) => return Err(e).context("writing the pseudo-terminal"),
        }
        // A program that stopped reading: its terminal's buffer is full; the rest waits, up to
        // a bound (then it is dropped, oldest first, as a UART overruns).
        if self.pending.len() > 1 << 16 {
            let cut = self.pending.len() - (1 << 16);
            self.pending.drain(..cut);
        }
        Ok(())
    }
}

/// Runs `o` on the two terminals until SIGINT/SIGTERM; `ready` gets their paths first.
pub fn serve(
    o: &Options,
    ready: impl FnOnce(&std::path::Path, &std::path::Path),
) -> Result<Report> {
    let wall0 = Instant::now();
    let mut o = o.clone();
    o.usb_plugged = true;
    let (mut emu, stack) = setup::build(&o)?;
    let mut usb = Term::open()?;
    let mut tft = Term::open()?;
    install_signals();
    ready(&usb.path, &tft.path);
    let mut sr = ServeReport {
        usb_device: usb.path.display().to_string(),
        tft_device: tft.path.display().to_string(),
        ..Default::default()
    };
    let mut injected: Option<Cyc> = None;
    let mut first_byte: Option<Cyc> = None;
    let mut anchor = (Instant::now(), emu.now());
    let ended_by = loop {
        if STOP.load(Ordering::SeqCst) {
            break "signal".to_string();
        }
        let now = emu.now();
        exchange(&mut emu, &mut usb, &mut tft, &mut sr, &mut first_byte)?;
        // Faults: `--fault-after` seconds after the first byte a host sent.
        if let (Some(f), Some(t0), None) = (o.fault, first_byte, injected) {
            if s_from_cyc(now.saturating_sub(t0)) >= o.fault_after_s && fault::inject(&mut emu, f) {
                injected = Some(now);
            }
        }
        let target = anchor.1 + (anchor.0.elapsed().as_secs_f64() * CPU_HZ as f64) as Cyc;
        let lag = target.saturating_sub(now);
        sr.lag_max_s = sr.lag_max_s.max(s_from_cyc(lag));
        if lag > (MAX_LAG.as_secs_f64() * CPU_HZ as f64) as Cyc {
            sr.lag_dropped_s += s_from_cyc(lag);
            anchor = (Instant::now(), now);
            continue;
        }
        if now < target {
            let end = emu.run_until(target.min(now + SLICE), |_| false)?;
            if let RunEnd::Lockup(why) = end {
                break format!("lockup: {why}");
            }
        } else {
            // Ahead of the wall clock: wait for the time or a host's bytes.
            let ahead = Duration::from_secs_f64(s_from_cyc(now - target)).min(SLICE_WAIT);
            wait(&[&usb, &tft], ahead);
        }
    };
    exchange(&mut emu, &mut usb, &mut tft, &mut sr, &mut first_byte)?;
    sr.ended_by = ended_by;
    // The first park seen on either port: where the report's pause point is found.
    let parked = [usb.paused_at, tft.paused_at].into_iter().flatten().min();
    if let Some(t) = parked {
        emu.board_mut().axes.mark("parked", t);
    }
    sr.usb_lines = usb.lines.iter().cloned().collect();
    sr.tft_lines = tft.lines.iter().cloned().collect();
    let wall_s = wall0.elapsed().as_secs_f64();
    sr.virtual_per_wall = s_from_cyc(emu.now()) / wall_s.max(1e-9);
    setup::finish(&emu, &o)?;
    let mut r = report::make(
        &emu,
        &[],
        &RunFacts {
            start_mm: o.start_mm,
            lsi_hz: o.lsi_hz,
            parked,
            requested: None,
            first_job_step: None,
            injected,
            stack,
            wall_s,
            usb_plugged: true,
        },
    );
    r.m115 = sr
        .usb_lines
        .iter()
        .chain(&sr.tft_lines)
        .find(|l| l.contains("FIRMWARE_NAME"))
        .cloned();
    r.serve = Some(sr);
    Ok(r)
}

/// Longest sleep while ahead of the wall clock.
const SLICE_WAIT: Duration = Duration::from_millis(5);

/// Moves bytes between the terminals and the board's ports, and follows the USB session.
fn exchange(
    emu: &mut Emulator,
    usb: &mut Term,
    tft: &mut Term,
    sr: &mut ServeReport,
    first_byte: &mut Option<Cyc>,
) -> Result<()> {
    let now = emu.now();
    let held = usb.held();
    let b = emu.board_mut();
    if held != usb.open {
        usb.open = held;
        usb.pending.clear();
        b.usb.set_open(now, held);
        sr.usb_sessions.push((s_from_cyc(now), held));
    }
    if usb.open && b.usb.host_tx.len() < USB_QUEUE {
        let bytes = usb.read(USB_QUEUE - b.usb.host_tx.len())?;
        if !bytes.is_empty() {
            first_byte.get_or_insert(now);
            b.usb.write(now, &bytes);
        }
    }
    if b.usart1.host_tx.len() < UART_QUEUE {
        let bytes = tft.read(UART_QUEUE - b.usart1.host_tx.len())?;
        if !bytes.is_empty() {
            first_byte.get_or_insert(now);
            b.usart1.host_tx.extend(bytes);
        }
    }
    usb.give(&b.usb.rx_log)?;
    tft.give(&b.usart1.tx_log)?;
    // Long sessions: the forwarded part of the logs is dropped.
    if b.usb.rx_log.len() > LOG_KEEP {
        b.usb.rx_log.drain(..usb.cursor);
        usb.cursor = 0;
    }
    if b.usart1.tx_log.len() > LOG_KEEP {
        b.usart1.tx_log.drain(..tft.cursor);
        tft.cursor = 0;
    }
    Ok(())
}

/// Sleeps until a held terminal has bytes or `d` passes.
fn wait(terms: &[&Term], d: Duration) {
    let held: Vec<_> = terms
        .iter()
        .filter(|t| t.open || !hung_up(t.master.as_fd()))
        .map(|t| t.master.as_fd())
        .collect();
    wait_readable(&held, d);
}
