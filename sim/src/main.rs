//! `sim`: run the firmware on virtual time. See `docs/sim.md`.
use anyhow::Context;
use clap::{Parser, Subcommand};
use sim::exec::PrinterFactory;
use sim::run::{Mode, PauseWhen, Policy, Scenario};
use std::io::Write as _;
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "sim",
    version,
    about = "Runs the printer firmware on virtual time"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Print a G-code file on the virtual printer, optionally with a pause, and measure it.
    Run(RunArgs),
    /// The latency experiments as a grid on built-in patterns (the paper's zigzag).
    Lab(LabArgs),
    /// The main demo: a built-in job with a pause mid-layer, every policy side by side.
    Demo(DemoArgs),
    /// A virtual printer on a pseudo-terminal for Pronterface/printcore/OctoPrint.
    Serve(sim::serve::ServeArgs),
    /// Print a built-in job's G-code (`zigzag` with --len, or `demo`).
    Pattern(PatternArgs),
}

#[derive(clap::Args)]
struct PatternArgs {
    /// `zigzag` or `demo`.
    name: String,
    /// Zigzag line length, mm.
    #[arg(long, default_value_t = 10.0)]
    len: f64,
    /// Zigzag speed, mm/s.
    #[arg(long, default_value_t = 30.0)]
    feed: f64,
}

#[derive(clap::Args)]
struct RunArgs {
    /// G-code file.
    file: PathBuf,
    /// Request a pause at this time after the start, seconds.
    #[arg(long, conflicts_with = "pause_at_layer")]
    pause_at: Option<f64>,
    /// Schedule a pause before layer N starts (`M761 L<N>`): layers count from 1 in print
    /// order, as the slicers' previews number them (turns of a spiral vase included).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pause_at_layer: Option<u32>,
    /// Pause mode.
    #[arg(long, value_enum, default_value = "layer")]
    mode: Mode,
    /// Policy.
    #[arg(long, value_enum, default_value = "firmware")]
    policy: Policy,
    /// Resume this long after the printer has parked, seconds (default 10; negative: never).
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    resume_after: f64,
    /// Print one JSON object instead of a summary.
    #[arg(long)]
    json: bool,
    /// Baud rate of the host link.
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// Queue size (moves) of the conventional policies.
    #[arg(long, default_value_t = 16)]
    buffer: usize,
    /// Planner segment length of the firmware policy, mm (default: the firmware's).
    #[arg(long)]
    segment: Option<f32>,
    /// Piece length of host-split, mm.
    #[arg(long, default_value_t = 0.2)]
    split: f64,
    /// Also measure the print-time cost of segmentation (one more run without it).
    #[arg(long)]
    seg_cost: bool,
    /// Send comments too (printcore and OctoPrint strip them; the firmware then finds layers
    /// by Z rise instead of the slicer's markers).
    #[arg(long)]
    keep_comments: bool,
}

#[derive(clap::Args)]
struct LabArgs {
    /// Line lengths L, mm (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "1,2,5,10,20,50,100")]
    lengths: Vec<f64>,
    /// Speeds, mm/s.
    #[arg(long, value_delimiter = ',', default_value = "30")]
    feeds: Vec<f64>,
    /// Queue sizes of the conventional policies, moves.
    #[arg(long, value_delimiter = ',', default_value = "16")]
    buffers: Vec<usize>,
    /// Segment lengths of the firmware policy, mm.
    #[arg(long, value_delimiter = ',', default_value = "0.2")]
    segments: Vec<f32>,
    /// Policies.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "fifo,host-split,firmware"
    )]
    policies: Vec<Policy>,
    /// Modes.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "layer,now")]
    modes: Vec<Mode>,
    /// Output directory for lab.csv and lab.svg.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Print the rows as JSON too.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct DemoArgs {
    /// Output directory for the picture and the JSON.
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

fn main() {
    let cli = Cli::parse();
    let r = match cli.cmd {
        Cmd::Run(a) => cmd_run(a),
        Cmd::Lab(a) => cmd_lab(a),
        Cmd::Demo(a) => sim::demo::run_demo(&a.out),
        Cmd::Serve(a) => sim::serve::serve(a),
        Cmd::Pattern(a) => cmd_pattern(a),
    };
    if let Err(e) = r {
        eprintln!("sim: {e:#}");
        std::process::exit(1);
    }
}

fn cmd_run(a: RunArgs) -> anyhow::Result<()> {
    let text = std::fs::read(&a.file).with_context(|| format!("reading {}", a.file.display()))?;
    // One buffer for the whole file (no copy when it is valid UTF-8): memory stays flat with
    // job length (docs/sim.md).
    let text = String::from_utf8(text)
        .unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned());
    let lines = sim::job::JobLines::from_text(text)?;
    let mut sc = Scenario::new(a.policy, a.mode);
    sc.pause = match (a.pause_at, a.pause_at_layer) {
        (Some(t), _) => {
            if !(t.is_finite() && t >= 0.0) {
                anyhow::bail!("--pause-at must be a time ≥ 0 in seconds");
            }
            Some(PauseWhen::AtUs((t * 1e6) as u64))
        }
        (None, Some(n)) => Some(PauseWhen::AtLayer(n)),
        _ => None,
    };
    sc.resume_after_us = if a.resume_after >= 0.0 && a.resume_after.is_finite() {
        Some((a.resume_after * 1e6) as u64)
    } else {
        None
    };
    sc.link.baud = a.baud.max(300);
    sc.link.strip_comments = !a.keep_comments;
    sc.queue_limit = a.buffer.max(2);
    sc.segment_len_mm = a.segment;
    sc.split_mm = a.split;
    sc.measure_segmentation_cost = a.seg_cost;
    // Without a pause nothing reads the executed-block record: do not keep it.
    sc.keep_records = false;
    let pb = indicatif::ProgressBar::new_spinner();
    if !a.json {
        pb.set_message(format!(
            "simulating {} ({} lines)",
            a.file.display(),
            lines.len()
        ));
        pb.enable_steady_tick(std::time::Duration::from_millis(200));
    }
    let out = sim::run::run_job(&PrinterFactory, &sc, lines)?;
    pb.finish_and_clear();
    // A job that should have finished and did not is a failure (exit status 1), after the
    // report is printed.
    let unfinished = sim::run::unfinished(&sc, &out);
    let mut o = stdout();
    if a.json {
        writeln!(o, "{}", serde_json::to_string_pretty(&out.report)?).context(STDOUT)?;
        o.flush().context(STDOUT)?;
        return unfinished.map_or(Ok(()), |why| Err(anyhow::anyhow!(why)));
    }
    let r = &out.report;
    writeln!(
        o,
        "{} — policy {}, mode {}",
        a.file.display(),
        r.policy,
        r.mode
    )
    .context(STDOUT)?;
    for ev in &out.timeline {
        writeln!(o, "  {:>10.3} s  {}", ev.t_s, ev.what).context(STDOUT)?;
    }
    writeln!(o, "{}", sim::demo::summary(r)).context(STDOUT)?;
    o.flush().context(STDOUT)?;
    unfinished.map_or(Ok(()), |why| Err(anyhow::anyhow!(why)))
}

/// What a failed write to standard output says (a closed pipe, a full disk).
const STDOUT: &str = "writing to standard output";

/// Standard output, buffered, written with `writeln!(…).context(STDOUT)?`: a closed pipe
/// (`sim run … | head -1`) or a full disk is a clean error and exit status 1, never a panic
/// as `println!` would make it.
fn stdout() -> std::io::BufWriter<std::io::StdoutLock<'static>> {
    std::io::BufWriter::new(std::io::stdout().lock())
}

fn cmd_lab(a: LabArgs) -> anyhow::Result<()> {
    let grid = sim::lab::Grid {
        lengths_mm: a.lengths,
        feeds_mm_s: a.feeds,
        buffers: a.buffers,
        segments_mm: a.segments,
        policies: a.policies,
        modes: a.modes,
        ..sim::lab::Grid::default()
    };
    let cells = sim::lab::cells(&grid);
    let pb = indicatif::ProgressBar::new(cells.len() as u64);
    pb.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut rows = Vec::new();
    for (l, f, b, s, p, m) in cells {
        pb.set_message(format!("L={l} {} {}", p.name(), m.name()));
        rows.push(sim::lab::run_cell(&grid, l, f, b, s, p, m)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mut o = stdout();
    writeln!(o, "{}", sim::lab::table(&rows)).context(STDOUT)?;
    for v in sim::lab::verdicts(&rows) {
        writeln!(o, "{v}").context(STDOUT)?;
    }
    sim::lab::write_outputs(&rows, &a.out)?;
    writeln!(
        o,
        "wrote {} and {}",
        a.out.join("lab.csv").display(),
        a.out.join("lab.svg").display()
    )
    .context(STDOUT)?;
    if a.json {
        writeln!(o, "{}", serde_json::to_string_pretty(&rows)?).context(STDOUT)?;
    }
    o.flush().context(STDOUT)
}

fn cmd_pattern(a: PatternArgs) -> anyhow::Result<()> {
    let lines = match a.name.as_str() {
        "zigzag" => {
            if !(a.len.is_finite() && a.len > 0.0 && a.feed.is_finite() && a.feed > 0.0) {
                anyhow::bail!("--len and --feed must be positive");
            }
            let mut z = sim::patterns::Zigzag::paper(a.len);
            z.feed_mm_s = a.feed;
            z.gcode().0
        }
        "demo" => sim::patterns::demo_part(3),
        other => anyhow::bail!("unknown pattern {other:?} (zigzag, demo)"),
    };
    let mut o = stdout();
    for l in lines {
        writeln!(o, "{l}").context(STDOUT)?;
    }
    o.flush().context(STDOUT)
}
