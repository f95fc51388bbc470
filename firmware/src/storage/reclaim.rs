//! Foreign data in the store's area, cleared without losing a record that can still be read.
//!
//! sequential-storage reads its area through page markers: the open sector (first word
//! written, last word erased) takes the saves, the sector after it must be erased. A sector
//! after the open one that is *not* erased means, to its repair, a migration cut by a power
//! loss: it erases the open sector and copies the items back from the next one. When that next
//! sector holds data of another firmware, zeros or a half-erased pattern instead, the repair
//! erased the records in the open sector with no power cut at all (measured on the NOR model:
//! a paused job stored, the other sector overwritten, the next settings save lost the job).
//! And an area sequential-storage cannot use at all was erased whole by the old reclaim, with
//! the record kept aside in RAM until rewritten.
//!
//! Both are now done without ever erasing a sector that holds a record that can be read:
//! - before a save ([`SettingsStore::guard_next_sector`]), if the sector after the open one is
//!   not erased and does not hold every record that can be read, it is erased (it cannot be the
//!   source of a migration, whose every current record it would hold); otherwise
//!   sequential-storage's repair redoes its migration from it, as designed.
//! - a save sequential-storage still refuses ([`SettingsStore::reclaim`]) erases each sector
//!   that holds no readable record, then saves again (sequential-storage then appends, or
//!   migrates the kept records with its own power-safe copy); only if that fails too is the
//!   area erased whole and the records kept in RAM written back (the one remaining window; the
//!   tests never reach it).
//!
//! "Holds a record" is a search of the sector for the record's item data (its key byte and its
//! bytes) at every word-aligned address, where sequential-storage places item data; the record's
//! own CRC makes a false match by foreign data negligible. The searches read at most a sector
//! per record and run only in these rare states; the common path reads the page markers (a few
//! words) and erases nothing more than before.

use super::reserve::PAD_KEY;
use super::store::{is_erased, SettingsStore, StoreError, Stored, BUF_LEN, JOB_KEY, SETTINGS_KEY};
use super::RecordError;
use embedded_storage::nor_flash::NorFlash;

/// A record read into RAM as sequential-storage lays out its item data: the key byte, then the
/// bytes.
struct Kept {
    data: [u8; BUF_LEN],
    len: usize,
}

/// A page marker's word (sequential-storage marks with zeros), 4-byte aligned for drivers that
/// need aligned sources.
#[repr(align(4))]
struct Marker([u8; 32]);

impl Kept {
    fn bytes(&self) -> &[u8] {
        self.data.get(..self.len).unwrap_or(&[])
    }
}

impl<F: NorFlash> SettingsStore<F> {
    /// The records that can be read now (settings, paused job).
    fn readable(&mut self) -> [Option<Kept>; 2] {
        [SETTINGS_KEY, JOB_KEY].map(|key| {
            let mut kept = Kept {
                data: [0; BUF_LEN],
                len: 0,
            };
            let n = self
                .fetch(key, |b| {
                    let dst = kept.data.get_mut(1..1 + b.len());
                    dst.ok_or(RecordError::Truncated)?.copy_from_slice(b);
                    Ok(b.len())
                })
                .ok()
                .flatten()?;
            *kept.data.first_mut()? = key;
            kept.len = n + 1;
            Some(kept)
        })
    }

    /// Start of each sector of the area.
    fn sectors(&self) -> impl Iterator<Item = u32> {
        let range = self.map.flash_range();
        range.clone().step_by(F::ERASE_SIZE)
    }

    /// Some byte of `sector`'s first or last word is written: sequential-storage does not see
    /// it as an open (erased) page.
    fn marked(&mut self, sector: u32) -> (bool, bool) {
        let word = F::WRITE_SIZE.max(F::READ_SIZE) as u32;
        let end = sector + F::ERASE_SIZE as u32;
        let flash = &mut self.map.flash().0;
        (
            !is_erased(flash, sector..sector + word),
            !is_erased(flash, end - word..end),
        )
    }

    /// True when `sector` holds `kept` (see the module documentation).
    fn holds(&mut self, sector: u32, kept: &Kept) -> Result<bool, StoreError> {
        let word = F::WRITE_SIZE.max(F::READ_SIZE) as u32;
        let end = sector + F::ERASE_SIZE as u32;
        let want = kept.bytes();
        let flash = &mut self.map.flash().0;
        let mut probe = [0u8; 32];
        let mut at = sector;
        'at: while at + want.len() as u32 <= end {
            for (i, piece) in want.chunks(probe.len()).enumerate() {
                let n = piece.len().next_multiple_of(F::READ_SIZE).min(probe.len());
                let part = probe.get_mut(..n).ok_or(StoreError::Other)?;
                let from = at + (i * 32) as u32;
                flash.read(from, part).map_err(|_| StoreError::Flash)?;
                if part.get(..piece.len()) != Some(piece) {
                    at += word;
                    continue 'at;
                }
            }
            return Ok(true);
        }
        Ok(false)
    }

    /// Erase `sector` behind sequential-storage's back.
    fn erase_sector(&mut self, sector: u32) -> Result<(), StoreError> {
        let end = sector + F::ERASE_SIZE as u32;
        let flash = &mut self.map.flash().0;
        flash.erase(sector, end).map_err(|_| StoreError::Flash)
    }

    /// After erasing behind sequential-storage's back, look a filler up: a key pointer its
    /// cache kept into an erased sector finds no item there and drops the whole cache (the
    /// records' pointers are never into one: they are where the records were read).
    fn forget_erased(&mut self) {
        let _ = self.fetch(PAD_KEY, |_| Ok(()));
    }

    /// The first sector sequential-storage reads as its open page (first word written, last
    /// erased), and the sector after it.
    fn open_pair(&mut self) -> Option<(u32, u32)> {
        let mut sectors = self.sectors().chain(self.sectors().take(1));
        let mut prev = sectors.next()?;
        for next in sectors {
            if self.marked(prev) == (true, false) {
                return Some((prev, next));
            }
            prev = next;
        }
        None
    }

    /// Put the page markers in a state sequential-storage's repair cannot turn against a
    /// readable record (module documentation), before any of its operations:
    /// 1. a sector whose last word is written and first erased (an erase cut half-way) is
    ///    erased, as its repair would, but before its repair looks for a cut migration;
    /// 2. every sector but the first that reads as an open page (first word written, last
    ///    erased: an erase cut leaving the first half, or foreign data) is closed, its last
    ///    word written as sequential-storage closes a page: it reads only the first, and
    ///    cannot migrate from a page that is not closed; closed, its records are read again,
    ///    after the first's, and the next save's repair migrates them;
    /// 3. with `before_save`: the sector after the open one is not erased and does not hold
    ///    every readable record: it is erased (it cannot be a migration's source, which holds
    ///    them all); otherwise sequential-storage's repair migrates from it, as designed.
    ///
    /// Common path: reads the page markers (two words a sector), writes and erases nothing.
    pub(super) fn prepare(&mut self, before_save: bool) -> Result<(), StoreError> {
        let word = F::WRITE_SIZE.max(F::READ_SIZE);
        let zeros = Marker([0; 32]);
        let marker = zeros.0.get(..word).ok_or(StoreError::Config)?;
        let mut first = true;
        let mut erased = false;
        for sector in self.sectors() {
            match self.marked(sector) {
                (false, true) => {
                    self.erase_sector(sector)?;
                    erased = true;
                }
                (true, false) if !first => {
                    let end = sector + F::ERASE_SIZE as u32;
                    let flash = &mut self.map.flash().0;
                    flash
                        .write(end - word as u32, marker)
                        .map_err(|_| StoreError::Flash)?;
                }
                (true, false) => first = false,
                _ => {}
            }
        }
        if erased {
            self.forget_erased();
        }
        let Some((_, next)) = self.open_pair().filter(|_| before_save) else {
            return Ok(());
        };
        if self.marked(next) == (false, false) {
            return Ok(());
        }
        for kept in self.readable().iter().flatten() {
            if !self.holds(next, kept)? {
                self.erase_sector(next)?;
                self.forget_erased();
                return Ok(());
            }
        }
        Ok(())
    }

    /// A save sequential-storage refused: erase each sector that holds no readable record and
    /// save again; if that fails too, erase the area and write the readable records back
    /// (module documentation).
    pub(super) fn reclaim(&mut self, key: u8, bytes: &[u8]) -> Result<Stored, StoreError> {
        self.prepare(true)?;
        let kept = self.readable();
        for sector in self.sectors() {
            let mut held = false;
            for k in kept.iter().flatten() {
                held |= self.holds(sector, k)?;
            }
            let end = sector + F::ERASE_SIZE as u32;
            if !held && !is_erased(&mut self.map.flash().0, sector..end) {
                self.erase_sector(sector)?;
            }
        }
        self.forget_erased();
        if self.store_item(key, bytes).is_ok() {
            return Ok(Stored::Reclaimed);
        }
        let range = self.map.flash_range();
        let flash = &mut self.map.flash().0;
        flash
            .erase(range.start, range.end)
            .map_err(|_| StoreError::Flash)?;
        self.forget_erased();
        for k in kept.iter().flatten() {
            if let Some((other, value)) = k.bytes().split_first() {
                if *other != key {
                    self.store_item(*other, value)?;
                }
            }
        }
        self.store_item(key, bytes)?;
        Ok(Stored::Reclaimed)
    }
}
