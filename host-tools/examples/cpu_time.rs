//! CPU-time measurement of the two README targets, for machines too loaded for wall-clock
//! benchmarks (criterion measures wall time; see `benches/design.rs`). Reads the process's
//! user+system time from `/proc/self/stat` (Linux) around many iterations.
//!
//! Run: `cargo run --release -p host-tools --example cpu_time [LARGE.gcode]`
//! (`CPU_TIME_N=<n>` sets the number of globe compiles, default 100).

use host_tools::design::checks::{check, CheckOptions};
use host_tools::design::modulate::{globe, Bitmap, Globe};
use host_tools::design::profile::Profile;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::job::stats::stats;

/// User + system CPU seconds of this process (None off Linux).
fn cpu_s() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0) // USER_HZ is 100 on Linux
}

fn main() -> anyhow::Result<()> {
    let p = Profile::ender3();
    let map = Bitmap::world_map()?;
    let w = GcodeWriter::new(&p, WriteOptions::default());
    let mut buf = Vec::with_capacity(2 << 20);
    // CPU_TIME_N=1 for one compile under a profiler (valgrind --tool=callgrind).
    let n: usize = std::env::var("CPU_TIME_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100)
        .max(1);
    let (c0, t0) = (cpu_s(), std::time::Instant::now());
    for _ in 0..n {
        buf.clear();
        let (m, _) = globe(&Globe::default(), &map)?;
        w.write_into(&m, &mut buf)?;
    }
    let (c1, t1) = (cpu_s(), t0.elapsed().as_secs_f64());
    if let (Some(a), Some(b)) = (c0, c1) {
        println!(
            "globe (45,000 strings) build + write: {:.2} ms CPU, {:.2} ms wall per compile ({} bytes)",
            (b - a) * 1000.0 / n as f64,
            t1 * 1000.0 / n as f64,
            buf.len()
        );
    }
    // The printability checks on the same model (`compile` runs them by default): the target
    // is no more than the compile itself.
    let (m, _) = globe(&Globe::default(), &map)?;
    let (c0, t0) = (cpu_s(), std::time::Instant::now());
    let mut issues = 0;
    for _ in 0..n {
        issues += check(&m, &p, &CheckOptions::default()).total();
    }
    let (c1, t1) = (cpu_s(), t0.elapsed().as_secs_f64());
    if let (Some(a), Some(b)) = (c0, c1) {
        println!(
            "globe (45,000 strings) checks: {:.2} ms CPU, {:.2} ms wall per check ({} issues)",
            (b - a) * 1000.0 / n as f64,
            t1 * 1000.0 / n as f64,
            issues / n
        );
    }
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
