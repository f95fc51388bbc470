//! The SD card as a job source: a FAT12/16/32 volume read through the well-kept
//! [`embedded_sdmmc`] crate (no heap, fixed handle tables) over any
//! [`embedded_sdmmc::BlockDevice`] — the SKR 2's SDIO card on the board
//! (`board/sd.rs`), a file-backed image in the simulator (`sim/src/sd.rs`), an image made by
//! the test in the tests.
//!
//! [`Card`] lists the files of the card, in its root directory and in sub-directories down to
//! [`CARD_MAX_DEPTH`] levels (with their long names when the card has them), opens one by its
//! path (`DIR/SUB/FILE.GCO`, each component by its short (8.3) or long name, ASCII case
//! ignored), and reads it at any byte offset. The
//! executive (`printer/sd.rs`) turns the bytes into lines with the host link's own line
//! assembler ([`crate::link::FileLines`]), so a job from the card is read by the same rules as
//! a streamed one, with its comments (and so its layer markers) always present.
//!
//! Paths are given and reported as Marlin's M20 lists them (`printListing` in Marlin's
//! `sd/cardreader.cpp`): the short names joined by `/`, no leading `/` (`DIR/SUB/FILE.GCO`;
//! a leading `/` is accepted when opening), and for M20 L the long path the same way, each
//! component by its long name (or its short one when it has none).
//!
//! Fixed capacities: one volume (the first MBR partition), the root directory and one
//! directory per level below it open at once, one open file ([`CARD_VOLUMES`], [`CARD_DIRS`],
//! [`CARD_FILES`]); [`CARD_MAX_DEPTH`] directory levels below the root (deeper directories
//! are not listed, and a deeper path is refused), which keeps every short path within
//! [`CARD_PATH_CAP`] bytes (the power-cut record's path); long names up to
//! [`LONG_NAME_CAP`] bytes of UTF-8 (longer ones are shown by their short name, as the crate
//! does), long paths up to [`LONG_PATH_CAP`] bytes (a longer one is listed by its short path).
//! No list of names is kept: a directory is read again for each of its sub-directories
//! (a listing reads each directory `1 + sub-directories` times). The crate keeps one 512-byte
//! block cache; this type adds no buffer of its own.
//!
//! Written: only the parked intake's spill file [`SPILL_NAME`] in the root directory (job
//! lines a host streams into a parked printer, kept until they run: `printer/spill.rs`,
//! docs/frontend.md "Host rules"), through [`Card::spill_append`], [`Card::spill_read_at`] and
//! [`Card::spill_remove`]. No M28/M928 logging. The crate needs an
//! MBR-partitioned card (every card sold is; a "superfloppy" without a partition table is
//! refused with a format error).

use embedded_sdmmc::{
    BlockDevice, DirEntry, Error, LfnBuffer, Mode, RawDirectory, RawFile, RawVolume, ShortFileName,
    TimeSource, Timestamp, VolumeIdx, VolumeManager,
};
use heapless::String;

/// Volumes open at once (the first partition).
pub const CARD_VOLUMES: usize = 1;
/// Directory levels below the root that are listed and opened (Marlin's SdFat branch allows
/// 10, `MAX_DIR_DEPTH` in `sd/cardreader.h`; 6 here keeps every short path within
/// [`CARD_PATH_CAP`], the power-cut record's path).
pub const CARD_MAX_DEPTH: usize = 6;
/// Directories open at once (the root and one per level below it).
pub const CARD_DIRS: usize = 1 + CARD_MAX_DEPTH;
/// Files open at once (the selected job, and the spill file while it is read or written).
pub const CARD_FILES: usize = 2;
/// The parked intake's spill file in the root directory (see `printer/spill.rs`). A name no
/// slicer writes; M20 lists it like any file while it exists.
pub const SPILL_NAME: &str = "LPSPILL.TMP";
/// Longest long file name kept, bytes of UTF-8 (the power-cut record keeps as many:
/// [`crate::storage::JOB_PATH_CAP`]).
pub const LONG_NAME_CAP: usize = crate::storage::JOB_PATH_CAP;
/// A short (8.3) name as text: `NAME.EXT`.
pub const SHORT_NAME_CAP: usize = 12;
/// Longest short path, `DIR/SUB/FILE.GCO` (bytes): the power-cut record's path capacity.
pub const CARD_PATH_CAP: usize = crate::storage::JOB_PATH_CAP;
const _: () = assert!(CARD_MAX_DEPTH * (SHORT_NAME_CAP + 1) + SHORT_NAME_CAP <= CARD_PATH_CAP);
/// Longest long path M20 L lists (bytes of UTF-8).
pub const LONG_PATH_CAP: usize = 2 * LONG_NAME_CAP;

/// Why a card operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CardError {
    /// No card answered, or it was not initialised (M21).
    NoCard,
    /// The card has no FAT volume this code reads (no MBR, unknown partition type, bad FAT).
    Format,
    /// No such file in the root directory.
    NotFound,
    /// The name cannot be a file name (empty, a directory, too long).
    BadName,
    /// The path goes more than [`CARD_MAX_DEPTH`] directories down.
    TooDeep,
    /// A block could not be read.
    Read,
    /// A block could not be written (the card is full, write-protected or failing).
    Write,
}

impl core::fmt::Display for CardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CardError::NoCard => "no card",
            CardError::Format => "no FAT volume",
            CardError::NotFound => "not found",
            CardError::BadName => "bad file name",
            CardError::TooDeep => "path too deep",
            CardError::Read => "read error",
            CardError::Write => "write error",
        })
    }
}

fn card_error<E: core::fmt::Debug>(e: Error<E>) -> CardError {
    match e {
        Error::DeviceError(_) => CardError::Read,
        Error::NotFound => CardError::NotFound,
        Error::FilenameError(_) | Error::OpenedDirAsFile => CardError::BadName,
        Error::FormatError(_)
        | Error::NoSuchVolume
        | Error::BadCluster
        | Error::UnterminatedFatChain
        | Error::BadBlockSize(_) => CardError::Format,
        _ => CardError::Read,
    }
}

/// A file of the card.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CardEntry {
    /// The short path, `DIR/SUB/FILE.GCO` (`FILE.GCO` in the root): what Marlin's M20 lists
    /// and M23 takes.
    pub short: String<CARD_PATH_CAP>,
    /// The long path (each component by its long name, or its short one), if the file or a
    /// directory above it has a long name and the path fits [`LONG_PATH_CAP`].
    pub long: Option<String<LONG_PATH_CAP>>,
    /// Size, bytes.
    pub size: u32,
}

/// One directory entry as this code sees it: a file or a sub-directory, visible.
struct Named {
    sfn: ShortFileName,
    short: String<SHORT_NAME_CAP>,
    long: Option<String<LONG_NAME_CAP>>,
    dir: bool,
    size: u32,
}

impl Named {
    /// A visible file or sub-directory (not hidden, system, the volume label, `.` or `..`).
    fn of(e: &DirEntry, long: Option<&str>) -> Option<Named> {
        let a = e.attributes;
        if a.is_volume() || a.is_hidden() || a.is_system() {
            return None;
        }
        // `NAME.EXT` from the 8.3 bytes (bytes beyond ASCII, an OEM code page, shown as `?`).
        let (base, ext) = (e.name.base_name(), e.name.extension());
        if base.first() == Some(&b'.') {
            return None;
        }
        let mut short: String<SHORT_NAME_CAP> = String::new();
        let dot: &[u8] = if ext.is_empty() { b"" } else { b"." };
        for &b in base.iter().chain(dot).chain(ext) {
            let _ = short.push(if b.is_ascii() { char::from(b) } else { '?' });
        }
        let long = long.and_then(|l| String::try_from(l).ok());
        Some(Named {
            sfn: e.name.clone(),
            short,
            long,
            dir: a.is_directory(),
            size: e.size,
        })
    }

    /// Whether `name` names this entry: its short or long name, ASCII case ignored (FAT names
    /// are case-insensitive).
    fn is(&self, name: &str) -> bool {
        self.short.eq_ignore_ascii_case(name)
            || self
                .long
                .as_ref()
                .is_some_and(|l| l.eq_ignore_ascii_case(name))
    }
}

/// `path` cut at its first `/`: the first component and the rest, if there is a `/` (a byte
/// search: `str::split`'s pattern machinery costs flash).
fn first_component(path: &str) -> (&str, Option<&str>) {
    match path.bytes().position(|b| b == b'/') {
        Some(i) => (path.get(..i).unwrap_or(""), path.get(i + 1..)),
        None => (path, None),
    }
}

/// `prefix/name` (or `name` for an empty prefix), if it fits.
fn joined<const N: usize>(prefix: &str, name: &str) -> Option<String<N>> {
    let mut s = String::new();
    if !prefix.is_empty() {
        s.push_str(prefix).ok()?;
        s.push_str("/").ok()?;
    }
    s.push_str(name).ok()?;
    Some(s)
}

/// The path of a directory being walked: short, and long while it fits.
struct DirPath {
    short: String<CARD_PATH_CAP>,
    /// None once it no longer fits [`LONG_PATH_CAP`].
    long: Option<String<LONG_PATH_CAP>>,
    /// A component so far has a long name.
    any_long: bool,
}

impl DirPath {
    const ROOT: DirPath = DirPath {
        short: String::new(),
        long: Some(String::new()),
        any_long: false,
    };

    fn child_path(
        &self,
        c: &Named,
    ) -> Option<(String<CARD_PATH_CAP>, Option<String<LONG_PATH_CAP>>)> {
        let short = joined(&self.short, &c.short)?;
        let long = self
            .long
            .as_ref()
            .and_then(|l| joined(l, c.long.as_deref().unwrap_or(&c.short)));
        Some((short, long))
    }

    /// The path of sub-directory `c` (None: it does not fit [`CARD_PATH_CAP`]).
    fn child(&self, c: &Named) -> Option<DirPath> {
        let (short, long) = self.child_path(c)?;
        Some(DirPath {
            short,
            long,
            any_long: self.any_long || c.long.is_some(),
        })
    }

    /// The entry of file `c` in this directory.
    fn entry(&self, c: &Named) -> Option<CardEntry> {
        let (short, long) = self.child_path(c)?;
        Some(CardEntry {
            short,
            long: long.filter(|_| self.any_long || c.long.is_some()),
            size: c.size,
        })
    }
}

/// The card is only read: file times are never written.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoClock;

impl TimeSource for NoClock {
    fn get_timestamp(&self) -> Timestamp {
        Timestamp {
            year_since_1970: 0,
            zero_indexed_month: 0,
            zero_indexed_day: 0,
            hours: 0,
            minutes: 0,
            seconds: 0,
        }
    }
}

/// The card: its block device, the FAT code's handles, the open file. See the module
/// documentation.
pub struct Card<D: BlockDevice>
where
    D::Error: core::fmt::Debug,
{
    vm: VolumeManager<D, NoClock, CARD_DIRS, CARD_FILES, CARD_VOLUMES>,
    mounted: Option<(RawVolume, RawDirectory)>,
    file: Option<RawFile>,
}

impl<D: BlockDevice> Card<D>
where
    D::Error: core::fmt::Debug,
{
    /// A card on `device`, not yet initialised ([`Card::mount`]).
    pub fn new(device: D) -> Self {
        Self {
            vm: VolumeManager::new_with_limits(device, NoClock, 0x5D00),
            mounted: None,
            file: None,
        }
    }

    /// Whether the card's volume is open (M21 succeeded, no M22 since).
    pub fn is_mounted(&self) -> bool {
        self.mounted.is_some()
    }

    /// Open the card's first FAT volume and its root directory (M21). A card already
    /// mounted is released first (the card may have been swapped).
    pub fn mount(&mut self) -> Result<(), CardError> {
        self.release();
        let volume = self.vm.open_raw_volume(VolumeIdx(0)).map_err(|e| match e {
            Error::DeviceError(_) => CardError::NoCard,
            e => card_error(e),
        })?;
        match self.vm.open_root_dir(volume) {
            Ok(root) => {
                self.mounted = Some((volume, root));
                Ok(())
            }
            Err(e) => {
                let _ = self.vm.close_volume(volume);
                Err(card_error(e))
            }
        }
    }

    /// Close the file, the directory and the volume (M22; also before a re-mount).
    pub fn release(&mut self) {
        self.close();
        if let Some((volume, root)) = self.mounted.take() {
            let _ = self.vm.close_dir(root);
            let _ = self.vm.close_volume(volume);
        }
    }

    fn root(&self) -> Result<RawDirectory, CardError> {
        self.mounted.map(|(_, r)| r).ok_or(CardError::NoCard)
    }

    /// Every entry of `dir` with its long name, through one `dyn` callback: the FAT code's
    /// directory walk is compiled once for listing and finding (flash is tight).
    fn scan(
        &mut self,
        dir: RawDirectory,
        f: &mut dyn FnMut(&DirEntry, Option<&str>),
    ) -> Result<(), CardError> {
        let mut storage = [0u8; LONG_NAME_CAP];
        let mut lfn = LfnBuffer::new(&mut storage);
        self.vm
            .iterate_dir_lfn(dir, &mut lfn, |e, long| f(e, long))
            .map_err(card_error)
    }

    /// The first visible entry of `dir` for which `pick` holds.
    fn pick(
        &mut self,
        dir: RawDirectory,
        pick: &mut dyn FnMut(&Named) -> bool,
    ) -> Result<Option<Named>, CardError> {
        let mut found = None;
        self.scan(dir, &mut |e, long| {
            if found.is_none() {
                found = Named::of(e, long).filter(|c| pick(c));
            }
        })?;
        Ok(found)
    }

    /// Call `f` with every file of `dir` (at `path`, `depth` levels below the root), then walk
    /// its sub-directories, in directory order. `n` counts the files.
    fn walk(
        &mut self,
        dir: RawDirectory,
        path: &DirPath,
        depth: usize,
        n: &mut usize,
        f: &mut dyn FnMut(usize, &CardEntry),
    ) -> Result<(), CardError> {
        let mut subdirs = 0usize;
        self.scan(dir, &mut |e, long| match Named::of(e, long) {
            Some(c) if c.dir => subdirs += 1,
            Some(c) => {
                if let Some(entry) = path.entry(&c) {
                    f(*n, &entry);
                    *n += 1;
                }
            }
            None => {}
        })?;
        if depth == CARD_MAX_DEPTH {
            return Ok(());
        }
        for i in 0..subdirs {
            // The i-th sub-directory: the directory is read again (no names are kept).
            let mut k = 0;
            let found = self.pick(dir, &mut |c| {
                k += usize::from(c.dir);
                c.dir && k == i + 1
            })?;
            let Some((c, sub)) =
                found.and_then(|c| Some((path.child(&c)?, c)).map(|(p, c)| (c, p)))
            else {
                continue;
            };
            let child = self.vm.open_dir(dir, &c.sfn).map_err(card_error)?;
            let walked = self.walk(child, &sub, depth + 1, n, f);
            let _ = self.vm.close_dir(child);
            walked?;
        }
        Ok(())
    }

    /// Call `f` with every file of the card (the root's, then each sub-directory's, in
    /// directory order, down to [`CARD_MAX_DEPTH`] levels; index from 0). Returns how many
    /// there are.
    pub fn for_each_file(
        &mut self,
        mut f: impl FnMut(usize, &CardEntry),
    ) -> Result<usize, CardError> {
        let root = self.root()?;
        let mut n = 0;
        self.walk(root, &DirPath::ROOT, 0, &mut n, &mut f)?;
        Ok(n)
    }

    /// Open the file at `path` for reading (closing the one open before); returns its entry.
    /// Each `/`-separated component is a short or long name, ASCII case ignored; a leading
    /// `/` is ignored (`M23 /DIR/FILE.GCO`).
    pub fn open(&mut self, path: &str) -> Result<CardEntry, CardError> {
        self.close();
        let root = self.root()?;
        let path = path.trim_start_matches('/');
        let mut parts = 0;
        let mut rest = Some(path);
        while let Some((name, next)) = rest.map(first_component) {
            if name.is_empty() || name == "." || name == ".." {
                return Err(CardError::BadName);
            }
            parts += 1;
            rest = next;
        }
        if parts > CARD_MAX_DEPTH + 1 {
            return Err(CardError::TooDeep);
        }
        let mut dir = root;
        let mut at = DirPath::ROOT;
        let opened = self.open_below(&mut dir, &mut at, path);
        if dir != root {
            let _ = self.vm.close_dir(dir);
        }
        let (entry, file) = opened?;
        self.file = Some(file);
        Ok(entry)
    }

    /// [`Card::open`] from `dir` down (`dir` is the last directory opened: the caller closes
    /// it).
    fn open_below(
        &mut self,
        dir: &mut RawDirectory,
        at: &mut DirPath,
        path: &str,
    ) -> Result<(CardEntry, RawFile), CardError> {
        let mut rest = Some(path);
        while let Some((name, next)) = rest.map(first_component) {
            rest = next;
            let last = rest.is_none();
            let c = self
                .pick(*dir, &mut |c| c.is(name))?
                .ok_or(CardError::NotFound)?;
            match (last, c.dir) {
                (true, false) => {
                    let entry = at.entry(&c).ok_or(CardError::BadName)?;
                    let file = self
                        .vm
                        .open_file_in_dir(*dir, &c.sfn, Mode::ReadOnly)
                        .map_err(card_error)?;
                    return Ok((entry, file));
                }
                (true, true) => return Err(CardError::BadName),
                (false, false) => return Err(CardError::NotFound),
                (false, true) => {
                    *at = at.child(&c).ok_or(CardError::BadName)?;
                    let child = self.vm.open_dir(*dir, &c.sfn).map_err(card_error)?;
                    if Some(*dir) != self.mounted.map(|(_, r)| r) {
                        let _ = self.vm.close_dir(*dir);
                    }
                    *dir = child;
                }
            }
        }
        Err(CardError::BadName)
    }

    /// Whether a file is open.
    pub fn is_open(&self) -> bool {
        self.file.is_some()
    }

    /// Read the open file from byte `offset` into `buf`; returns how many bytes were read
    /// (0 at or past the end).
    pub fn read_at(&mut self, offset: u32, buf: &mut [u8]) -> Result<usize, CardError> {
        let file = self.file.ok_or(CardError::NoCard)?;
        let len = self.vm.file_length(file).map_err(card_error)?;
        if offset >= len {
            return Ok(0);
        }
        if self.vm.file_offset(file).map_err(card_error)? != offset {
            self.vm
                .file_seek_from_start(file, offset)
                .map_err(card_error)?;
        }
        self.vm.read(file, buf).map_err(card_error)
    }

    /// Close the open file, if any.
    pub fn close(&mut self) {
        if let Some(f) = self.file.take() {
            let _ = self.vm.close_file(f);
        }
    }

    /// Append `bytes` to the spill file [`SPILL_NAME`] (created when missing); returns its
    /// length after. The file is opened and closed around each call (a few per minute), so
    /// the directory entry always has the true length and the job file's handle is untouched.
    pub fn spill_append(&mut self, bytes: &[u8]) -> Result<u32, CardError> {
        let root = self.root()?;
        let f = self
            .vm
            .open_file_in_dir(root, SPILL_NAME, Mode::ReadWriteCreateOrAppend)
            .map_err(write_error)?;
        let wrote = self.vm.write(f, bytes).map_err(write_error);
        let len = self.vm.file_length(f).map_err(write_error);
        let closed = self.vm.close_file(f).map_err(write_error);
        wrote?;
        closed?;
        len
    }

    /// Read the spill file from byte `offset` into `buf`; returns how many bytes were read
    /// (0 at or past its end, or when there is none).
    pub fn spill_read_at(&mut self, offset: u32, buf: &mut [u8]) -> Result<usize, CardError> {
        let root = self.root()?;
        let f = match self.vm.open_file_in_dir(root, SPILL_NAME, Mode::ReadOnly) {
            Ok(f) => f,
            Err(Error::NotFound) => return Ok(0),
            Err(e) => return Err(card_error(e)),
        };
        let read = (|| {
            let len = self.vm.file_length(f).map_err(card_error)?;
            if offset >= len {
                return Ok(0);
            }
            self.vm
                .file_seek_from_start(f, offset)
                .map_err(card_error)?;
            self.vm.read(f, buf).map_err(card_error)
        })();
        let _ = self.vm.close_file(f);
        read
    }

    /// Delete the spill file (nothing when there is none).
    pub fn spill_remove(&mut self) -> Result<(), CardError> {
        let root = self.root()?;
        match self.vm.delete_file_in_dir(root, SPILL_NAME) {
            Ok(()) | Err(Error::NotFound) => Ok(()),
            Err(e) => Err(write_error(e)),
        }
    }
}

fn write_error<E: core::fmt::Debug>(e: Error<E>) -> CardError {
    match e {
        Error::DeviceError(_) | Error::NotEnoughSpace | Error::ReadOnly => CardError::Write,
        e => card_error(e),
    }
}
