//! `sim serve`: the firmware as a virtual printer on a pseudo-terminal. Pronterface/printcore,
//! OctoPrint or any serial host opens the device path it prints and talks to the firmware's own
//! host link (line numbers, checksums, `ok`, `Resend:`, realtime pause/resume, `//action:`).
//!
//! Time runs at real time by default (`--speed N` runs the virtual clock N times faster). The
//! session ends on Ctrl-C / SIGTERM, when the host closes the device (if nothing else holds it),
//! or after `--exit-after-idle` seconds of an idle printer with no bytes from the host. With
//! `--record FILE.json` every pause seen is written then, with the fields of `sim run --json`.
//!
//! There is no reference run here (the host decides what comes next), so the figures come from
//! the firmware's own records: reaction = the first speed-up or brake record after the request
//! (for the conventional policies, which neither speed up nor brake, the stop), stop = the
//! firmware's `Stopped` record; lost/duplicated = segments missing or repeated among the
//! executed records of each move.
//!
//! Submodules: `pty` (the pseudo-terminal, `--link`, signals), `track` (requests and pauses
//! followed as the session runs), `report` (the session judged when it ends).

mod pty;
mod report;
mod track;

pub use report::{ServeRecord, HOST_LIFT_MIN_MM, HOST_PARK_TOL_MM, HOST_STOP_MIN_US};

use crate::exec::{PrinterExec, PrinterFactory};
use crate::port::{Executive, RunState};
use crate::recorder::Recorder;
use crate::run::{Factory, Mode, Policy, Scenario};
use crate::session::{extrusion_layers, MoveLog, SessionReport};
use crate::thermal::Heaters;
use anyhow::Context;
use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
use pty::{check_link_path, install_signals, open_pty, STOP};
use report::reports;
use std::io::Write as _;
use std::os::fd::AsFd;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use track::{note_request, track, PauseTrack, Sniffer};

/// `sim serve` options.
#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    /// Virtual seconds per real second.
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
    /// The machine outlives the session: minimum endstops (G28 homes through them) and the
    /// head's true position kept in this file for the next start (see `sim::powercut`).
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
}

/// Run the virtual printer until the session ends; prints the device path on stdout.
pub fn serve(a: ServeArgs) -> anyhow::Result<()> {
    serve_with(a, |path| {
        println!("{}", path.display());
        let _ = std::io::stdout().flush();
    })
    .map(|_| ())
}

/// Run the virtual printer until the session ends, calling `ready` with the device path once
/// it can be opened. Returns the pause records (also written to `--record` if given).
pub fn serve_with(
    a: ServeArgs,
    ready: impl FnOnce(&std::path::Path),
) -> anyhow::Result<ServeRecord> {
    if !(a.speed.is_finite() && a.speed > 0.0 && a.speed <= 1e6) {
        anyhow::bail!(
            "--speed {}: outside 0..=1000000 (virtual seconds per second)",
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
    let mut flash = a
        .flash
        .as_deref()
        .map(crate::flash::FlashStore::open)
        .transpose()?;
    let mut card = match a.sd.as_deref() {
        Some(p) if p.is_dir() => Some(crate::sd::ImageDevice::from_dir(p)?),
        Some(p) => Some(crate::sd::ImageDevice::open(p)?),
        None => None,
    }
    .map(firmware::storage::sd::Card::new);
    if let Some(l) = &a.link {
        check_link_path(l)?;
    }
    let (master, slave, path) = open_pty()?;
    if let Some(l) = &a.link {
        // A stale link from an earlier session (checked above) is replaced; nothing else.
        if std::fs::symlink_metadata(l).is_ok() {
            std::fs::remove_file(l).with_context(|| format!("removing {}", l.display()))?;
        }
        std::os::unix::fs::symlink(&path, l).with_context(|| format!("symlink {}", l.display()))?;
    }
    install_signals();
    ready(&path);
    eprintln!(
        "sim serve: virtual printer on {} ({} policy, {}× real time); Ctrl-C ends the session",
        path.display(),
        a.policy.name(),
        a.speed
    );

    let mut sc = Scenario::new(a.policy, Mode::Layer);
    sc.allow_cold = a.allow_cold_extrusion;
    let mut fw: PrinterExec = PrinterFactory.make(&sc.machine, &sc.knobs());
    fw.keep_executed = true;
    let mut rec = Recorder::new();
    // Power-cut checks: the head where the last session left it, endstops, the move trace.
    let mut body = match a.machine.as_deref() {
        Some(p) => {
            let (b, pos) = crate::powercut::MachineBody::open(p)?;
            fw = fw.with_endstops([pos[0], pos[1], pos[2]]);
            rec.pos = pos;
            Some(b)
        }
        None => None,
    };
    let mut trace = a
        .trace
        .as_deref()
        .map(crate::powercut::MoveTrace::open)
        .transpose()?;
    let mut heaters = Heaters::ender3();
    let mut sniff = Sniffer::default();
    let mut pauses: Vec<PauseTrack> = Vec::new();
    let start = Instant::now();
    let mut last_rx = Instant::now();
    // When output was last written: the session does not end right after an answer (closing
    // the master hangs the terminal up, and Linux then discards what the host had not read).
    let mut last_tx = Instant::now();
    let mut out = String::new();
    let mut pending_out: Vec<u8> = Vec::new();
    let mut buf = [0u8; 4096];
    let mut rx_pending: Vec<u8> = Vec::new();
    let mut notes_seen = 0usize;
    let mut cancel_marks: Vec<usize> = Vec::new();
    let mut last_poll_us = 0u64;
    let mut first_byte_us: Option<u64> = None;
    let mut hung_up = false;
    loop {
        if STOP.load(Ordering::SeqCst) {
            break;
        }
        let now_us = (start.elapsed().as_secs_f64() * a.speed * 1e6) as u64;
        // Settings store: the first pass loads the saved settings (before any host byte is
        // read, as at power-up), later passes carry out M500/M501.
        if let Some(f) = flash.as_mut() {
            f.service(&mut fw.printer);
        }
        // The SD card: commands waiting for it, and the job's lines while the queue has room.
        if let Some(c) = card.as_mut() {
            fw.printer.attach_card();
            fw.printer.service_card(c, now_us);
        }
        // Host bytes. Flow control: what the firmware does not take stays in `rx_pending`, and
        // the pty is not read again until it is all taken, so the host's writes block in the
        // pty as they would on a USB port that NAKs.
        loop {
            if !rx_pending.is_empty() {
                let n = fw.receive(&rx_pending, now_us);
                let mut reqs = Vec::new();
                sniff.feed(&rx_pending[..n], &mut reqs);
                rx_pending.drain(..n);
                for r in reqs {
                    note_request(&mut pauses, r, now_us, &rec, &fw);
                }
                if !rx_pending.is_empty() {
                    break;
                }
            }
            match nix::unistd::read(master.as_fd(), &mut buf) {
                Ok(0) => break,
                Ok(n) => {
                    last_rx = Instant::now();
                    first_byte_us.get_or_insert(now_us);
                    rx_pending.extend_from_slice(&buf[..n]);
                }
                Err(nix::errno::Errno::EAGAIN) => break,
                Err(nix::errno::Errno::EIO) => {
                    hung_up = true;
                    break;
                }
                Err(e) => return Err(e).context("reading the pseudo-terminal"),
            }
        }
        if hung_up {
            break;
        }
        // Steps due by now.
        let mut n = 0;
        while let Some(t) = fw.next_step_us(now_us) {
            if t > now_us || n > 200_000 {
                break;
            }
            if let Some(ev) = fw.pop_step(t) {
                if rec.on_step(&ev) {
                    fw.poll(t);
                }
            }
            n += 1;
        }
        if now_us >= last_poll_us + 1000 || n > 0 {
            heaters.tick(&mut fw, now_us);
            fw.poll(now_us);
            last_poll_us = now_us;
        }
        rec.on_status(&fw.status(), now_us);
        track(&mut pauses, &fw, &rec, &mut notes_seen, &mut cancel_marks);
        // Idle: no motion (idle, paused, halted, cancelled: anything but a running job or a
        // wait). Decided before the output is taken: asking for the next step can load a block
        // and let a waiting command (M400) complete and answer, and that answer must go out
        // before an idle exit.
        let st = fw.status().state;
        let idle = fw.next_step_us(now_us).is_none()
            && !matches!(
                st,
                RunState::Printing | RunState::Pausing | RunState::Resuming
            );
        if idle {
            // Nothing moves: the head's position and the finished moves are kept now, so a
            // killed session (a power cut) leaves them.
            if let Some(b) = body.as_mut() {
                b.keep(rec.pos)?;
            }
            if let Some(t) = trace.as_mut() {
                t.flush(&rec.records)?;
            }
        }
        // Output.
        out.clear();
        fw.take_output(&mut out);
        pending_out.extend_from_slice(out.as_bytes());
        // Unsolicited temperature reports (M155 auto-report, which a host such as
        // host-tools send or OctoPrint turns on and never off) and `busy:` keep-alives (sent
        // every M113 period while a host line waits, e.g. behind a full queue while parked)
        // are not answers: they do not keep an idle session alive.
        let answers = out.lines().any(|l| {
            let l = l.trim_start();
            !l.starts_with("T:") && !l.starts_with("busy:")
        });
        if !pending_out.is_empty() {
            match nix::unistd::write(&master, &pending_out) {
                Ok(w) => {
                    pending_out.drain(..w);
                    if answers {
                        last_tx = Instant::now();
                    }
                }
                Err(nix::errno::Errno::EAGAIN) => {}
                Err(nix::errno::Errno::EIO) => break,
                Err(e) => return Err(e).context("writing the pseudo-terminal"),
            }
        }
        // Idle exit, once every answer is out (the answers of this round included).
        if a.exit_after_idle > 0.0
            && idle
            && pending_out.is_empty()
            && last_tx.elapsed() > Duration::from_secs_f64(a.exit_after_idle)
            && last_rx.elapsed() > Duration::from_secs_f64(a.exit_after_idle)
        {
            break;
        }
        // Sleep until the next step is due, a byte arrives, or 2 ms pass.
        let wait_ms = match fw.next_step_us(now_us) {
            Some(t) if t > now_us => (((t - now_us) as f64 / a.speed) / 1000.0).min(2.0) as i32,
            Some(_) => 0,
            None => 2,
        };
        if wait_ms > 0 {
            let mut fds = [PollFd::new(master.as_fd(), PollFlags::POLLIN)];
            let _ = poll(&mut fds, PollTimeout::from(wait_ms.clamp(0, 2) as u16));
        }
    }
    drop(slave);
    if let Some(t) = trace.as_mut() {
        t.flush(&rec.records)?;
    }
    if let Some(b) = body.as_mut() {
        // The head stops where its last step left it, whatever the firmware had planned.
        b.keep(rec.pos)?;
    }
    let end_us = rec.last_step_us;
    let moves = MoveLog {
        executed: &fw.executed,
        cancel_marks: &cancel_marks,
        moving_at_end: fw.printer.next_step_us().is_some(),
    }
    .counts();
    let mut reports = reports(
        &pauses,
        &rec,
        &fw,
        &sc,
        first_byte_us.unwrap_or(0),
        end_us,
        &moves,
    );
    // Wall time of the session and virtual time per wall second (≈ `--speed`).
    let wall_s = start.elapsed().as_secs_f64();
    for r in &mut reports {
        r.sim_wall_s = wall_s;
        r.realtime_factor = if wall_s > 0.0 {
            end_us as f64 * 1e-6 / wall_s
        } else {
            0.0
        };
    }
    let layers = extrusion_layers(&rec.records);
    let cancelled_last = cancel_marks.last().is_some_and(|&m| m >= fw.executed.len());
    let record = ServeRecord {
        session: SessionReport {
            lines_received: sniff.lines,
            numbered_lines_received: sniff.numbered,
            moves_executed: moves.moves,
            segments_executed: moves.segments,
            lost_moves: moves.lost.0,
            duplicated_moves: moves.duplicated.0,
            lost_segments: moves.lost.1,
            duplicated_segments: moves.duplicated.1,
            cancelled_moves: moves.cancelled,
            running_at_end: moves.running_at_end,
            cancelled: !cancel_marks.is_empty(),
            finished: fw.status().state == RunState::Idle
                && !cancelled_last
                && !moves.running_at_end
                && moves.lost.0 == 0
                && moves.moves > 0,
            layers_extruded: layers.last().map_or(0, |l| l.1 + 1),
            pauses: reports.len(),
            print_time_s: end_us.saturating_sub(first_byte_us.unwrap_or(0)) as f64 * 1e-6,
        },
        pauses: reports,
    };
    if let Some(p) = &a.record {
        std::fs::write(p, serde_json::to_string_pretty(&record)?)
            .with_context(|| format!("writing {}", p.display()))?;
        eprintln!(
            "sim serve: wrote the session and {} pause record(s) to {}",
            record.pauses.len(),
            p.display()
        );
    }
    if let Some(l) = &a.link {
        // Only our own link: never what someone put there since.
        if std::fs::read_link(l).is_ok_and(|t| t == path) {
            let _ = std::fs::remove_file(l);
        }
    }
    Ok(record)
}
