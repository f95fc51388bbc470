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
    /// Let E move below the minimum hotend temperature, as `M302 P1` does (by default the
    /// cold-extrusion guard is on, as on the board: the file must heat first).
    #[arg(long)]
    allow_cold_extrusion: bool,
    /// Exit 0 even when the printer refused lines (they are still reported).
    #[arg(long)]
    allow_refused: bool,
    /// Give up after this many hours of virtual time (default: no limit; a job that stops
    /// moving and taking lines ends the run after 3 virtual hours, see docs/sim.md).
    #[arg(long)]
    max_hours: Option<f64>,
    /// The printer: a built-in profile (ender3, k1max, prusa-mk4, prusa-mini, bambu-x1,
    /// voron300) or a machine file, the same as `sim serve --machine` (see docs/sim.md).
    /// Default: the Ender-3.
    #[arg(long)]
    machine: Option<String>,
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
    /// Compare with the emulated board's report of `board-demo.gcode` (scripts/demo.sh runs
    /// board-emu on it): both timelines, both stop points, `board-demo.svg`.
    #[arg(long)]
    compare_board: Option<PathBuf>,
}

fn main() {
    let cli = Cli::parse();
    let r = match cli.cmd {
        Cmd::Run(a) => cmd_run(a),
        Cmd::Lab(a) => cmd_lab(a),
        Cmd::Demo(a) => match &a.compare_board {
            Some(r) => sim::demo_board::compare(&a.out, r),
            // The demo, then the job and the request for the emulated board's run.
            None => sim::demo::run_demo(&a.out).and_then(|_| sim::demo_board::prepare(&a.out)),
        },
        Cmd::Serve(a) => sim::serve::serve(a),
        Cmd::Pattern(a) => cmd_pattern(a),
    };
    if let Err(e) = r {
        eprintln!("sim: {e:#}");
        std::process::exit(1);
    }
}

/// A number from the command line inside `range`, or an error naming the option.
fn in_range<T: PartialOrd + std::fmt::Display + Copy>(
    name: &str,
    v: T,
    range: std::ops::RangeInclusive<T>,
) -> anyhow::Result<T> {
    if range.contains(&v) {
        Ok(v)
    } else {
        anyhow::bail!("--{name} {v}: outside {}..={}", range.start(), range.end())
    }
}

/// A finite number from the command line inside `range` (NaN is outside every range).
fn finite_in(name: &str, v: f64, range: std::ops::RangeInclusive<f64>) -> anyhow::Result<f64> {
    in_range(name, v, range)
}

/// Longest virtual time an option may name, s (ten years: every sum of times stays far
/// inside the µs clock's `u64`).
const MAX_TIME_S: f64 = 10.0 * 365.0 * 86_400.0;

/// Seconds from the command line as µs (finite, `0..=MAX_TIME_S`).
fn seconds_us(name: &str, s: f64) -> anyhow::Result<u64> {
    if !s.is_finite() {
        anyhow::bail!("--{name} {s}: not a number of seconds");
    }
    Ok((in_range(name, s, 0.0..=MAX_TIME_S)? * 1e6) as u64)
}

/// The scenario `sim run` runs: every number checked against what the firmware and the host
/// model accept (never a panic, never a run the firmware would not make).
fn run_scenario(a: &RunArgs) -> anyhow::Result<Scenario> {
    let mut sc = Scenario::new(a.policy, a.mode);
    sc.pause = match (a.pause_at, a.pause_at_layer) {
        (Some(t), _) => Some(PauseWhen::AtUs(seconds_us("pause-at", t)?)),
        (None, Some(n)) => Some(PauseWhen::AtLayer(n)),
        _ => None,
    };
    sc.resume_after_us = if a.resume_after.is_nan() {
        anyhow::bail!("--resume-after NaN: not a number of seconds");
    } else if a.resume_after >= 0.0 {
        Some(seconds_us("resume-after", a.resume_after)?)
    } else {
        None
    };
    sc.link.baud = in_range("baud", a.baud, 300..=4_000_000)?;
    sc.link.strip_comments = !a.keep_comments;
    // A conventional firmware's queue: 2 moves up to what the firmware's queues hold.
    let most = firmware::planner::RING_CAPACITY + 1;
    sc.queue_limit = in_range("buffer", a.buffer, 2..=most)?;
    // What M760 L accepts (the firmware's range table): shorter segments flood the ring.
    sc.segment_len_mm = match a.segment {
        Some(l) => {
            let b = firmware::ranges::SEGMENT;
            Some(in_range("segment", l, b.min..=b.max)?)
        }
        None => None,
    };
    sc.split_mm = in_range("split", a.split, 0.01..=1000.0)?;
    sc.measure_segmentation_cost = a.seg_cost;
    sc.allow_cold = a.allow_cold_extrusion;
    if let Some(h) = a.max_hours {
        if !h.is_finite() {
            anyhow::bail!("--max-hours {h}: not a number");
        }
        sc.max_time_us = seconds_us(
            "max-hours",
            in_range("max-hours", h, 0.001..=87_600.0)? * 3600.0,
        )?;
    }
    if let Some(m) = &a.machine {
        sc.machine = sim::machines::Machine::load(m)?.config;
    }
    // Without a pause nothing reads the executed-block record: do not keep it.
    sc.keep_records = false;
    Ok(sc)
}

/// The refused lines as `sim run` reports them (JSON field `refused_lines`).
#[derive(serde::Serialize)]
struct RefusedLines {
    /// Job lines the printer refused.
    count: u64,
    /// The first ones: line number in the file (1-based), the line, the printer's reply.
    first: Vec<RefusedJson>,
}

#[derive(serde::Serialize)]
struct RefusedJson {
    line: usize,
    text: String,
    reply: String,
}

/// `sim run --json`: the pause report and the refused lines.
#[derive(serde::Serialize)]
struct RunJson<'a> {
    #[serde(flatten)]
    report: &'a sim::metrics::PauseReport,
    /// The printer's name (`--machine`).
    machine: &'a str,
    /// Why the pause did not stop where the layer reference says it must (`null`: it did, or
    /// nothing to judge); the run then exits non-zero.
    layer_verdict: Option<String>,
    refused_lines: RefusedLines,
    /// Lines the printer did not know (start-code macros the sim cannot run: `PRINT_START` …).
    unknown_commands: RefusedLines,
    /// Lines longer than the host model reads (`sim::job::MAX_LINE_BYTES`), sent cut.
    cut_lines: u64,
}

fn cmd_run(a: RunArgs) -> anyhow::Result<()> {
    let sc = run_scenario(&a)?;
    // The file is streamed (read again by each engine), never held whole (docs/sim.md).
    let lines = sim::job::JobLines::open(&a.file)
        .with_context(|| format!("reading {}", a.file.display()))?;
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
    // report is printed; so are refused lines (unless --allow-refused).
    let unfinished = sim::run::unfinished(&sc, &out);
    let verdict = sim::run::layer_verdict(&sc, &out);
    let listed = |l: &sim::hostlink::Refusals| RefusedLines {
        count: l.count,
        first: l
            .first
            .iter()
            .map(|r| RefusedJson {
                line: r.index + 1,
                text: r.text.clone(),
                reply: r.reply.clone(),
            })
            .collect(),
    };
    let refused = listed(&out.refused);
    let unknown = listed(&out.unknown);
    let failure = match (unfinished, &verdict, refused.count) {
        (Some(why), _, _) => Some(why),
        (None, Some(why), _) => Some(why.clone()),
        (None, None, 0) => None,
        (None, None, _) if a.allow_refused => None,
        (None, None, n) => Some(format!(
            "the printer refused {n} line{} of the job (--allow-refused to accept that)",
            if n == 1 { "" } else { "s" }
        )),
    };
    let machine_name = match &a.machine {
        Some(m) => sim::machines::Machine::load(m)?.name,
        None => sim::machines::Machine::ender3().name,
    };
    let mut o = stdout();
    if a.json {
        let j = RunJson {
            report: &out.report,
            machine: &machine_name,
            layer_verdict: verdict,
            refused_lines: refused,
            unknown_commands: unknown,
            cut_lines: out.cut_lines,
        };
        writeln!(o, "{}", serde_json::to_string_pretty(&j)?).context(STDOUT)?;
        o.flush().context(STDOUT)?;
        return failure.map_or(Ok(()), |why| Err(anyhow::anyhow!(why)));
    }
    let r = &out.report;
    writeln!(
        o,
        "{} — {}, policy {}, mode {}",
        a.file.display(),
        machine_name,
        r.policy,
        r.mode
    )
    .context(STDOUT)?;
    for ev in &out.timeline {
        writeln!(o, "  {:>10.3} s  {}", ev.t_s, ev.what).context(STDOUT)?;
    }
    writeln!(o, "{}", sim::demo::summary(r)).context(STDOUT)?;
    if let Some(why) = &verdict {
        writeln!(o, "layer verdict (layerref): FAILED: {why}").context(STDOUT)?;
    }
    for (what, list) in [
        ("refused lines", &refused),
        (
            "lines the printer does not know (macros the sim cannot run)",
            &unknown,
        ),
    ] {
        if list.count == 0 {
            continue;
        }
        writeln!(o, "{what}: {}", list.count).context(STDOUT)?;
        for f in &list.first {
            writeln!(o, "  line {}: {}  →  {}", f.line, f.text, f.reply).context(STDOUT)?;
        }
        if list.count > list.first.len() as u64 {
            writeln!(o, "  … ({} more)", list.count - list.first.len() as u64).context(STDOUT)?;
        }
    }
    if out.cut_lines > 0 {
        writeln!(
            o,
            "{} line(s) longer than {} bytes were sent cut",
            out.cut_lines,
            sim::job::MAX_LINE_BYTES
        )
        .context(STDOUT)?;
    }
    o.flush().context(STDOUT)?;
    failure.map_or(Ok(()), |why| Err(anyhow::anyhow!(why)))
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
    for &l in &a.lengths {
        finite_in("lengths", l, 0.01..=10_000.0)?;
    }
    for &f in &a.feeds {
        finite_in("feeds", f, 0.1..=2_000.0)?;
    }
    for &b in &a.buffers {
        in_range("buffers", b, 2..=firmware::planner::RING_CAPACITY + 1)?;
    }
    let seg = firmware::ranges::SEGMENT;
    for &s in &a.segments {
        in_range("segments", s, seg.min..=seg.max)?;
    }
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
            finite_in("len", a.len, 0.01..=10_000.0)?;
            finite_in("feed", a.feed, 0.1..=2_000.0)?;
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
