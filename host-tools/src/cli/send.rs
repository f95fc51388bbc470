//! `host-tools send FILE.gcode --port PORT`: streams a job to a printer (or to `sim serve`'s
//! pseudo-terminal) with line numbers and checksums, pauses at a layer boundary (our firmware's
//! pause, or the host-side method on stock firmware), lets the rest of the job be edited while
//! paused, and resumes. A terminal UI when stdout is a terminal, plain log lines otherwise.
//!
//! Unattended: `--pause-at-layer N`, `--pause-now-at S`, `--resume-after S`, `--swap-at-pause
//! FILE`. Exit status 0 when the job completes; non-zero with a message otherwise.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};

use crate::job::sender::fallback::HostPause;
use crate::job::sender::tui::{fmt_duration, Snapshot, Tui, UiAction};
use crate::job::sender::{Event, Options, PauseMethod, Request, Session, State};
use crate::job::{ops, Job};

/// Pause method choice on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodArg {
    /// Detect from M115: our firmware's pause when advertised, else the host-side method.
    Auto,
    /// Our firmware's layer-aware pause (realtime M25 / M25 S1 / M24).
    Firmware,
    /// The host-side method for stock firmware (split moves, pause sequence at the layer end).
    Host,
}

/// Arguments of `host-tools send`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// G-code file to print.
    pub file: PathBuf,
    /// Serial port or pseudo-terminal path (e.g. /dev/ttyUSB0, or the path `sim serve` prints).
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 115200)]
    pub baud: u32,
    /// Pause before layer N starts: the n-th layer printed, from 1 (the slicer preview's number;
    /// `M761 L<n>`, `M27` and the sim count the same way: docs/planner.md, "What a layer is").
    #[arg(long)]
    pub pause_at_layer: Option<u32>,
    /// Pause now (mid-layer) this many seconds after the job starts.
    #[arg(long)]
    pub pause_now_at: Option<f64>,
    /// Resume this many seconds after each pause (unattended runs).
    #[arg(long)]
    pub resume_after: Option<f64>,
    /// At the first pause at a layer boundary, continue with this re-sliced file from the next
    /// unprinted layer (layers the print already covers are skipped by Z).
    #[arg(long)]
    pub swap_at_pause: Option<PathBuf>,
    /// Pause method.
    #[arg(long, value_enum, default_value_t = MethodArg::Auto)]
    pub method: MethodArg,
    /// Host-side method: longest move piece, mm (0.1–0.2; 0 = no splitting).
    #[arg(long, default_value_t = 0.2)]
    pub split_mm: f64,
    /// Host-side method: park X, mm (back corner).
    #[arg(long)]
    pub park_x: Option<f64>,
    /// Host-side method: park Y, mm (back corner).
    #[arg(long)]
    pub park_y: Option<f64>,
    /// Host-side method: retract at the pause, mm.
    #[arg(long)]
    pub retract: Option<f64>,
    /// Host-side method: Z lift before parking, mm (0 = the paper's sequence).
    #[arg(long)]
    pub lift: Option<f64>,
    /// Feed factor for the rest of the layer after a layer pause request (paper: ×3; 1 = off).
    /// Host-side method: applied by the sender; our firmware: sent as `M760 S`. Default: the
    /// firmware's `PauseConfig` (3).
    #[arg(long)]
    pub speedup: Option<f64>,
    /// Highest volumetric flow the extruder can melt, mm³/s: bounds the speed-up of extruding
    /// moves. Host-side: applied by the sender; our firmware: sent as `M760 V`. Default: the
    /// firmware's `PauseConfig` (12).
    #[arg(long)]
    pub max_flow: Option<f64>,
    /// Filament diameter, mm, for the flow bound of the host-side speed-up.
    #[arg(long, default_value_t = 1.75)]
    pub filament_diameter: f64,
    /// Plain log lines even on a terminal (no TUI).
    #[arg(long)]
    pub plain: bool,
    /// Seconds to wait for the printer to answer.
    #[arg(long, default_value_t = 30.0)]
    pub connect_timeout: f64,
    /// Print every line received from the printer (plain mode).
    #[arg(long)]
    pub verbose: bool,
}

fn load_job(path: &Path) -> anyhow::Result<Job> {
    let text = crate::fileio::read_text_bounded(path, crate::fileio::Limit::Gcode)?;
    Job::from_gcode(&text).with_context(|| format!("reading the job in {}", path.display()))
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let job = load_job(&args.file)?;
    let swap = match &args.swap_at_pause {
        Some(p) => Some(load_job(p)?),
        None => None,
    };
    let pause_at = match args.pause_at_layer {
        Some(n) => match job.index_of_layer(n) {
            Some(i) => Some(i),
            None => bail!(
                "--pause-at-layer {n}: the job has {} layers (1..{}; layers count from 1)",
                job.layers.len(),
                job.layers.len()
            ),
        },
        None => None,
    };
    let mut hp = HostPause {
        split_mm: args.split_mm,
        ..HostPause::default()
    };
    if let Some(v) = args.park_x {
        hp.park_xy_mm.0 = v;
    }
    if let Some(v) = args.park_y {
        hp.park_xy_mm.1 = v;
    }
    if let Some(v) = args.retract {
        hp.retract_mm = v;
    }
    if let Some(v) = args.lift {
        hp.lift_mm = v;
    }
    if let Some(v) = args.speedup {
        if !(1.0..=10.0).contains(&v) {
            bail!("--speedup {v}: expected a factor from 1 (off) to 10");
        }
        hp.speedup_factor = v;
    }
    if let Some(v) = args.max_flow {
        if !(v > 0.0 && v <= 100.0) {
            bail!("--max-flow {v}: expected mm³/s above 0 and at most 100");
        }
        hp.max_volumetric_mm3_s = v;
    }
    if !(args.filament_diameter > 0.5 && args.filament_diameter < 5.0) {
        bail!(
            "--filament-diameter {}: expected mm, e.g. 1.75 or 2.85",
            args.filament_diameter
        );
    }
    hp.filament_diameter_mm = args.filament_diameter;
    // Our firmware speeds the layer up itself: pass the flags on (M760).
    let mut firmware_setup = Vec::new();
    if args.speedup.is_some() || args.max_flow.is_some() {
        let mut l = "M760".to_string();
        if let Some(v) = args.speedup {
            l.push_str(&format!(" S{v}"));
        }
        if let Some(v) = args.max_flow {
            l.push_str(&format!(" V{v}"));
        }
        firmware_setup.push(l);
    }
    let port = serialport::new(&args.port, args.baud)
        .timeout(Duration::from_millis(5))
        .open()
        .with_context(|| format!("opening {}", args.port))?;
    let opts = Options {
        method: match args.method {
            MethodArg::Auto => None,
            MethodArg::Firmware => Some(PauseMethod::Firmware),
            MethodArg::Host => Some(PauseMethod::HostSide),
        },
        host_pause: hp,
        firmware_setup,
        connect_timeout: Duration::from_secs_f64(args.connect_timeout.max(0.1)),
        ..Options::default()
    };
    let file_name = args
        .file
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut session = Session::new(port, job, opts);
    session.set_rx_log(args.verbose);
    if let Some(i) = pause_at {
        session.pause_before_layer(i);
    }
    let use_tui = !args.plain && std::io::stdout().is_terminal();
    let mut ui = if use_tui { Some(Tui::start()?) } else { None };
    let stdin_cmds = if use_tui {
        None
    } else {
        Some(stdin_commands())
    };
    let mut driver = Driver {
        swap,
        resume_after: args.resume_after.map(Duration::from_secs_f64),
        pause_now_at: args.pause_now_at.map(Duration::from_secs_f64),
        paused_since: None,
        messages: Vec::new(),
        plain: !use_tui,
    };
    let t0 = Instant::now();
    let mut last_draw = Duration::ZERO;
    loop {
        let now = t0.elapsed();
        session.poll(now).context("serial port")?;
        for l in session.take_rx_log() {
            driver.log(now, format!("< {l}"));
        }
        for ev in session.drain_events() {
            driver.on_event(&mut session, ev, now)?;
        }
        driver.unattended(&mut session, now)?;
        if let Some(rx) = &stdin_cmds {
            while let Ok(cmd) = rx.try_recv() {
                match parse_stdin_command(&cmd) {
                    Some(a) => driver.apply(&mut session, a, now)?,
                    None => driver.log(now, format!("unknown command {cmd:?}")),
                }
            }
        }
        if let Some(t) = ui.as_mut() {
            let editable = matches!(
                session.state(),
                State::Paused {
                    boundary: Some(_),
                    ..
                }
            );
            if let Some(a) = t.poll_action(Duration::ZERO, editable)? {
                driver.apply(&mut session, a, now)?;
            }
            if now.saturating_sub(last_draw) >= Duration::from_millis(100) || session.finished() {
                last_draw = now;
                t.draw(&snapshot(&session, &file_name, &driver.messages, now))?;
            }
        }
        if session.finished() {
            break;
        }
    }
    drop(ui);
    let now = t0.elapsed();
    match session.state() {
        State::Done => {
            println!(
                "job complete: {} layers, {} lines written, {} resends, {}",
                session.progress().layers,
                session.progress().lines_written,
                session.progress().resends,
                fmt_duration(session.elapsed_s(now))
            );
            Ok(())
        }
        State::Cancelled => bail!("the job was cancelled"),
        State::Failed(m) => bail!("{m}"),
        other => bail!("stopped in state {other:?}"),
    }
}

fn snapshot<P: std::io::Read + std::io::Write>(
    s: &Session<P>,
    file: &str,
    messages: &[String],
    now: Duration,
) -> Snapshot {
    let p = s.progress();
    Snapshot {
        file: file.to_string(),
        state: state_text(s.state(), s.job()),
        method: match s.method() {
            Some(PauseMethod::Firmware) => "firmware layer pause".into(),
            Some(PauseMethod::HostSide) => "host-side pause (stock firmware)".into(),
            None => "connecting".into(),
        },
        fraction: if p.est_total_s > 0.0 {
            p.est_done_s / p.est_total_s
        } else {
            0.0
        },
        layer: p.layer.map(|l| (l + 1, p.layers)),
        temps: p.temps,
        elapsed_s: s.elapsed_s(now),
        left_s: s.time_left_s(now),
        editable: matches!(
            s.state(),
            State::Paused {
                boundary: Some(_),
                ..
            }
        ),
        messages: messages.to_vec(),
    }
}

fn state_text(s: &State, job: &Job) -> String {
    match s {
        State::Paused {
            boundary: Some(b),
            prompt: None,
        } => format!(
            "paused before {}; the rest of the job can be edited",
            job.boundary_name(*b)
        ),
        State::Paused {
            prompt: Some(p), ..
        } => format!("waiting for you: {p} (r to resume)"),
        State::Paused { .. } => "paused".into(),
        State::Failed(m) => format!("failed: {m}"),
        other => format!("{other:?}").to_lowercase(),
    }
}

struct Driver {
    swap: Option<Job>,
    resume_after: Option<Duration>,
    pause_now_at: Option<Duration>,
    paused_since: Option<Duration>,
    messages: Vec<String>,
    plain: bool,
}

impl Driver {
    fn log(&mut self, now: Duration, msg: String) {
        let line = format!("[{:8.2}s] {msg}", now.as_secs_f64());
        if self.plain {
            println!("{line}");
        }
        self.messages.push(line);
        if self.messages.len() > 200 {
            self.messages.drain(..100);
        }
    }

    fn on_event<P: std::io::Read + std::io::Write>(
        &mut self,
        s: &mut Session<P>,
        ev: Event,
        now: Duration,
    ) -> anyhow::Result<()> {
        match ev {
            Event::Connected(m) => {
                let fw = s.capabilities().firmware.clone().unwrap_or_default();
                self.log(now, format!("connected: {fw}; pause method {m:?}"));
            }
            Event::Layer(i) => {
                let n = s.job().layers.len();
                let name = s.job().boundary_name(i);
                self.log(now, format!("sending {name} ({}/{n})", i + 1));
            }
            Event::Pausing => self.log(now, "pausing".into()),
            Event::Paused(b) => {
                self.paused_since = Some(now);
                match b {
                    Some(b) if s.pause_was_now() => self.log(
                        now,
                        format!(
                            "paused now (mid-layer); edits apply from {}, the first not yet sent",
                            s.job().boundary_name(b)
                        ),
                    ),
                    Some(b) => self.log(
                        now,
                        format!("paused at the boundary before {}", s.job().boundary_name(b)),
                    ),
                    None => self.log(now, "paused".into()),
                }
                if let (Some(new), Some(_)) = (self.swap.take(), b) {
                    let r = s.edit_job(|job, at| ops::continue_with(job, at, &new));
                    match r {
                        Ok(r) => self.log(
                            now,
                            format!(
                                "swapped in the re-sliced file: printed top Z {:.3} mm, continuing with its {} ({} covered layers skipped, flow x{:.2}, {} layers)",
                                r.top_mm, new.boundary_name(r.first_new_layer), r.skipped_covered, r.flow_factor, r.layers_added
                            ),
                        ),
                        Err(e) => bail!("cannot swap in the re-sliced file: {e}"),
                    }
                }
            }
            Event::Resumed => {
                self.paused_since = None;
                self.log(now, "resumed".into());
            }
            Event::Message(m) => self.log(now, format!("printer: {m}")),
            Event::Note(m) => self.log(now, format!("note: {m}")),
            Event::PrinterError(e) => self.log(now, format!("printer error: {e}")),
            Event::Resend(n) => self.log(now, format!("resend from line {n}")),
            Event::Action(a) => self.log(now, format!("action: {a:?}")),
            Event::Done => self.log(now, "job complete".into()),
            Event::Cancelled => self.log(now, "cancelled".into()),
            Event::Failed(m) => self.log(now, format!("failed: {m}")),
        }
        Ok(())
    }

    fn unattended<P: std::io::Read + std::io::Write>(
        &mut self,
        s: &mut Session<P>,
        now: Duration,
    ) -> anyhow::Result<()> {
        if let Some(t) = self.pause_now_at {
            if s.state() == &State::Printing && s.elapsed_s(now) >= t.as_secs_f64() {
                self.pause_now_at = None;
                self.log(now, "pause now (--pause-now-at)".into());
                s.request(Request::PauseNow, now)?;
            }
        }
        if let (Some(after), Some(since)) = (self.resume_after, self.paused_since) {
            if matches!(s.state(), State::Paused { .. }) && now.saturating_sub(since) >= after {
                self.paused_since = None;
                self.log(now, "resume (--resume-after)".into());
                s.request(Request::Resume, now)?;
            }
        }
        Ok(())
    }

    fn apply<P: std::io::Read + std::io::Write>(
        &mut self,
        s: &mut Session<P>,
        a: UiAction,
        now: Duration,
    ) -> anyhow::Result<()> {
        let req = match &a {
            UiAction::PauseAtLayer => Some(Request::PauseAtLayer),
            UiAction::PauseNow => Some(Request::PauseNow),
            UiAction::Resume => Some(Request::Resume),
            UiAction::Cancel => Some(Request::Cancel),
            UiAction::EmergencyStop => Some(Request::EmergencyStop),
            _ => None,
        };
        if let Some(r) = req {
            s.request(r, now)?;
            return Ok(());
        }
        let result: Result<String, String> = match a {
            UiAction::Swap(path) => match load_job(Path::new(&path)) {
                Ok(new) => s
                    .edit_job(|job, at| ops::continue_with(job, at, &new))
                    .map(|r| {
                        format!(
                            "continuing with {path} from its {} (flow x{:.2})",
                            new.boundary_name(r.first_new_layer),
                            r.flow_factor
                        )
                    })
                    .map_err(|e| e.to_string()),
                Err(e) => Err(format!("{e:#}")),
            },
            UiAction::Purge => {
                let hp = HostPause::default();
                let t = ops::purge_template(hp.park_xy_mm.0 - 30.0, hp.park_xy_mm.1 - 5.0, 15.0);
                s.edit_job(|job, at| ops::insert_template(job, at, &t, 2.0))
                    .map(|n| format!("purge/wipe inserted ({n} lines)"))
                    .map_err(|e| e.to_string())
            }
            UiAction::Hair => s
                .edit_job(|job, at| {
                    let t = ops::hair_template(job, at, 24, 4.0, 0.05)?;
                    ops::insert_template(job, at, &t, 2.0)
                })
                .map(|n| format!("hair template inserted ({n} lines)"))
                .map_err(|e| e.to_string()),
            UiAction::Skip(n) => s
                .edit_job(|job, at| ops::skip_layers(job, at, n, true, 3.0))
                .map(|r| {
                    format!(
                        "skipped {n} layers (flow x{:.2} on the next)",
                        r.flow_factor
                    )
                })
                .map_err(|e| e.to_string()),
            UiAction::FilamentChange => s
                .edit_job(|job, at| ops::filament_change(job, at, &ops::FilamentChange::default()))
                .map(|_| "filament change inserted (you will be prompted after resume)".into())
                .map_err(|e| e.to_string()),
            UiAction::Template(path) => match std::fs::read_to_string(&path) {
                Ok(t) => s
                    .edit_job(|job, at| ops::insert_template(job, at, &t, 2.0))
                    .map(|n| format!("template {path} inserted ({n} lines)"))
                    .map_err(|e| e.to_string()),
                Err(e) => Err(format!("reading {path}: {e}")),
            },
            _ => Ok(String::new()),
        };
        match result {
            Ok(m) => self.log(now, m),
            Err(e) => self.log(now, format!("edit refused: {e}")),
        }
        Ok(())
    }
}

/// Plain mode reads commands from stdin, one a line: `pause`, `pause-now`, `resume`, `cancel`,
/// `swap FILE`, `purge`, `hair`, `skip N`, `filament`, `template FILE`.
fn stdin_commands() -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        loop {
            line.clear();
            match std::io::stdin().read_line(&mut line) {
                Ok(0) | Err(_) => break,
                Ok(_) => {
                    if tx.send(line.trim().to_string()).is_err() {
                        break;
                    }
                }
            }
        }
    });
    rx
}

fn parse_stdin_command(cmd: &str) -> Option<UiAction> {
    let (word, rest) = match cmd.split_once(' ') {
        Some((w, r)) => (w, r.trim()),
        None => (cmd, ""),
    };
    Some(match word {
        "pause" => UiAction::PauseAtLayer,
        "pause-now" => UiAction::PauseNow,
        "resume" => UiAction::Resume,
        "cancel" => UiAction::Cancel,
        "estop" => UiAction::EmergencyStop,
        "swap" if !rest.is_empty() => UiAction::Swap(rest.to_string()),
        "purge" => UiAction::Purge,
        "hair" => UiAction::Hair,
        "skip" => UiAction::Skip(rest.parse().ok()?),
        "filament" => UiAction::FilamentChange,
        "template" if !rest.is_empty() => UiAction::Template(rest.to_string()),
        _ => return None,
    })
}
