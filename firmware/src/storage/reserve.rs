//! Erase ahead: keep enough already-erased room in the store's open sector that the saves of a
//! whole print (a power-cut record at every layer pause, its clearing at every resume, an
//! M500) never need a sector erase.
//!
//! Why: sequential-storage erases a sector inside the save that overflows the open one (it
//! copies the current items to the next sector, then erases the old one). On the STM32F4 a
//! 128 KiB sector erase takes 1 s typically and up to 2 s (DS8626, "Flash memory
//! programming", x32 parallelism), during which every flash read stalls: the code, the
//! interrupts, the heaters' PWM and the step interrupt stop. An erase during a layer pause
//! (heaters holding temperature, a host waiting) is what this avoids.
//!
//! How, with sequential-storage's own operations only (its format is not touched): when idle,
//! the executive asks [`SettingsStore::erase_ahead`]; if the open sector has less than the
//! reserve ([`SettingsStore::reserve_bytes`]) left, filler items (key [`PAD_KEY`]) are stored
//! until the store moves to the next sector, which it erased the previous time round, and
//! erases the old one — now, while nothing waits for it. Every filler is an ordinary store,
//! so a power cut during it keeps the records (sequential-storage's guarantees); the last
//! filler left current is replaced by an empty one so the next sector switch copies little.
//!
//! The free room is read from the flash: the open ("partial-open") sector is the one whose
//! first word is written and last word is not (sequential-storage's page markers); its free
//! room is what follows its last written byte, up to the end marker. The tests below run the
//! real sequential-storage on the NOR-flash model, so a change of that layout fails them.

use super::store::{SettingsStore, StoreError};
use embedded_storage::nor_flash::NorFlash;

/// Map key of the filler items (never read back).
pub const PAD_KEY: u8 = 3;

/// Bytes of one filler item's value (with its key, within the store's work buffer).
const PAD_LEN: usize = 224;

/// What [`SettingsStore::erase_ahead`] found or did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EraseAhead {
    /// The open sector has at least the reserve left: nothing done.
    Enough {
        /// Free bytes in the open sector.
        free: u32,
    },
    /// The store moved to the next sector and erased the old one.
    Erased {
        /// Free bytes in the new open sector.
        free: u32,
        /// Filler items written to get there.
        fillers: u32,
    },
    /// The area's state could not be read as sequential-storage leaves it (no open sector):
    /// nothing done (the next save repairs or opens one).
    Unknown,
}

impl<F: NorFlash> SettingsStore<F> {
    /// Free bytes the store keeps erased for saves while not idle: an eighth of a sector
    /// (16 KiB of the SKR 2's 128 KiB sectors: about fifty pause/resume cycles).
    pub fn reserve_bytes(&self) -> u32 {
        (F::ERASE_SIZE / 8) as u32
    }

    /// Free bytes left in the open sector (`None`: no open sector, e.g. an area never
    /// written, which has a whole sector free and needs no erase for the first one).
    pub fn open_sector_free(&mut self) -> Result<Option<u32>, StoreError> {
        let range = self.map.flash_range();
        let flash = &mut self.map.flash().0;
        let sector = F::ERASE_SIZE as u32;
        let word = F::WRITE_SIZE.max(F::READ_SIZE) as u32;
        let mut start = range.start;
        while start + sector <= range.end {
            let end = start + sector;
            let first = written(flash, start, start + word)?;
            let last = written(flash, end - word, end)?;
            if first && !last {
                let used_to = last_written(flash, start + word, end - word)?;
                let used_to = used_to.div_ceil(word) * word;
                return Ok(Some((end - word).saturating_sub(used_to)));
            }
            start = end;
        }
        Ok(None)
    }

    /// If the open sector has less than [`Self::reserve_bytes`] free, move to the next sector
    /// now (erasing the old one): call only while idle. See the module documentation.
    pub fn erase_ahead(&mut self) -> Result<EraseAhead, StoreError> {
        let reserve = self.reserve_bytes();
        let Some(mut free) = self.open_sector_free()? else {
            return Ok(EraseAhead::Unknown);
        };
        if free >= reserve {
            return Ok(EraseAhead::Enough { free });
        }
        let pad = [0u8; PAD_LEN];
        // Each filler takes at least PAD_LEN bytes: a sector's worth is the most it can take.
        let most = F::ERASE_SIZE / PAD_LEN + 2;
        for n in 1..=most as u32 {
            self.store(PAD_KEY, &pad)?;
            let now = self.open_sector_free()?.unwrap_or(0);
            if now > free {
                // Switched: the filler now current was copied over; replace it by an empty one.
                self.store(PAD_KEY, &[])?;
                let free = self.open_sector_free()?.unwrap_or(0);
                return Ok(EraseAhead::Erased { free, fillers: n });
            }
            free = now;
        }
        Err(StoreError::Full)
    }
}

/// Some byte of `from..to` is not erased (0xFF).
fn written<F: NorFlash>(flash: &mut F, from: u32, to: u32) -> Result<bool, StoreError> {
    let mut chunk = [0u8; 64];
    let mut at = from;
    while at < to {
        let n = (to - at).min(chunk.len() as u32) as usize;
        let part = chunk.get_mut(..n).ok_or(StoreError::Other)?;
        flash.read(at, part).map_err(|_| StoreError::Flash)?;
        if part.iter().any(|b| *b != 0xFF) {
            return Ok(true);
        }
        at += n as u32;
    }
    Ok(false)
}

/// One past the last byte of `from..to` that is not erased (`from` if all are), reading from
/// the end (the free room is at the end of an open sector, so this reads only that much).
fn last_written<F: NorFlash>(flash: &mut F, from: u32, to: u32) -> Result<u32, StoreError> {
    let mut chunk = [0u8; 64];
    let mut end = to;
    while end > from {
        let n = (end - from).min(chunk.len() as u32);
        let start = end - n;
        let part = chunk.get_mut(..n as usize).ok_or(StoreError::Other)?;
        flash.read(start, part).map_err(|_| StoreError::Flash)?;
        if let Some(i) = part.iter().rposition(|b| *b != 0xFF) {
            return Ok(start + i as u32 + 1);
        }
        end = start;
    }
    Ok(from)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::job::tests::sample;
    use crate::storage::NorFlashModel;

    /// The SKR 2's geometry: two 128 KiB sectors, 16-byte words.
    type Board = NorFlashModel<Vec<u8>, 16, { 128 * 1024 }>;
    const AREA: core::ops::Range<u32> = 0..256 * 1024;

    fn board() -> SettingsStore<Board> {
        SettingsStore::new(Board::erased(vec![0; 256 * 1024]), AREA).unwrap()
    }

    fn erases(st: &mut SettingsStore<Board>) -> u32 {
        st.flash_mut().erases()
    }

    /// One pause/resume cycle's saves: the power-cut record, then its clearing.
    fn pause_cycle(st: &mut SettingsStore<Board>, k: u32) {
        st.save_job(&sample(k, k.is_multiple_of(2))).unwrap();
        st.clear_job().unwrap();
    }

    #[test]
    fn the_free_room_follows_the_saves() {
        let mut st = board();
        assert_eq!(
            st.open_sector_free(),
            Ok(None),
            "a new area has no open sector"
        );
        assert_eq!(st.erase_ahead(), Ok(EraseAhead::Unknown));
        pause_cycle(&mut st, 0);
        let f0 = st.open_sector_free().unwrap().unwrap();
        pause_cycle(&mut st, 1);
        let f1 = st.open_sector_free().unwrap().unwrap();
        assert!(f0 < 128 * 1024 && f1 < f0, "{f0} {f1}");
        println!("one pause/resume cycle takes {} bytes of flash", f0 - f1);
        // The reserve holds at least fifty cycles.
        assert!((f0 - f1) * 50 <= st.reserve_bytes(), "{}", f0 - f1);
    }

    /// Prints of an M500 and up to fifty pauses each, with the erase-ahead between them (idle):
    /// no save or clear of a pause ever erases; only the erase-aheads do. Over several laps
    /// of both sectors, and the records are always there.
    #[test]
    fn saves_during_prints_never_erase_when_erased_ahead_between_prints() {
        let mut st = board();
        let mut k = 0;
        let mut erased_ahead = 0;
        let mut saved = 0;
        for print in 0..28u32 {
            let pauses = 10 + (print * 7) % 41; // 10..=50
            let before = erases(&mut st);
            // An M500 before the print, then its pauses.
            st.save(&crate::storage::store::tests::nth(k)).unwrap();
            saved = k;
            for _ in 0..pauses {
                pause_cycle(&mut st, k);
                k += 1;
            }
            assert_eq!(erases(&mut st), before, "print {print}: a save erased");
            // Idle between prints.
            match st.erase_ahead().unwrap() {
                EraseAhead::Erased { free, fillers } => {
                    erased_ahead += 1;
                    assert!(free >= st.reserve_bytes() && fillers > 0);
                }
                EraseAhead::Enough { free } => assert!(free >= st.reserve_bytes()),
                EraseAhead::Unknown => panic!("the area has an open sector"),
            }
            assert!(st.open_sector_free().unwrap().unwrap() >= st.reserve_bytes());
        }
        assert!(
            erased_ahead >= 2,
            "{erased_ahead}: the test did not lap the sectors"
        );
        assert_eq!(
            st.load(),
            Ok(Some(crate::storage::store::tests::nth(saved)))
        );
        assert_eq!(st.load_job(), Ok(None));
        st.save_job(&sample(7, true)).unwrap();
        // A reboot reads the same.
        let bytes = st.into_flash().into_inner();
        let mut st = SettingsStore::new(Board::new(bytes), AREA).unwrap();
        assert_eq!(st.load_job(), Ok(Some(sample(7, true))));
        assert_eq!(
            st.load(),
            Ok(Some(crate::storage::store::tests::nth(saved)))
        );
    }

    /// Without erase-ahead the same prints do erase inside a pause's save (what this module
    /// prevents): the test above is not passing for want of sector switches.
    #[test]
    fn without_erase_ahead_a_pause_save_erases() {
        let mut st = board();
        let mut in_save = 0;
        for k in 0..2_000u32 {
            let before = erases(&mut st);
            pause_cycle(&mut st, k);
            if erases(&mut st) > before {
                in_save += 1;
                if in_save == 2 {
                    break;
                }
            }
        }
        assert!(in_save >= 2, "{in_save}");
    }

    /// A power cut at any write or erase of an erase-ahead keeps both records.
    #[test]
    fn a_power_cut_during_erase_ahead_keeps_the_records() {
        type Small = NorFlashModel<Vec<u8>, 4, 2048>;
        const RANGE: core::ops::Range<u32> = 0..3 * 2048;
        let mut st = SettingsStore::new(Small::erased(vec![0; 3 * 2048]), RANGE).unwrap();
        let s = crate::storage::store::tests::nth(5);
        st.save(&s).unwrap();
        st.save_job(&sample(3, false)).unwrap();
        // Fill until the reserve is not met.
        let mut k = 0;
        while st.open_sector_free().unwrap().unwrap() >= st.reserve_bytes() {
            st.save_job(&sample(3, false)).unwrap();
            k += 1;
            assert!(k < 100);
        }
        let base = st.into_flash().into_inner();
        let mut cuts = 0;
        for n in 0.. {
            let mut flash = Small::new(base.clone());
            flash.cut_power_at(n);
            let mut st = SettingsStore::new(flash, RANGE).unwrap();
            let r = st.erase_ahead();
            let mut flash = st.into_flash();
            if r.is_ok() && !flash.is_off() {
                assert!(matches!(r, Ok(EraseAhead::Erased { .. })), "{r:?}");
                break;
            }
            cuts += 1;
            flash.restore_power();
            let mut st = SettingsStore::new(flash, RANGE).unwrap();
            assert_eq!(st.load(), Ok(Some(s)), "cut at {n}");
            assert_eq!(st.load_job(), Ok(Some(sample(3, false))), "cut at {n}");
        }
        assert!(cuts > 3, "{cuts}");
    }
}
