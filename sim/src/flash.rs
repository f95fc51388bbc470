//! `sim serve --flash FILE`: the board's settings area as a file, so M500 survives the session.
//!
//! The file is the area's image: [`SKR2_AREA`]'s size (two 128 KiB sectors, 262 144 bytes),
//! `0xFF` where erased. It is driven through the firmware's own NOR-flash model
//! ([`Skr2FlashModel`]: erase = `0xFF`, writes only clear bits, 4-byte words as on the board)
//! and every write or erase is written through to the file at once, so a killed session keeps
//! what the firmware had stored. A missing file is created erased; a file of another size is refused.

use anyhow::{bail, Context};
use firmware::printer::Printer;
use firmware::storage::{ModelError, SettingsStore, Skr2FlashModel, SKR2_AREA};
use std::fs::{File, OpenOptions};
use std::io::Read;
use std::os::unix::fs::FileExt;
use std::path::Path;

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Bytes of the image: the SKR 2's settings area.
pub const IMAGE_LEN: usize = SKR2_AREA.len() as usize;

/// Why a file-backed flash operation failed.
#[derive(Debug)]
pub enum FileFlashError {
    /// The model refused the operation (bounds, alignment).
    Model(ModelError),
    /// The file could not be written.
    Io,
}

impl NorFlashError for FileFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FileFlashError::Model(e) => e.kind(),
            FileFlashError::Io => NorFlashErrorKind::Other,
        }
    }
}

/// A NOR flash whose contents live in a file (write-through).
pub struct FileFlash {
    model: Skr2FlashModel<Vec<u8>>,
    file: File,
}

impl FileFlash {
    /// Open `path` (created erased when missing).
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .with_context(|| format!("opening the flash image {}", path.display()))?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes)
            .with_context(|| format!("reading {}", path.display()))?;
        if bytes.is_empty() {
            bytes = vec![0xFF; IMAGE_LEN];
            file.write_all_at(&bytes, 0)
                .with_context(|| format!("writing {}", path.display()))?;
        } else if bytes.len() != IMAGE_LEN {
            bail!(
                "{} is {} bytes, not a settings flash image ({IMAGE_LEN} bytes)",
                path.display(),
                bytes.len()
            );
        }
        Ok(Self {
            model: Skr2FlashModel::new(bytes),
            file,
        })
    }

    fn persist(&mut self, from: u32, len: usize) -> Result<(), FileFlashError> {
        let start = from as usize;
        let bytes = self
            .model
            .bytes()
            .get(start..start + len)
            .ok_or(FileFlashError::Model(ModelError::OutOfBounds))?;
        self.file
            .write_all_at(bytes, u64::from(from))
            .map_err(|_| FileFlashError::Io)
    }
}

impl ErrorType for FileFlash {
    type Error = FileFlashError;
}

impl ReadNorFlash for FileFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FileFlashError> {
        self.model
            .read(offset, bytes)
            .map_err(FileFlashError::Model)
    }

    fn capacity(&self) -> usize {
        IMAGE_LEN
    }
}

impl NorFlash for FileFlash {
    const WRITE_SIZE: usize = <Skr2FlashModel<Vec<u8>> as NorFlash>::WRITE_SIZE;
    const ERASE_SIZE: usize = <Skr2FlashModel<Vec<u8>> as NorFlash>::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FileFlashError> {
        self.model.erase(from, to).map_err(FileFlashError::Model)?;
        self.persist(from, (to - from) as usize)
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FileFlashError> {
        self.model
            .write(offset, bytes)
            .map_err(FileFlashError::Model)?;
        self.persist(offset, bytes.len())
    }
}

/// The settings store of a `sim serve` session, on a file.
pub struct FlashStore {
    store: SettingsStore<FileFlash>,
    booted: bool,
}

impl FlashStore {
    /// Open the image at `path`.
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        let flash = FileFlash::open(path)?;
        let store = SettingsStore::new(flash, 0..IMAGE_LEN as u32)
            .map_err(|e| anyhow::anyhow!("settings store on {}: {e}", path.display()))?;
        Ok(Self {
            store,
            booted: false,
        })
    }

    /// Call from the session loop: the first call loads the saved settings into the printer
    /// (as the board does at power-up), every call carries out a pending M500/M501.
    pub fn service(&mut self, p: &mut Printer) {
        if !self.booted {
            self.booted = true;
            p.load_settings(&mut self.store);
        }
        p.service_store(&mut self.store);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::config::MachineConfig;

    #[test]
    fn the_image_keeps_saved_settings_between_opens() {
        let dir = std::env::temp_dir().join(format!("sim-flash-{}", std::process::id()));
        let _ = std::fs::remove_file(&dir);
        let mut p = Printer::new(MachineConfig::ENDER3);
        let mut fs = FlashStore::open(&dir).unwrap();
        fs.service(&mut p);
        let lines = b"M92 E101\nM500\n";
        assert_eq!(p.receive(lines, 0), lines.len(), "both lines taken");
        p.poll(0);
        fs.service(&mut p);
        let mut out = String::new();
        p.write_output(&mut out).unwrap();
        assert!(out.contains("Settings Stored"), "{out}");
        assert_eq!(std::fs::metadata(&dir).unwrap().len(), IMAGE_LEN as u64);
        drop(fs);
        let mut p = Printer::new(MachineConfig::ENDER3);
        FlashStore::open(&dir).unwrap().service(&mut p);
        assert_eq!(p.settings().steps_per_mm[3], 101.0);
        std::fs::write(&dir, b"short").unwrap();
        assert!(FlashStore::open(&dir).is_err());
        let _ = std::fs::remove_file(&dir);
    }
}
