//! Front-end throughput on real slicer output (`tests/fixtures/slicer/prusaslicer.gcode`):
//!
//! - `parse`: G-code parser alone, line by line;
//! - `link+parse`: host link (line assembly, realtime scan, FIFO) then the parser;
//! - `parse+machine`: parser, machine state and layer detection (the executive's front half).
//!
//! `cargo bench -p firmware --bench parse -- --warm-up-time 1 --measurement-time 3`
//! (criterion reports bytes/s of G-code text).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use firmware::config::MachineConfig;
use firmware::gcode::parse_line;
use firmware::link::{HostLink, Response};
use firmware::machine::{Action, Interpreter};
use std::hint::black_box;

fn fixture() -> Vec<u8> {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/fixtures/slicer/prusaslicer.gcode"
    );
    std::fs::read(p).unwrap_or_else(|e| panic!("{p}: {e}"))
}

fn bench(c: &mut Criterion) {
    let text = fixture();
    let lines: Vec<&[u8]> = text.split(|&b| b == b'\n').collect();
    let cfg = MachineConfig::ENDER3;
    let mut g = c.benchmark_group("frontend");
    g.throughput(Throughput::Bytes(text.len() as u64));

    g.bench_function("parse", |b| {
        b.iter(|| {
            let mut n = 0usize;
            for l in &lines {
                if let Ok(p) = parse_line(black_box(l)) {
                    n += p.command.is_some() as usize;
                }
            }
            n
        })
    });

    g.bench_function("link+parse", |b| {
        b.iter(|| {
            let mut link = HostLink::new();
            let mut n = 0usize;
            let mut sink = [0u8; 256];
            // The host sends one line per ok; feed line by line and answer each.
            for l in &lines {
                let _ = link.receive(black_box(l));
                let _ = link.receive(b"\n");
                while let Some(rx) = link.pop_line() {
                    if let Ok(p) = parse_line(rx.text()) {
                        n += p.command.is_some() as usize;
                    }
                    link.respond(Response::Ok);
                }
                while link.read_output(&mut sink) > 0 {}
            }
            n
        })
    });

    g.bench_function("parse+machine", |b| {
        b.iter(|| {
            let mut it = Interpreter::new(&cfg);
            let mut moves = 0usize;
            for l in &lines {
                if let Ok(p) = parse_line(black_box(l)) {
                    if let Ok(step) = it.line(&p, &cfg) {
                        moves += matches!(step.action, Action::Move(_)) as usize;
                    }
                }
            }
            moves
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
