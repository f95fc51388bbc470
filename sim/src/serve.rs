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

use crate::exec::{PrinterExec, PrinterFactory};
use crate::metrics::{max_abs_diff, PauseReport};
use crate::port::{Executive, Lane, RunState};
use crate::recorder::{Recorder, Scale};
use crate::run::{Factory, Mode, Policy, Scenario};
use crate::session::{extrusion_layers, first_boundary_after, MoveLog, SessionReport};
use crate::thermal::Heaters;
use anyhow::Context;
use firmware::motion::{PauseMode, Realtime};
use firmware::printer::Record;
use nix::fcntl::{fcntl, FcntlArg, OFlag};
use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
use nix::sys::termios;
use std::io::Write as _;
use std::os::fd::{AsFd, OwnedFd};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

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
}

static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: nix::libc::c_int) {
    STOP.store(true, Ordering::SeqCst);
}

fn install_signals() {
    use nix::sys::signal::{sigaction, SaFlags, SigAction, SigHandler, SigSet, Signal};
    let sa = SigAction::new(
        SigHandler::Handler(on_signal),
        SaFlags::empty(),
        SigSet::empty(),
    );
    for s in [Signal::SIGINT, Signal::SIGTERM, Signal::SIGHUP] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
        let _ = unsafe { sigaction(s, &sa) };
    }
}

/// One pause as the session saw it.
#[derive(Clone, Debug, Default)]
struct PauseTrack {
    mode: Option<PauseMode>,
    t_req_us: u64,
    pos_req: [i32; 4],
    rec_idx_req: usize,
    reaction_us: Option<u64>,
    stopped: Option<(u64, [i32; 4], Option<u32>, bool)>,
    parked_us: Option<u64>,
    resume_req_us: Option<u64>,
    rec_idx_resume: usize,
    resumed: Option<(u64, [i32; 4])>,
    /// The firmware cancelled the job before this pause reached Paused: a cancel, not a pause.
    cancelled: bool,
}

/// What `sim serve --record` writes: the whole session, and one object per pause.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ServeRecord {
    /// Lines, moves, lost/duplicated, cancelled, finished: with or without a pause.
    pub session: SessionReport,
    /// One object per pause (the fields of `sim run --json`).
    pub pauses: Vec<PauseReport>,
}

/// Lines from the host, assembled to find realtime requests (for the record only: the
/// firmware's own link acts on them).
#[derive(Default)]
struct Sniffer {
    buf: Vec<u8>,
    /// Complete non-empty lines seen, and of those the numbered ones.
    lines: u64,
    numbered: u64,
}

impl Sniffer {
    fn feed(&mut self, bytes: &[u8], out: &mut Vec<Realtime>) {
        for &b in bytes {
            if let Some(r) = firmware::link::control_byte(b) {
                out.push(r);
                continue;
            }
            if b == b'\n' || b == b'\r' {
                let line = std::mem::take(&mut self.buf);
                let text = String::from_utf8_lossy(&line);
                let body = text.trim();
                if body.is_empty() {
                    continue;
                }
                self.lines += 1;
                self.numbered += u64::from(body.starts_with('N'));
                let body = match body.strip_prefix('N') {
                    Some(rest) => rest.split_once(' ').map_or("", |x| x.1),
                    None => body,
                };
                let body = body.split('*').next().unwrap_or("");
                if let Ok(l) = firmware::gcode::parse_line(body.as_bytes()) {
                    if let Some(r) = l.command.as_ref().and_then(firmware::link::realtime_of) {
                        out.push(r);
                    }
                }
            } else if self.buf.len() < 256 {
                self.buf.push(b);
            }
        }
    }
}

fn open_pty() -> anyhow::Result<(OwnedFd, OwnedFd, PathBuf)> {
    let pty = nix::pty::openpty(None, None).context("openpty")?;
    let mut t = termios::tcgetattr(&pty.slave).context("tcgetattr")?;
    termios::cfmakeraw(&mut t);
    termios::tcsetattr(&pty.slave, termios::SetArg::TCSANOW, &t).context("tcsetattr")?;
    let path = nix::unistd::ttyname(&pty.slave).context("ttyname")?;
    let flags = fcntl(&pty.master, FcntlArg::F_GETFL).context("fcntl")?;
    fcntl(
        &pty.master,
        FcntlArg::F_SETFL(OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK),
    )
    .context("fcntl")?;
    Ok((pty.master, pty.slave, path))
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
    if !(a.speed.is_finite() && a.speed > 0.0) {
        anyhow::bail!("--speed must be a positive number");
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

    let sc = Scenario::new(a.policy, Mode::Layer);
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

/// `--link PATH` may name nothing yet, or a symlink to a pseudo-terminal (a stale link of an
/// earlier session, replaced). Anything else — a file, a directory, a device, a link to
/// anything else — is refused: the sim never destroys what a path points to.
fn check_link_path(l: &std::path::Path) -> anyhow::Result<()> {
    match std::fs::symlink_metadata(l) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e).with_context(|| format!("--link {}", l.display())),
        Ok(m) if m.file_type().is_symlink() => {
            let target =
                std::fs::read_link(l).with_context(|| format!("--link {}", l.display()))?;
            if target.starts_with("/dev/pts/") {
                Ok(())
            } else {
                anyhow::bail!(
                    "--link {}: exists and links to {}, not to a pseudo-terminal; refusing to \
                     replace it (choose another path)",
                    l.display(),
                    target.display()
                )
            }
        }
        Ok(_) => anyhow::bail!(
            "--link {}: exists and is not a symlink; refusing to replace it (choose another path)",
            l.display()
        ),
    }
}

fn note_request(
    pauses: &mut Vec<PauseTrack>,
    r: Realtime,
    now_us: u64,
    rec: &Recorder,
    fw: &PrinterExec,
) {
    match r {
        Realtime::Pause(mode) => {
            let active = pauses
                .last()
                .is_some_and(|p| p.resumed.is_none() && p.resume_req_us.is_none());
            // Called after the firmware took the bytes: a pause it accepted shows as Pausing
            // (also from an idle printer inside a streamed job, e.g. at a boundary the host
            // drained with M400); a refused one leaves it as it was.
            let state = fw.status().state;
            if !active && matches!(state, RunState::Pausing | RunState::Paused) {
                pauses.push(PauseTrack {
                    mode: Some(mode),
                    t_req_us: now_us,
                    pos_req: rec.pos,
                    rec_idx_req: rec.records.len(),
                    ..PauseTrack::default()
                });
            }
        }
        Realtime::Resume => {
            if let Some(p) = pauses.last_mut() {
                if p.resume_req_us.is_none() && p.stopped.is_some() {
                    p.resume_req_us = Some(now_us);
                    p.rec_idx_resume = rec.records.len().saturating_sub(1);
                }
            }
        }
        _ => {}
    }
}

fn track(
    pauses: &mut Vec<PauseTrack>,
    fw: &PrinterExec,
    rec: &Recorder,
    seen: &mut usize,
    cancel_marks: &mut Vec<usize>,
) {
    for r in fw.notes.iter().skip(*seen) {
        if let Record::State {
            state: firmware::printer::State::Cancelled,
            ..
        } = *r
        {
            cancel_marks.push(fw.executed.len());
            if let Some(p) = pauses.last_mut() {
                if p.parked_us.is_none() {
                    p.cancelled = true;
                }
            }
        }
        // A pause the firmware started by itself (M761 schedule, M600/M0, M25 in the job):
        // tracked from the moment it began.
        if let Record::State {
            state: firmware::printer::State::Pausing,
            t_us,
        } = *r
        {
            let active = pauses
                .last()
                .is_some_and(|p| p.resumed.is_none() && p.resume_req_us.is_none());
            if !active {
                pauses.push(PauseTrack {
                    mode: Some(PauseMode::Layer),
                    t_req_us: t_us,
                    pos_req: rec.pos,
                    rec_idx_req: rec.records.len(),
                    ..PauseTrack::default()
                });
            }
        }
        let Some(p) = pauses.last_mut() else {
            continue;
        };
        match *r {
            Record::SpeedUp { t_us } | Record::Brake { t_us, .. }
                if t_us >= p.t_req_us && p.reaction_us.is_none() =>
            {
                p.reaction_us = Some(t_us);
            }
            Record::Stopped {
                pos,
                layer,
                mid_block,
                t_us,
            } if p.stopped.is_none() => {
                p.stopped = Some((t_us, pos, layer, mid_block));
            }
            Record::State { state, t_us }
                if state == firmware::printer::State::Paused && p.parked_us.is_none() =>
            {
                p.parked_us = Some(t_us);
            }
            _ => {}
        }
    }
    *seen = fw.notes.len();
    // A resume is found in the executed blocks (the first job block after the request); a
    // host may already have asked for the next pause by then, so every pause is looked at.
    for p in pauses
        .iter_mut()
        .filter(|p| p.resume_req_us.is_some() && p.resumed.is_none())
    {
        let t_res = p.resume_req_us.unwrap_or(0);
        if let Some(r) = rec
            .records
            .iter()
            .skip(p.rec_idx_resume)
            .find(|r| r.tag.lane == Lane::Job && r.t_start_us >= t_res)
        {
            p.resumed = Some((r.t_start_us, r.start));
        }
    }
}

fn reports(
    pauses: &[PauseTrack],
    rec: &Recorder,
    fw: &PrinterExec,
    sc: &Scenario,
    t0_us: u64,
    end_us: u64,
    moves: &crate::session::MoveCounts,
) -> Vec<PauseReport> {
    let scale = Scale::from_config(&sc.machine);
    let layers = extrusion_layers(&rec.records);
    let cancelled_last = fw.notes.iter().rev().find_map(|r| match *r {
        Record::State { state, .. } => Some(state == firmware::printer::State::Cancelled),
        _ => None,
    }) == Some(true);
    // What every record of the session shares.
    let base = PauseReport {
        policy: sc.policy.name().into(),
        lost_moves: moves.lost.0,
        duplicated_moves: moves.duplicated.0,
        lost_segments: moves.lost.1,
        duplicated_segments: moves.duplicated.1,
        executed_in_order: moves.lost.1 == 0 && moves.duplicated.1 == 0,
        print_time_s: end_us.saturating_sub(t0_us) as f64 * 1e-6,
        finished: fw.status().state == RunState::Idle
            && !cancelled_last
            && !moves.running_at_end
            && moves.lost.0 == 0,
        steps: rec.steps,
        ..PauseReport::default()
    };
    let mut out: Vec<PauseReport> = pauses
        .iter()
        .filter(|p| !p.cancelled)
        .map(|p| {
            let mut r = PauseReport {
                mode: match p.mode {
                    Some(PauseMode::Now) => "now".into(),
                    _ => "layer".into(),
                },
                request_s: Some(p.t_req_us as f64 * 1e-6),
                parked_s: p.parked_us.map(|t| t as f64 * 1e-6),
                ..base.clone()
            };
            if let Some((t_stop, pos, layer, mid)) = p.stopped {
                r.stop_s = Some(t_stop.saturating_sub(p.t_req_us) as f64 * 1e-6);
                r.reaction_s =
                    Some(p.reaction_us.unwrap_or(t_stop).saturating_sub(p.t_req_us) as f64 * 1e-6);
                r.pause_point_steps = Some(pos);
                r.stopped_at_layer_boundary = layer.is_some() && !mid;
                r.stop_layer = layer.and_then(|l| l.checked_sub(1));
                // Judged from the extrusion heights, not from the firmware's layer detector.
                r.first_boundary_after_request =
                    first_boundary_after(&rec.records, &layers, p.t_req_us, t_stop) == Some(true);
                r.extrusion_after_request_mm = Some(scale.e_mm(&p.pos_req, &pos));
                // Travel: block pieces between the request and the stop.
                let mut travel = 0.0;
                let mut at = p.pos_req;
                for s in rec.records.iter().skip(p.rec_idx_req.saturating_sub(1)) {
                    if s.t_start_us > t_stop {
                        break;
                    }
                    if s.tag.lane != Lane::Job {
                        continue;
                    }
                    let from = if s.t_start_us < p.t_req_us {
                        at
                    } else {
                        s.start
                    };
                    travel += scale.xyz_dist_mm(&from, &s.end);
                    at = s.end;
                }
                r.travel_after_request_mm = Some(travel);
                if let Some((t_res, start)) = p.resumed {
                    r.resumed_s = Some(t_res as f64 * 1e-6);
                    r.paused_s = Some(t_res.saturating_sub(t_stop) as f64 * 1e-6);
                    r.resume_position_error_steps = Some(max_abs_diff(&pos, &start));
                }
            }
            r
        })
        .collect();
    out.extend(host_stops(pauses, rec, fw, &base, sc));
    out
}

/// A standstill of at least this long between two extruding moves of a job, with no firmware
/// pause in it, is a pause the host made (the paper's host-side method: it stops sending,
/// parks with ordinary G-code and later returns) — if the head stood parked the way a host
/// parks ([`HOST_LIFT_MIN_MM`], [`HOST_PARK_TOL_MM`]). A standstill where a job move ended is a
/// host too slow for the virtual clock (a loaded machine at `--speed 20`), not a pause.
/// Virtual µs.
pub const HOST_STOP_MIN_US: u64 = 5_000_000;
/// A host pause lifts the head at least this much above the last extrusion (host-tools' host
/// pause lifts 1 mm; slicers' Z-hops on travel are smaller), mm ...
pub const HOST_LIFT_MIN_MM: f64 = 0.9;
/// ... or parks it within this distance of the machine's park corner (the paper's sequence,
/// which does not lift), mm.
pub const HOST_PARK_TOL_MM: f64 = 2.0;

/// Pauses the host made by itself (no realtime request, no firmware pause), found in the
/// executed blocks: the head stood still for [`HOST_STOP_MIN_US`] or more between two
/// extruding moves. Reported with mode `host`: the stop is the end of the last extruding move
/// before the standstill; it was at a layer boundary when the firmware's layer counter differs
/// between that move and the first extruding move after (no layer extruded on both sides); the
/// resume error compares that first move's start with the stop point (all four axes, so an
/// un-retract that does not restore E shows).
fn host_stops(
    pauses: &[PauseTrack],
    rec: &Recorder,
    fw: &PrinterExec,
    base: &PauseReport,
    sc: &Scenario,
) -> Vec<PauseReport> {
    let scale = Scale::from_config(&sc.machine);
    let park = (
        f64::from(sc.machine.pause.park_x_mm),
        f64::from(sc.machine.pause.park_y_mm),
    );
    // The host's park pattern, seen where the head stood still: lifted at least
    // HOST_LIFT_MIN_MM above the last extrusion, or at the machine's park corner. A host that
    // is merely slow (the firmware starved of lines) leaves the head where a job move ended.
    let parked = |last: &[i32; 4], still: &[i32; 4]| {
        let (a, b) = (scale.mm(last), scale.mm(still));
        b[2] - a[2] >= HOST_LIFT_MIN_MM
            || ((b[0] - park.0).abs() <= HOST_PARK_TOL_MM
                && (b[1] - park.1).abs() <= HOST_PARK_TOL_MM)
    };
    let layers: Vec<(u64, u32)> = fw
        .notes
        .iter()
        .filter_map(|r| match *r {
            Record::Layer { layer, t_us } => Some((t_us, layer)),
            _ => None,
        })
        .collect();
    let layer_at = |t_us: u64| -> Option<u32> {
        layers
            .iter()
            .take_while(|(t, _)| *t <= t_us)
            .last()
            .map(|x| x.1)
    };
    let fw_stop_in = |a: u64, b: u64| {
        pauses.iter().any(|p| {
            p.stopped.is_some_and(|(t, ..)| t >= a && t <= b)
                || (p.t_req_us >= a && p.t_req_us <= b)
        })
    };
    let extrudes = |r: &crate::recorder::SegRecord| {
        r.tag.lane == Lane::Job
            && r.end[3] > r.start[3]
            && (r.end[0] != r.start[0] || r.end[1] != r.start[1])
    };
    let mut out = Vec::new();
    let mut last_ext: Option<&crate::recorder::SegRecord> = None;
    let mut longest_gap = (0u64, 0u64); // (length, start) since the last extruding move
    let mut still_at = [0i32; 4]; // where the head stood during that standstill
    let mut prev_end: Option<u64> = None;
    let mut prev_pos = [0i32; 4];
    // Block end positions after the longest standstill since the last extruding move.
    let mut after_gap: Vec<[i32; 4]> = Vec::new();
    for r in &rec.records {
        if let Some(pe) = prev_end {
            let gap = r.t_start_us.saturating_sub(pe);
            if last_ext.is_some() && gap > longest_gap.0 {
                longest_gap = (gap, pe);
                still_at = prev_pos;
                after_gap.clear();
            }
        }
        prev_end = Some(r.t_end_us);
        prev_pos = r.end;
        if !extrudes(r) {
            after_gap.push(r.end);
            continue;
        }
        if let Some(le) = last_ext {
            let (gap, gap_start) = longest_gap;
            if gap >= HOST_STOP_MIN_US
                && parked(&le.end, &still_at)
                && !fw_stop_in(le.t_end_us, r.t_start_us)
            {
                let before = layer_at(le.t_start_us);
                let after = layer_at(r.t_start_us);
                // The host's return: the closest any position after the standstill (up to the
                // start of this extruding move) comes to the stop point.
                let err = after_gap
                    .iter()
                    .chain(std::iter::once(&r.start))
                    .map(|p| max_abs_diff(&le.end, p))
                    .min()
                    .unwrap_or(0);
                out.push(PauseReport {
                    mode: "host".into(),
                    stopped_at_layer_boundary: before != after,
                    first_boundary_after_request: before != after,
                    stop_layer: before,
                    pause_point_steps: Some(le.end),
                    resume_position_error_steps: Some(err),
                    parked_s: Some(gap_start as f64 * 1e-6),
                    resumed_s: Some(r.t_start_us as f64 * 1e-6),
                    paused_s: Some(gap as f64 * 1e-6),
                    ..base.clone()
                });
            }
        }
        last_ext = Some(r);
        longest_gap = (0, 0);
        after_gap.clear();
    }
    out
}
