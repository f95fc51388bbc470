//! Reading the store's two sectors from a flash (the format is in `format.rs`): a sector's
//! generation, whether a range is erased, where its written bytes end, and the walk over its
//! frames that finds each key's newest whole one — what a boot reads, and what a save reads
//! back before it says it is done.

use super::format::{self, Layout, FRAME_CAP, KEYS};
use embedded_storage::nor_flash::ReadNorFlash;

/// The area's geometry: two sectors of `sector` bytes from `base` (flash offsets).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Area {
    /// First byte of sector 0.
    pub base: u32,
    /// Sector (erase unit) size, bytes.
    pub sector: u32,
    /// The format's sizes for this flash's program word.
    pub layout: Layout,
}

impl Area {
    /// Flash offset of sector `index` (0 or 1).
    pub fn start(&self, index: usize) -> u32 {
        self.base + index as u32 * self.sector
    }
}

/// A flash read failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadError;

/// A frame in a sector: its offset there and its data length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    /// Offset of the frame's head in its sector.
    pub at: u32,
    /// Data bytes.
    pub len: u16,
}

/// A frame's bytes (aligned: some internal flash drivers want aligned sources).
#[repr(align(4))]
pub struct FrameBuf(pub [u8; FRAME_CAP]);

fn read<F: ReadNorFlash>(f: &mut F, at: u32, b: &mut [u8]) -> Result<(), ReadError> {
    f.read(at, b).map_err(|_| ReadError)
}

/// The generation of sector `index`: the epoch of a header copy this store wrote (the higher
/// if both are readable), `None` when neither is (erased, foreign or damaged).
pub fn epoch<F: ReadNorFlash>(f: &mut F, a: &Area, index: usize) -> Result<Option<u32>, ReadError> {
    let mut b = [0u8; 16];
    let mut best: Option<u32> = None;
    for copy in 0..2 {
        read(f, a.start(index) + copy * a.layout.head(), &mut b)?;
        if let Some(e) = format::parse_sector_header(&b) {
            best = Some(best.map_or(e, |x| x.max(e)));
        }
    }
    Ok(best)
}

/// True when every byte of `from..to` reads `0xFF`.
pub fn is_erased<F: ReadNorFlash>(f: &mut F, from: u32, to: u32) -> Result<bool, ReadError> {
    let mut chunk = [0u8; 64];
    let mut at = from;
    while at < to {
        let n = (to - at).min(64);
        let part = &mut chunk[..n as usize];
        read(f, at, part)?;
        if part.iter().any(|b| *b != 0xFF) {
            return Ok(false);
        }
        at += n;
    }
    Ok(true)
}

/// Offset in sector `index` just past its last byte that is not `0xFF`, rounded up to a word
/// (at least where frames start): nothing is ever programmed below it again. Reads from the
/// end, so only the free room (and the last word written).
pub fn used_end<F: ReadNorFlash>(f: &mut F, a: &Area, index: usize) -> Result<u32, ReadError> {
    let mut chunk = [0u8; 64];
    let floor = a.layout.records_start();
    let mut end = a.sector;
    while end > floor {
        let n = (end - floor).min(64);
        let start = end - n;
        let part = &mut chunk[..n as usize];
        read(f, a.start(index) + start, part)?;
        if let Some(i) = part.iter().rposition(|b| *b != 0xFF) {
            return Ok(a.layout.padded(start + i as u32 + 1));
        }
        end = start;
    }
    Ok(floor)
}

/// The walk over a sector's frames, in the order they were written: a head this store wrote
/// there (its CRC binds it to its offset and the sector's epoch) is a frame, skipped whole;
/// anything else (a frame cut before its head was whole, stray bytes) is stepped over a word
/// at a time. Nothing is appended inside a head's frame (see [`Walk::end`]), so a whole head is
/// never inside another frame.
pub struct Walk {
    at: u32,
    until: u32,
    epoch: u32,
    /// Past the last frame whose head was found (where frames start, if none).
    heads_end: u32,
}

impl Walk {
    /// A walk over sector `index` of generation `epoch`, up to `until` (its [`used_end`]).
    pub fn new(a: &Area, epoch: u32, until: u32) -> Self {
        let start = a.layout.records_start();
        Walk {
            at: start,
            until,
            epoch,
            heads_end: start,
        }
    }

    /// The next frame head: its slot and key.
    pub fn next<F: ReadNorFlash>(
        &mut self,
        f: &mut F,
        a: &Area,
        index: usize,
    ) -> Result<Option<(Slot, u8)>, ReadError> {
        let mut b = [0u8; 16];
        while self.at < self.until && self.at + 16 <= a.sector {
            let at = self.at;
            read(f, a.start(index) + at, &mut b)?;
            if let Some(h) = format::parse_head(&b, at, self.epoch) {
                let end = at + a.layout.frame_len(u32::from(h.len));
                if end <= a.sector {
                    self.at = end;
                    self.heads_end = end;
                    return Ok(Some((Slot { at, len: h.len }, h.key)));
                }
            }
            self.at = at + a.layout.word;
        }
        Ok(None)
    }

    /// Where the next frame may be written, once the walk is over: past `used` (the
    /// sector's [`used_end`]) and past the last head's frame, even one whose commit was never
    /// written (its commit's place may read erased).
    pub fn end(&self, used: u32) -> u32 {
        used.max(self.heads_end)
    }
}

/// Read the frame at `slot` of sector `index` (generation `epoch`) into `buf` and check it
/// whole: true when its head and commit are what this store wrote there. Its data is then at
/// `buf[H..H + len]`.
pub fn read_frame<F: ReadNorFlash>(
    f: &mut F,
    a: &Area,
    index: usize,
    epoch: u32,
    slot: Slot,
    buf: &mut FrameBuf,
) -> Result<bool, ReadError> {
    let n = a.layout.frame_len(u32::from(slot.len)) as usize;
    let Some(frame) = buf.0.get_mut(..n) else {
        return Ok(false);
    };
    read(f, a.start(index) + slot.at, frame)?;
    Ok(format::parse_head(frame, slot.at, epoch)
        .is_some_and(|h| h.len == slot.len && format::commit_ok(a.layout, frame, slot.at, h)))
}

/// Heads remembered per key during a scan: the newest whole frame is almost always the last
/// head, or the one before it (two copies of every save).
const RECENT: usize = 4;

/// What a scan of a trusted sector found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scan {
    /// Each key's newest whole frame.
    pub latest: [Option<Slot>; KEYS],
    /// Keys with a frame head but no whole frame: a record damaged, or its only save cut.
    pub damaged: [bool; KEYS],
    /// Where the next frame may be written.
    pub end: u32,
}

/// Scan sector `index` (generation `epoch`): each key's newest whole frame, and the free room.
/// The last [`RECENT`] heads of each key are checked newest first; if none is whole (saves
/// cut again and again), the sector is walked again checking every frame of that key.
pub fn scan<F: ReadNorFlash>(
    f: &mut F,
    a: &Area,
    index: usize,
    epoch: u32,
    buf: &mut FrameBuf,
) -> Result<Scan, ReadError> {
    let used = used_end(f, a, index)?;
    let mut recent = [[None::<Slot>; RECENT]; KEYS];
    let mut seen = [0usize; KEYS];
    let mut walk = Walk::new(a, epoch, used);
    while let Some((slot, key)) = walk.next(f, a, index)? {
        let Some(k) = format::key_index(key) else {
            continue;
        };
        recent[k][seen[k] % RECENT] = Some(slot);
        seen[k] += 1;
    }
    let mut latest = [None; KEYS];
    for k in 0..KEYS {
        for back in 1..=seen[k].min(RECENT) {
            let Some(slot) = recent[k][(seen[k] - back) % RECENT] else {
                continue;
            };
            if read_frame(f, a, index, epoch, slot, buf)? {
                latest[k] = Some(slot);
                break;
            }
        }
        if latest[k].is_none() && seen[k] > RECENT {
            let mut again = Walk::new(a, epoch, used);
            while let Some((slot, key)) = again.next(f, a, index)? {
                if format::key_index(key) == Some(k) && read_frame(f, a, index, epoch, slot, buf)? {
                    latest[k] = Some(slot);
                }
            }
        }
    }
    Ok(Scan {
        latest,
        damaged: core::array::from_fn(|k| seen[k] > 0 && latest[k].is_none()),
        end: walk.end(used),
    })
}
