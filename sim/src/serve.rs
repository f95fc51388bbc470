//! `sim serve`: the firmware as a virtual printer on a pseudo-terminal. Pronterface/printcore,
//! OctoPrint or any serial host opens the device path it prints and talks to the firmware's own
//! host link (line numbers, checksums, `ok`, `Resend:`, realtime pause/resume, `//action:`).
//!
//! Time runs at real time by default (`--speed N` runs the virtual clock N times faster). The
//! session ends on Ctrl-C / SIGTERM, or after `--exit-after-idle` seconds of an idle printer
//! with no bytes from a host. A host may close the device and open it again: the firmware is
//! told (a session ending and starting on that port, as DTR on the board's USB port; see
//! `wire`). With `--tft` a second pseudo-terminal is the TFT UART port (its path is printed on
//! the second line). With `--record FILE.json` every pause seen is written then, with the
//! fields of `sim run --json`.
//!
//! There is no reference run here (the host decides what comes next), so the figures come from
//! the firmware's own records: reaction = the first speed-up or brake record after the request
//! (for the conventional policies, which neither speed up nor brake, the stop), stop = the
//! firmware's `Stopped` record; lost/duplicated = segments missing or repeated among the
//! executed records of each move.
//!
//! Submodules: `pty` (the pseudo-terminal, `--link`, signals), `wire` (the ports: reading with
//! flow control, writing, hosts coming and going), `machine` (the firmware, heaters, flash,
//! card, power-cut body), `track` (requests and pauses followed as the session runs), `report`
//! (the session judged when it ends).

mod clock;
mod machine;
pub mod pty;
mod report;
mod track;
mod wire;

pub use report::{PortReport, ServeRecord, HOST_LIFT_MIN_MM, HOST_PARK_TOL_MM, HOST_STOP_MIN_US};

use crate::run::{Mode, Policy, Scenario};
use anyhow::Context;
use firmware::link::PortId;
use machine::Machine;
use pty::{check_link_path, install_signals, STOP};
use report::{session_record, Seen};
use std::io::Write as _;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use track::{track, PauseTrack};
use wire::PtyPort;

/// Slowest `--speed`: a virtual millisecond per real second (slower is no use: a 1 s dwell
/// would take 17 minutes; `1e-300` froze the clock and was accepted before issue 31).
pub const MIN_SPEED: f64 = 1e-3;
/// Fastest `--speed`.
pub const MAX_SPEED: f64 = 1e6;

/// `sim serve` options.
#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    /// Virtual seconds per real second (0.001 to 1000000).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Write the pauses seen to this JSON file when the session ends.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Firmware policy (fifo and host-split model a conventional firmware).
    #[arg(long, value_enum, default_value = "firmware")]
    pub policy: Policy,
    /// End the session after this many real seconds without host bytes while nothing moves
    /// (idle, paused or halted printer; 0 = never).
    #[arg(long, default_value_t = 0.0)]
    pub exit_after_idle: f64,
    /// Also make a symlink to the device at this path (e.g. /tmp/printer). The path must not
    /// exist, or be a stale symlink to a pseudo-terminal; anything else is refused.
    #[arg(long)]
    pub link: Option<PathBuf>,
    /// Keep the settings (M500) in this flash image between sessions (created erased when
    /// missing; see `sim::flash`).
    #[arg(long)]
    pub flash: Option<PathBuf>,
    /// The machine file (see `sim::machines`): which printer this is (a profile from
    /// `sim/machines/`, or four numbers for the Ender-3 of earlier sessions), and — the machine
    /// outlives the session — minimum endstops (G28 homes through them) and the head's true
    /// position kept in it for the next start (see `sim::powercut`).
    #[arg(long)]
    pub machine: Option<PathBuf>,
    /// Append every executed job move, as the sim saw its steps, to this file (see
    /// `sim::powercut`).
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// The SD card: a directory (its files are put on a FAT image made at startup) or a card
    /// image file (MBR + FAT16/32); see `sim::sd` and docs/sd.md.
    #[arg(long)]
    pub sd: Option<PathBuf>,
    /// Let E move below the minimum hotend temperature, as `M302 P1` does (by default the
    /// cold-extrusion guard is on, as on the board: heat first, M104/M109).
    #[arg(long)]
    pub allow_cold_extrusion: bool,
    /// Also serve the TFT UART port on a second pseudo-terminal (its path is printed on a
    /// second line).
    #[arg(long)]
    pub tft: bool,
    /// Single control bytes (Ctrl-X halt, Ctrl-C cancel, …) are requests on the TFT port too
    /// (by default only on the USB port: docs/frontend.md, "Control bytes").
    #[arg(long)]
    pub tft_control_bytes: bool,
    /// The virtual clock waits for the hosts: at most 10× real time while a host owes its
    /// reply to an `ok`, and no jump when the sim stalls (see `sim::serve::clock`). For tests
    /// that judge virtual delays at a high `--speed`.
    #[arg(long)]
    pub host_paced: bool,
}

/// Run the virtual printer until the session ends; prints the device path on stdout (and the
/// TFT port's on a second line with `--tft`).
pub fn serve(a: ServeArgs) -> anyhow::Result<()> {
    serve_ports(a, |paths| {
        for p in paths {
            println!("{}", p.display());
        }
        let _ = std::io::stdout().flush();
    })
    .map(|_| ())
}

/// [`serve_ports`] with the USB port's path alone given to `ready`.
pub fn serve_with(
    a: ServeArgs,
    ready: impl FnOnce(&std::path::Path),
) -> anyhow::Result<ServeRecord> {
    serve_ports(a, |paths| {
        if let Some(p) = paths.first() {
            ready(p)
        }
    })
}

/// Run the virtual printer until the session ends, calling `ready` with the device paths
/// (USB, then TFT with `--tft`) once they can be opened. Returns the pause records (also
/// written to `--record` if given).
pub fn serve_ports(a: ServeArgs, ready: impl FnOnce(&[PathBuf])) -> anyhow::Result<ServeRecord> {
    if !(a.speed.is_finite() && (MIN_SPEED..=MAX_SPEED).contains(&a.speed)) {
        anyhow::bail!(
            "--speed {}: outside {MIN_SPEED}..={MAX_SPEED} (virtual seconds per real second)",
            a.speed
        );
    }
    // A Duration of at most ten years (Duration::from_secs_f64 panics past u64 seconds).
    if !(a.exit_after_idle.is_finite() && (0.0..=3.2e8).contains(&a.exit_after_idle)) {
        anyhow::bail!(
            "--exit-after-idle {}: outside 0..=320000000 seconds",
            a.exit_after_idle
        );
    }
    let mut sc = Scenario::new(a.policy, Mode::Layer);
    sc.allow_cold = a.allow_cold_extrusion;
    let mut m = Machine::open(&a, &sc)?;
    let mut ports = open_ports(&a)?;
    install_signals();
    let paths: Vec<PathBuf> = ports.iter().map(|p| p.path.clone()).collect();
    ready(&paths);
    eprintln!(
        "sim serve: virtual printer on {} ({} policy, {}× real time); Ctrl-C ends the session",
        paths
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(" and "),
        a.policy.name(),
        a.speed
    );
    let mut seen = SessionLoop::default();
    let start = Instant::now();
    seen.run(&a, &mut m, &mut ports)?;
    m.keep()?;
    let lines = ports.iter().fold((0, 0), |acc, p| {
        (acc.0 + p.sniff.lines, acc.1 + p.sniff.numbered)
    });
    let refused_numbered = ports.iter().map(|p| p.sniff.refused_numbered).sum();
    let mut record = session_record(
        &mut m.fw,
        &m.rec,
        &sc,
        &Seen {
            pauses: &seen.pauses,
            cancel_marks: &seen.cancel_marks,
            lines,
            refused_numbered,
            first_byte_us: seen.first_byte_us,
            wall_s: start.elapsed().as_secs_f64(),
        },
    );
    record.ports = ports
        .iter()
        .map(|p| PortReport {
            port: p.id.name().into(),
            lines_received: p.sniff.lines,
            numbered_lines_received: p.sniff.numbered,
            parked_host_waits: p.sniff.parked_waits,
            parked_host_wait_max_s: p.sniff.parked_wait_max_us as f64 * 1e-6,
            refused_numbered_lines: p.sniff.refused_numbered,
        })
        .collect();
    if let Some(p) = &a.record {
        std::fs::write(p, serde_json::to_string_pretty(&record)?)
            .with_context(|| format!("writing {}", p.display()))?;
        eprintln!(
            "sim serve: wrote the session and {} pause record(s) to {}",
            record.pauses.len(),
            p.display()
        );
    }
    if let (Some(l), Some(usb)) = (&a.link, paths.first()) {
        // Only our own link: never what someone put there since.
        if std::fs::read_link(l).is_ok_and(|t| &t == usb) {
            let _ = std::fs::remove_file(l);
        }
    }
    Ok(record)
}

/// The USB port's pseudo-terminal (with its `--link`), and the TFT port's with `--tft`.
fn open_ports(a: &ServeArgs) -> anyhow::Result<Vec<PtyPort>> {
    if let Some(l) = &a.link {
        check_link_path(l)?;
    }
    let mut ports = vec![PtyPort::open(PortId::Usb, true)?];
    if a.tft {
        ports.push(PtyPort::open(PortId::Tft, a.tft_control_bytes)?);
    }
    if let Some(l) = &a.link {
        // A stale link from an earlier session (checked above) is replaced; nothing else.
        if std::fs::symlink_metadata(l).is_ok() {
            std::fs::remove_file(l).with_context(|| format!("removing {}", l.display()))?;
        }
        std::os::unix::fs::symlink(&ports[0].path, l)
            .with_context(|| format!("symlink {}", l.display()))?;
    }
    Ok(ports)
}

/// What the loop follows as the session runs.
#[derive(Default)]
struct SessionLoop {
    pauses: Vec<PauseTrack>,
    notes_seen: usize,
    cancel_marks: Vec<usize>,
    first_byte_us: Option<u64>,
}

impl SessionLoop {
    /// Until a signal or the idle exit: storage, host bytes (flow control: what the firmware
    /// does not take stays pending and the device is not read meanwhile, so the host's writes
    /// block in the pty as they would on a USB port that NAKs), steps, output.
    fn run(&mut self, a: &ServeArgs, m: &mut Machine, ports: &mut [PtyPort]) -> anyhow::Result<()> {
        let mut last_rx = Instant::now();
        // When answers last went out: the session does not end right after an answer (closing
        // the master hangs the terminal up, and Linux then discards what the host had not
        // read).
        let mut last_tx = Instant::now();
        let mut clock = clock::Clock::new(a.speed, a.host_paced);
        while !STOP.load(Ordering::SeqCst) {
            let owes = ports.iter().any(|p| p.owes_reply(clock::HOST_TURN_GRACE));
            let now_us = clock.now_us(owes);
            m.service_storage(now_us);
            for p in ports.iter_mut() {
                p.watch_session(&mut m.fw, now_us);
                if p.receive(&mut m.fw, now_us, &mut self.pauses, &m.rec)? {
                    last_rx = Instant::now();
                    self.first_byte_us.get_or_insert(now_us);
                }
            }
            m.run_until(now_us);
            track(
                &mut self.pauses,
                &m.fw,
                &m.rec,
                &mut self.notes_seen,
                &mut self.cancel_marks,
            );
            let idle = m.idle(now_us)?;
            for p in ports.iter_mut() {
                if p.send(&mut m.fw, now_us)? {
                    last_tx = Instant::now();
                }
            }
            // Idle exit, once every answer is out (the answers of this round included).
            let quiet = Duration::from_secs_f64(a.exit_after_idle);
            if a.exit_after_idle > 0.0
                && idle
                && ports.iter().all(PtyPort::drained)
                && last_tx.elapsed() > quiet
                && last_rx.elapsed() > quiet
            {
                break;
            }
            wire::wait(ports, m.wait_us(now_us, a.speed));
        }
        Ok(())
    }
}
