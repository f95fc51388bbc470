//! Data this store did not write, anywhere in the area: in both sectors at first boot, in the
//! sector beside the records, in the free room after them — and every save after it cut at
//! every operation in every shape.

use crate::common::*;
use firmware::storage::{Cut, Moment, RecordStore, SettingsStore, StoreError};

/// The saves done on each area: both records and clears, at every moment, enough of them to
/// switch sectors (into the foreign one) at least once.
fn saves() -> impl Iterator<Item = (Op, Moment)> {
    (0..12u32).map(|i| {
        let at = [
            Moment::Paused,
            Moment::Paused,
            Moment::Idle,
            Moment::Printing,
        ][i as usize % 4];
        (Op::nth(i + 600), at)
    })
}

/// Run [`saves`] on `area` (holding `want`): before each, that save cut at every operation in
/// every shape must leave the old records or the new; then it runs, and must load back
/// (or, while printing with no erased room, fail and keep everything). Returns the cuts.
fn saves_keep_everything(what: &str, area: Vec<u8>, want: Want) -> u32 {
    let mut bytes = area;
    let mut want = want;
    let mut cuts = 0;
    {
        let mut st = store::<16>(bytes.clone());
        assert_eq!(Want::loaded(&mut st), Ok(want.clone()), "{what}: boot");
        assert_eq!(st.into_flash().ops(), 0, "{what}: a boot writes nothing");
    }
    for (i, (op, at)) in saves().enumerate() {
        let new = want.after(op);
        for kind in Cut::shapes(2) {
            for n in 0.. {
                let ctx = format!("{what}, save {i} {op:?} {at:?}, {kind:?} cut at {n}");
                let Ok(cut) = cut_during::<16>(&bytes, n, kind, at, op) else {
                    break;
                };
                cuts += 1;
                let got =
                    Want::loaded(&mut store::<16>(cut)).unwrap_or_else(|e| panic!("{ctx}: {e}"));
                assert!(got == want || got == new, "{ctx}: {got:?}");
            }
        }
        let mut st = store::<16>(bytes.clone());
        let r = op.run(&mut st, at);
        let ctx = format!("{what}, save {i} {op:?} {at:?}: {r:?}");
        match r {
            Ok(_) => want = new,
            Err(StoreError::NoErasedRoom) if at == Moment::Printing => {}
            Err(e) => panic!("{ctx}: {e}"),
        }
        bytes = st.into_flash().into_inner();
        assert_eq!(
            Want::loaded(&mut store::<16>(bytes.clone())),
            Ok(want.clone()),
            "{ctx}"
        );
    }
    cuts
}

/// An area whose records (settings 0, a job 1) are in sector `index`, the other erased.
fn records_in(index: usize) -> (Vec<u8>, Want) {
    let (mut bytes, want) = area_after::<16>(2);
    if index == 1 {
        let (a, b) = bytes.split_at_mut(S);
        a.swap_with_slice(b);
    }
    let mut st = store::<16>(bytes.clone());
    assert_eq!(st.current_sector(), Ok(Some(index)));
    assert_eq!(Want::loaded(&mut st), Ok(want.clone()));
    (bytes, want)
}

#[test]
fn foreign_data_at_first_boot_loads_nothing_and_the_first_save_takes_a_sector() {
    let mut areas = 0;
    let mut cuts = 0;
    for (name, data) in foreign(S) {
        for (place, sectors) in [
            ("sector 0", [Some(&data), None]),
            ("sector 1", [None, Some(&data)]),
            ("both sectors", [Some(&data), Some(&data)]),
        ] {
            let mut bytes = vec![0xFF; 2 * S];
            for (i, d) in sectors.iter().enumerate() {
                if let Some(d) = d {
                    bytes[i * S..(i + 1) * S].copy_from_slice(d);
                }
            }
            let mut st = store::<16>(bytes.clone());
            assert_eq!(
                st.load_settings(),
                Err(StoreError::Foreign),
                "{name} in {place}"
            );
            assert_eq!(st.load_job(), Ok(None), "{name} in {place}");
            areas += 1;
            cuts += saves_keep_everything(&format!("{name} in {place}"), bytes, Want::NONE);
        }
    }
    println!("foreign data at first boot: {areas} areas, {cuts} cuts");
}

#[test]
fn foreign_data_beside_the_records_never_costs_one() {
    let mut areas = 0;
    let mut cuts = 0;
    for (name, data) in foreign(S) {
        for index in 0..2 {
            let (mut bytes, want) = records_in(index);
            let other = 1 - index;
            bytes[other * S..(other + 1) * S].copy_from_slice(&data);
            areas += 1;
            let what = format!("records in sector {index}, {name} in the other");
            cuts += saves_keep_everything(&what, bytes, want);
        }
    }
    println!("foreign data beside the records: {areas} areas, {cuts} cuts");
}

#[test]
fn foreign_data_in_the_free_room_after_the_records_never_costs_one() {
    let mut areas = 0;
    let mut cuts = 0;
    for (name, data) in foreign(S) {
        for index in 0..2 {
            let (mut bytes, want) = records_in(index);
            let mut st: SettingsStore<_> = store::<16>(bytes.clone());
            let free = st.free_bytes().unwrap().unwrap() as usize;
            let from = index * S + S - free;
            bytes[from..(index + 1) * S].copy_from_slice(&data[S - free..]);
            areas += 1;
            let what = format!("records in sector {index}, {name} after them");
            cuts += saves_keep_everything(&what, bytes, want);
        }
    }
    println!("foreign data after the records: {areas} areas, {cuts} cuts");
}
