//! The store: the settings and the paused job in two flash sectors, in the format of
//! `format.rs` (docs/settings.md, "The store", gives the reasoning and the guarantees).
//!
//! - **One sector is current**: the one whose header (written by this store: magic, format,
//!   epoch, CRC; two copies) has the higher epoch. Nothing else is trusted: a sector of zeros,
//!   random bytes, another firmware's data (Marlin's flash EEPROM emulation uses sector 11) or
//!   an interrupted erase has no such header and is never read for records, never taken for an
//!   interrupted sector switch.
//! - **A save appends** two copies of the record's frame to the current sector, each written
//!   head and data first, read back, then its commit (written last, read back). Appends go
//!   past every byte that is not erased, so a stray byte in the free room costs room, not a
//!   record. A clear of the paused job always fits (every other save leaves room for it).
//! - **A sector switch** (the current sector is full) writes the records still current (the
//!   other key's, copied from whole frames) and the new one into the other sector — erased and
//!   read back erased first — and then that sector's header with the next epoch: the header,
//!   written last, is the switch's commit. The old sector is left as it is until the
//!   erase-ahead erases it while idle, so a switch erases at most one sector, and none when the
//!   other sector was erased ahead.
//! - **Every save is read back** as a boot reads it: the area is scanned again from the flash
//!   and the record must come back byte for byte, or the save is an error.
//! - **Erases only when affordable** ([`Moment`]): while idle always; while paused only if the
//!   driver says its flash can ([`SettingsStore::erase_while_paused`]); while printing never.
//!
//! A power cut at any operation leaves the current sector as it was or the new record
//! committed; a cut in a switch leaves the old sector current (the new one has no header yet)
//! or the new one whole. An erase only ever touches the sector that is not current.

use super::api::{Ahead, Moment, RecordStore, Saved, StoreError};
use super::format::{self, key_index, Layout, KEYS, MAX_DATA};
use super::job::PausedJob;
use super::record::Settings;
use super::sector::{self, Area, FrameBuf, ReadError, Slot};
use embedded_storage::nor_flash::NorFlash;

/// Key of the settings record.
pub const SETTINGS_KEY: u8 = 1;
/// Key of the paused-job record.
pub const JOB_KEY: u8 = 2;

impl From<ReadError> for StoreError {
    fn from(_: ReadError) -> Self {
        StoreError::Flash
    }
}

/// What the store knows of the area (read from the flash; dropped after every write, so the
/// flash, not RAM, is the truth).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mount {
    /// No sector has a header this store wrote; `erased`: which ones read all `0xFF`.
    Unclaimed { erased: [bool; 2] },
    /// A sector is current.
    Current(Current),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Current {
    /// Sector 0 or 1.
    index: usize,
    /// Its generation.
    epoch: u32,
    /// Where the next frame may go.
    end: u32,
    /// Each key's newest whole frame.
    latest: [Option<Slot>; KEYS],
    /// Keys with frames but none whole.
    damaged: [bool; KEYS],
}

/// Where a frame's data comes from.
#[derive(Clone, Copy)]
enum Source<'a> {
    /// The caller's bytes.
    Bytes(&'a [u8]),
    /// A whole frame of the current sector (copied in a switch).
    Frame(Current, Slot),
}

/// `a` is a later generation than `b` (serial-number order: an epoch that wraps still counts
/// as later).
fn later(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// Records in two NOR-flash sectors. See the module documentation.
pub struct SettingsStore<F: NorFlash> {
    flash: F,
    area: Area,
    erase_while_paused: bool,
    mount: Option<Mount>,
    buf: FrameBuf,
}

impl<F: NorFlash> SettingsStore<F> {
    /// A store in `range` (byte offsets within `flash`): exactly two whole sectors, each
    /// large enough for the records and a switch. Nothing is read until the first use; a
    /// pause may erase (see [`Self::erase_while_paused`]).
    pub fn new(flash: F, range: core::ops::Range<u32>) -> Result<Self, StoreError> {
        let sector = F::ERASE_SIZE as u32;
        let word = F::WRITE_SIZE as u32;
        let layout = Layout { word };
        let read = F::READ_SIZE as u32;
        let fits = layout.records_start()
            + 6 * layout.frame_len(MAX_DATA as u32)
            + 2 * layout.frame_len(0)
            <= sector;
        let ok = word.is_power_of_two()
            && word <= 32
            && read.is_power_of_two()
            && read <= word.min(16)
            && sector.is_multiple_of(64)
            && fits
            && range.start.is_multiple_of(sector)
            && range.end.checked_sub(range.start) == Some(2 * sector);
        if !ok {
            return Err(StoreError::Config);
        }
        Ok(Self {
            flash,
            area: Area {
                base: range.start,
                sector,
                layout,
            },
            erase_while_paused: true,
            mount: None,
            buf: FrameBuf([0; format::FRAME_CAP]),
        })
    }

    /// Whether a save while paused ([`Moment::Paused`]) may erase a sector when it finds no
    /// erased room: the driver's call (the SKR 2 switches the heaters off and feeds the
    /// watchdog around an erase; a driver that cannot should say `false`, and such a save
    /// then fails with [`StoreError::NoErasedRoom`]). `true` unless set.
    pub fn erase_while_paused(mut self, yes: bool) -> Self {
        self.erase_while_paused = yes;
        self
    }

    /// The flash back (to reboot a model in tests, or to close the sim's file).
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// The flash (tests count its operations; the board's wrapper feeds the watchdog). Anything
    /// written through it is read again by the store's next use.
    pub fn flash_mut(&mut self) -> &mut F {
        self.mount = None;
        &mut self.flash
    }

    /// The current sector (0 or 1), `None` while nothing was ever saved.
    pub fn current_sector(&mut self) -> Result<Option<usize>, StoreError> {
        Ok(match self.mounted()? {
            Mount::Current(c) => Some(c.index),
            Mount::Unclaimed { .. } => None,
        })
    }

    /// Erased bytes left in the current sector, `None` while nothing was ever saved.
    pub fn free_bytes(&mut self) -> Result<Option<u32>, StoreError> {
        let sector = self.area.sector;
        Ok(match self.mounted()? {
            Mount::Current(c) => Some(sector - c.end),
            Mount::Unclaimed { .. } => None,
        })
    }

    /// Erased bytes a save of `len` data bytes takes in the current sector: its two frames,
    /// and (but for a clear) the room every save leaves for a cleared job.
    pub fn room_for(&self, len: usize) -> u32 {
        let l = self.area.layout;
        let clear = 2 * l.frame_len(0);
        2 * l.frame_len(len as u32) + if len == 0 { 0 } else { clear }
    }

    /// Free bytes the erase-ahead keeps in the current sector: an eighth of a sector (16 KiB
    /// of the SKR 2's 128 KiB: 28 pause/resume cycles at 584 bytes, with the other sector
    /// erased for 224 more).
    pub fn reserve_bytes(&self) -> u32 {
        self.area.sector / 8
    }

    /// The raw bytes stored under `key` (`None`: nothing, or a cleared record; an error for a
    /// record with frames in flash but none whole).
    pub fn read(&mut self, key: u8) -> Result<Option<&[u8]>, StoreError> {
        let h = self.area.layout.head() as usize;
        Ok(self
            .fetch(key)?
            .and_then(move |len| self.buf.0.get(h..h + len)))
    }

    /// Store `bytes` under `key` (empty: the key has no value) at moment `at`; it is read
    /// back from the flash before this returns `Ok`.
    pub fn write(&mut self, key: u8, bytes: &[u8], at: Moment) -> Result<Saved, StoreError> {
        key_index(key).ok_or(StoreError::Config)?;
        if bytes.len() > MAX_DATA {
            return Err(StoreError::TooLarge);
        }
        let done = self.write_record(key, bytes, at);
        // Read everything again from the flash, as a boot would.
        self.mount = None;
        let saved = done?;
        match self.read(key)? {
            Some(back) if back == bytes => Ok(saved),
            None if bytes.is_empty() => Ok(saved),
            _ => Err(StoreError::NotVerified),
        }
    }

    /// The area as the flash has it now.
    fn mounted(&mut self) -> Result<Mount, StoreError> {
        if let Some(m) = self.mount {
            return Ok(m);
        }
        let (f, a) = (&mut self.flash, &self.area);
        let e = [sector::epoch(f, a, 0)?, sector::epoch(f, a, 1)?];
        let current = match e {
            [None, None] => None,
            [Some(e0), Some(e1)] if later(e1, e0) => Some((1, e1)),
            [Some(e0), _] => Some((0, e0)),
            [None, Some(e1)] => Some((1, e1)),
        };
        let m = match current {
            None => {
                let mut erased = [false; 2];
                for (i, e) in erased.iter_mut().enumerate() {
                    *e = sector::is_erased(f, a.start(i), a.start(i) + a.sector)?;
                }
                Mount::Unclaimed { erased }
            }
            Some((index, epoch)) => {
                let scan = sector::scan(f, a, index, epoch, &mut self.buf)?;
                Mount::Current(Current {
                    index,
                    epoch,
                    end: scan.end,
                    latest: scan.latest,
                    damaged: scan.damaged,
                })
            }
        };
        self.mount = Some(m);
        Ok(m)
    }

    /// Length of `key`'s data, read whole into the buffer (`None`: no value). A key whose
    /// frames are all damaged (or whose only save was cut) is [`StoreError::Damaged`].
    fn fetch(&mut self, key: u8) -> Result<Option<usize>, StoreError> {
        let k = key_index(key).ok_or(StoreError::Config)?;
        // A frame the scan found whole and that no longer is was changed under the store:
        // read the area again once.
        for _ in 0..2 {
            let Mount::Current(c) = self.mounted()? else {
                return Ok(None);
            };
            if c.damaged[k] {
                return Err(StoreError::Damaged);
            }
            let Some(slot) = c.latest[k].filter(|s| s.len > 0) else {
                return Ok(None);
            };
            let (f, a) = (&mut self.flash, &self.area);
            if sector::read_frame(f, a, c.index, c.epoch, slot, &mut self.buf)? {
                return Ok(Some(usize::from(slot.len)));
            }
            self.mount = None;
        }
        Err(StoreError::NotVerified)
    }

    fn erase_allowed(&self, at: Moment) -> bool {
        match at {
            Moment::Idle => true,
            Moment::Paused => self.erase_while_paused,
            Moment::Printing => false,
        }
    }

    /// Erase sector `index` (never the current one) and check it reads erased.
    fn erase(&mut self, index: usize) -> Result<(), StoreError> {
        let from = self.area.start(index);
        let to = from + self.area.sector;
        self.flash.erase(from, to).map_err(|_| StoreError::Flash)?;
        if sector::is_erased(&mut self.flash, from, to)? {
            Ok(())
        } else {
            Err(StoreError::EraseFailed)
        }
    }

    /// Make sector `index` erased for a switch, at moment `at`.
    fn make_room(&mut self, index: usize, at: Moment) -> Result<Saved, StoreError> {
        let from = self.area.start(index);
        if sector::is_erased(&mut self.flash, from, from + self.area.sector)? {
            return Ok(Saved::Written);
        }
        if !self.erase_allowed(at) {
            return Err(StoreError::NoErasedRoom);
        }
        self.erase(index)?;
        Ok(Saved::AfterErase)
    }

    fn write_record(&mut self, key: u8, bytes: &[u8], at: Moment) -> Result<Saved, StoreError> {
        match self.mounted()? {
            Mount::Unclaimed { erased } => {
                if bytes.is_empty() {
                    return Ok(Saved::Written); // nothing to clear
                }
                // An erased sector if there is one; else sector 0 (foreign data) is erased.
                let target = usize::from(!erased[0] && erased[1]);
                let saved = self.make_room(target, at)?;
                self.write_generation(target, 1, None, Some((key, bytes)))?;
                Ok(saved)
            }
            Mount::Current(c) => {
                let k = key_index(key).ok_or(StoreError::Config)?;
                if bytes.is_empty() && !c.damaged[k] && c.latest[k].is_none_or(|s| s.len == 0) {
                    return Ok(Saved::Written); // nothing to clear
                }
                // A cleared job always fits: every other save leaves room for one.
                let clear = 2 * self.area.layout.frame_len(0);
                let limit = self.area.sector - if bytes.is_empty() { 0 } else { clear };
                let (index, epoch) = (c.index, c.epoch);
                if self
                    .write_copies(index, epoch, c.end, key, Source::Bytes(bytes), limit)?
                    .is_some()
                {
                    return Ok(Saved::Written);
                }
                // The sector is full: switch to the other one.
                let other = 1 - c.index;
                let saved = self.make_room(other, at)?;
                self.write_generation(other, epoch.wrapping_add(1), Some(c), Some((key, bytes)))?;
                Ok(saved)
            }
        }
    }

    /// Write two copies of a frame of `src` into sector `index` (generation `epoch`) from
    /// offset `end`, ending by `limit`; returns where the next frame may go, or `None` when
    /// there is no room (a copy may have been written). A copy that does not read back (the
    /// room was not erased: a stray write) is written again past every byte not erased.
    fn write_copies(
        &mut self,
        index: usize,
        epoch: u32,
        mut end: u32,
        key: u8,
        src: Source<'_>,
        limit: u32,
    ) -> Result<Option<u32>, StoreError> {
        let len = match src {
            Source::Bytes(b) => b.len() as u32,
            Source::Frame(_, slot) => u32::from(slot.len),
        };
        let frame = self.area.layout.frame_len(len);
        let (mut copies, mut misses) = (0, 0);
        while copies < 2 {
            if end + frame * (2 - copies) > limit || misses > 2 {
                return Ok(None);
            }
            if self.write_frame(index, epoch, end, key, src)? {
                copies += 1;
                end += frame;
            } else {
                misses += 1;
                let used = sector::used_end(&mut self.flash, &self.area, index)?;
                end = (end + frame).max(used);
            }
        }
        Ok(Some(end))
    }

    /// Write one frame of `src` at offset `at` of sector `index`: head and data, read back,
    /// then the commit, read back. `Ok(false)`: it did not read back.
    fn write_frame(
        &mut self,
        index: usize,
        epoch: u32,
        at: u32,
        key: u8,
        src: Source<'_>,
    ) -> Result<bool, StoreError> {
        let l = self.area.layout;
        let h = l.head() as usize;
        let len = match src {
            Source::Bytes(b) => {
                let d = self
                    .buf
                    .0
                    .get_mut(h..h + b.len())
                    .ok_or(StoreError::TooLarge)?;
                d.copy_from_slice(b);
                b.len()
            }
            Source::Frame(c, slot) => {
                let (f, a) = (&mut self.flash, &self.area);
                if !sector::read_frame(f, a, c.index, c.epoch, slot, &mut self.buf)? {
                    // The record to carry over is no longer whole: no switch without it.
                    return Err(StoreError::NotVerified);
                }
                usize::from(slot.len)
            }
        };
        let n = format::encode_frame(l, &mut self.buf.0, at, epoch, key, len);
        let body = h + l.padded(len as u32) as usize;
        let start = self.area.start(index) + at;
        Ok(self.program(start, 0..body)? && self.program(start + body as u32, body..n)?)
    }

    /// Program `buf[part]` at flash offset `to` and read it back: true when it reads as
    /// written.
    fn program(&mut self, to: u32, part: core::ops::Range<usize>) -> Result<bool, StoreError> {
        let bytes = self.buf.0.get(part).ok_or(StoreError::TooLarge)?;
        self.flash.write(to, bytes).map_err(|_| StoreError::Flash)?;
        let mut back = [0u8; 32];
        for (k, want) in bytes.chunks(32).enumerate() {
            let got = &mut back[..want.len()];
            self.flash
                .read(to + 32 * k as u32, got)
                .map_err(|_| StoreError::Flash)?;
            if got != want {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// A sector switch: into sector `target` (erased), the records of `from` still current
    /// (but `new`'s key) and `new`, then the header of generation `epoch`, written last.
    fn write_generation(
        &mut self,
        target: usize,
        epoch: u32,
        from: Option<Current>,
        new: Option<(u8, &[u8])>,
    ) -> Result<(), StoreError> {
        let l = self.area.layout;
        let limit = self.area.sector;
        let mut end = l.records_start();
        let no_room = StoreError::NotVerified;
        if let Some(c) = from {
            for (k, slot) in c.latest.iter().enumerate() {
                let key = k as u8 + 1;
                let Some(slot) = slot.filter(|s| s.len > 0) else {
                    continue;
                };
                if new.is_some_and(|(nk, _)| nk == key) {
                    continue;
                }
                let src = Source::Frame(c, slot);
                end = self
                    .write_copies(target, epoch, end, key, src, limit)?
                    .ok_or(no_room)?;
            }
        }
        if let Some((key, bytes)) = new.filter(|(_, b)| !b.is_empty()) {
            self.write_copies(target, epoch, end, key, Source::Bytes(bytes), limit)?
                .ok_or(no_room)?;
        }
        // The commit of the switch: the header, two copies.
        let h = l.head() as usize;
        self.buf.0[..16].copy_from_slice(&format::sector_header(epoch));
        self.buf.0[16..h].fill(0xFF);
        let start = self.area.start(target);
        if !self.program(start, 0..h)? {
            return Err(StoreError::NotVerified);
        }
        // The second copy guards the first against a stray byte; whether the switch is done
        // is decided by reading the area back.
        self.program(start + h as u32, 0..h)?;
        Ok(())
    }

    fn erase_ahead_now(&mut self) -> Result<Ahead, StoreError> {
        let Mount::Current(mut c) = self.mounted()? else {
            return Ok(Ahead::NothingSaved);
        };
        let mut erased = 0;
        if self.area.sector - c.end < self.reserve_bytes() {
            let other = 1 - c.index;
            if self.make_room(other, Moment::Idle)? == Saved::AfterErase {
                erased += 1;
            }
            self.write_generation(other, c.epoch.wrapping_add(1), Some(c), None)?;
            self.mount = None;
            // Every record current before is current after, with its length.
            let kept = |l: &[Option<Slot>; KEYS]| l.map(|s| s.filter(|s| s.len > 0).map(|s| s.len));
            c = match self.mounted()? {
                Mount::Current(n) if n.index == other && kept(&n.latest) == kept(&c.latest) => n,
                _ => return Err(StoreError::NotVerified),
            };
        }
        if self.make_room(1 - c.index, Moment::Idle)? == Saved::AfterErase {
            erased += 1;
        }
        Ok(Ahead::Ready {
            free_bytes: self.area.sector - c.end,
            erased,
        })
    }
}

impl<F: NorFlash> RecordStore for SettingsStore<F> {
    fn load_settings(&mut self) -> Result<Option<Settings>, StoreError> {
        if let Mount::Unclaimed { erased } = self.mounted()? {
            return if erased == [true, true] {
                Ok(None)
            } else {
                Err(StoreError::Foreign)
            };
        }
        match self.read(SETTINGS_KEY)? {
            None => Ok(None),
            Some(b) => Settings::decode(b).map(Some).map_err(StoreError::Record),
        }
    }

    fn save_settings(&mut self, s: &Settings, at: Moment) -> Result<Saved, StoreError> {
        s.validate().map_err(StoreError::Record)?;
        self.write(SETTINGS_KEY, &s.encode(), at)
    }

    fn load_job(&mut self) -> Result<Option<PausedJob>, StoreError> {
        match self.read(JOB_KEY)? {
            None => Ok(None),
            Some(b) => PausedJob::decode(b).map(Some).map_err(StoreError::Record),
        }
    }

    fn save_job(&mut self, job: &PausedJob, at: Moment) -> Result<Saved, StoreError> {
        self.write(JOB_KEY, &job.encode(), at)
    }

    fn clear_job(&mut self, at: Moment) -> Result<Saved, StoreError> {
        self.write(JOB_KEY, &[], at)
    }

    fn erase_ahead(&mut self) -> Result<Ahead, StoreError> {
        let r = self.erase_ahead_now();
        if r.is_err() {
            self.mount = None;
        }
        r
    }
}
