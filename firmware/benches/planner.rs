//! Planner cost per segment (segmentation + lookahead + pop), and step generator cost per
//! step event, on the host.
//!
//! `CARGO_TARGET_DIR=... cargo bench -p firmware --bench planner -- --warm-up-time 1 --measurement-time 3`

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use firmware::config::MachineConfig;
use firmware::motion::MoveRequest;
use firmware::planner::{BlockKind, Planner};
use firmware::stepgen::StepGen;
use std::hint::black_box;

/// A job of short chords (a 20 mm circle in 64 chords, 10 turns) and long lines, in steps.
fn job() -> Vec<MoveRequest> {
    let mut v = Vec::new();
    let mut seq = 0;
    let mut e = 0.0f32;
    for turn in 0..10 {
        for k in 0..=64 {
            let a = k as f32 / 64.0 * std::f32::consts::TAU;
            let (x, y) = (100.0 + 20.0 * a.cos(), 100.0 + 20.0 * a.sin());
            e += 0.065;
            seq += 1;
            v.push(MoveRequest {
                target: [(x * 80.0) as i32, (y * 80.0) as i32, 0, (e * 93.0) as i32],
                feed_mm_s: 60.0,
                seq,
            });
        }
        let x = if turn % 2 == 0 { 200.0 } else { 20.0 };
        seq += 1;
        v.push(MoveRequest {
            target: [(x * 80.0) as i32, 8000, 0, (e * 93.0) as i32],
            feed_mm_s: 150.0,
            seq,
        });
    }
    v
}

/// Push every move, popping blocks as the ring fills; returns the number of segments planned.
fn plan(cfg: &MachineConfig, moves: &[MoveRequest]) -> usize {
    let mut p = Planner::new();
    let mut n = 0;
    for m in moves {
        while !p.can_accept() {
            if black_box(p.pop()).is_some() {
                n += 1;
            }
            p.exec_done();
            p.refill();
        }
        let _ = p.push_move(cfg, m, BlockKind::Job);
    }
    while p.pop().is_some() {
        n += 1;
        p.exec_done();
        p.refill();
    }
    n
}

fn bench(c: &mut Criterion) {
    let cfg = MachineConfig::ENDER3;
    let moves = job();
    let segs = plan(&cfg, &moves);
    let mut g = c.benchmark_group("planner");
    g.throughput(Throughput::Elements(segs as u64));
    g.bench_function("segment_incl_lookahead", |b| {
        b.iter(|| plan(&cfg, black_box(&moves)))
    });
    // Worst case for the lookahead: a straight line sent as separate 0.2 mm moves at
    // 150 mm/s: the ring (12.8 mm) is shorter than the braking distance (22.5 mm), so every new
    // block raises every entry and the backward pass covers the whole ring each time.
    let worst: Vec<MoveRequest> = (1..=2000)
        .map(|k| MoveRequest {
            target: [k * 16, 8000, 0, 0],
            feed_mm_s: 150.0,
            seq: k as u32,
        })
        .collect();
    let wsegs = plan(&cfg, &worst);
    g.throughput(Throughput::Elements(wsegs as u64));
    g.bench_function("segment_worst_case_short_moves", |b| {
        b.iter(|| plan(&cfg, black_box(&worst)))
    });
    g.finish();

    // Step events: one 50 mm diagonal move with extrusion, cut into 0.2 mm segments.
    let mut p = Planner::new();
    let m = MoveRequest {
        target: [4000, 3000, 0, 400],
        feed_mm_s: 80.0,
        seq: 1,
    };
    let _ = p.push_move(&cfg, &m, BlockKind::Job);
    let mut blocks = Vec::new();
    while let Some(pb) = p.pop() {
        blocks.push(pb);
        p.exec_done();
        p.refill();
    }
    let count = |blocks: &[firmware::planner::PlannedBlock]| {
        let mut sg = StepGen::new();
        let mut n = 0u64;
        for pb in blocks {
            sg.load(*pb, 0);
            while let Some(ev) = sg.next_event() {
                black_box(ev);
                n += 1;
            }
            sg.unload();
        }
        n
    };
    let events = count(&blocks);
    let mut g = c.benchmark_group("stepgen");
    g.throughput(Throughput::Elements(events));
    g.bench_function("step_event", |b| b.iter(|| count(black_box(&blocks))));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
