//! The store: records kept in a NOR-flash area through sequential-storage's map, which appends
//! every save as a new item (header CRC, data CRC) and only erases a sector once the items
//! still current have been copied out of it. A power cut during a save therefore leaves either
//! the previous item or the new one current; a half-written item fails its CRC and is skipped.
//!
//! The store is generic over the blocking [`NorFlash`] traits: the board passes its flash
//! sectors, the sim a file-backed model, the tests [`super::NorFlashModel`].
//!
//! **An area it cannot use is reclaimed by the next write**: sectors left by another firmware,
//! zeros, random bytes or a half-erased sector make sequential-storage answer `Corrupted` or
//! `FullStorage` even after its own repair, for ever, and no command would erase them. Loading
//! then falls back to the factory values (the executive says so); the next store keeps aside
//! the other record if it can still be read, erases the whole area, writes that record back
//! and then the new one ([`Stored::Reclaimed`]). A power cut during the reclaim leaves the area
//! unreadable or erased (the factory values load, as before the reclaim) or the new record, and
//! the next store reclaims again if needed; a record kept aside is lost if the power goes
//! between the erase and its rewrite (the record was in an area nothing else could be written
//! to).

use super::flash::{block_on, Blocking};
use super::job::{PausedJob, JOB_RECORD_LEN};
use super::record::{RecordError, Settings, RECORD_LEN};
use embedded_storage::nor_flash::NorFlash;
use sequential_storage::cache::key_pointers::ArrayKeyPointers;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

/// Map key of the settings record.
pub const SETTINGS_KEY: u8 = 1;
/// Map key of the paused-job record.
pub const JOB_KEY: u8 = 2;

/// Bytes of the work buffer: room for the longest record plus its key byte, rounded up to the
/// largest flash word sequential-storage supports (32 B).
pub const BUF_LEN: usize = 256;
const _: () = assert!((RECORD_LEN + 1).div_ceil(32) * 32 <= BUF_LEN);
const _: () = assert!((JOB_RECORD_LEN + 1).div_ceil(32) * 32 <= BUF_LEN);

/// What a cleared paused-job entry holds (no job).
const NO_JOB: [u8; 1] = [0];

/// Why the store could not load or save.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// The flash area is not a whole number (≥ 2) of sectors, or its sectors are too small.
    Config,
    /// The flash driver reported an error (the operation may have been cut short).
    Flash,
    /// The area is full of current items (cannot happen with the few keys kept here).
    Full,
    /// The area's contents make no sense to sequential-storage and could not be repaired.
    Corrupted,
    /// An item was found but its record was refused.
    Record(RecordError),
    /// The area has been written, but holds no valid record of the kind asked for (its item
    /// was damaged: sequential-storage's CRC skipped it).
    NoValidRecord,
    /// Any other sequential-storage error.
    Other,
}

impl core::fmt::Display for StoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StoreError::Config => f.write_str("settings area misconfigured"),
            StoreError::Flash => f.write_str("flash error"),
            StoreError::Full => f.write_str("settings area full"),
            StoreError::Corrupted => f.write_str("settings area corrupted"),
            StoreError::Record(e) => write!(f, "{e}"),
            StoreError::NoValidRecord => f.write_str("no valid record in a used flash area"),
            StoreError::Other => f.write_str("settings store error"),
        }
    }
}

fn store_error<E>(e: sequential_storage::Error<E>) -> StoreError {
    match e {
        sequential_storage::Error::Storage { .. } => StoreError::Flash,
        sequential_storage::Error::FullStorage => StoreError::Full,
        sequential_storage::Error::Corrupted { .. } => StoreError::Corrupted,
        _ => StoreError::Other,
    }
}

/// How a record was stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stored {
    /// Appended to the area (the usual way).
    Appended,
    /// The area held data the store could not use: it was erased first (see the module
    /// documentation).
    Reclaimed,
}

/// sequential-storage's cache of where each key's newest item is (the settings, the paused
/// job and the erase-ahead's filler: 3 keys, room for 4; about 40 bytes). Without it every
/// lookup scans the whole area, and a sector switch, which looks up every item of the old
/// sector, read 89.6 MB of flash for ~600 stale settings items (measured on the NOR model
/// with the board's geometry): seconds of MCU time with the executor and the heaters' PWM
/// stopped and the watchdog starved (a reset on the emulated board). With it the switch reads
/// a few hundred kilobytes (`cargo test -p firmware --lib storage::store -- --nocapture`).
/// The cache follows sequential-storage's rules: one per store, passed to every call; it is
/// rebuilt from the flash after a reboot (a new store).
type KeyCache = Cache<Uncached, Uncached, ArrayKeyPointers<u8, 4>, u8>;

/// A 4-byte-aligned work buffer (some internal flash drivers need aligned sources).
#[repr(align(4))]
struct Buf([u8; BUF_LEN]);

/// Records in a NOR-flash area. See the module documentation.
pub struct SettingsStore<F: NorFlash> {
    pub(super) map: MapStorage<u8, Blocking<F>, KeyCache>,
    buf: Buf,
    /// Some byte of the area was not erased when the store was made (or a record was stored
    /// since): a missing record then means a damaged one.
    used: bool,
}

impl<F: NorFlash> SettingsStore<F> {
    /// A store in `range` (byte offsets within `flash`, whole sectors, at least two).
    pub fn new(mut flash: F, range: core::ops::Range<u32>) -> Result<Self, StoreError> {
        let config =
            MapConfig::<Blocking<F>>::try_new(range.clone()).map_err(|_| StoreError::Config)?;
        let used = !is_erased(&mut flash, range);
        Ok(Self {
            map: MapStorage::new(
                Blocking(flash),
                config,
                Cache::new(Uncached, Uncached, ArrayKeyPointers::new()),
            ),
            buf: Buf([0; BUF_LEN]),
            used,
        })
    }

    /// The flash back (to reboot a model in tests, or to close the sim's file).
    pub fn into_flash(self) -> F {
        self.map.destroy().0 .0
    }

    /// The flash (tests count its operations; the board's wrapper reports on its erases).
    pub fn flash_mut(&mut self) -> &mut F {
        &mut self.map.flash().0
    }

    /// The raw bytes stored under `key` (None: nothing stored), handed to `decode`.
    pub fn fetch<T>(
        &mut self,
        key: u8,
        decode: impl FnOnce(&[u8]) -> Result<T, RecordError>,
    ) -> Result<Option<T>, StoreError> {
        let item =
            block_on(self.map.fetch_item::<&[u8]>(&mut self.buf.0, &key)).map_err(store_error)?;
        match item {
            None => Ok(None),
            Some(bytes) => decode(bytes).map(Some).map_err(StoreError::Record),
        }
    }

    /// Store `bytes` under `key` (the previous value stays current until this one is whole);
    /// an area sequential-storage cannot use is reclaimed first (module documentation).
    pub fn store(&mut self, key: u8, bytes: &[u8]) -> Result<Stored, StoreError> {
        self.used = true;
        match block_on(self.map.store_item(&mut self.buf.0, &key, &bytes)) {
            Ok(()) => Ok(Stored::Appended),
            Err(
                sequential_storage::Error::Corrupted { .. }
                | sequential_storage::Error::FullStorage,
            ) => self.reclaim(key, bytes),
            Err(e) => Err(store_error(e)),
        }
    }

    /// Erase the whole area and store `bytes` under `key`, keeping the other record if it
    /// can be read.
    fn reclaim(&mut self, key: u8, bytes: &[u8]) -> Result<Stored, StoreError> {
        let other = if key == SETTINGS_KEY {
            JOB_KEY
        } else {
            SETTINGS_KEY
        };
        let mut kept = [0u8; BUF_LEN];
        let kept_len = match block_on(self.map.fetch_item::<&[u8]>(&mut self.buf.0, &other)) {
            Ok(Some(b)) => kept.get_mut(..b.len()).map(|k| {
                k.copy_from_slice(b);
                b.len()
            }),
            _ => None,
        };
        block_on(self.map.erase_all()).map_err(store_error)?;
        if let Some(k) = kept_len.and_then(|n| kept.get(..n)) {
            block_on(self.map.store_item(&mut self.buf.0, &other, &k)).map_err(store_error)?;
        }
        block_on(self.map.store_item(&mut self.buf.0, &key, &bytes)).map_err(store_error)?;
        Ok(Stored::Reclaimed)
    }

    /// True when some record (of any key) can be read.
    fn any_record(&mut self) -> bool {
        [SETTINGS_KEY, JOB_KEY, super::reserve::PAD_KEY]
            .into_iter()
            .any(|k| matches!(self.fetch(k, |_| Ok(())), Ok(Some(()))))
    }

    /// The saved settings: `Ok(None)` when none were ever saved, an error when what is there
    /// cannot be read or is refused (the caller falls back to the factory defaults).
    pub fn load(&mut self) -> Result<Option<Settings>, StoreError> {
        match self.fetch(SETTINGS_KEY, Settings::decode)? {
            Some(s) => Ok(Some(s)),
            // Written, but no readable record at all: the settings item was damaged.
            None if self.used && !self.any_record() => Err(StoreError::NoValidRecord),
            None => Ok(None),
        }
    }

    /// Save `s` (checked first: out-of-range settings are never written).
    pub fn save(&mut self, s: &Settings) -> Result<Stored, StoreError> {
        s.validate().map_err(StoreError::Record)?;
        self.store(SETTINGS_KEY, &s.encode())
    }

    /// The paused job kept for a power-cut resume (None: none, or cleared).
    pub fn load_job(&mut self) -> Result<Option<PausedJob>, StoreError> {
        let got = self.fetch(JOB_KEY, |b| {
            if b == NO_JOB {
                Ok(None)
            } else {
                PausedJob::decode(b).map(Some)
            }
        })?;
        Ok(got.flatten())
    }

    /// Keep `job` for a power-cut resume (replaces the previous one only once whole).
    pub fn save_job(&mut self, job: &PausedJob) -> Result<Stored, StoreError> {
        self.store(JOB_KEY, &job.encode())
    }

    /// Forget the paused job (it resumed, or was cancelled).
    pub fn clear_job(&mut self) -> Result<Stored, StoreError> {
        self.store(JOB_KEY, &NO_JOB)
    }
}

/// True when every byte of `range` reads `0xFF` (a read error counts as written).
fn is_erased<F: NorFlash>(flash: &mut F, range: core::ops::Range<u32>) -> bool {
    let mut chunk = [0u8; 64];
    let mut at = range.start;
    while at < range.end {
        let n = (range.end - at).min(chunk.len() as u32) as usize;
        let Some(part) = chunk.get_mut(..n) else {
            return false;
        };
        if flash.read(at, part).is_err() || part.iter().any(|b| *b != 0xFF) {
            return false;
        }
        at += n as u32;
    }
    true
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::config::MachineConfig;
    use crate::storage::{Cut, FlashOp, NorFlashModel, Stored};
    use crate::thermal::pid::PidGains;

    /// Small sectors so a few dozen saves wrap around the area.
    type Small = NorFlashModel<Vec<u8>, 4, 1024>;
    const SMALL_RANGE: core::ops::Range<u32> = 0..3 * 1024;

    fn factory() -> Settings {
        Settings::from_config(
            &MachineConfig::ENDER3,
            Some(PidGains {
                kp: 21.73,
                ki: 1.54,
                kd: 76.55,
            }),
            None,
        )
    }

    /// The k-th distinct settings (k = 0 is the factory set).
    pub(crate) fn nth(k: u32) -> Settings {
        let mut s = factory();
        s.steps_per_mm[0] = 80.0 + k as f32 * 0.125;
        s.max_feed_mm_s[2] = 5.0 + (k % 7) as f32;
        s.driver_current_ma[3] = 600 + (k % 50) as u16;
        s
    }

    fn small_store(bytes: Vec<u8>) -> SettingsStore<Small> {
        SettingsStore::new(Small::new(bytes), SMALL_RANGE).unwrap()
    }

    /// `len` bytes of a fixed-seed xorshift32 generator.
    fn noise(mut seed: u32, len: usize) -> Vec<u8> {
        (0..len)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                seed as u8
            })
            .collect()
    }

    /// `op` on a store over the area `bytes` with the power cut at its `n`-th flash write or
    /// erase (letting `kind` of it through). `None` when `op` succeeded, so `n` is past its
    /// last operation (the power then never went off); else the flash as the cut left it,
    /// powered again.
    fn cut_during(
        bytes: &[u8],
        n: u32,
        kind: Cut,
        op: impl FnOnce(&mut SettingsStore<Small>) -> Result<Stored, StoreError>,
    ) -> Option<Small> {
        let mut flash = Small::new(bytes.to_vec());
        flash.cut_power(n, kind);
        let mut st = SettingsStore::new(flash, SMALL_RANGE).unwrap();
        let done = op(&mut st).is_ok();
        let mut flash = st.into_flash();
        if done {
            assert!(!flash.is_off(), "op {n}: succeeded with the power off");
            return None;
        }
        flash.restore_power();
        Some(flash)
    }

    #[test]
    fn an_empty_area_loads_nothing_and_a_save_loads_back() {
        let mut st = small_store(vec![0xFF; 3 * 1024]);
        assert_eq!(st.load(), Ok(None));
        st.save(&nth(3)).unwrap();
        assert_eq!(st.load(), Ok(Some(nth(3))));
        // A reboot (a new store on the same bytes) sees the same.
        let bytes = st.into_flash().into_inner();
        assert_eq!(small_store(bytes).load(), Ok(Some(nth(3))));
    }

    #[test]
    fn the_board_geometry_works_and_erases_rarely() {
        // Two 128 KiB sectors as on the STM32F407 (sectors 10 and 11), 16-byte words.
        type Board = NorFlashModel<Vec<u8>, 16, { 128 * 1024 }>;
        let mut st = SettingsStore::new(Board::erased(vec![0; 256 * 1024]), 0..256 * 1024).unwrap();
        for k in 0..200 {
            st.save(&nth(k)).unwrap();
        }
        assert_eq!(st.load(), Ok(Some(nth(199))));
        let flash = st.into_flash();
        assert_eq!(
            flash.erases(),
            0,
            "200 saves fit one sector without an erase"
        );
        // Bytes per save: the record, its key and sequential-storage's item header, padded to
        // the 16-byte word.
        let used = flash.bytes().iter().rposition(|b| *b != 0xFF).unwrap_or(0);
        let per_save = used.div_ceil(200);
        println!(
            "record {RECORD_LEN} B, {per_save} B of flash per save, {} saves per 128 KiB sector",
            128 * 1024 / per_save
        );
        assert!(
            (RECORD_LEN..RECORD_LEN + 48).contains(&per_save),
            "{per_save}"
        );
    }

    /// A flash that counts the bytes read through it.
    struct Counting<F>(F, u64);

    impl<F: embedded_storage::nor_flash::ErrorType> embedded_storage::nor_flash::ErrorType
        for Counting<F>
    {
        type Error = F::Error;
    }

    impl<F: NorFlash> embedded_storage::nor_flash::ReadNorFlash for Counting<F> {
        const READ_SIZE: usize = F::READ_SIZE;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            self.1 += bytes.len() as u64;
            self.0.read(offset, bytes)
        }
        fn capacity(&self) -> usize {
            self.0.capacity()
        }
    }

    impl<F: NorFlash> NorFlash for Counting<F> {
        const WRITE_SIZE: usize = F::WRITE_SIZE;
        const ERASE_SIZE: usize = F::ERASE_SIZE;
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            self.0.write(offset, bytes)
        }
        fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            self.0.erase(from, to)
        }
    }

    /// The save that switches sectors on the board's geometry, after a sector full of stale
    /// settings items: what it reads from the flash (each byte read costs MCU time with the
    /// executor stopped; the key cache keeps it small).
    #[test]
    fn a_sector_switch_reads_little() {
        type Board = NorFlashModel<Vec<u8>, 16, { 128 * 1024 }>;
        let mut st = SettingsStore::new(
            Counting(Board::erased(vec![0; 256 * 1024]), 0),
            0..256 * 1024,
        )
        .unwrap();
        let mut k = 0;
        let (read, erases) = loop {
            let (r0, e0) = (st.flash_mut().1, st.flash_mut().0.erases());
            st.save(&nth(k)).unwrap();
            k += 1;
            let e1 = st.flash_mut().0.erases();
            if e1 > e0 {
                break (st.flash_mut().1 - r0, e1);
            }
        };
        assert_eq!(erases, 1);
        assert_eq!(st.load(), Ok(Some(nth(k - 1))));
        println!("sector switch after {k} saves: {read} bytes read");
        assert!(read < 1_000_000, "{read} bytes read by one save");
    }

    #[test]
    fn out_of_range_settings_are_never_written() {
        let mut st = small_store(vec![0xFF; 3 * 1024]);
        let mut bad = factory();
        bad.accel_print_mm_s2 = -1.0;
        assert!(matches!(st.save(&bad), Err(StoreError::Record(_))));
        assert_eq!(st.into_flash().ops(), 0);
    }

    #[test]
    fn another_version_or_garbage_is_an_error_not_a_crash() {
        let mut st = small_store(vec![0xFF; 3 * 1024]);
        let mut old = factory().encode();
        old[0] = 0; // format 0
        let crc = crate::storage::crc32(&old[..old.len() - 4]);
        let n = old.len();
        old[n - 4..].copy_from_slice(&crc.to_le_bytes());
        st.store(SETTINGS_KEY, &old).unwrap();
        assert_eq!(st.load(), Err(StoreError::Record(RecordError::Version(0))));
        // Every byte of the area garbage: never a panic, never settings.
        let mut st = small_store(noise(0x1234_5678, 3 * 1024));
        assert!(!matches!(st.load(), Ok(Some(_))));
        // And the store can be used again after that (sequential-storage repairs it, or the
        // save reclaims the area).
        assert!(st.save(&nth(1)).is_ok());
        assert_eq!(st.load(), Ok(Some(nth(1))));
    }

    /// Areas sequential-storage cannot use: zeros, random bytes, a half-erased sector over
    /// zeros, zeros with the last sector erased.
    fn foreign() -> Vec<(&'static str, Vec<u8>)> {
        let random = noise(0x0bad_f1a5, 3 * 1024);
        let mut half = vec![0u8; 3 * 1024];
        half[..512].fill(0xFF);
        let mut last = vec![0u8; 3 * 1024];
        last[2048..].fill(0xFF);
        vec![
            ("zeros", vec![0; 3 * 1024]),
            ("random", random),
            ("half-erased", half),
            ("zeros, last sector erased", last),
        ]
    }

    /// Issue 24: a foreign area answered `Corrupted` or `FullStorage` to every save, for ever.
    /// Now the save reclaims it; and a power cut at any write or erase of that reclaim (every
    /// kind of cut) leaves either no readable settings (the factory values load, as before
    /// the reclaim) or the new ones, never anything else; the next save then works, even if
    /// it is cut too at any of its operations and done again, and that second cut leaves old
    /// or new too: never nothing where the first cut had left the new settings.
    #[test]
    fn a_foreign_area_is_reclaimed_and_a_power_cut_in_the_reclaim_keeps_none_or_new() {
        let mut cuts = 0;
        let mut twice = 0;
        let mut reclaimed = 0;
        for (what, bytes) in foreign() {
            let mut st = small_store(bytes.clone());
            assert!(!matches!(st.load(), Ok(Some(_))), "{what}");
            // sequential-storage's own repair handles some patterns (random bytes here); the
            // rest is reclaimed.
            let how = st.save(&nth(1));
            assert!(how.is_ok(), "{what}: {how:?}");
            if what == "zeros" {
                // Every sector looks closed and full: only a reclaim makes room.
                assert_eq!(how, Ok(Stored::Reclaimed), "{what}");
            }
            reclaimed += usize::from(how == Ok(Stored::Reclaimed));
            assert_eq!(st.load(), Ok(Some(nth(1))), "{what}");
            assert_eq!(st.save(&nth(2)), Ok(Stored::Appended), "{what}");
            for kind in [Cut::Partial, Cut::PartialTail, Cut::Before] {
                for n in 0.. {
                    let Some(flash) = cut_during(&bytes, n, kind, |st| st.save(&nth(1))) else {
                        break;
                    };
                    cuts += 1;
                    let after_cut = flash.into_inner();
                    let mut st = small_store(after_cut.clone());
                    let got = st.load();
                    let ctx = format!("{what}, {kind:?} cut at op {n}: {got:?}");
                    // Old (nothing readable: the factory values) or new.
                    let first = match got {
                        Ok(Some(s)) => {
                            assert_eq!(s, nth(1), "{ctx}");
                            Some(s)
                        }
                        _ => None,
                    };
                    // The next save is cut too, at each of its operations in turn; the one
                    // after it works.
                    for m in 0.. {
                        let Some(flash) = cut_during(&after_cut, m, kind, |st| st.save(&nth(3)))
                        else {
                            break;
                        };
                        twice += 1;
                        let mut st = SettingsStore::new(flash, SMALL_RANGE).unwrap();
                        // Old or new again: once the reclaim has written its record, a
                        // cut in the next save never leaves nothing.
                        match (st.load(), first) {
                            (Ok(Some(s)), _) => {
                                assert!(s == nth(1) || s == nth(3), "{ctx}, then cut at {m}")
                            }
                            (got, Some(_)) => {
                                panic!("{ctx}, then cut at {m}: nothing left ({got:?})")
                            }
                            (_, None) => {}
                        }
                        assert!(st.save(&nth(4)).is_ok(), "{ctx}, then cut at {m}");
                        assert_eq!(st.load(), Ok(Some(nth(4))), "{ctx}, then cut at {m}");
                    }
                }
            }
        }
        assert!(cuts > 20, "{cuts}");
        assert!(reclaimed >= 1, "{reclaimed} of 4 areas reclaimed");
        println!(
            "reclaim power-fail sweep: {reclaimed} of 4 foreign areas reclaimed, {cuts} cuts, {twice} second cuts"
        );
    }

    /// Settings and a paused job side by side: a cut during a job save or clear keeps the
    /// settings whole and the job old-or-new; a cut during a settings save keeps the job.
    #[test]
    fn a_power_cut_while_saving_one_record_never_touches_the_other() {
        use crate::storage::job::tests::sample;
        let mut cuts = 0;
        for before in 1..30u32 {
            let mut st = small_store(vec![0xFF; 3 * 1024]);
            for k in 0..before {
                st.save(&nth(k)).unwrap();
                st.save_job(&sample(k, k % 2 == 0)).unwrap();
            }
            let base = st.into_flash().into_inner();
            let (s_old, j_old) = (nth(before - 1), sample(before - 1, (before - 1) % 2 == 0));
            let s_new = nth(before);
            let j_new = sample(before, before % 2 == 0);
            // 0: save a job, 1: clear the job, 2: save settings.
            for what in 0..3 {
                for n in 0.. {
                    let Some(flash) = cut_during(&base, n, Cut::Partial, |st| match what {
                        0 => st.save_job(&j_new),
                        1 => st.clear_job(),
                        _ => st.save(&s_new),
                    }) else {
                        break;
                    };
                    cuts += 1;
                    let mut st = SettingsStore::new(flash, SMALL_RANGE).unwrap();
                    let s = st.load().unwrap();
                    let j = st.load_job().unwrap();
                    let ctx = format!("{before} saves, op {what}, cut at {n}");
                    match what {
                        0 => {
                            assert_eq!(s, Some(s_old), "{ctx}");
                            assert!(
                                j == Some(j_old.clone()) || j == Some(j_new.clone()),
                                "{ctx}"
                            );
                        }
                        1 => {
                            assert_eq!(s, Some(s_old), "{ctx}");
                            assert!(j == Some(j_old.clone()) || j.is_none(), "{ctx}");
                        }
                        _ => {
                            assert!(s == Some(s_old) || s == Some(s_new), "{ctx}");
                            assert_eq!(j, Some(j_old.clone()), "{ctx}");
                        }
                    }
                }
            }
        }
        assert!(cuts > 200, "{cuts}");
        println!("two-record power-fail sweep: {cuts} cuts");
    }

    #[test]
    fn a_job_saved_loads_and_a_cleared_one_is_gone() {
        use crate::storage::job::tests::sample;
        let mut st = small_store(vec![0xFF; 3 * 1024]);
        assert_eq!(st.load_job(), Ok(None));
        st.save_job(&sample(4, false)).unwrap();
        let bytes = st.into_flash().into_inner();
        let mut st = small_store(bytes);
        assert_eq!(st.load_job(), Ok(Some(sample(4, false))));
        st.clear_job().unwrap();
        assert_eq!(st.load_job(), Ok(None));
        // A job alone is no damaged settings record.
        assert_eq!(st.load(), Ok(None));
    }

    /// Cut the power at every write and erase of a save, after `before` earlier saves (so the
    /// save lands at every place of the sectors, page closes and erases included): the next
    /// boot loads the previous settings or the new ones, never anything else, and a later save
    /// works.
    #[test]
    fn a_power_cut_at_any_flash_operation_of_a_save_keeps_old_or_new() {
        let mut cuts = 0;
        let mut new_seen = 0;
        let mut erases_cut = 0;
        for (before, kind) in (1..40u32).flat_map(|b| [(b, Cut::Partial), (b, Cut::Before)]) {
            let mut st = small_store(vec![0xFF; 3 * 1024]);
            for k in 0..before {
                st.save(&nth(k)).unwrap();
            }
            let base = st.into_flash().into_inner();
            let old = nth(before - 1);
            let new = nth(before);
            for n in 0.. {
                // None: n is past the save's last operation.
                let Some(flash) = cut_during(&base, n, kind, |st| st.save(&new)) else {
                    break;
                };
                cuts += 1;
                if flash.cut_op() == Some(FlashOp::Erase) {
                    erases_cut += 1;
                }
                let mut st = SettingsStore::new(flash, SMALL_RANGE).unwrap();
                let got = st.load().unwrap_or_else(|e| {
                    panic!("{before} saves, {kind:?} cut at op {n}: load failed: {e}")
                });
                assert!(
                    got == Some(old) || got == Some(new),
                    "{before} saves, {kind:?} cut at op {n}: {got:?}"
                );
                if got == Some(new) {
                    new_seen += 1;
                }
                st.save(&nth(1000)).unwrap();
                assert_eq!(st.load(), Ok(Some(nth(1000))));
            }
        }
        // sequential-storage's last write of a save is the one that makes the new item whole,
        // so every cut (even one just before that write) loads the old settings; a save whose
        // operations all ran loads the new ones (the `break` above). Erases were cut too.
        assert!(cuts > 150, "{cuts} cuts tested");
        assert!(erases_cut > 0, "no erase was cut");
        println!("power-fail sweep: {cuts} cuts, {new_seen} loaded the new settings, {erases_cut} during an erase");
    }
}
