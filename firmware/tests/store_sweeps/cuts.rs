//! Power cuts at every flash operation of every save, sector switch and erase-ahead.

use crate::common::*;
use firmware::storage::{Ahead, Cut, FlashOp, Moment, RecordStore, SettingsStore};

/// Every prefix of saves (so the save under test lands at every place of a sector, sector
/// switches included), each of the three saves, each of its writes and erases, each cut
/// shape: a boot loads the old record or the new one and the other exactly; a save after it
/// works and loads back.
fn sweep<const W: usize>(prefixes: u32, seeds: u32) -> (u32, u32, u32) {
    let (mut cuts, mut new_seen, mut erases_cut) = (0, 0, 0);
    for prefix in 0..prefixes {
        let (base, old) = area_after::<W>(prefix);
        for op in [Op::Settings(500), Op::Job(501), Op::Clear] {
            let new = old.after(op);
            for kind in Cut::shapes(seeds) {
                for n in 0.. {
                    let ctx = format!("word {W}, {prefix} saves, {op:?}, {kind:?} cut at {n}");
                    let (bytes, cut) = match cut_op_during::<W>(&base, n, kind, Moment::Idle, op) {
                        Ok(b) => b,
                        Err(done) => {
                            // Past the save's last operation: it completed, and says so only
                            // if the record reads back.
                            assert!(done.is_ok(), "{ctx}: {done:?}");
                            let got = Want::loaded(&mut store::<W>(base_after::<W>(&base, op)));
                            assert_eq!(got, Ok(new.clone()), "{ctx}");
                            break;
                        }
                    };
                    cuts += 1;
                    erases_cut += u32::from(cut == Some(FlashOp::Erase));
                    let mut st = store::<W>(bytes);
                    let got = Want::loaded(&mut st).unwrap_or_else(|e| panic!("{ctx}: {e}"));
                    assert!(got == old || got == new, "{ctx}: {got:?}");
                    new_seen += u32::from(got == new && new != old);
                    // The store goes on from there.
                    let next = Op::Settings(777);
                    next.run(&mut st, Moment::Idle)
                        .unwrap_or_else(|e| panic!("{ctx}, then a save: {e}"));
                    let after = got.after(next);
                    let bytes = st.into_flash().into_inner();
                    assert_eq!(Want::loaded(&mut store::<W>(bytes)), Ok(after), "{ctx}");
                }
            }
        }
    }
    (cuts, new_seen, erases_cut)
}

/// The area after `op` runs on `base` with the power on.
fn base_after<const W: usize>(base: &[u8], op: Op) -> Vec<u8> {
    let mut st = store::<W>(base.to_vec());
    op.run(&mut st, Moment::Idle).expect("save");
    st.into_flash().into_inner()
}

#[test]
fn a_power_cut_at_any_operation_of_any_save_keeps_old_or_new_and_the_other_record() {
    let (c4, n4, e4) = sweep::<4>(32, 3);
    let (c16, n16, e16) = sweep::<16>(32, 3);
    println!(
        "save sweep: {} cuts ({c4} at 4-byte words, {c16} at 16), {} during an erase, {} loaded the new record",
        c4 + c16,
        e4 + e16,
        n4 + n16
    );
    assert!(e4 > 0 && e16 > 0, "no erase was cut");
    assert!(c4 + c16 > 3000, "{}", c4 + c16);
}

/// A cut, then a cut in the next save too (at each of its operations): the second boot loads
/// what the first did, or the second save's record.
#[test]
fn a_cut_in_the_save_after_a_cut_keeps_what_the_first_left_or_the_new() {
    let mut cuts = 0;
    for prefix in [3, 7, 11, 16, 22] {
        let (base, _) = area_after::<16>(prefix);
        for op in [Op::Settings(500), Op::Job(501)] {
            for kind in [
                Cut::Partial,
                Cut::PartialTail,
                Cut::NearlyAll,
                Cut::Scattered(5),
            ] {
                for n in 0.. {
                    let Ok(first) = cut_during::<16>(&base, n, kind, Moment::Idle, op) else {
                        break;
                    };
                    let left = Want::loaded(&mut store::<16>(first.clone())).expect("first boot");
                    let second = Op::Job(900);
                    for m in 0.. {
                        let ctx = format!("{prefix} saves, {op:?} {kind:?} at {n}, then at {m}");
                        let Ok(bytes) = cut_during::<16>(&first, m, kind, Moment::Idle, second)
                        else {
                            break;
                        };
                        cuts += 1;
                        let got = Want::loaded(&mut store::<16>(bytes)).expect(&ctx);
                        assert!(got == left || got == left.after(second), "{ctx}: {got:?}");
                    }
                }
            }
        }
    }
    println!("second-cut sweep: {cuts} cuts");
    assert!(cuts > 300, "{cuts}");
}

/// A two-sector area of 4 KiB sectors (the erase-ahead keeps an eighth, 512 bytes: small
/// enough for the saves to leave less).
type Four = firmware::storage::NorFlashModel<Vec<u8>, 16, 4096>;

fn four(bytes: Vec<u8>) -> SettingsStore<Four> {
    SettingsStore::new(Four::new(bytes), 0..8192).expect("store")
}

/// Areas whose current sector has less than the erase-ahead's reserve left: after `prefix`
/// saves of the usual prefix, the first time the room falls under the reserve.
fn short_of_room(prefix: u32) -> (Vec<u8>, Want) {
    let mut st = four(vec![0xFF; 8192]);
    let mut want = Want::NONE;
    let mut i = 0;
    loop {
        let low = st
            .free_bytes()
            .unwrap()
            .is_some_and(|f| f < st.reserve_bytes());
        if low && i >= prefix {
            return (st.into_flash().into_inner(), want);
        }
        let op = Op::nth(i);
        op.run(&mut st, Moment::Idle).expect("save");
        want = want.after(op);
        i += 1;
    }
}

/// The erase-ahead (idle: a switch when the current sector is short of room, and the erase of
/// the other sector) cut at every operation in every shape keeps both records.
#[test]
fn a_power_cut_at_any_operation_of_an_erase_ahead_keeps_both_records() {
    let mut cuts = 0;
    let mut switched = 0;
    let mut prefix = 0;
    for _ in 0..6 {
        let (base, want) = short_of_room(prefix);
        prefix += 7;
        let before = four(base.clone()).current_sector().unwrap();
        for kind in Cut::shapes(3) {
            for n in 0.. {
                let mut m = Four::new(base.clone());
                m.cut_power(n, kind);
                let mut st = SettingsStore::new(m, 0..8192).unwrap();
                let r = st.erase_ahead();
                let mut flash = st.into_flash();
                let ctx = format!("{prefix} saves, {kind:?} cut at {n}: {r:?}");
                if !flash.is_off() {
                    let Ok(Ahead::Ready { free_bytes, .. }) = r else {
                        panic!("{ctx}");
                    };
                    let mut st = four(flash.into_inner());
                    assert!(free_bytes >= st.reserve_bytes(), "{ctx}");
                    assert_eq!(Want::loaded(&mut st), Ok(want.clone()), "{ctx}");
                    switched += u32::from(st.current_sector().unwrap() != before);
                    break;
                }
                cuts += 1;
                flash.restore_power();
                let mut st = four(flash.into_inner());
                assert_eq!(Want::loaded(&mut st), Ok(want.clone()), "{ctx}");
                // Done again with the power on, it gets there.
                let again = st.erase_ahead();
                assert!(matches!(again, Ok(Ahead::Ready { .. })), "{ctx}: {again:?}");
                assert_eq!(Want::loaded(&mut st), Ok(want.clone()), "{ctx}");
            }
        }
    }
    println!("erase-ahead sweep: {cuts} cuts ({switched} completed ones switched sectors)");
    assert!(cuts > 100 && switched > 0, "{cuts} {switched}");
}
