//! Lookahead against hand-computed profiles, and the incremental plan against a full replan.

use firmware::config::MachineConfig;
use firmware::motion::MoveRequest;
use firmware::planner::{junction_v2, BlockKind, Planner, PlannerPolicy, RING_CAPACITY};
use firmware::stepgen::{Profile, StepGen};
use proptest::prelude::*;

fn cfg() -> MachineConfig {
    MachineConfig::ENDER3
}

fn planner(segment: bool) -> Planner {
    let mut p = Planner::new();
    p.policy = PlannerPolicy {
        segment,
        max_blocks: RING_CAPACITY,
        stop_at_marks: true,
    };
    p
}

fn mv(p: &mut Planner, x_mm: f32, y_mm: f32, feed: f32, seq: u32) {
    let req = MoveRequest {
        target: [(x_mm * 80.0) as i32, (y_mm * 80.0) as i32, 0, 0],
        feed_mm_s: feed,
        seq,
    };
    assert_eq!(p.push_move(&cfg(), &req, BlockKind::Job), Ok(true));
}

/// Run one block alone through the step generator and return its duration in seconds.
fn duration_s(p: &mut Planner) -> f64 {
    let pb = p.pop().unwrap();
    let mut sg = StepGen::new();
    sg.load(pb, 0);
    let mut last = 0;
    while let Some(ev) = sg.next_event() {
        last = ev.t_ns;
    }
    last as f64 / 1e9
}

#[test]
fn accelerate_cruise_decelerate() {
    // 10 mm at 50 mm/s, 500 mm/s²: 0.1 s up over 2.5 mm, 5 mm cruise in 0.1 s, 0.1 s down.
    let mut p = planner(false);
    mv(&mut p, 10.0, 0.0, 50.0, 1);
    let t = duration_s(&mut p);
    assert!((t - 0.3).abs() < 1e-4, "{t}");
    let pr = Profile::new(0.0, 10.0, 0.0, 50.0, 0.0, 500.0);
    assert!((pr.d_acc - 2.5).abs() < 1e-5 && (pr.d_dec - 2.5).abs() < 1e-5);
    assert!((pr.time_at(10.0) - 0.3).abs() < 1e-5);
    assert!((pr.speed_at(5.0) - 50.0).abs() < 1e-4);
}

#[test]
fn triangle_profile() {
    // 2 mm at 100 mm/s: the peak is √(a·L) = √1000 = 31.62 mm/s, time 2·v/a = 0.12649 s.
    let mut p = planner(false);
    mv(&mut p, 2.0, 0.0, 100.0, 1);
    let t = duration_s(&mut p);
    assert!((t - 0.126_49).abs() < 1e-4, "{t}");
    let pr = Profile::new(0.0, 2.0, 0.0, 100.0, 0.0, 500.0);
    assert!((pr.vc - 31.622_78).abs() < 1e-3);
}

#[test]
fn junction_90_degrees() {
    // v² = a·δ·sin(θ/2)/(1 − sin(θ/2)) with θ/2 = 45°: 500 · 0.013 · 2.41421 = 15.692.
    let j = junction_v2(&[1.0, 0.0, 0.0, 0.0], &[0.0, 1.0, 0.0, 0.0], 0.013, 500.0);
    assert!((j - 15.692).abs() < 1e-2, "{j}");
    // The planner with the Ender-3 default δ = 0.08 mm (Marlin's Ender-3 examples):
    // 500 · 0.08 · 2.41421 = 96.569 (9.83 mm/s).
    let mut p = planner(false);
    mv(&mut p, 10.0, 0.0, 100.0, 1);
    mv(&mut p, 10.0, 10.0, 100.0, 2);
    let b = p.get(1).unwrap();
    assert!((b.entry_v2 - 96.569).abs() < 1e-2, "{}", b.entry_v2);
}

#[test]
fn collinear_junction_full_speed() {
    let j = junction_v2(&[1.0, 0.0, 0.0, 0.0], &[1.0, 0.0, 0.0, 0.0], 0.013, 500.0);
    assert!(j.is_infinite());
    let mut p = planner(false);
    mv(&mut p, 10.0, 0.0, 50.0, 1);
    mv(&mut p, 20.0, 0.0, 50.0, 2);
    // 10 mm is enough to reach 50 mm/s (needs 2.5 mm) and to stop after the second move.
    assert_eq!(p.get(1).unwrap().entry_v2, 2500.0);
    // Reversal: full stop.
    let r = junction_v2(&[1.0, 0.0, 0.0, 0.0], &[-1.0, 0.0, 0.0, 0.0], 0.013, 500.0);
    assert_eq!(r, 0.0);
}

#[test]
fn segments_of_one_move_join_at_full_speed() {
    let mut p = planner(true);
    mv(&mut p, 100.0, 0.0, 50.0, 1);
    // 500 segments of 0.2 mm; the ring holds 64; the rest is the pending remainder.
    assert_eq!(p.len(), RING_CAPACITY);
    assert_eq!(p.pending_segments(), 500 - RING_CAPACITY as u32);
    // From rest: entry of segment k is min(50², 2·a·0.2·k).
    for k in 0..RING_CAPACITY {
        let b = p.get(k).unwrap();
        let expect = (2.0 * 500.0 * 0.2 * k as f32).min(2500.0);
        assert!(
            (b.entry_v2 - expect).abs() < 1e-2,
            "seg {k}: {} vs {expect}",
            b.entry_v2
        );
    }
    // The pending remainder counts as lookahead: the last queued block leaves at full speed.
    let last = p.get(RING_CAPACITY - 1).unwrap();
    assert_eq!(last.entry_v2, 2500.0);
}

#[test]
fn small_ring_reaches_full_speed_on_long_moves() {
    // With 8 blocks of 0.2 mm (1.6 mm of ring) a 100 mm move still cruises at 100 mm/s,
    // because the uncut remainder is known lookahead.
    let mut p = planner(true);
    p.policy.max_blocks = 8;
    mv(&mut p, 100.0, 0.0, 100.0, 1);
    let mut sg = StepGen::new();
    let mut vmax = 0.0f32;
    let mut t_end = 0;
    loop {
        if sg.current().is_none_or(|e| e.finished()) {
            if sg.current().is_some() {
                sg.unload();
                p.exec_done();
            }
            let Some(pb) = p.pop() else { break };
            p.refill();
            vmax = vmax.max(pb.entry_v2.sqrt());
            sg.load(pb, t_end);
        }
        while let Some(ev) = sg.next_event() {
            t_end = ev.t_ns;
        }
    }
    assert!((vmax - 100.0).abs() < 0.01, "{vmax}");
    // 100 mm at 100 mm/s with 10 mm ramps each side: 0.2 + 0.8 + 0.2 = 1.2 s.
    let t = t_end as f64 / 1e9;
    assert!((t - 1.2).abs() < 2e-3, "{t}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

    /// After every push and pop the incremental plan (planned pointer) equals a full replan,
    /// every entry is within its limit, and the plan is feasible both ways: each block can
    /// reach the next entry and the last one can stop.
    #[test]
    fn incremental_plan_equals_full_and_is_feasible(
        moves in prop::collection::vec((0.0f32..200.0, 0.0f32..200.0, 5.0f32..200.0), 1..60),
        pops in prop::collection::vec(any::<bool>(), 60),
        segment in any::<bool>(),
    ) {
        let mut p = planner(segment);
        p.policy.max_blocks = 16;
        for (i, &(x, y, f)) in moves.iter().enumerate() {
            while !p.can_accept() {
                prop_assert!(p.pop().is_some());
                p.exec_done();
                p.refill();
            }
            mv(&mut p, x, y, f, i as u32);
            if pops[i % pops.len()] && p.get(0).is_some() {
                p.pop();
                p.exec_done();
                p.refill();
            }
            let mut full = p.clone();
            full.replan_all();
            for k in 0..p.len() {
                let (a, b) = (p.get(k).unwrap(), full.get(k).unwrap());
                prop_assert!((a.entry_v2 - b.entry_v2).abs() <= 1e-3 * b.entry_v2.max(1.0),
                    "block {k}: incremental {} full {}", a.entry_v2, b.entry_v2);
                prop_assert!(a.entry_v2 <= a.entry_max_v2 * 1.0001 || k == 0);
                if k + 1 < p.len() {
                    let n = p.get(k + 1).unwrap();
                    let reach = 2.0 * a.accel_mm_s2 * a.len_mm;
                    prop_assert!(n.entry_v2 <= a.entry_v2 + reach * 1.0001 + 1e-3);
                    prop_assert!(a.entry_v2 <= n.entry_v2 + reach * 1.0001 + 1e-3 || k == 0);
                }
            }
        }
    }
}

#[test]
fn step_times_from_standstill_follow_the_profile() {
    // 10 mm X at 50 mm/s: step k at s = k/80 mm; during the ramp t = √(2s/a).
    let mut p = planner(false);
    mv(&mut p, 10.0, 0.0, 50.0, 1);
    let pb = p.pop().unwrap();
    let mut sg = StepGen::new();
    sg.load(pb, 0);
    let mut last = 0u64;
    for k in 1..=800u32 {
        let ev = sg.next_event().unwrap();
        assert!(ev.t_ns >= last, "monotonic");
        last = ev.t_ns;
        let s = k as f64 / 80.0;
        if k <= 2 || k == 4 || k == 8 || k % 8 == 0 && s <= 2.5 {
            let exact = (2.0 * s / 500.0).sqrt();
            let t = ev.t_ns as f64 / 1e9;
            assert!((t - exact).abs() < 2e-6, "step {k}: {t} vs {exact}");
        }
    }
    assert!(sg.next_event().is_none());
}

#[test]
fn speed_up_is_bounded_by_axis_limits_and_volumetric_flow() {
    use firmware::planner::{kinematics, sped_up_mm_s};
    let c = cfg();
    // 10 mm X with 0.5 mm of filament: 0.05 mm filament per mm; 1.75 mm filament area
    // 2.405 mm² → 0.1203 mm³ per mm of path; 12 mm³/s allows 99.8 mm/s.
    let k = kinematics(&c, &[800, 0, 0, (0.5 * 93.0) as i32], 40.0).unwrap();
    let v = sped_up_mm_s(&k, 3.0, 12.0, 1.75);
    let area = std::f32::consts::PI * 0.875 * 0.875;
    let limit = 12.0 / (area * k.e_per_mm);
    assert!((v - limit).abs() < 0.01 && v < 120.0, "{v} vs {limit}");
    // Travel (no E): ×3 up to the axis limit.
    let t = kinematics(&c, &[800, 0, 0, 0], 40.0).unwrap();
    assert_eq!(sped_up_mm_s(&t, 3.0, 12.0, 1.75), 120.0);
    let fast = kinematics(&c, &[800, 0, 0, 0], 400.0).unwrap();
    assert_eq!(sped_up_mm_s(&fast, 3.0, 12.0, 1.75), 500.0);
    // Never slower than nominal, and factor 1 is off.
    let slow = kinematics(&c, &[800, 0, 0, 930], 40.0).unwrap();
    assert_eq!(sped_up_mm_s(&slow, 3.0, 1.0, 1.75), slow.nominal_mm_s);
    assert_eq!(sped_up_mm_s(&t, 1.0, 12.0, 1.75), 40.0);
}

#[test]
fn layer_request_speeds_up_blocks_before_the_barrier_only() {
    use firmware::motion::{LayerMark, LayerSource};
    let mut p = planner(true);
    mv(&mut p, 4.0, 0.0, 20.0, 1);
    p.push_mark(LayerMark {
        layer: 1,
        z_um: None,
        source: LayerSource::Comment,
    })
    .unwrap();
    mv(&mut p, 4.0, 4.0, 20.0, 2);
    let first_id = p.get(0).unwrap().id;
    p.set_barrier(first_id + 20);
    p.speed_up();
    for k in 0..p.len() {
        let b = p.get(k).unwrap();
        if b.seq == 1 {
            assert_eq!(b.nominal_v2, 60.0 * 60.0, "sped up ×3");
        } else {
            assert_eq!(b.nominal_v2, 20.0 * 20.0, "behind the barrier: untouched");
        }
    }
    // The plan stops at the barrier: the last block before it can stop.
    let last = p.get(19).unwrap();
    assert!(last.entry_v2 <= 2.0 * last.accel_mm_s2 * last.len_mm * 1.0001);
}
