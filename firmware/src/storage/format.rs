//! The store's on-flash format, as bytes (no flash access here; `sector.rs` reads it from a
//! flash, `store.rs` writes it). All multi-byte fields little-endian; every unit a whole number
//! of the flash's program words (`word`, a power of two up to 32 bytes: 4 on the STM32F4 as
//! embassy-stm32 programs it).
//!
//! ```text
//! sector  = header copy 0 │ header copy 1 │ frame │ frame │ … │ erased (0xFF) to the end
//! header  = u32 magic "LPst" │ u16 store format (1) │ u16 0 │ u32 epoch │
//!           u32 CRC-32 of the 12 bytes before it           (padded to H = max(16, word))
//! frame   = head │ data (len bytes, 0xFF-padded to a word) │ commit
//! head    = u32 magic "LPrc" │ u8 key │ u8 0 │ u16 len │ u32 epoch │
//!           u32 CRC-32 of (the 12 bytes before it, the frame's offset in its sector as u32)
//!                                                          (padded to H)
//! commit  = u32 magic "LPok" │ u32 CRC-32 of (head's 16 bytes, data, offset as u32)
//!                                                          (padded to C = max(8, word))
//! ```
//!
//! A sector is trusted only by a header this store wrote (magic, format, CRC); of two trusted
//! sectors the one with the higher epoch is current. A frame counts only with its commit
//! written after it and matching: a frame cut at any point, or whose bytes a stray write
//! changed, fails its CRC. Both CRCs bind the frame to its place (its offset) and the head to its
//! sector's generation (epoch): the same bytes anywhere else — a frame's image inside another
//! record's data, a frame left from an earlier life of the sector — are not a frame. A frame
//! with no data (`len` 0) says the key has no value (a cleared paused job).

use super::crc::crc32_parts;
use super::job::JOB_RECORD_LEN;
use super::record::RECORD_LEN;

/// First word of a sector header.
pub const SECTOR_MAGIC: u32 = u32::from_le_bytes(*b"LPst");
/// First word of a frame's head.
pub const FRAME_MAGIC: u32 = u32::from_le_bytes(*b"LPrc");
/// First word of a frame's commit.
pub const COMMIT_MAGIC: u32 = u32::from_le_bytes(*b"LPok");
/// Version of this layout (in every sector header).
pub const STORE_FORMAT: u16 = 1;
/// Most data bytes one frame carries (the paused-job record, 244 bytes, is the longest).
pub const MAX_DATA: usize = 256;
/// Keys the store keeps: 1 the settings, 2 the paused job.
pub const KEYS: usize = 2;

const _: () = assert!(JOB_RECORD_LEN <= MAX_DATA && RECORD_LEN <= MAX_DATA);

/// Bytes of the largest frame (head and commit at a 32-byte word, the longest data).
pub const FRAME_CAP: usize = 32 + MAX_DATA + 32;

/// The layout's sizes for a flash programmed in words of `word` bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Program word, bytes.
    pub word: u32,
}

impl Layout {
    /// Bytes of a header copy and of a frame's head.
    pub const fn head(self) -> u32 {
        if self.word > 16 {
            self.word
        } else {
            16
        }
    }

    /// Bytes of a frame's commit.
    pub const fn commit(self) -> u32 {
        if self.word > 8 {
            self.word
        } else {
            8
        }
    }

    /// Where the first frame of a sector starts (after the two header copies).
    pub const fn records_start(self) -> u32 {
        2 * self.head()
    }

    /// `len` rounded up to whole words.
    pub const fn padded(self, len: u32) -> u32 {
        len.div_ceil(self.word) * self.word
    }

    /// Bytes of a frame carrying `len` data bytes.
    pub const fn frame_len(self, len: u32) -> u32 {
        self.head() + self.padded(len) + self.commit()
    }
}

/// A key's number (1 or 2) as an index into per-key tables, `None` for any other byte.
pub const fn key_index(key: u8) -> Option<usize> {
    match key {
        1..=2 => Some(key as usize - 1),
        _ => None,
    }
}

fn le32(b: &[u8], at: usize) -> u32 {
    match b.get(at..at + 4) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

/// The 16 bytes of a sector header of generation `epoch`.
pub fn sector_header(epoch: u32) -> [u8; 16] {
    let mut h = [0u8; 16];
    h[0..4].copy_from_slice(&SECTOR_MAGIC.to_le_bytes());
    h[4..6].copy_from_slice(&STORE_FORMAT.to_le_bytes());
    h[8..12].copy_from_slice(&epoch.to_le_bytes());
    let crc = crc32_parts(&[&h[..12]]);
    h[12..16].copy_from_slice(&crc.to_le_bytes());
    h
}

/// The epoch of a sector header copy (its first 16 bytes), `None` when the bytes are not a
/// header this store wrote (another magic or format, a wrong CRC).
pub fn parse_sector_header(b: &[u8]) -> Option<u32> {
    let h = b.get(..16)?;
    let ok = le32(h, 0) == SECTOR_MAGIC
        && h[4..8] == [STORE_FORMAT as u8, (STORE_FORMAT >> 8) as u8, 0, 0]
        && le32(h, 12) == crc32_parts(&[&h[..12]]);
    ok.then(|| le32(h, 8))
}

/// A frame's head, read and checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Head {
    /// Key (1 or 2).
    pub key: u8,
    /// Data bytes.
    pub len: u16,
}

/// The head at offset `at` of a sector of generation `epoch`, if `b` (its first 16 bytes) is
/// one this store wrote there.
pub fn parse_head(b: &[u8], at: u32, epoch: u32) -> Option<Head> {
    let h = b.get(..16)?;
    let len = u16::from_le_bytes([h[6], h[7]]);
    let ok = le32(h, 0) == FRAME_MAGIC
        && key_index(h[4]).is_some()
        && h[5] == 0
        && usize::from(len) <= MAX_DATA
        && le32(h, 8) == epoch
        && le32(h, 12) == crc32_parts(&[&h[..12], &at.to_le_bytes()]);
    ok.then_some(Head { key: h[4], len })
}

/// Fill `buf` with the frame for offset `at` of a sector of generation `epoch`, key `key`,
/// whose `len` data bytes are already at `buf[H..H + len]`; returns the frame's length.
/// `buf` must hold [`Layout::frame_len`]`(len)` bytes.
pub fn encode_frame(l: Layout, buf: &mut [u8], at: u32, epoch: u32, key: u8, len: usize) -> usize {
    let (h, c) = (l.head() as usize, l.commit() as usize);
    let data_end = h + l.padded(len as u32) as usize;
    let total = data_end + c;
    let Some(buf) = buf.get_mut(..total) else {
        return 0;
    };
    buf[0..4].copy_from_slice(&FRAME_MAGIC.to_le_bytes());
    buf[4] = key;
    buf[5] = 0;
    buf[6..8].copy_from_slice(&(len as u16).to_le_bytes());
    buf[8..12].copy_from_slice(&epoch.to_le_bytes());
    let crc = crc32_parts(&[&buf[..12], &at.to_le_bytes()]);
    buf[12..16].copy_from_slice(&crc.to_le_bytes());
    buf[16..h].fill(0xFF);
    buf[h + len..data_end].fill(0xFF);
    let crc = crc32_parts(&[&buf[..16], &buf[h..h + len], &at.to_le_bytes()]);
    let commit = &mut buf[data_end..];
    commit.fill(0xFF);
    commit[0..4].copy_from_slice(&COMMIT_MAGIC.to_le_bytes());
    commit[4..8].copy_from_slice(&crc.to_le_bytes());
    total
}

/// True when `frame` (a whole frame's bytes, head first, at offset `at`) has its commit
/// written and matching: the frame is whole and unchanged.
pub fn commit_ok(l: Layout, frame: &[u8], at: u32, head: Head) -> bool {
    let h = l.head() as usize;
    let len = usize::from(head.len);
    let c = h + l.padded(u32::from(head.len)) as usize;
    let (Some(head16), Some(data), Some(commit)) = (
        frame.get(..16),
        frame.get(h..h + len),
        frame.get(c..c + l.commit() as usize),
    ) else {
        return false;
    };
    le32(commit, 0) == COMMIT_MAGIC
        && le32(commit, 4) == crc32_parts(&[head16, data, &at.to_le_bytes()])
}

#[cfg(test)]
mod tests {
    use super::*;

    const L4: Layout = Layout { word: 4 };
    const L16: Layout = Layout { word: 16 };

    #[test]
    fn sizes_follow_the_word() {
        assert_eq!((L4.head(), L4.commit(), L4.records_start()), (16, 8, 32));
        assert_eq!(
            (L16.head(), L16.commit(), L16.records_start()),
            (16, 16, 32)
        );
        let l32 = Layout { word: 32 };
        assert_eq!((l32.head(), l32.commit(), l32.frame_len(1)), (32, 32, 96));
        // The board's frames (4-byte words): settings 188, paused job 268, a cleared job 24
        // bytes; at 16-byte words 208, 288, 32.
        let (settings, job) = (RECORD_LEN as u32, JOB_RECORD_LEN as u32);
        assert_eq!(
            [L4.frame_len(settings), L4.frame_len(job), L4.frame_len(0)],
            [188, 268, 24]
        );
        assert_eq!(
            [
                L16.frame_len(settings),
                L16.frame_len(job),
                L16.frame_len(0)
            ],
            [208, 288, 32]
        );
        assert!(l32.frame_len(MAX_DATA as u32) as usize <= FRAME_CAP);
    }

    #[test]
    fn a_header_round_trips_and_any_changed_bit_is_refused() {
        let h = sector_header(7);
        assert_eq!(parse_sector_header(&h), Some(7));
        for i in 0..16 * 8 {
            let mut d = h;
            d[i / 8] ^= 1 << (i % 8);
            assert_eq!(parse_sector_header(&d), None, "bit {i}");
        }
        assert_eq!(parse_sector_header(&[0xFF; 16]), None);
        assert_eq!(parse_sector_header(&[0; 16]), None);
    }

    #[test]
    fn a_frame_is_bound_to_its_place_and_generation_and_every_bit_counts() {
        for l in [L4, L16] {
            let mut buf = [0u8; FRAME_CAP];
            let data = b"seven bytes";
            let h = l.head() as usize;
            buf[h..h + data.len()].copy_from_slice(data);
            let n = encode_frame(l, &mut buf, 96, 3, 2, data.len());
            assert_eq!(n, l.frame_len(data.len() as u32) as usize);
            let head = parse_head(&buf, 96, 3).unwrap();
            assert_eq!(head, Head { key: 2, len: 11 });
            assert!(commit_ok(l, &buf[..n], 96, head));
            // Elsewhere, or in another generation: not a frame.
            assert_eq!(parse_head(&buf, 96 + l.word, 3), None);
            assert_eq!(parse_head(&buf, 96, 4), None);
            assert!(!commit_ok(l, &buf[..n], 96 + l.word, head));
            // Any bit of head, data or commit changed: refused (padding is not data).
            let data_end = h + data.len();
            let commit = h + l.padded(data.len() as u32) as usize;
            for i in 0..n * 8 {
                let mut d = buf;
                d[i / 8] ^= 1 << (i % 8);
                let ok = parse_head(&d, 96, 3).is_some_and(|hd| commit_ok(l, &d[..n], 96, hd));
                let byte = i / 8;
                let padding = (16..h).contains(&byte)
                    || (data_end..commit).contains(&byte)
                    || byte >= commit + 8;
                assert_eq!(ok, padding, "word {}, bit {i}", l.word);
            }
        }
    }
}
