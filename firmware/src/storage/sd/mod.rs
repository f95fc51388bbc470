//! The SD card as a job source: a FAT12/16/32 volume read through the well-kept
//! [`embedded_sdmmc`] crate (no heap, fixed handle tables) over any
//! [`embedded_sdmmc::BlockDevice`] — the SKR 2's SDIO card on the board
//! (`board/sd.rs`), a file-backed image in the simulator (`sim/src/sd.rs`), an image made by
//! the test in the tests.
//!
//! [`Card`] lists the files of the card's root directory (with their long names when the card
//! has them), opens one by its short (8.3) or long name, and reads it at any byte offset. The
//! executive (`printer/sd.rs`) turns the bytes into lines with the host link's own line
//! assembler ([`crate::link::FileLines`]), so a job from the card is read by the same rules as
//! a streamed one, with its comments (and so its layer markers) always present.
//!
//! Fixed capacities: one volume (the first MBR partition), one open directory (the root), one
//! open file ([`CARD_VOLUMES`], [`CARD_DIRS`], [`CARD_FILES`]); long names up to
//! [`LONG_NAME_CAP`] bytes of UTF-8 (longer ones are shown by their short name, as the crate
//! does). The crate keeps one 512-byte block cache; this type adds no buffer of its own.
//!
//! Limits: files in sub-directories are not listed or opened (root only); the card is read,
//! never written (no M28/M928 logging). The crate needs an MBR-partitioned card (every card
//! sold is; a "superfloppy" without a partition table is refused with a format error).

use embedded_sdmmc::{
    BlockDevice, Error, LfnBuffer, Mode, RawDirectory, RawFile, RawVolume, ShortFileName,
    TimeSource, Timestamp, VolumeIdx, VolumeManager,
};
use heapless::String;

/// Volumes open at once (the first partition).
pub const CARD_VOLUMES: usize = 1;
/// Directories open at once (the root).
pub const CARD_DIRS: usize = 1;
/// Files open at once (the selected job).
pub const CARD_FILES: usize = 1;
/// Longest long file name kept, bytes of UTF-8 (the power-cut record keeps as many:
/// [`crate::storage::JOB_PATH_CAP`]).
pub const LONG_NAME_CAP: usize = crate::storage::JOB_PATH_CAP;
/// A short (8.3) name as text: `NAME.EXT`.
pub const SHORT_NAME_CAP: usize = 12;

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
    /// A block could not be read.
    Read,
}

impl core::fmt::Display for CardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CardError::NoCard => "no card",
            CardError::Format => "no FAT volume",
            CardError::NotFound => "not found",
            CardError::BadName => "bad file name",
            CardError::Read => "read error",
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

/// A file of the card's root directory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CardEntry {
    /// The short (8.3) name, `NAME.EXT` (what Marlin's M20 lists and M23 takes).
    pub short: String<SHORT_NAME_CAP>,
    /// The long name, if the card has one that fits [`LONG_NAME_CAP`].
    pub long: Option<String<LONG_NAME_CAP>>,
    /// Size, bytes.
    pub size: u32,
}

impl CardEntry {
    /// Whether `name` names this entry: its short or long name, ASCII case ignored (FAT
    /// names are case-insensitive).
    pub fn is_named(&self, name: &str) -> bool {
        self.short.eq_ignore_ascii_case(name)
            || self
                .long
                .as_ref()
                .is_some_and(|l| l.eq_ignore_ascii_case(name))
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

fn entry_of(e: &embedded_sdmmc::DirEntry, long: Option<&str>) -> Option<CardEntry> {
    let a = e.attributes;
    if a.is_directory() || a.is_volume() || a.is_hidden() || a.is_system() {
        return None;
    }
    let mut short = String::new();
    let _ = core::fmt::write(&mut short, format_args!("{}", e.name));
    let long = long.and_then(|l| {
        let mut s = String::new();
        s.push_str(l).ok()?;
        Some(s)
    });
    Some(CardEntry {
        short,
        long,
        size: e.size,
    })
}

/// The name without the leading `/` hosts write (`M23 /FILE.GCO`).
fn strip_root(name: &str) -> &str {
    name.trim_start_matches('/')
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

    /// Every entry of the root directory with its long name, through one `dyn` callback: the
    /// FAT code's directory walk is compiled once for listing and finding (flash is tight).
    fn scan(
        &mut self,
        f: &mut dyn FnMut(&embedded_sdmmc::DirEntry, Option<&str>),
    ) -> Result<(), CardError> {
        let root = self.root()?;
        let mut storage = [0u8; LONG_NAME_CAP];
        let mut lfn = LfnBuffer::new(&mut storage);
        self.vm
            .iterate_dir_lfn(root, &mut lfn, |e, long| f(e, long))
            .map_err(card_error)
    }

    /// Call `f` with every file of the root directory, in directory order (index from 0).
    /// Returns how many there are.
    pub fn for_each_file(
        &mut self,
        mut f: impl FnMut(usize, &CardEntry),
    ) -> Result<usize, CardError> {
        let mut n = 0;
        self.scan(&mut |e, long| {
            if let Some(entry) = entry_of(e, long) {
                f(n, &entry);
                n += 1;
            }
        })?;
        Ok(n)
    }

    /// The root directory's file named `name` (short or long name, see
    /// [`CardEntry::is_named`]; a leading `/` is ignored).
    pub fn find(&mut self, name: &str) -> Result<(CardEntry, ShortFileName), CardError> {
        let name = strip_root(name);
        if name.is_empty() || name.contains('/') {
            return Err(CardError::BadName);
        }
        let mut found = None;
        self.scan(&mut |e, long| {
            if found.is_none() {
                if let Some(entry) = entry_of(e, long).filter(|c| c.is_named(name)) {
                    found = Some((entry, e.name.clone()));
                }
            }
        })?;
        found.ok_or(CardError::NotFound)
    }

    /// Open the file `name` for reading (closing the one open before); returns its entry.
    pub fn open(&mut self, name: &str) -> Result<CardEntry, CardError> {
        self.close();
        let (entry, sfn) = self.find(name)?;
        let root = self.root()?;
        let file = self
            .vm
            .open_file_in_dir(root, &sfn, Mode::ReadOnly)
            .map_err(card_error)?;
        self.file = Some(file);
        Ok(entry)
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
}
