//! One stray byte at every offset of the area (any value): no record lost, and every save
//! after it either reads back or says it failed.

use crate::common::*;
use firmware::storage::Moment;

/// Areas to spoil: records in sector 0 with sector 1 erased (as after an erase-ahead), and
/// records in sector 1 after a switch, sector 0 holding the generation before.
fn bases() -> Vec<(Vec<u8>, Want)> {
    let fresh = area_after::<16>(4);
    let mut prefix = 4;
    let switched = loop {
        let (bytes, want) = area_after::<16>(prefix);
        if store::<16>(bytes.clone()).current_sector() == Ok(Some(1)) {
            break (bytes, want);
        }
        prefix += 1;
    };
    vec![fresh, switched]
}

#[test]
fn one_stray_byte_anywhere_loses_no_record_and_no_save_claims_what_did_not_read_back() {
    let mut spoiled = 0;
    let mut switches = 0;
    for (b, (base, want)) in bases().into_iter().enumerate() {
        for at in 0..2 * S {
            for value in [0x00, 0xFE, 0xA5, 0xFF] {
                if base[at] == value {
                    continue;
                }
                spoiled += 1;
                let mut bytes = base.clone();
                bytes[at] = value;
                let ctx = format!("area {b}, byte {at:#x} = {value:#04x}");
                let mut st = store::<16>(bytes);
                assert_eq!(Want::loaded(&mut st), Ok(want.clone()), "{ctx}: boot");
                // The saves after it: each reads back (a store returning Ok) and a boot loads
                // them; every fourth offset goes on until the store has switched sectors.
                let mut w = want.clone();
                let first = st.current_sector().unwrap();
                let n = if at % 4 == 0 { 12 } else { 2 };
                for i in 0..n {
                    let op = [Op::Settings(700 + i), Op::Job(800 + i)][i as usize % 2];
                    op.run(&mut st, Moment::Paused)
                        .unwrap_or_else(|e| panic!("{ctx}, save {i} {op:?}: {e}"));
                    w = w.after(op);
                }
                switches += u32::from(st.current_sector().unwrap() != first);
                let bytes = st.into_flash().into_inner();
                assert_eq!(
                    Want::loaded(&mut store::<16>(bytes)),
                    Ok(w),
                    "{ctx}: after saves"
                );
            }
        }
    }
    println!("stray bytes: {spoiled} areas spoiled, {switches} went through a sector switch");
    assert!(switches > 1000, "{switches}");
}
