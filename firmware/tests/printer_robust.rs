//! Bad input never crashes the executive: random bytes, random G-code-ish lines and random
//! realtime requests at random times, with steps pulled in between.
use firmware::config::MachineConfig;
use firmware::motion::{PauseMode, Realtime};
use firmware::printer::{Printer, State};
use proptest::prelude::*;

fn realtime() -> impl Strategy<Value = Realtime> {
    prop_oneof![
        Just(Realtime::Pause(PauseMode::Layer)),
        Just(Realtime::Pause(PauseMode::Now)),
        Just(Realtime::Resume),
        Just(Realtime::Cancel),
        Just(Realtime::QuickStop),
        Just(Realtime::BreakWait),
        Just(Realtime::EmergencyStop),
    ]
}

fn line() -> impl Strategy<Value = String> {
    prop_oneof![
        "G[0-3] X-?[0-9]{1,3}(\\.[0-9]{1,3})? Y[0-9]{1,3} Z[0-9]{0,2} E-?[0-9]{0,2}(\\.[0-9])? F[0-9]{1,5}",
        "G1 E-?[0-9]\\.[0-9]+ F[0-9]{2,4}",
        Just("G28".to_string()),
        Just("G91".to_string()),
        Just("G90".to_string()),
        Just("M83".to_string()),
        Just("M82".to_string()),
        Just("G92 E0".to_string()),
        Just(";LAYER_CHANGE".to_string()),
        "M10[49] S[0-9]{1,3}",
        "M76[01] ?[LZSRVXYF]?[0-9]{0,3}",
        "M(0|1|600|400|114|115|105|220 S[0-9]{1,3}|204 P[0-9]{1,4})",
        "G4 P[0-9]{1,4}",
        "G2 X[0-9]{1,2} Y[0-9]{1,2} I[0-9] J[0-9]",
        "[ -~]{0,40}",
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

    #[test]
    fn never_panics(
        lines in prop::collection::vec(line(), 0..40),
        noise in prop::collection::vec(any::<u8>(), 0..64),
        reqs in prop::collection::vec((0u64..20_000_000, realtime()), 0..6),
    ) {
        let mut p = Printer::new(MachineConfig::ENDER3);
        let mut now = 0u64;
        let mut out = String::new();
        // Bytes not taken yet wait here (flow control), offered again at every tick.
        let mut pending = noise;
        let mut reqs = reqs;
        reqs.sort_by_key(|r| r.0);
        let mut ri = 0;
        for l in &lines {
            pending.extend_from_slice(format!("{l}\n").as_bytes());
            for _ in 0..50 {
                let n = p.receive(&pending, now);
                pending.drain(..n);
                while ri < reqs.len() && reqs[ri].0 <= now {
                    p.request(reqs[ri].1, now);
                    ri += 1;
                }
                p.poll(now);
                while let Some(t) = p.next_step_ns() {
                    if t > (now + 10_000) * 1000 {
                        break;
                    }
                    prop_assert!(p.next_step().is_some());
                }
                now += 10_000;
            }
            p.write_output(&mut out).unwrap();
        }
        let s = p.status();
        if s.state == State::Halted {
            prop_assert!(p.next_step_ns().is_none());
        }
    }
}
