//! The SKR 2's geometry (two 128 KiB sectors, 16-byte words): pause saves find erased room
//! when the printer erased ahead while idle, and a switch there survives every cut.

use crate::common::{job, settings, Op, Want};
use firmware::storage::{
    Ahead, Cut, Moment, RecordStore, Saved, SettingsStore, Skr2FlashModel, StoreError,
};

const LEN: usize = 256 * 1024;

type Board = SettingsStore<Skr2FlashModel<Vec<u8>>>;

fn board(bytes: Vec<u8>) -> Board {
    SettingsStore::new(Skr2FlashModel::new(bytes), 0..LEN as u32).expect("store")
}

fn erases(st: &mut Board) -> u32 {
    st.flash_mut().erases()
}

/// Prints of an M500 and 10 to 50 layer pauses each (the record at the park, its clearing at
/// the resume), with the erase-ahead between prints: on a store that may never erase while
/// paused, no pause save fails and none erases, over several laps of both sectors.
#[test]
fn pause_saves_find_erased_room_when_the_printer_erased_ahead_while_idle() {
    let mut st = board(vec![0xFF; LEN]).erase_while_paused(false);
    let (mut k, mut laps, mut erased_ahead) = (0u32, 0, 0);
    let mut sector = None;
    let mut want = Want::NONE;
    for print in 0..60u32 {
        let pauses = 10 + (print * 7) % 41;
        let before = erases(&mut st);
        st.save_settings(&settings(print), Moment::Idle).unwrap();
        want = want.after(Op::Settings(print));
        for _ in 0..pauses {
            let r = st.save_job(&job(k), Moment::Paused);
            assert!(
                matches!(r, Ok(Saved::Written)),
                "print {print}, pause {k}: {r:?}"
            );
            let r = st.clear_job(Moment::Paused);
            assert!(
                matches!(r, Ok(Saved::Written)),
                "print {print}, resume {k}: {r:?}"
            );
            k += 1;
        }
        assert_eq!(erases(&mut st), before, "print {print}: a save erased");
        match st.erase_ahead().unwrap() {
            Ahead::Ready { free_bytes, erased } => {
                assert!(free_bytes >= st.reserve_bytes());
                erased_ahead += erased;
            }
            Ahead::NothingSaved => panic!("records were saved"),
        }
        let now = st.current_sector().unwrap();
        laps += u32::from(sector.is_some_and(|s| Some(s) != now));
        let now = now.unwrap();
        sector = Some(now);
    }
    assert_eq!(Want::loaded(&mut st), Ok(want.clone()));
    println!(
        "board: {k} pause cycles in 60 prints, {laps} sector switches, {erased_ahead} sectors erased ahead, none while paused"
    );
    assert!(laps >= 3, "{laps}: the test did not lap the sectors");
    let bytes = st.into_flash().into_inner();
    assert_eq!(Want::loaded(&mut board(bytes)), Ok(want));
}

/// The emulated board's erase-during-a-pause area (`board-emu/tests/emulated.rs`): the current
/// sector (11) nearly full, sector 10 holding the generation before, no erase-ahead since.
/// Settings `s` and a kept job saved in it.
pub fn nearly_full() -> (Vec<u8>, Want) {
    let mut st = board(vec![0xFF; LEN]);
    st.save_job(&job(3), Moment::Idle).unwrap();
    let mut k = 0;
    // Leave less room than a job save takes.
    let job_needs = st.room_for(firmware::storage::JOB_RECORD_LEN);
    while st.current_sector().unwrap() != Some(1) || st.free_bytes().unwrap().unwrap() >= job_needs
    {
        st.save_settings(&settings(k), Moment::Idle).unwrap();
        k += 1;
    }
    let want = Want::loaded(&mut st).unwrap();
    assert!(want.job.is_some());
    (st.into_flash().into_inner(), want)
}

#[test]
fn a_pause_save_with_no_erased_room_erases_only_if_the_moment_affords_it() {
    let (bytes, want) = nearly_full();
    let job = job(9);
    // A driver that cannot guard an erase while paused: the record is not kept, and says why.
    let mut st = board(bytes.clone()).erase_while_paused(false);
    assert_eq!(
        st.save_job(&job, Moment::Paused),
        Err(StoreError::NoErasedRoom)
    );
    assert_eq!(erases(&mut st), 0);
    assert_eq!(Want::loaded(&mut st), Ok(want.clone()));
    // Nor while printing, whatever the driver.
    let mut st = board(bytes.clone());
    assert_eq!(
        st.save_job(&job, Moment::Printing),
        Err(StoreError::NoErasedRoom)
    );
    // The SKR 2 (heaters off, watchdog fed): one erase, of sector 10, and the record is kept.
    let mut st = board(bytes.clone());
    assert_eq!(st.save_job(&job, Moment::Paused), Ok(Saved::AfterErase));
    assert_eq!(erases(&mut st), 1);
    assert_eq!(st.current_sector(), Ok(Some(0)));
    assert_eq!(Want::loaded(&mut st), Ok(want.after(Op::Job(9))));
    // Its clearing at the resume needs no erase.
    assert_eq!(st.clear_job(Moment::Paused), Ok(Saved::Written));
}

/// That switch, cut at every write and erase in every shape: old records or new, never less.
#[test]
fn a_switch_on_the_boards_geometry_survives_every_cut() {
    let (bytes, want) = nearly_full();
    let mut cuts = 0;
    for kind in Cut::shapes(4) {
        for n in 0.. {
            let mut m = Skr2FlashModel::new(bytes.clone());
            m.cut_power(n, kind);
            let mut st = SettingsStore::new(m, 0..LEN as u32).unwrap();
            let r = st.save_job(&job(9), Moment::Paused);
            let mut flash = st.into_flash();
            if !flash.is_off() {
                assert_eq!(r, Ok(Saved::AfterErase));
                break;
            }
            cuts += 1;
            flash.restore_power();
            let got = Want::loaded(&mut board(flash.into_inner()));
            let ctx = format!("{kind:?} cut at {n}: {got:?}");
            assert!(
                got == Ok(want.clone()) || got == Ok(want.after(Op::Job(9))),
                "{ctx}"
            );
        }
    }
    println!("board switch sweep: {cuts} cuts");
    assert!(cuts > 40, "{cuts}");
}
