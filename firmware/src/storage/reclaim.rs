//! Foreign data in the store's area, cleared without losing a record that can still be read.
//!
//! sequential-storage reads its area through page markers: a sector whose first word is written
//! and last erased is the open page (the first such one from the start is taken), a sector with
//! both written is closed, both erased is open for use; the sector after the open one must be
//! erased. Three of its rules turn against records when the area holds data it did not write
//! (another firmware's, zeros, random bytes) or an erase was cut half-way:
//! - a sector after the open one that is not erased is, to its repair (run whenever an
//!   operation meets `Corrupted`), a migration cut by a power loss: it erases the open sector
//!   and copies the items back from that one. A foreign sector there cost the records in the
//!   open one on the next save, no power cut needed (measured: a paused job stored, the other
//!   sector overwritten with zeros, the next M500 lost the job);
//! - a second sector that reads as open (an erase cut that left the first half as it was, or
//!   foreign data) is never read when it comes after the first, and shadows the records when
//!   it comes before;
//! - an area it refuses outright was erased whole by the old reclaim, the record kept in RAM
//!   until rewritten: lost if the power went between.
//!
//! [`SettingsStore::prepare`] runs before every load and save: it erases a sector whose last
//! word is written and first is not (an erase cut half-way: sequential-storage's own repair
//! erases it, but only after it has looked for a cut migration), closes every sector but the
//! first that reads as open (one word written, as sequential-storage closes a page: its records
//! are read again, and the next save migrates them), and, before a save, erases the sector
//! after the open one if it is not erased and does not hold every readable record (a
//! migration's source holds them all; a foreign sector does not; otherwise sequential-storage's
//! repair migrates, as designed). [`SettingsStore::reclaim`], for a save sequential-storage
//! still refuses, runs it, erases each sector that holds no readable record and saves again;
//! only if that fails too is the whole area erased and the readable records written back from
//! RAM (the one window left; no test reaches it).
//!
//! "Holds a record" is a search of the sector for the record's item data (its key byte then
//! its bytes) at every word-aligned address, where sequential-storage places item data; the
//! record's own CRC makes a false match by foreign data negligible. The searches read at most
//! a sector per record and run only in these rare states: the common path reads two words per
//! sector and writes or erases nothing more than before.
//!
//! Limits: the guarantees are checked on two-sector areas (the board's sectors 10 and 11, the
//! sim's file); with three or more sectors, a cut erase of a foreign sector below the records'
//! one that leaves its first half can still hide them, because sequential-storage walks back
//! from the first open-looking sector only through the sectors just before it. Its own sector
//! switch, cut in its erase of the old sector in that same way (the model's
//! `Cut::PartialTail`), can load an older value when the old sector comes first: not changed
//! here (`a_power_cut_at_any_flash_operation_of_a_save_keeps_old_or_new` cuts in the other two
//! ways).

use super::reserve::PAD_KEY;
use super::store::{
    is_erased, present, SettingsStore, StoreError, Stored, BUF_LEN, JOB_KEY, SETTINGS_KEY,
};
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
    /// The records that can be read now (settings, paused job); an empty one where none can.
    fn readable(&mut self) -> [Kept; 2] {
        let mut kept = [SETTINGS_KEY, JOB_KEY].map(|key| {
            let mut data = [0; BUF_LEN];
            data[0] = key;
            Kept { data, len: 0 }
        });
        for k in &mut kept {
            let key = k.data[0];
            let got = self.fetch(key, |b| {
                let dst = k.data.get_mut(1..1 + b.len());
                dst.ok_or(RecordError::Truncated)?.copy_from_slice(b);
                Ok(b.len() + 1)
            });
            k.len = got.ok().flatten().unwrap_or(0);
        }
        kept
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
        let _ = self.fetch(PAD_KEY, present);
    }

    /// The first sector sequential-storage reads as its open page (first word written, last
    /// erased), and the sector after it.
    pub(super) fn open_pair(&mut self) -> Option<(u32, u32)> {
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
        for kept in self.readable().iter().filter(|k| k.len > 0) {
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
            for k in kept.iter().filter(|k| k.len > 0) {
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
        for k in &kept {
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
