//! Benchmarks of the design compiler (README targets):
//! - compile the globe (45,000 modulated strings) to G-code: ≤ 20 ms;
//! - `stats` on a large slicer file: ≥ 100 MB/s.
//!
//! Run: `CARGO_TARGET_DIR=... cargo bench -p host-tools --bench design -- --warm-up-time 1 --measurement-time 3`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use host_tools::design::modulate::{globe, Bitmap, Globe};
use host_tools::design::profile::Profile;
use host_tools::design::script::ScriptRunner;
use host_tools::design::writer::{GcodeWriter, WriteOptions};
use host_tools::gcode::read::{default_reader, GcodeReader};
use host_tools::job::stats::stats;
use std::hint::black_box;
use std::path::PathBuf;

fn globe_bench(c: &mut Criterion) {
    let p = Profile::ender3();
    let map = Bitmap::world_map().expect("map");
    let w = GcodeWriter::new(&p, WriteOptions::default());
    let mut g = c.benchmark_group("globe");
    g.sample_size(20);
    // The whole compile through the library: helix → sphere → modulation → G-code text.
    g.bench_function("build_and_write_45000_strings", |b| {
        let mut buf = Vec::with_capacity(2 << 20);
        b.iter(|| {
            buf.clear();
            let (m, _) = globe(&Globe::default(), &map).expect("globe");
            w.write_into(&m, &mut buf).expect("write");
            black_box(buf.len())
        })
    });
    let (m, _) = globe(&Globe::default(), &map).expect("globe");
    g.bench_function("write_only", |b| {
        let mut buf = Vec::with_capacity(2 << 20);
        b.iter(|| {
            buf.clear();
            w.write_into(&m, &mut buf).expect("write");
            black_box(buf.len())
        })
    });
    // Through the script engine, as `host-tools compile examples/globe.rhai` does (no checks).
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/globe.rhai");
    let runner = ScriptRunner::new(p.clone());
    g.bench_function("script_and_write", |b| {
        let mut buf = Vec::with_capacity(2 << 20);
        b.iter(|| {
            buf.clear();
            let out = runner.run_file(&script).expect("script");
            w.write_into(&out.model, &mut buf).expect("write");
            black_box(buf.len())
        })
    });
    g.finish();
}

/// A large slicer file: the committed PrusaSlicer fixture repeated to about 40 MB (or, when
/// the fixture is missing, a synthetic layered file of the same size).
fn large_file() -> Vec<u8> {
    let fixture = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fixtures/slicer/prusaslicer.gcode");
    let one = std::fs::read(fixture).unwrap_or_else(|_| {
        let mut s = String::from("G90\nM82\nG92 E0\n");
        let mut e = 0.0;
        for layer in 0..100 {
            s.push_str(&format!(
                ";LAYER_CHANGE\n;Z:{:.2}\nG1 Z{:.2} F600\n",
                0.2 * (layer + 1) as f64,
                0.2 * (layer + 1) as f64
            ));
            for i in 0..100 {
                e += 0.05;
                s.push_str(&format!(
                    "G1 X{:.3} Y{:.3} E{:.5} F1800\n",
                    100.0 + (i as f64 * 0.3).sin() * 20.0,
                    100.0 + (i as f64 * 0.3).cos() * 20.0,
                    e
                ));
            }
        }
        s.into_bytes()
    });
    let mut out = Vec::with_capacity(41 << 20);
    while out.len() < 40 << 20 {
        out.extend_from_slice(&one);
        out.extend_from_slice(b"\nG92 E0\n");
    }
    out
}

fn stats_bench(c: &mut Criterion) {
    let data = large_file();
    let p = Profile::ender3();
    let mut g = c.benchmark_group("stats");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(data.len() as u64));
    g.bench_function("stats_large_slicer_file", |b| {
        b.iter(|| black_box(stats(&data, &p).expect("stats").print_time_s))
    });
    g.bench_function("read_firmware_parser", |b| {
        b.iter(|| {
            let mut n = 0u64;
            default_reader().read(&data, &mut |_| n += 1).expect("read");
            black_box(n)
        })
    });
    g.finish();
}

criterion_group!(benches, globe_bench, stats_bench);
criterion_main!(benches);
