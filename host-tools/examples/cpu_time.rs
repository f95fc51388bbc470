//! CPU-time measurement of the README targets, for machines too loaded for wall-clock
//! benchmarks (criterion measures wall time; see `benches/design.rs`):
//! - compile the globe (45,000 modulated strings) to G-code;
//! - the printability checks cost no more than the compile (issue 15), on the globe and on
//!   the 45,000-segment helix of `scripts/bench-fullcontrol.sh`;
//! - `stats` throughput on a large file (optional argument).
//!
//! CPU time is this thread's run time from `/proc/thread-self/schedstat` (nanoseconds; the
//! design code is single-threaded), else the process's user + system ticks from
//! `/proc/self/stat`. Compile and checks are measured in alternating rounds in the same warm
//! process (each round: `n` compiles, then `n` checks of the same model) and the medians are
//! printed, so a burst of load on a shared machine shifts one round, not the figure.
//!
//! Run: `cargo run --release -p host-tools --example cpu_time [LARGE.gcode]`
//! (`CPU_TIME_N=<n>` compiles per round, default 30; `CPU_TIME_ROUNDS=<r>`, default 7).

use host_tools::design::checks::{check, CheckOptions};
use host_tools::design::model::Model;
use host_tools::design::modulate::{globe, Bitmap, Globe};
use host_tools::design::parts::Helix;
use host_tools::design::profile::Profile;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::job::stats::stats;

/// CPU seconds of this thread (or process), None off Linux.
fn cpu_s() -> Option<f64> {
    if let Ok(s) = std::fs::read_to_string("/proc/thread-self/schedstat") {
        if let Some(ns) = s
            .split_whitespace()
            .next()
            .and_then(|v| v.parse::<f64>().ok())
        {
            return Some(ns / 1e9);
        }
    }
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0) // USER_HZ is 100 on Linux
}

/// CPU milliseconds per call of `f`, over `n` calls.
fn per_call_ms(n: usize, mut f: impl FnMut()) -> anyhow::Result<f64> {
    let c0 = cpu_s().ok_or_else(|| anyhow::anyhow!("no CPU clock (Linux /proc only)"))?;
    for _ in 0..n {
        f();
    }
    let c1 = cpu_s().ok_or_else(|| anyhow::anyhow!("no CPU clock"))?;
    Ok((c1 - c0) * 1000.0 / n as f64)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
        .max(1)
}

/// Measures the compile (`build` then write) against the checks of the same model, in
/// alternating rounds, and prints the medians.
fn compile_vs_checks(
    name: &str,
    p: &Profile,
    rounds: usize,
    n: usize,
    build: impl Fn() -> anyhow::Result<Model>,
) -> anyhow::Result<()> {
    let w = GcodeWriter::new(p, WriteOptions::default());
    let mut buf = Vec::with_capacity(2 << 20);
    let model = build()?;
    let o = CheckOptions::default();
    let issues = check(&model, p, &o).total();
    let (mut compile, mut checks, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..rounds {
        let mut err = None;
        let c = per_call_ms(n, || {
            buf.clear();
            if let Err(e) = build().and_then(|m| Ok(w.write_into(&m, &mut buf)?)) {
                err = Some(e);
            }
        })?;
        if let Some(e) = err {
            return Err(e);
        }
        let k = per_call_ms(n, || {
            std::hint::black_box(check(&model, p, &o).total());
        })?;
        compile.push(c);
        checks.push(k);
        ratio.push(k / c);
    }
    let (c, k, r) = (
        median(&mut compile),
        median(&mut checks),
        median(&mut ratio),
    );
    println!(
        "{name}: compile (build + write, {} bytes) {c:.2} ms CPU, checks ({issues} issues) {k:.2} ms CPU: checks / compile {r:.2} (median of {rounds} rounds of {n}; rounds {:.2}..{:.2})",
        buf.len(),
        ratio[0],
        ratio[ratio.len() - 1],
    );
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let p = Profile::ender3();
    let map = Bitmap::world_map()?;
    // CPU_TIME_N=1 CPU_TIME_ROUNDS=1 for one compile under a profiler.
    let n = env_usize("CPU_TIME_N", 30);
    let rounds = env_usize("CPU_TIME_ROUNDS", 7);
    compile_vs_checks("globe (45,000 strings)", &p, rounds, n, || {
        Ok(globe(&Globe::default(), &map)?.0)
    })?;
    // The helix of scripts/bench-fullcontrol.sh (its `helix_part.rhai`), without the script.
    compile_vs_checks("helix (45,000 segments)", &p, rounds, n, || {
        Ok(Helix {
            radius_mm: 20.0,
            pitch_mm: 0.2,
            turns: 150.0,
            per_turn: 300,
            ..Helix::default()
        }
        .build()?)
    })?;
    if let Some(path) = std::env::args().nth(1) {
        let data = std::fs::read(&path)?;
        let reps = 5;
        let (c0, t0) = (cpu_s(), std::time::Instant::now());
        let mut t = 0.0;
        for _ in 0..reps {
            t += stats(&data, &p)
                .map_err(|e| anyhow::anyhow!("{e}"))?
                .print_time_s;
        }
        let (c1, t1) = (cpu_s(), t0.elapsed().as_secs_f64());
        if let (Some(a), Some(b)) = (c0, c1) {
            let mb = data.len() as f64 * reps as f64 / 1e6;
            println!(
                "stats on {path} ({:.1} MB): {:.0} MB/s CPU, {:.0} MB/s wall (est. {:.0} s)",
                data.len() as f64 / 1e6,
                mb / (b - a),
                mb / t1,
                t / reps as f64
            );
        }
    }
    Ok(())
}
