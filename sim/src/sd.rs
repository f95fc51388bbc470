//! `sim serve --sd DIR`: the directory as the printer's SD card, read through the firmware's
//! own FAT code ([`firmware::storage::sd::Card`], embedded-sdmmc).
//!
//! At startup the files of DIR (regular files, in its sub-directories too) are copied into a
//! FAT image in a temporary file, made with the `fatfs` crate (an independent FAT
//! implementation, so the firmware's reader is checked against a writer it does not share; no
//! external tool such as mkfs.fat/mtools is needed). The image has an MBR with one partition
//! at block 2048, as cards are sold (embedded-sdmmc reads only MBR-partitioned cards): FAT16
//! with 512-byte clusters up to 24 MiB of files, FAT32 beyond. Long file names are kept
//! (VFAT). The image is served as a file-backed block device ([`ImageDevice`]) and deleted
//! when the session ends; later changes to DIR are not seen (restart the session).
//! `--sd IMAGE` serves an existing image instead. The firmware writes only its parked
//! intake's spill file (docs/frontend.md, "Host rules"); those writes go to blocks kept in
//! memory ([`ImageDevice`]'s overlay), so an image file is never changed by a session.

use anyhow::{bail, Context};
use embedded_sdmmc::{Block, BlockCount, BlockDevice, BlockIdx};
use std::fs::{File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// First block of the partition (1 MiB in, as card formatters align it).
pub const PARTITION_START_BLOCK: u32 = 2048;
/// Largest total file size put on a FAT16 image, bytes.
const FAT16_FILES_MAX: u64 = 24 << 20;

/// A card image in a file, as a block device.
pub struct ImageDevice {
    file: File,
    blocks: u32,
    /// Deleted on drop (a temporary image built from a directory).
    temp: Option<PathBuf>,
    /// Blocks the firmware wrote (the spill file), kept in memory for the session.
    written: std::cell::RefCell<std::collections::HashMap<u32, [u8; 512]>>,
}

impl ImageDevice {
    /// Serve an existing image (opened read-only).
    pub fn open(path: &Path) -> anyhow::Result<Self> {
        let file = File::open(path).with_context(|| format!("opening {}", path.display()))?;
        let len = file.metadata()?.len();
        if len < 512 * u64::from(PARTITION_START_BLOCK) / 2 || len % 512 != 0 {
            bail!("{} is not a card image ({len} bytes)", path.display());
        }
        Ok(Self {
            file,
            blocks: u32::try_from(len / 512).unwrap_or(u32::MAX),
            temp: None,
            written: Default::default(),
        })
    }

    /// Build an image of `dir`'s files (and its sub-directories') in a temporary file (see
    /// the module documentation).
    pub fn from_dir(dir: &Path) -> anyhow::Result<Self> {
        let mut files = Vec::new();
        collect_files(dir, "", 0, &mut files)?;
        files.sort();
        let path = std::env::temp_dir().join(format!(
            "sim-sd-{}-{}.img",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_nanos())
                .unwrap_or(0)
        ));
        let mut contents = Vec::new();
        for (name, p) in &files {
            contents.push((
                name.clone(),
                std::fs::read(p).with_context(|| format!("reading {}", p.display()))?,
            ));
        }
        write_image(&path, &contents)?;
        let mut dev = Self::open(&path)?;
        dev.temp = Some(path);
        Ok(dev)
    }
}

impl Drop for ImageDevice {
    fn drop(&mut self) {
        if let Some(p) = &self.temp {
            let _ = std::fs::remove_file(p);
        }
    }
}

impl BlockDevice for ImageDevice {
    type Error = io::ErrorKind;

    fn read(&self, blocks: &mut [Block], start: BlockIdx) -> Result<(), Self::Error> {
        let written = self.written.borrow();
        for (i, b) in blocks.iter_mut().enumerate() {
            let idx = start.0.saturating_add(i as u32);
            if let Some(w) = written.get(&idx) {
                b.contents = *w;
                continue;
            }
            self.file
                .read_exact_at(&mut b.contents, u64::from(idx) * 512)
                .map_err(|e| e.kind())?;
        }
        Ok(())
    }

    fn write(&self, blocks: &[Block], start: BlockIdx) -> Result<(), Self::Error> {
        // Into the overlay: the image file is never changed by a session.
        let mut written = self.written.borrow_mut();
        for (i, b) in blocks.iter().enumerate() {
            let idx = start.0.saturating_add(i as u32);
            if idx >= self.blocks {
                return Err(io::ErrorKind::InvalidInput);
            }
            written.insert(idx, b.contents);
        }
        Ok(())
    }

    fn num_blocks(&self) -> Result<BlockCount, Self::Error> {
        Ok(BlockCount(self.blocks))
    }
}

/// A byte range of a file (the partition), for `fatfs`.
struct Part<'a> {
    file: &'a File,
    start: u64,
    len: u64,
    pos: u64,
}

impl Read for Part<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = (buf.len() as u64).min(self.len.saturating_sub(self.pos)) as usize;
        let n = self.file.read_at(&mut buf[..n], self.start + self.pos)?;
        self.pos += n as u64;
        Ok(n)
    }
}

impl Write for Part<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = (buf.len() as u64).min(self.len.saturating_sub(self.pos)) as usize;
        if n == 0 && !buf.is_empty() {
            return Err(io::Error::new(io::ErrorKind::WriteZero, "partition full"));
        }
        let n = self.file.write_at(&buf[..n], self.start + self.pos)?;
        self.pos += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Seek for Part<'_> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let p = match to {
            SeekFrom::Start(p) => p as i128,
            SeekFrom::Current(d) => self.pos as i128 + d as i128,
            SeekFrom::End(d) => self.len as i128 + d as i128,
        };
        if p < 0 {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, "seek before 0"));
        }
        self.pos = p as u64;
        Ok(self.pos)
    }
}

/// Directory levels below DIR that `from_dir` copies (deeper ones are left out; the firmware
/// reads 6, `CARD_MAX_DEPTH`, and the tests make deeper ones on purpose with `write_image`).
const COPY_DEPTH: usize = 16;

/// The regular files under `dir` as (`prefix/name` path, file path), down to COPY_DEPTH.
fn collect_files(
    dir: &Path,
    prefix: &str,
    depth: usize,
    out: &mut Vec<(String, PathBuf)>,
) -> anyhow::Result<()> {
    for e in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let e = e?;
        let name = format!("{prefix}{}", e.file_name().to_string_lossy());
        let t = e.file_type()?;
        if t.is_file() {
            out.push((name, e.path()));
        } else if t.is_dir() && depth < COPY_DEPTH {
            collect_files(&e.path(), &format!("{name}/"), depth + 1, out)?;
        }
    }
    Ok(())
}

/// Write a card image holding `files` (path, contents) to `path`: MBR, one FAT partition. A
/// path with `/` puts the file in sub-directories (created as needed).
pub fn write_image(path: &Path, files: &[(String, Vec<u8>)]) -> anyhow::Result<()> {
    let total: u64 = files.iter().map(|(_, c)| c.len() as u64 + 4096).sum();
    let fat16 = total <= FAT16_FILES_MAX;
    // FAT16 with 512-byte clusters needs 4085..65525 clusters; FAT32 at least 65525.
    let part_bytes = if fat16 {
        (total + total / 4 + (4 << 20)).clamp(8 << 20, 30 << 20)
    } else {
        (total + total / 4 + (4 << 20)).max(40 << 20)
    };
    let part_blocks = u32::try_from(part_bytes / 512).context("image too large")?;
    let start = u64::from(PARTITION_START_BLOCK) * 512;
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(path)
        .with_context(|| format!("creating {}", path.display()))?;
    file.set_len(start + u64::from(part_blocks) * 512)?;
    let mut mbr = [0u8; 512];
    let entry = &mut mbr[446..462];
    entry[4] = if fat16 { 0x0E } else { 0x0C }; // FAT16 LBA / FAT32 LBA
    entry[8..12].copy_from_slice(&PARTITION_START_BLOCK.to_le_bytes());
    entry[12..16].copy_from_slice(&part_blocks.to_le_bytes());
    mbr[510] = 0x55;
    mbr[511] = 0xAA;
    file.write_all_at(&mbr, 0)?;
    let part = || Part {
        file: &file,
        start,
        len: u64::from(part_blocks) * 512,
        pos: 0,
    };
    let fat_type = if fat16 {
        fatfs::FatType::Fat16
    } else {
        fatfs::FatType::Fat32
    };
    fatfs::format_volume(
        part(),
        fatfs::FormatVolumeOptions::new()
            .fat_type(fat_type)
            .bytes_per_cluster(512)
            .total_sectors(part_blocks)
            .volume_label(*b"LAYERPAUSE "),
    )
    .context("formatting the card image")?;
    let fs = fatfs::FileSystem::new(part(), fatfs::FsOptions::new())
        .context("opening the new card image")?;
    let root = fs.root_dir();
    for (name, contents) in files {
        let mut dir = root.clone();
        let mut parts: Vec<&str> = name.split('/').collect();
        let leaf = parts.pop().unwrap_or_default();
        for d in parts {
            dir = match dir.open_dir(d) {
                Ok(sub) => sub,
                Err(_) => dir
                    .create_dir(d)
                    .with_context(|| format!("directory {d} of {name} on the card image"))?,
            };
        }
        let mut f = dir
            .create_file(leaf)
            .with_context(|| format!("{name} on the card image"))?;
        f.truncate()?;
        f.write_all(contents)
            .with_context(|| format!("writing {name} to the card image"))?;
        f.flush()?;
    }
    drop(root);
    fs.unmount().context("closing the card image")?;
    Ok(())
}
